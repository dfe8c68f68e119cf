//! Giving freed heap memory back to the system, and running out of it
//! with a clear message.
//!
//! glibc's allocator keeps memory that the program frees in its arenas, for
//! later allocations of the same sizes; arrays of more than a few megabytes
//! are mapped separately and never reuse it. A stage that frees many
//! medium-sized buffers (the extraction's parts: thousands of them, hundreds
//! of megabytes on a noisy volume) and then allocates large arrays would keep
//! both resident: on 48³ noise that is a third of the peak. [`release`] hands
//! the free pages back (`malloc_trim`), so the peak is what is in use.

/// The allocator of the `septa` binary: the system's, except that an
/// allocation the system refuses ends the process with a clear message and
/// exit status 2, as every other error does (`error: out of memory while
/// extracting: 93 MB more were refused; ...`), instead of Rust's abort
/// (`memory allocation of N bytes failed`, SIGABRT, a backtrace when
/// `RUST_BACKTRACE` is set). The work is estimated before the big stages
/// (see [`crate::estimate`]); this is for what the estimate did not foresee
/// (a `--max-memory` above what the system gives, a limit set with
/// `ulimit -v`, other programs taking memory meanwhile). Allocations made
/// inside [`fallible`] still fail as `try_reserve` reports them, so that
/// the caller can turn them into an [`Error`](crate::Error).
///
/// Temporary output files are left to [`crate::io::temp::sweep_stale`]
/// (the next write into the same directory removes them): removing them
/// here would need memory.
///
/// ```no_run
/// #[global_allocator]
/// static ALLOCATOR: septa::memory::ClearOutOfMemory = septa::memory::ClearOutOfMemory;
/// ```
pub struct ClearOutOfMemory;

// SAFETY: every call goes to the system allocator with the same arguments;
// a null result either goes back to the caller (inside `fallible`) or ends
// the process without returning.
unsafe impl std::alloc::GlobalAlloc for ClearOutOfMemory {
    unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
        // SAFETY: the caller's contract is the system allocator's
        let p = unsafe { std::alloc::System.alloc(layout) };
        if p.is_null() {
            refused(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: std::alloc::Layout) -> *mut u8 {
        // SAFETY: as `alloc`
        let p = unsafe { std::alloc::System.alloc_zeroed(layout) };
        if p.is_null() {
            refused(layout.size());
        }
        p
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: std::alloc::Layout, new_size: usize) -> *mut u8 {
        // SAFETY: as `alloc`; `ptr` came from this allocator, that is, the system's
        let p = unsafe { std::alloc::System.realloc(ptr, layout, new_size) };
        if p.is_null() {
            refused(new_size);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
        // SAFETY: `ptr` came from the system allocator
        unsafe { std::alloc::System.dealloc(ptr, layout) }
    }
}

thread_local! {
    /// Set while this thread runs [`fallible`].
    static FALLIBLE: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// What the pipeline is doing, for the message: a `&'static str` behind a
/// `'static` reference (one pointer, read and written atomically).
static ACTIVITY: std::sync::atomic::AtomicPtr<&'static str> =
    std::sync::atomic::AtomicPtr::new(std::ptr::null_mut());

/// Says what the process is doing (`"extracting"`), for the out-of-memory
/// message of [`ClearOutOfMemory`].
pub fn set_activity(what: &'static &'static str) {
    ACTIVITY.store(
        (what as *const &'static str).cast_mut(),
        std::sync::atomic::Ordering::Relaxed,
    );
}

/// Runs `f` with allocation failures reported to the caller (as
/// `try_reserve` does) rather than ending the process, under
/// [`ClearOutOfMemory`].
pub fn fallible<R>(f: impl FnOnce() -> R) -> R {
    struct Restore(bool);
    impl Drop for Restore {
        fn drop(&mut self) {
            FALLIBLE.with(|c| c.set(self.0));
        }
    }
    let _restore = Restore(FALLIBLE.with(|c| c.replace(true)));
    f()
}

/// An allocation of `bytes` was refused: unless inside [`fallible`], the
/// message and the end of the process. Nothing here allocates.
fn refused(bytes: usize) {
    if FALLIBLE.try_with(|c| c.get()).unwrap_or(false) {
        return;
    }
    let mut msg = Message::default();
    msg.push(b"error: out of memory");
    let activity = ACTIVITY.load(std::sync::atomic::Ordering::Relaxed);
    if !activity.is_null() {
        msg.push(b" while ");
        // SAFETY: only `set_activity` stores here, from a `&'static &'static str`
        msg.push(unsafe { *activity }.as_bytes());
    }
    msg.push(b": the system refused ");
    msg.push_number(bytes.div_ceil(1 << 20));
    msg.push(
        b" MB more. This volume needs more memory than the process may have \
          (the machine's, a container's limit, or `ulimit -v`): free some, raise the limit, \
          or work on a crop of the volume (`septa extract --help`: --max-memory, --no-remesh)\n",
    );
    end_process(&msg.buf[..msg.len]);
}

/// A message built without allocating (longer text is cut).
struct Message {
    buf: [u8; 512],
    len: usize,
}

impl Default for Message {
    fn default() -> Self {
        Message {
            buf: [0; 512],
            len: 0,
        }
    }
}

impl Message {
    fn push(&mut self, bytes: &[u8]) {
        let n = bytes.len().min(self.buf.len() - self.len);
        self.buf[self.len..self.len + n].copy_from_slice(&bytes[..n]);
        self.len += n;
    }

    fn push_number(&mut self, mut x: usize) {
        let mut digits = [0u8; 20];
        let mut i = digits.len();
        loop {
            i -= 1;
            digits[i] = b'0' + (x % 10) as u8;
            x /= 10;
            if x == 0 {
                break;
            }
        }
        self.push(&digits[i..]);
    }
}

/// Writes `msg` to stderr and ends the process with status 2, without
/// allocating, unwinding or running exit handlers (which might allocate).
#[cfg(unix)]
fn end_process(msg: &[u8]) -> ! {
    unsafe extern "C" {
        fn write(fd: i32, buf: *const u8, count: usize) -> isize;
        fn _exit(status: i32) -> !;
    }
    // SAFETY: `msg` is a valid buffer of its length; write and _exit are
    // async-signal-safe and take no other state
    unsafe {
        let mut rest = msg;
        while !rest.is_empty() {
            let n = write(2, rest.as_ptr(), rest.len());
            if n <= 0 {
                break;
            }
            rest = &rest[n as usize..];
        }
        _exit(2)
    }
}

/// Elsewhere: the message as far as stderr takes it, then an abort.
#[cfg(not(unix))]
fn end_process(msg: &[u8]) -> ! {
    use std::io::Write;
    let _ = std::io::stderr().write_all(msg);
    std::process::abort()
}

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
