//! Heap tuning for a process that extracts features over and over.
//!
//! One extraction allocates a handful of 0.2–2 MiB buffers (the decoded image, the unwrapped
//! grid, pyramid levels, the spectrum) and frees them. glibc's defaults serve such sizes with
//! fresh `mmap`s, or trim them off the heap top on free, so every request pays to fault the
//! same pages in again and to zero them: about a quarter of the feature time for a 512×512
//! image (`cargo bench --bench features`). Fixed thresholds keep those buffers in the heap.

/// Allocations above this size still get their own mapping (and are returned on free):
/// large photographs do not stay resident after their request.
const MMAP_THRESHOLD: i32 = 4 << 20;
/// Free memory at the heap top beyond this is returned to the kernel.
const TRIM_THRESHOLD: i32 = 8 << 20;

/// Applies the thresholds; call once at start-up. A no-op on other allocators.
pub fn tune() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes allocator parameters; it takes the allocator's lock.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD);
        libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_THRESHOLD);
    }
}
