//! Heap tuning for a process that extracts features over and over.
//!
//! One extraction allocates a handful of 0.3–2 MiB buffers (the decoded image, the unwrapped
//! grid, pyramid levels, the spectrum; more for larger photographs) and frees them. glibc's
//! defaults serve such sizes with fresh `mmap`s, or trim them off the heap top on free, so
//! every request pays to fault the same pages in again and to zero them: about a quarter of
//! the feature time for a 512×512 image (`cargo bench --bench features`). Fixed thresholds
//! keep those buffers in the heap; the price is that the process keeps its peak heap.
//!
//! That price is paid per arena, and glibc gives up to 8 arenas per CPU to the threads
//! that allocate: the CPU pool, the runtime, and the blocking pool that admin calls and
//! job records run on, whose threads come and go. Under concurrent admin traffic the soak
//! (`scripts/soak.sh`) saw RSS climb from 36 to 41 MiB over five minutes as new threads
//! landed on fresh arenas, then stay; with one arena per CPU it stays at 28 MiB.

/// Allocations above this size still get their own mapping, returned to the kernel on
/// free: a huge photograph does not stay resident. (glibc's maximum.)
const MMAP_THRESHOLD: i32 = 32 << 20;
/// Free memory at the top of a heap beyond this is returned to the kernel.
const TRIM_THRESHOLD: i32 = 64 << 20;

/// Arenas: one per CPU (at least two), instead of glibc's eight; `MALLOC_ARENA_MAX` in the
/// environment wins.
fn arenas() -> i32 {
    std::thread::available_parallelism().map_or(2, |n| n.get().clamp(2, 64) as i32)
}

/// Applies the thresholds; call once at start-up (the binary does, for every command).
/// Returns whether the allocator accepted them (always true off glibc, where it does nothing).
pub fn tune() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes allocator parameters, under the allocator's lock.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD) == 1
            && libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_THRESHOLD) == 1
            && (std::env::var_os("MALLOC_ARENA_MAX").is_some_and(|v| !v.is_empty())
                || libc::mallopt(libc::M_ARENA_MAX, arenas()) == 1)
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    true
}

/// Returns the free memory of every arena to the kernel. The thresholds above keep a peak
/// heap on purpose; after a one-off burst (a model file read and parsed: several times the
/// file's size, briefly) that peak is waste, so the caller releases it.
pub fn release_free() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only gives free pages back, under the allocator's locks.
    unsafe {
        libc::malloc_trim(0);
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn glibc_accepts_the_thresholds() {
        // mallopt refuses an mmap threshold above 32 MiB without a word; this catches it.
        assert!(super::tune());
    }
}
