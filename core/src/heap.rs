//! Handing the heap's free memory back to the system between pipeline stages.
//!
//! Why: glibc's allocator keeps the memory a stage frees in its arenas (one per thread that
//! allocated, and rayon's workers allocate), and raises its threshold for mapping large blocks
//! apart each time one is freed, so that the next stage's vectors of a few tens of megabytes are
//! carved out of the heap too. The resident set then stays at the high-water mark of the earlier
//! stages plus what the later ones add on top of the fragments. Trimming after a stage that
//! frees large tables (the merge's shadow engine, the packing's tables) gives those pages back
//! before the next stage allocates, so the peak is the largest stage's, not their sum.

/// Returns the free pages of every arena of the allocator to the system (glibc's
/// `malloc_trim`); does nothing on other platforms, whose allocators return memory themselves
/// or not at all.
pub fn trim() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: malloc_trim takes a plain integer and only walks the allocator's own lists,
        // under the allocator's locks.
        unsafe {
            libc::malloc_trim(0);
        }
    }
}
