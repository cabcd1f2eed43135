//! What an interrupted run leaves behind, and who may write into a folder.
//!
//! - Every temporary output file (`.penumbra-*.tmp`) and every run lock is registered here while
//!   it lives; [`remove_registered`] deletes those left, which the binary's SIGINT/SIGTERM handler
//!   calls before it exits with 130/143.
//! - [`RunLock`] makes a run folder single-writer: `<dir>/.penumbra.lock` holds the owner's pid;
//!   a second run into the same folder is refused while that process lives, and a lock left by a
//!   killed process is taken over. The lock holder also removes temporary files that killed runs
//!   left in its folder (`remove_stale_temp_files`).

use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Paths to delete if the process is interrupted.
static REGISTERED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Name of the lock file in a run folder.
pub const LOCK_FILE: &str = ".penumbra.lock";

/// Registers a path to delete on interruption.
pub fn register(path: &Path) {
    if let Ok(mut v) = REGISTERED.lock() {
        v.push(path.to_path_buf());
    }
}

/// Forgets a registered path (it was renamed into place or removed).
pub fn forget(path: &Path) {
    if let Ok(mut v) = REGISTERED.lock()
        && let Some(i) = v.iter().rposition(|p| p == path)
    {
        v.swap_remove(i);
    }
}

/// Deletes every registered path that still exists; returns how many were removed.
pub fn remove_registered() -> usize {
    let paths = match REGISTERED.lock() {
        Ok(mut v) => std::mem::take(&mut *v),
        Err(_) => return 0,
    };
    paths
        .iter()
        .filter(|p| std::fs::remove_file(p).is_ok())
        .count()
}

/// Removes `.penumbra-*.tmp` files in `dir` (not recursive) that no live process owns: call it
/// only while holding the folder's [`RunLock`]. Returns how many were removed.
fn remove_stale_temp_files(dir: &Path) -> usize {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    let live: Vec<PathBuf> = REGISTERED.lock().map(|v| v.clone()).unwrap_or_default();
    entries
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with(".penumbra-") && n.ends_with(".tmp"))
        })
        .filter(|p| !live.contains(p))
        .filter(|p| std::fs::remove_file(p).is_ok())
        .count()
}

/// The single-writer lock of a run folder; released (file removed) on drop.
#[derive(Debug)]
pub struct RunLock {
    path: PathBuf,
    /// The folder, when this lock created it (removed again on drop if still empty).
    created: Option<PathBuf>,
}

impl RunLock {
    /// Takes the lock of `dir` (created if missing), or errors naming the live owner.
    fn acquire(dir: &Path) -> Result<Self, String> {
        let created = (!dir.exists()).then(|| dir.to_path_buf());
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("creating output folder {}: {e}", dir.display()))?;
        let path = dir.join(LOCK_FILE);
        for _ in 0..2 {
            match std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&path)
            {
                Ok(mut f) => {
                    use std::io::Write as _;
                    let _ = writeln!(f, "{}", std::process::id());
                    register(&path);
                    return Ok(RunLock { path, created });
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    let owner = std::fs::read_to_string(&path)
                        .ok()
                        .and_then(|t| t.trim().parse::<u32>().ok());
                    if let Some(pid) = owner
                        && process_alive(pid)
                    {
                        return Err(format!(
                            "another penumbra run (pid {pid}) is writing into {}; wait for it or choose another output folder",
                            dir.display()
                        ));
                    }
                    // Left by a killed run (or unreadable): take it over.
                    let _ = std::fs::remove_file(&path);
                }
                Err(e) => return Err(format!("locking {}: {e}", path.display())),
            }
        }
        Err(format!(
            "could not lock {} (another run took it meanwhile)",
            dir.display()
        ))
    }
}

impl RunLock {
    /// Starts a run into `dir`: takes its lock, removes the temporary files that killed runs left
    /// in it and its immediate sub-folders, and removes the old completion manifest (`manifest`,
    /// e.g. `run.json`, which the run writes last), so that a run killed part-way leaves a folder
    /// without a manifest rather than old and new files under an old manifest.
    pub fn begin(dir: &Path, manifest: &str) -> Result<Self, String> {
        let lock = Self::acquire(dir)?;
        remove_stale_temp_files(dir);
        if let Ok(entries) = std::fs::read_dir(dir) {
            for e in entries.filter_map(Result::ok) {
                if e.file_type().is_ok_and(|t| t.is_dir()) {
                    remove_stale_temp_files(&e.path());
                }
            }
        }
        match std::fs::remove_file(dir.join(manifest)) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => {
                return Err(format!(
                    "removing the old {manifest} in {}: {e}",
                    dir.display()
                ));
            }
        }
        Ok(lock)
    }
}

impl Drop for RunLock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
        forget(&self.path);
        // A run that failed before writing anything leaves no empty folder behind.
        if let Some(dir) = &self.created {
            let _ = std::fs::remove_dir(dir);
        }
    }
}

/// Whether a process with this pid exists (Linux `/proc`; elsewhere assumed alive unless it is
/// this process's own stale pid file).
fn process_alive(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    let proc_root = Path::new("/proc");
    if proc_root.join("self").exists() {
        proc_root.join(pid.to_string()).exists()
    } else {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_has_one_writer_and_stale_locks_are_taken_over() {
        let dir = tempfile::tempdir().unwrap();
        let lock = RunLock::acquire(dir.path()).unwrap();
        let err = RunLock::acquire(dir.path()).unwrap_err();
        assert!(err.contains("another penumbra run"), "{err}");
        drop(lock);
        assert!(!dir.path().join(LOCK_FILE).exists());
        // A lock of a dead process (pid beyond pid_max) is taken over.
        std::fs::write(dir.path().join(LOCK_FILE), "4194305\n").unwrap();
        let _lock = RunLock::acquire(dir.path()).unwrap();
        std::fs::write(dir.path().join(".penumbra-abc.tmp"), "x").unwrap();
        std::fs::write(dir.path().join("keep.tmp"), "x").unwrap();
        assert_eq!(remove_stale_temp_files(dir.path()), 1);
        assert!(dir.path().join("keep.tmp").exists());
    }
}
