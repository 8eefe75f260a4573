//! A run's hold on its output folder: a lock file created exclusively before the run
//! touches the folder, removed when the run ends. A second run or resume into a folder a
//! running process holds is refused with [`crate::RunError::FolderInUse`] and changes
//! nothing there (a second run deleted the first one's files while it was still writing
//! them; two resumes interleaved `frames.csv`).
//!
//! The lock file holds the owner's process id (and on Linux its start time). A lock left
//! by a process that no longer exists (killed, or the machine restarted) is taken over: on
//! Linux the owner is looked up in `/proc`, where a zombie or a process that reuses the
//! id with another start time is no owner; elsewhere a lock older than a day counts as
//! stale.

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

/// Process `pid`'s state letter and start time (clock ticks after boot) from
/// `/proc/<pid>/stat`, or `None` where there is no such process (or no `/proc`).
fn proc_stat(pid: u32) -> Option<(char, u64)> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // `pid (comm) state ...`: the command may hold spaces and parentheses.
    let rest = &stat[stat.rfind(')')? + 1..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let state = fields.first()?.chars().next()?;
    // Field 22 of the line is the start time; `fields` starts at field 3.
    let start = fields.get(19)?.parse().ok()?;
    Some((state, start))
}

/// What this process writes into its lock: its id and, on Linux, its start time, so that
/// a later process given the same id is not taken for the owner.
fn lock_text() -> String {
    let pid = std::process::id();
    match proc_stat(pid) {
        Some((_, start)) => format!("{pid} {start}"),
        None => pid.to_string(),
    }
}

/// Whether the process of a lock's `pid` (and `start` time, when the lock has one) is
/// alive, as far as this platform can tell. On Linux a zombie (killed, not yet reaped by
/// its parent) is dead, and so is a process that reuses the id but started at another
/// time; both held the folder before.
fn alive(pid: u32, start: Option<u64>, lock: &Path) -> bool {
    if cfg!(target_os = "linux") {
        return match proc_stat(pid) {
            Some(('Z' | 'X' | 'x', _)) | None => false,
            Some((_, started)) => start.is_none_or(|s| s == started),
        };
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
                    write!(f, "{}", lock_text()).map_err(LockError::Io)?;
                    return Ok(FolderLock { path });
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    let text = std::fs::read_to_string(&path).unwrap_or_default();
                    let mut words = text.split_whitespace();
                    let first = words.next().unwrap_or("");
                    let start: Option<u64> = words.next().and_then(|w| w.parse().ok());
                    match first.parse::<u32>() {
                        Ok(pid) if pid == std::process::id() => {
                            // This process holds it already (a run inside a run is not
                            // possible; a lock left by an earlier run of this process
                            // that was not dropped): taken over.
                            return Ok(FolderLock { path });
                        }
                        Ok(pid) if alive(pid, start, &path) => return Err(LockError::Held { pid }),
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

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;

    fn lock_with(dir: &Path, text: &str) {
        std::fs::write(dir.join(LOCK_FILE), text).unwrap();
    }

    #[test]
    fn a_live_owner_holds_and_a_zombie_or_a_reused_id_does_not() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        // A live process with its start time holds the folder.
        let mut child = std::process::Command::new("sleep")
            .arg("5")
            .spawn()
            .unwrap();
        let (_, start) = proc_stat(child.id()).unwrap();
        lock_with(d, &format!("{} {start}", child.id()));
        assert!(matches!(
            FolderLock::acquire(d),
            Err(LockError::Held { .. })
        ));
        // The same id with another start time: a reused id, not the owner.
        lock_with(d, &format!("{} {}", child.id(), start + 1));
        drop(FolderLock::acquire(d).expect("a reused id does not hold the folder"));
        // Killed and not yet reaped: a zombie does not hold it either.
        child.kill().unwrap();
        let zombie = (0..200).any(|_| {
            std::thread::sleep(std::time::Duration::from_millis(5));
            proc_stat(child.id()).is_some_and(|(s, _)| s == 'Z')
        });
        assert!(zombie, "the child did not become a zombie");
        lock_with(d, &child.id().to_string());
        drop(FolderLock::acquire(d).expect("a zombie does not hold the folder"));
        child.wait().unwrap();
        // This process's own lock text names it.
        assert!(lock_text().starts_with(&format!("{} ", std::process::id())));
    }
}
