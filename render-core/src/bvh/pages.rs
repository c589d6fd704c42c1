//! Huge pages for a big BVH. An incoherent ray's walk lands on a new 4 KiB page at nearly
//! every node and leaf chunk, and a 1M-triangle mesh's walked arrays (48 MB) span about
//! 12 000 such pages, several times what the second-level TLB holds; in 2 MiB pages they are
//! 23. Embree asks Linux for the same (`MADV_HUGEPAGE`) for its BVH. Elsewhere than Linux
//! with glibc this does nothing.

/// Size of a huge page on x86-64 and most aarch64 Linux kernels.
const HUGE_PAGE: usize = 2 << 20;

/// Asks for the whole huge pages inside `items` to be backed by huge pages now, as far as the
/// kernel can (it may refuse: the pages are then left as they are). Contents are unchanged.
pub(super) fn ask_for_huge_pages<T>(items: &[T]) {
    let begin = (items.as_ptr() as usize).next_multiple_of(HUGE_PAGE);
    let end = (items.as_ptr() as usize + size_of_val(items)) / HUGE_PAGE * HUGE_PAGE;
    if end > begin {
        advise(begin, end - begin);
    }
}

#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn advise(begin: usize, len: usize) {
    // MADV_HUGEPAGE marks the range for huge pages when the system leaves it to the program
    // (transparent_hugepage=madvise); MADV_COLLAPSE (Linux 6.1) moves pages already written
    // into huge ones at once, where the marking alone would wait for khugepaged (32 MB took
    // 12-23 ms here; it compacts memory synchronously, so a fragmented machine takes longer,
    // once per BVH build). Older kernels reject MADV_COLLAPSE, which is harmless.
    // SAFETY: advice on whole pages of a live allocation; neither call changes their contents.
    unsafe {
        libc::madvise(begin as *mut libc::c_void, len, libc::MADV_HUGEPAGE);
        libc::madvise(begin as *mut libc::c_void, len, libc::MADV_COLLAPSE);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn advise(_begin: usize, _len: usize) {}

#[cfg(test)]
mod tests {
    use super::*;

    /// The advice may move pages (MADV_COLLAPSE copies them into a huge page); what they
    /// hold must not change, whatever the slice's size and alignment.
    #[test]
    fn asking_for_huge_pages_keeps_what_the_pages_hold() {
        let words: Vec<u32> = (0..(3 * HUGE_PAGE / 4) as u32 + 12_345).map(|i| i.wrapping_mul(2_654_435_761)).collect();
        let before = words.clone();
        for slice in [&words[..], &words[1..], &words[..0], &words[7..9], &words[HUGE_PAGE / 8..]] {
            ask_for_huge_pages(slice);
        }
        assert!(words == before);
    }
}
