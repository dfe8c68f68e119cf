//! Temporary files and directories of the writers: short names, removal on
//! SIGINT/SIGTERM/SIGHUP, and the removal of those that dead processes left.
//!
//! Every writer fills a temporary path beside its target and renames it into
//! place. The temporary names are short (`.septa-<pid>-<n>.tmp`, whatever the
//! target is called), so a target name near the file system's limit still
//! works. Each one is registered here while it exists: when the process is
//! told to stop, [`install_signal_cleanup`]'s thread removes them all before
//! the process ends. What a killed process (SIGKILL, power loss) leaves is
//! removed by [`sweep_stale`] on the next write into the same directory: a
//! temporary name carries its process id, and only names of processes that
//! no longer run are touched.

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use crate::error::{Error, Result};

/// Paths to remove if the process is stopped; the lock also orders the
/// renames of [`replace_with`] against the signal thread.
static REGISTERED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Set once a stop signal arrived: writers stop creating files.
static STOPPING: AtomicBool = AtomicBool::new(false);

/// Numbers the temporary names of this process.
static NEXT: AtomicU64 = AtomicU64::new(0);

const PREFIX: &str = ".septa-";

/// What a temporary path is for (its suffix).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Being written: `.tmp`.
    New,
    /// An old output moved aside to be removed: `.old`.
    Old,
}

impl Kind {
    fn suffix(self) -> &'static str {
        match self {
            Kind::New => ".tmp",
            Kind::Old => ".old",
        }
    }
}

/// A fresh temporary name in `dir`: `.septa-<pid>-<n>.tmp` (or `.old`).
pub fn temp_path(dir: &Path, kind: Kind) -> PathBuf {
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    dir.join(format!(
        "{PREFIX}{}-{n}{}",
        std::process::id(),
        kind.suffix()
    ))
}

/// A registered temporary path: removed if the process is stopped, and by
/// [`Registered::remove`]; dropping it only forgets it (it was renamed).
#[derive(Debug)]
pub struct Registered {
    path: PathBuf,
    active: bool,
}

impl Registered {
    /// The path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Removes the path (a file or a whole directory) and forgets it.
    pub fn remove(self) {
        remove_path(&self.path);
    }
}

impl Drop for Registered {
    fn drop(&mut self) {
        if self.active {
            forget(&mut lock(), &self.path);
        }
    }
}

fn forget(paths: &mut Vec<PathBuf>, path: &Path) {
    if let Some(i) = paths.iter().rposition(|p| p == path) {
        paths.swap_remove(i);
    }
}

fn lock() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    // a writer that panicked holding the lock leaves a usable list behind
    REGISTERED.lock().unwrap_or_else(|e| e.into_inner())
}

/// Registers `path` for removal if the process is stopped.
pub fn register(path: PathBuf) -> Registered {
    lock().push(path.clone());
    Registered { path, active: true }
}

/// Creates and registers a temporary directory in `dir`.
pub fn create_dir(dir: &Path) -> Result<Registered> {
    check_not_stopping(dir)?;
    let path = temp_path(dir, Kind::New);
    let reg = register(path);
    std::fs::create_dir(reg.path()).map_err(|e| Error::io(reg.path(), e))?;
    Ok(reg)
}

/// True once a stop signal arrived.
pub fn stopping() -> bool {
    STOPPING.load(Ordering::SeqCst)
}

/// An error once a stop signal arrived, so that writers stop creating files.
pub fn check_not_stopping(path: &Path) -> Result<()> {
    if stopping() {
        return Err(Error::io(
            path,
            std::io::Error::new(std::io::ErrorKind::Interrupted, "interrupted by a signal"),
        ));
    }
    Ok(())
}

/// Whether `path` lies inside a registered temporary directory (its files
/// need no fsync of their own: the directory is synced once, see
/// [`crate::io::sync_tree`]).
pub fn inside_registered_dir(path: &Path) -> bool {
    lock().iter().any(|p| path.starts_with(p) && path != p)
}

/// Puts the finished `tmp` in place of `target`. With `old`, the existing
/// `target` is first moved there, and returned registered (to be removed by
/// the caller, or by the signal thread). Both renames happen while the
/// signal thread waits, so a stop leaves either the old target or the new
/// one in place, never neither. If the second rename fails, the old target
/// is put back.
pub fn replace_with(
    tmp: Registered,
    target: &Path,
    old: Option<&Path>,
) -> Result<Option<Registered>> {
    let mut tmp = tmp;
    let mut paths = lock();
    if let Some(old) = old {
        if let Err(e) = std::fs::rename(target, old) {
            drop(paths);
            tmp.remove();
            return Err(Error::io(target, e));
        }
    }
    if let Err(e) = std::fs::rename(tmp.path(), target) {
        if let Some(old) = old {
            let _ = std::fs::rename(old, target);
        }
        drop(paths);
        tmp.remove();
        return Err(Error::io(target, e));
    }
    forget(&mut paths, tmp.path());
    tmp.active = false;
    Ok(old.map(|old| {
        paths.push(old.to_path_buf());
        Registered {
            path: old.to_path_buf(),
            active: true,
        }
    }))
}

/// Removes a file, or a directory with everything in it; a writer may still
/// be adding files to it (before it sees [`stopping`]), so try a few times.
fn remove_path(path: &Path) {
    for _ in 0..50 {
        let gone = match std::fs::symlink_metadata(path) {
            Err(_) => true,
            Ok(m) if m.is_dir() => std::fs::remove_dir_all(path).is_ok(),
            Ok(_) => std::fs::remove_file(path).is_ok(),
        };
        if gone {
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
}

/// Removes every registered path (the stop-signal path). Holding the lock
/// keeps renames from happening meanwhile.
pub fn remove_all_registered() {
    STOPPING.store(true, Ordering::SeqCst);
    let mut paths = lock();
    for p in paths.drain(..) {
        remove_path(&p);
    }
}

/// Starts a thread that, on SIGINT, SIGTERM or SIGHUP, removes every
/// registered temporary path and then ends the process the way the signal
/// would have (exit status 128 + signal). Call once, early.
pub fn install_signal_cleanup() -> Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])
        .map_err(|e| Error::invalid(format!("cannot install the signal handlers: {e}")))?;
    std::thread::Builder::new()
        .name("septa-signals".into())
        .spawn(move || {
            if let Some(sig) = signals.forever().next() {
                remove_all_registered();
                let _ = signal_hook::low_level::emulate_default_handler(sig);
                std::process::exit(128 + sig);
            }
        })
        .map_err(|e| Error::invalid(format!("cannot start the signal thread: {e}")))?;
    Ok(())
}

/// The process id in a temporary name septa made: `.septa-<pid>-<n>.tmp|.old`,
/// or the older `.<name>.tmp-septa-<pid>` / `.<name>.old-septa-<pid>`.
fn owner(name: &str) -> Option<u32> {
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    if let Some(rest) = name.strip_prefix(PREFIX) {
        let rest = rest
            .strip_suffix(Kind::New.suffix())
            .or_else(|| rest.strip_suffix(Kind::Old.suffix()))?;
        let (pid, n) = rest.split_once('-')?;
        return (digits(pid) && digits(n)).then(|| pid.parse().ok())?;
    }
    if !name.starts_with('.') {
        return None;
    }
    let (_, pid) = name
        .rsplit_once(".tmp-septa-")
        .or_else(|| name.rsplit_once(".old-septa-"))?;
    digits(pid).then(|| pid.parse().ok())?
}

/// Whether process `pid` runs; `None` where that cannot be told (no /proc).
fn process_runs(pid: u32) -> Option<bool> {
    let proc = Path::new("/proc");
    if !proc.join("self").exists() {
        return None;
    }
    Some(proc.join(pid.to_string()).exists())
}

/// Removes the temporary files and directories that septa processes which no
/// longer run left in `dir` (killed while writing); returns what it removed.
/// Where it cannot tell whether a process runs, it removes nothing.
pub fn sweep_stale(dir: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let me = std::process::id();
    let mut removed = Vec::new();
    for e in entries.flatten() {
        let name = e.file_name();
        let Some(pid) = name.to_str().and_then(owner) else {
            continue;
        };
        if pid == me || process_runs(pid) != Some(false) {
            continue;
        }
        let path = e.path();
        remove_path(&path);
        if std::fs::symlink_metadata(&path).is_err() {
            removed.push(path);
        }
    }
    removed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_owners() {
        let p = temp_path(Path::new("d"), Kind::New);
        let name = p.file_name().unwrap().to_str().unwrap();
        assert!(name.len() < 32, "{name}");
        assert_eq!(owner(name), Some(std::process::id()));
        assert_eq!(owner(".septa-12-3.old"), Some(12));
        assert_eq!(owner(".out.tmp-septa-77"), Some(77));
        assert_eq!(owner(".x.old-septa-5"), Some(5));
        for not_ours in [
            "septa-1-2.tmp",
            ".septa-1.tmp",
            ".septa-a-2.tmp",
            ".septa-1-2.tmpx",
            "notes.txt",
            ".out.tmp-septa-",
            ".out.tmp-septa-1x",
        ] {
            assert_eq!(owner(not_ours), None, "{not_ours}");
        }
    }

    #[test]
    fn sweep_removes_only_dead_owners() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        // pid 0 never names a user process; our own pid runs
        let dead_dir = d.join(".septa-0-1.tmp");
        std::fs::create_dir(&dead_dir).unwrap();
        std::fs::write(dead_dir.join("f"), "x").unwrap();
        let dead_file = d.join(".out.ply.tmp-septa-0");
        std::fs::write(&dead_file, "x").unwrap();
        let live = temp_path(d, Kind::New);
        std::fs::create_dir(&live).unwrap();
        let user = d.join("user.txt");
        std::fs::write(&user, "keep").unwrap();
        let removed = sweep_stale(d);
        if process_runs(1).is_none() {
            assert!(removed.is_empty());
            return;
        }
        assert_eq!(removed.len(), 2, "{removed:?}");
        assert!(!dead_dir.exists() && !dead_file.exists());
        assert!(live.exists() && user.exists());
    }

    #[test]
    fn registered_paths_are_forgotten_when_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let reg = create_dir(dir.path()).unwrap();
        let inner = reg.path().join("a.ply");
        assert!(inside_registered_dir(&inner));
        let to = dir.path().join("out");
        assert!(replace_with(reg, &to, None).unwrap().is_none());
        assert!(to.is_dir());
        assert!(!inside_registered_dir(&to.join("a.ply")));
    }
}
