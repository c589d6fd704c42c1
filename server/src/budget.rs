//! Memory budgets, checked before allocation: the server's (every session together) and each
//! session's. Work that will allocate reserves its estimate first and holds the
//! [`Reservation`] as long as the memory lives; a reservation that does not fit is refused
//! with `RESOURCE_EXHAUSTED` naming what asked and how much.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use tonic::Status;

/// One budget: a limit and what is reserved against it.
#[derive(Debug)]
pub struct Budget {
    name: String,
    limit: u64,
    used: AtomicU64,
}

impl Budget {
    /// A budget of `limit` bytes, `name`d in refusals ("server", "session s…").
    pub fn new(name: impl Into<String>, limit: u64) -> Arc<Self> {
        Arc::new(Budget { name: name.into(), limit, used: AtomicU64::new(0) })
    }

    /// The limit in bytes.
    pub fn limit(&self) -> u64 {
        self.limit
    }

    /// Bytes reserved now.
    pub fn used(&self) -> u64 {
        self.used.load(Ordering::Acquire)
    }

    /// Bytes still free.
    pub fn available(&self) -> u64 {
        self.limit.saturating_sub(self.used())
    }

    /// Refuses `bytes` that cannot fit even into the whole of what is free now, without
    /// reserving anything (declared sizes, checked before the data arrives).
    pub fn check_fits(budgets: &[Arc<Budget>], bytes: u64, what: &str) -> Result<(), Status> {
        drop(Reservation::take(budgets, bytes, what)?);
        Ok(())
    }

    /// Takes `bytes` if they fit under the limit.
    fn take(&self, bytes: u64) -> Result<(), u64> {
        self.used
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |used| used.checked_add(bytes).filter(|&total| total <= self.limit))
            .map(|_| ())
    }

    fn give_back(&self, bytes: u64) {
        self.used.fetch_sub(bytes, Ordering::AcqRel);
    }
}

/// Bytes held against one or more budgets (a session's and the server's), released on drop.
#[derive(Debug, Default)]
pub struct Reservation {
    budgets: Vec<Arc<Budget>>,
    bytes: u64,
}

impl Reservation {
    /// Reserves `bytes` of every budget in `budgets`, or none of them. `what` names the
    /// allocation in the refusal ("film for 16384x16384 with 12 AOVs").
    pub fn take(budgets: &[Arc<Budget>], bytes: u64, what: &str) -> Result<Reservation, Status> {
        let mut r = Reservation { budgets: Vec::with_capacity(budgets.len()), bytes: 0 };
        r.bytes = bytes;
        for b in budgets {
            if let Err(used) = b.take(bytes) {
                // Already-taken budgets are returned by the drop of `r`.
                return Err(Status::resource_exhausted(format!(
                    "{what} needs {}, but the {} memory budget of {} has {} free",
                    human(bytes),
                    b.name,
                    human(b.limit),
                    human(b.limit.saturating_sub(used))
                )));
            }
            r.budgets.push(Arc::clone(b));
        }
        Ok(r)
    }

    /// Grows the reservation by `bytes` in every budget it holds, or not at all.
    pub fn grow(&mut self, bytes: u64, what: &str) -> Result<(), Status> {
        let more = Reservation::take(&self.budgets, bytes, what)?;
        self.absorb(more);
        Ok(())
    }

    /// Moves another reservation's bytes into this one (both must hold the same budgets).
    pub fn absorb(&mut self, mut other: Reservation) {
        if self.budgets.is_empty() {
            self.budgets = std::mem::take(&mut other.budgets);
        }
        self.bytes += std::mem::take(&mut other.bytes);
    }

    /// Sets the reservation to `bytes`: growing takes the difference from every budget it
    /// holds (or fails, leaving it as it was), shrinking gives the difference back.
    pub fn resize(&mut self, bytes: u64, what: &str) -> Result<(), Status> {
        if bytes > self.bytes {
            return self.grow(bytes - self.bytes, what);
        }
        for b in &self.budgets {
            b.give_back(self.bytes - bytes);
        }
        self.bytes = bytes;
        Ok(())
    }

    /// Bytes held.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }
}

impl Drop for Reservation {
    fn drop(&mut self) {
        for b in &self.budgets {
            b.give_back(self.bytes);
        }
    }
}

/// Bytes for people: "1.5 GiB".
pub fn human(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = bytes as f64;
    let mut unit = 0;
    while v >= 1024.0 && unit + 1 < UNITS.len() {
        v /= 1024.0;
        unit += 1;
    }
    if unit == 0 { format!("{bytes} B") } else { format!("{v:.1} {}", UNITS[unit]) }
}

/// Parses a size as operators write it: `2G`, `512M`, `1.5GiB`, `1000000` (bytes).
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let split = t.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let n: f64 = number.parse().map_err(|_| format!("'{s}' is not a size (examples: 2G, 512M, 1048576)"))?;
    let scale: u64 = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1,
        "k" | "kb" | "kib" => 1 << 10,
        "m" | "mb" | "mib" => 1 << 20,
        "g" | "gb" | "gib" => 1 << 30,
        "t" | "tb" | "tib" => 1 << 40,
        u => return Err(format!("'{s}': unknown unit '{u}' (B, K, M, G, T)")),
    };
    let bytes = n * scale as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(format!("'{s}' is not a positive size"));
    }
    Ok(bytes as u64)
}

/// The default server budget: half of the machine's memory (from `/proc/meminfo`), or 8 GiB
/// where that cannot be read. The other half is for the OS, the allocator's slack and what
/// the estimates do not count.
pub fn default_server_budget() -> u64 {
    let total = std::fs::read_to_string("/proc/meminfo").ok().and_then(|m| {
        let line = m.lines().find(|l| l.starts_with("MemTotal:"))?;
        let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        Some(kib * 1024)
    });
    total.map_or(8 << 30, |t| t / 2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reservations_are_all_or_nothing_and_return_on_drop() {
        let server = Budget::new("server", 100);
        let session = Budget::new("session s1", 60);
        let both = [Arc::clone(&session), Arc::clone(&server)];
        let a = Reservation::take(&both, 50, "a").unwrap();
        let e = Reservation::take(&both, 20, "film").unwrap_err();
        assert_eq!(e.code(), tonic::Code::ResourceExhausted);
        assert!(e.message().contains("film") && e.message().contains("session s1") && e.message().contains("10 B free"), "{e:?}");
        assert_eq!((session.used(), server.used()), (50, 50), "the refused one took nothing");
        let other = Reservation::take(&[Arc::clone(&server)], 50, "b").unwrap();
        assert!(Reservation::take(&[Arc::clone(&server)], 1, "c").is_err());
        drop(a);
        assert_eq!((session.used(), server.used()), (0, 50));
        drop(other);
        assert_eq!(server.used(), 0);
    }

    #[test]
    fn growing_takes_from_the_same_budgets() {
        let server = Budget::new("server", 100);
        let mut r = Reservation::take(&[Arc::clone(&server)], 10, "x").unwrap();
        r.grow(80, "y").unwrap();
        assert!(r.grow(20, "z").is_err());
        assert_eq!((r.bytes(), server.used()), (90, 90));
        drop(r);
        assert_eq!(server.used(), 0);
    }

    #[test]
    fn sizes_parse_as_operators_write_them() {
        assert_eq!(parse_size("2G"), Ok(2 << 30));
        assert_eq!(parse_size("512M"), Ok(512 << 20));
        assert_eq!(parse_size("1.5GiB"), Ok(3 << 29));
        assert_eq!(parse_size("4096"), Ok(4096));
        assert!(parse_size("lots").is_err() && parse_size("0").is_err() && parse_size("2X").is_err());
        assert_eq!(human(3 << 29), "1.5 GiB");
    }
}
