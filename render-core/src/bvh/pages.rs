//! Huge pages for a big BVH. An incoherent ray's walk lands on a new 4 KiB page at nearly
//! every node and leaf chunk, and a 1M-triangle mesh's walked arrays (48 MB) span about
//! 12 000 such pages, several times what the second-level TLB holds; in 2 MiB pages they are
//! 23. Embree asks Linux for the same (`MADV_HUGEPAGE`) for its BVH. Elsewhere than Linux
//! with glibc this does nothing.

/// Size of a huge page on x86-64 and most aarch64 Linux kernels.
const HUGE_PAGE: usize = 2 << 20;

/// glibc's largest threshold for serving an allocation with a fresh mapping
/// (`DEFAULT_MMAP_THRESHOLD_MAX` on 64-bit; the threshold rises towards it as big blocks are
/// freed). Smaller blocks may reuse memory written before.
const FRESH_MAPPING: usize = 32 << 20;

/// An empty vector with room for at least `len` items whose whole huge pages are marked for
/// huge pages before anything is written to them. Fresh memory is then backed by huge pages as
/// it is first written, where collapsing pages already written ([`ask_for_huge_pages`]) copies
/// them: 0.45 s for a 3.1M-triangle mesh's 143 MB here. An array of a huge page or more gets
/// room for more than [`FRESH_MAPPING`] bytes so that its memory is fresh; the room it does
/// not fill is never written, so it costs address space, not memory.
pub(super) fn huge_vec<T>(len: usize) -> Vec<T> {
    let bytes = len * size_of::<T>();
    let room = match bytes >= HUGE_PAGE && size_of::<T>() > 0 {
        true => len.max((FRESH_MAPPING + HUGE_PAGE).div_ceil(size_of::<T>())),
        false => len,
    };
    let v = Vec::with_capacity(room);
    let (begin, end) = whole_huge_pages(v.as_ptr() as usize, bytes);
    if end > begin {
        mark(begin, end - begin);
    }
    v
}

/// Asks for the whole huge pages inside `items` to be backed by huge pages now, as far as the
/// kernel can (it may refuse: the pages are then left as they are). Contents are unchanged.
/// Cheap where [`huge_vec`] got them already; it catches memory the allocator reused.
pub(super) fn ask_for_huge_pages<T>(items: &[T]) {
    let (begin, end) = whole_huge_pages(items.as_ptr() as usize, size_of_val(items));
    if end > begin {
        mark(begin, end - begin);
        collapse(begin, end - begin);
    }
}

/// The first and past-the-end addresses of the whole huge pages in `len` bytes from `start`.
fn whole_huge_pages(start: usize, len: usize) -> (usize, usize) {
    (start.next_multiple_of(HUGE_PAGE), (start + len) / HUGE_PAGE * HUGE_PAGE)
}

/// MADV_HUGEPAGE: marks the range for huge pages when the system leaves it to the program
/// (transparent_hugepage=madvise); pages not yet written come as huge pages.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn mark(begin: usize, len: usize) {
    // SAFETY: advice on whole pages of a live allocation; it does not change their contents.
    unsafe { libc::madvise(begin as *mut libc::c_void, len, libc::MADV_HUGEPAGE) };
}

/// MADV_COLLAPSE (Linux 6.1): moves pages already written into huge ones at once, where the
/// marking alone would wait for khugepaged. It copies them and compacts memory synchronously,
/// so it costs about 3 ms per MB here; on pages that are huge already it only checks. Older
/// kernels reject it, which is harmless.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn collapse(begin: usize, len: usize) {
    // SAFETY: advice on whole pages of a live allocation; it does not change their contents.
    unsafe { libc::madvise(begin as *mut libc::c_void, len, libc::MADV_COLLAPSE) };
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn mark(_begin: usize, _len: usize) {}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn collapse(_begin: usize, _len: usize) {}

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

    /// Where the system gives huge pages to programs that ask (transparent_hugepage set to
    /// `madvise` or `always`, as on Debian and this project's CI), a vector from `huge_vec` is
    /// backed by huge pages as it is written, with nothing collapsed afterwards.
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    #[test]
    fn a_huge_vec_gets_huge_pages_as_it_is_written() {
        let mode = std::fs::read_to_string("/sys/kernel/mm/transparent_hugepage/enabled").unwrap_or_default();
        if !mode.contains("[madvise]") && !mode.contains("[always]") {
            eprintln!("transparent huge pages are off here ({mode:?}): nothing to check");
            return;
        }
        let len = 3 * HUGE_PAGE / size_of::<u64>();
        let mut words: Vec<u64> = huge_vec(len);
        words.resize(len, 7);
        // Three huge pages written from wherever the allocation starts: two whole ones. The
        // advice splits the mapping where they begin. One is asked for, not both, so that a
        // machine short of free huge pages at that moment does not fail the test; without the
        // advice there are none.
        let huge = anon_huge_bytes_of_mapping_holding((words.as_ptr() as usize).next_multiple_of(HUGE_PAGE));
        assert!(huge >= HUGE_PAGE, "{huge} bytes in huge pages");
        assert!(words.iter().all(|&w| w == 7));
    }

    /// `AnonHugePages` of the mapping holding `address`, from `/proc/self/smaps`.
    fn anon_huge_bytes_of_mapping_holding(address: usize) -> usize {
        let smaps = std::fs::read_to_string("/proc/self/smaps").unwrap();
        let mut inside = false;
        for line in smaps.lines() {
            let range = line.split_whitespace().next().and_then(|r| r.split_once('-'));
            if let Some((lo, hi)) =
                range.and_then(|(lo, hi)| Some((usize::from_str_radix(lo, 16).ok()?, usize::from_str_radix(hi, 16).ok()?)))
            {
                inside = (lo..hi).contains(&address);
            } else if inside && let Some(kb) = line.strip_prefix("AnonHugePages:") {
                return kb.trim().trim_end_matches("kB").trim().parse::<usize>().unwrap() << 10;
            }
        }
        panic!("no mapping holds {address:#x}")
    }
}
