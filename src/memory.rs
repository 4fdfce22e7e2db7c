//! How freed memory goes back to the operating system (glibc on Linux; elsewhere these do
//! nothing). The peak resident memory of a run is set at neighbour-list rebuilds, where the old
//! per-slot and per-slab arrays are freed and new ones allocated; memory that glibc keeps after a
//! free counts towards that peak although nothing uses it.

/// glibc raises its mmap threshold each time a large block is freed, after which the per-slot
/// arrays that a rebuild frees and allocates anew (megabytes each) come from the heap, whose
/// holes stay resident, and with rayon's threads from several heaps (arenas). Pinning the
/// threshold at 256 KiB and using one arena keeps every large array in its own mapping, returned
/// to the OS when freed: the peak resident memory of the 97,200-sphere benchmark bed dropped from
/// about 84-108 MB (run to run) to 56 MB. (A lower threshold also maps the per-slab spring pools,
/// tens of KiB each, but their growth in the pair pass then costs mremap calls: measured 10 %
/// slower on 2 threads.) Call it before any thread exists.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[allow(unsafe_code)]
pub fn configure_allocator() {
    // SAFETY: mallopt only changes allocator parameters; the caller calls it before any thread
    // exists.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 256 * 1024);
        libc::mallopt(libc::M_ARENA_MAX, 1);
    }
}

/// See the Linux version.
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
pub fn configure_allocator() {}

/// Returns the free pages inside the heap to the OS (`malloc_trim`). Blocks below the mmap
/// threshold, such as the per-slab spring pools, live in the heap; the holes they leave when a
/// rebuild frees them stay resident otherwise, while the rebuild allocates its new arrays
/// elsewhere. Called twice per rebuild, it took the peak resident memory of the 97,200-sphere
/// bed from 47.4 to 43-44 MiB. Its cost, a walk over the heap's free chunks, is paid per
/// rebuild, not per step.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[allow(unsafe_code)]
pub fn return_free_pages() {
    // SAFETY: malloc_trim only releases free memory; it is thread-safe.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// See the Linux version.
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
pub fn return_free_pages() {}
