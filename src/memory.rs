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

/// The most memory the process has had resident so far (`VmHWM`), in bytes;
/// `None` where the system does not say (other than Linux).
pub fn peak_resident_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

#[cfg(test)]
mod tests {
    #[test]
    #[cfg(target_os = "linux")]
    fn the_peak_covers_what_was_touched() {
        let before = super::peak_resident_bytes().expect("linux reports VmHWM");
        let block = vec![1u8; 64 << 20];
        std::hint::black_box(&block);
        let after = super::peak_resident_bytes().expect("linux reports VmHWM");
        assert!(
            after >= (64 << 20) && after >= before,
            "{before} -> {after}"
        );
        super::release();
    }
}
