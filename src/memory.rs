//! Giving freed heap memory back to the system.
//!
//! glibc's allocator keeps memory that the program frees in its arenas, for
//! later allocations of the same sizes; arrays of more than a few megabytes
//! are mapped separately and never reuse it. A stage that frees many
//! medium-sized buffers (the extraction's parts: thousands of them, hundreds
//! of megabytes on a noisy volume) and then allocates large arrays would keep
//! both resident: on 48³ noise that is a third of the peak. [`release`] hands
//! the free pages back (`malloc_trim`), so the peak is what is in use.

/// Returns the allocator's free memory to the system (glibc); elsewhere it
/// does nothing (other allocators return it themselves, or keep it).
pub fn release() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        unsafe extern "C" {
            /// glibc: releases free memory at the top of the heap and every
            /// whole free page inside it; returns 1 when some was released.
            fn malloc_trim(pad: usize) -> i32;
        }
        // SAFETY: malloc_trim takes no pointers and may be called at any
        // time from any thread (it locks each arena while it trims it).
        unsafe {
            malloc_trim(0);
        }
    }
}
