//! Transparent huge pages for the large arrays of a triangle hierarchy.
//!
//! A ray through a hierarchy of a million triangles reads a dozen nodes and a few triangle packs scattered over
//! about 80 MiB; with 4 KiB pages nearly every one of those reads of an incoherent ray also misses the TLB and
//! walks the page table. Linux backs memory with 2 MiB pages where a program asks for it with
//! `madvise(MADV_HUGEPAGE)` (the default `transparent_hugepage/enabled` setting, `madvise`), which lets the TLB
//! cover 512 times as much memory. The advice changes neither the contents nor the validity of the memory, only
//! how the kernel backs it, and it is given before the array is written so that its first touches fault in
//! huge pages. Elsewhere, or where the kernel refuses, nothing changes.

/// Arrays smaller than one huge page are left alone: they could not fill one.
const HUGE_PAGE: usize = 2 << 20;

/// An empty vector with room for `capacity` elements whose buffer, when it spans at least a huge page, the kernel
/// is asked to back with transparent huge pages (on Linux; elsewhere a plain [`Vec::with_capacity`]).
pub(super) fn huge_vec<T>(capacity: usize) -> Vec<T> {
    let v: Vec<T> = Vec::with_capacity(capacity);
    advise(v.as_ptr().cast(), v.capacity() * std::mem::size_of::<T>());
    v
}

/// `v`'s elements in a vector from [`huge_vec`] (a copy, when `v` spans a huge page).
pub(super) fn into_huge<T: Copy>(v: Vec<T>) -> Vec<T> {
    if std::mem::size_of_val(v.as_slice()) < HUGE_PAGE {
        return v;
    }
    let mut huge = huge_vec(v.len());
    huge.extend_from_slice(&v);
    huge
}

/// Advises the kernel to back the whole pages within `bytes` bytes from `start` with huge pages; returns whether
/// it took the advice (false for a range under a huge page, off Linux, or when `madvise` fails).
#[cfg(target_os = "linux")]
#[allow(unsafe_code)] // one madvise call (see SAFETY below)
fn advise(start: *const u8, bytes: usize) -> bool {
    if bytes < HUGE_PAGE {
        return false;
    }
    const PAGE: usize = 4096;
    let first = (start as usize).next_multiple_of(PAGE);
    let end = (start as usize + bytes) / PAGE * PAGE;
    if end <= first {
        return false;
    }
    // SAFETY: the range lies within one live allocation (`start .. start + bytes`, page-aligned inwards), and
    // MADV_HUGEPAGE only tells the kernel how to back it: no byte of it changes, and no mapping is added or
    // removed, whatever the kernel does with the advice.
    unsafe { libc::madvise(first as *mut libc::c_void, end - first, libc::MADV_HUGEPAGE) == 0 }
}

#[cfg(not(target_os = "linux"))]
fn advise(_start: *const u8, _bytes: usize) -> bool {
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn copies_keep_every_element_and_small_arrays_are_left_alone() {
        let small: Vec<u64> = (0..1000).collect();
        let at = small.as_ptr();
        let kept = into_huge(small);
        assert_eq!(kept.as_ptr(), at, "a small array is not copied");
        let big: Vec<u64> = (0..(HUGE_PAGE as u64 / 8) * 3 + 5).collect();
        let huge = into_huge(big.clone());
        assert_eq!(huge, big);
        assert_eq!(huge.capacity(), big.len());
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn linux_takes_the_advice_for_large_buffers_only() {
        let v: Vec<u8> = Vec::with_capacity(3 * HUGE_PAGE);
        assert!(!advise(v.as_ptr(), HUGE_PAGE - 1));
        // A kernel built without transparent huge pages refuses the advice (EINVAL): nothing to check there.
        if std::path::Path::new("/sys/kernel/mm/transparent_hugepage").exists() {
            assert!(advise(v.as_ptr(), v.capacity()));
        }
    }
}
