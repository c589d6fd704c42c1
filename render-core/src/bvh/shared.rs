//! A slice that tasks on the thread pool write at once, each at its own indices: what the
//! parallel tree builds write their nodes through.

/// A slice several threads write, each at indices no other thread touches meanwhile.
pub(super) struct Shared<'a, T> {
    start: *mut T,
    len: usize,
    _borrow: std::marker::PhantomData<&'a mut [T]>,
}

impl<T> Clone for Shared<'_, T> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<T> Copy for Shared<'_, T> {}

// SAFETY: the slice is borrowed for as long as any copy lives, so it outlives every task; it
// is only written through `set`, whose callers keep their indices apart.
unsafe impl<T: Send> Send for Shared<'_, T> {}
unsafe impl<T: Send> Sync for Shared<'_, T> {}

impl<'a, T> Shared<'a, T> {
    pub(super) fn new(items: &'a mut [T]) -> Self {
        Shared { start: items.as_mut_ptr(), len: items.len(), _borrow: std::marker::PhantomData }
    }

    /// SAFETY: no other thread reads or writes index `i` meanwhile.
    pub(super) unsafe fn set(&self, i: usize, value: T) {
        assert!(i < self.len);
        unsafe { self.start.add(i).write(value) };
    }

    /// SAFETY: no other thread writes index `i` meanwhile.
    pub(super) unsafe fn get(&self, i: usize) -> T
    where
        T: Copy,
    {
        assert!(i < self.len);
        unsafe { self.start.add(i).read() }
    }
}
