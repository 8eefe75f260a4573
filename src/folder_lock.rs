//! A run's hold on its output folder: a lock file created exclusively before the run
//! touches the folder, removed when the run ends. A second run or resume into a folder a
//! running process holds is refused with [`crate::RunError::FolderInUse`] and changes
//! nothing there (a second run deleted the first one's files while it was still writing
//! them; two resumes interleaved `frames.csv`).
//!
//! The lock file holds the owner's process id. A lock left by a process that no longer
//! exists (killed, or the machine restarted) is taken over: on Linux the owner is looked up
//! in `/proc`; elsewhere a lock older than a day counts as stale.

use std::io::Write;
use std::path::{Path, PathBuf};

/// The lock file's name in the output folder.
pub const LOCK_FILE: &str = ".needlesim.lock";

/// Held while a run writes into its folder; removes the lock file when dropped.
#[derive(Debug)]
pub struct FolderLock {
    path: PathBuf,
}

/// Why the folder could not be locked.
#[derive(Debug)]
pub enum LockError {
    /// Another live process holds it.
    Held {
        /// Its process id, as its lock file says.
        pid: u32,
    },
    /// The lock file could not be created or read.
    Io(std::io::Error),
}

/// Whether the process `pid` is alive, as far as this platform can tell.
fn alive(pid: u32, lock: &Path) -> bool {
    if cfg!(target_os = "linux") {
        return Path::new(&format!("/proc/{pid}")).exists();
    }
    // Elsewhere: a lock younger than a day is taken as held.
    std::fs::metadata(lock)
        .and_then(|m| m.modified())
        .ok()
        .and_then(|t| t.elapsed().ok())
        .is_none_or(|age| age.as_secs() < 86_400)
}

impl FolderLock {
    /// Locks `dir` (which must exist) for this process.
    pub fn acquire(dir: &Path) -> Result<FolderLock, LockError> {
        let path = dir.join(LOCK_FILE);
        for _ in 0..2 {
            match std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&path)
            {
                Ok(mut f) => {
                    write!(f, "{}", std::process::id()).map_err(LockError::Io)?;
                    return Ok(FolderLock { path });
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    let text = std::fs::read_to_string(&path).unwrap_or_default();
                    match text.trim().parse::<u32>() {
                        Ok(pid) if pid == std::process::id() => {
                            // This process holds it already (a run inside a run is not
                            // possible; a lock left by an earlier run of this process
                            // that was not dropped): taken over.
                            return Ok(FolderLock { path });
                        }
                        Ok(pid) if alive(pid, &path) => return Err(LockError::Held { pid }),
                        // Stale (or unreadable, a writer killed mid-write): removed and
                        // tried once more.
                        _ => {
                            let _ = std::fs::remove_file(&path);
                        }
                    }
                }
                Err(e) => return Err(LockError::Io(e)),
            }
        }
        Err(LockError::Io(std::io::Error::other(format!(
            "{} keeps being recreated",
            path.display()
        ))))
    }
}

impl Drop for FolderLock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}
