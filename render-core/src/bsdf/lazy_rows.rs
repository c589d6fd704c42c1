//! Tables built a row at a time, each row when a lookup first reads it.
//!
//! The energy tables ([`super::energy`], the Disney diffuse scales) are integrated by this
//! crate's own code, and built whole they took 8.2 s on one core (5 s on two): a render's
//! first tile waited for every table its materials touched, although a material reads only
//! the two to four rows around its own roughness and IOR. Each row's cells seed their own
//! random streams from their coordinates, so a row is the same whether it is built alone, by
//! a lookup, or with the whole table.

use std::sync::OnceLock;

/// `count` rows of `T`, row `i` made by `build(i)` the first time it is read.
pub(crate) struct LazyRows<T> {
    rows: Box<[OnceLock<T>]>,
    build: fn(usize) -> T,
}

impl<T: Send + Sync> LazyRows<T> {
    /// A table of `count` rows, none built yet.
    pub(crate) fn new(count: usize, build: fn(usize) -> T) -> Self {
        LazyRows { rows: (0..count).map(|_| OnceLock::new()).collect(), build }
    }

    /// Row `i`, built now if no lookup has built it before. A thread reading a row another
    /// thread is building waits for that row only. `build` runs no parallel work of its own:
    /// a rayon worker waiting here cannot be handed a task that needs the same row.
    #[inline]
    pub(crate) fn row(&self, i: usize) -> &T {
        self.rows[i].get_or_init(|| (self.build)(i))
    }

    /// Builds every row not built yet, in parallel on the current rayon pool.
    pub(crate) fn build_all(&self) {
        use rayon::prelude::*;
        (0..self.rows.len()).into_par_iter().for_each(|i| {
            self.row(i);
        });
    }

    /// How many rows have been built.
    #[cfg(test)]
    pub(crate) fn built(&self) -> usize {
        self.rows.iter().filter(|r| r.get().is_some()).count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_are_built_once_when_first_read() {
        static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let table = LazyRows::new(8, |i| {
            CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            [i as f32; 4]
        });
        assert_eq!(table.built(), 0);
        assert_eq!(table.row(5), &[5.0; 4]);
        assert_eq!(table.row(5), &[5.0; 4]);
        assert_eq!((table.built(), CALLS.load(std::sync::atomic::Ordering::Relaxed)), (1, 1));
        table.build_all();
        assert_eq!((table.built(), CALLS.load(std::sync::atomic::Ordering::Relaxed)), (8, 8));
        assert!((0..8).all(|i| table.row(i) == &[i as f32; 4]));
    }
}
