//! A run directory's lock: one writer at a time, whichever side writes
//! (a sweep in Rust, a fit, tune or recommend driven from Python). An
//! advisory lock on `.pupper.lock` that the OS drops when its holder dies,
//! kill -9 included, so a resume after a kill finds it free.

use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::Path;

use crate::error::{Error, Result};
use crate::results::files::refuse_non_regular;
use crate::results::output::LOCK;

/// A held run-directory lock. The lock file names its holder while held
/// and nobody after; it is never removed (a second writer would then lock
/// a new file while this one still holds the old).
#[derive(Debug)]
pub struct RunLock {
    file: File,
}

impl RunLock {
    /// Takes `dir`'s lock, or says who holds it (`Error::RunBusy`), and
    /// deletes the temporary files a killed writer left (holding the lock,
    /// no live writer owns them).
    pub fn take(dir: &Path) -> Result<RunLock> {
        let path = dir.join(LOCK);
        refuse_non_regular(&path)?;
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(|e| Error::io("open", &path, e))?;
        match file.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => {
                let mut holder = String::new();
                let _ = file.read_to_string(&mut holder);
                let holder = holder.trim();
                return Err(Error::RunBusy(format!(
                    "run directory '{}' is being written by another pupper ({}): wait for it to end, or choose another --out",
                    dir.display(),
                    if holder.is_empty() {
                        "a process starting up"
                    } else {
                        holder
                    }
                )));
            }
            Err(std::fs::TryLockError::Error(e)) => return Err(Error::io("lock", &path, e)),
        }
        let me = format!(
            "pid {} on {}, since unix time {}",
            std::process::id(),
            hostname(),
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs())
        );
        file.set_len(0)
            .and_then(|()| file.seek(SeekFrom::Start(0)))
            .and_then(|_| file.write_all(me.as_bytes()))
            .map_err(|e| Error::io("write", &path, e))?;
        remove_stale_temps(dir);
        Ok(RunLock { file })
    }
}

impl Drop for RunLock {
    fn drop(&mut self) {
        // names nobody; closing the file releases the lock
        let _ = self.file.set_len(0);
    }
}

/// This machine's name, as a lock and a shard record give it.
pub fn hostname() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_string())
        .or_else(|_| std::env::var("HOSTNAME"))
        .unwrap_or_else(|_| "this host".into())
}

/// Whether `name` is a file pupper's writers leave that no run is made
/// of: the lock, and a killed writer's temporary file (`.NAME.tmpPID`).
pub fn is_ours_to_ignore(name: &str) -> bool {
    name == LOCK || is_stale_temp(name)
}

fn is_stale_temp(name: &str) -> bool {
    name.starts_with('.') && name.contains(".tmp")
}

fn remove_stale_temps(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        if is_stale_temp(&e.file_name().to_string_lossy()) {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_lock_is_refused_naming_the_first_and_freed_when_it_is_dropped() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join(".summary.csv.tmp99"), "half").unwrap();
        std::fs::write(dir.path().join("mine.txt"), "kept").unwrap();
        let first = RunLock::take(dir.path()).unwrap();
        assert!(!dir.path().join(".summary.csv.tmp99").exists());
        assert!(dir.path().join("mine.txt").exists());
        match RunLock::take(dir.path()) {
            Err(Error::RunBusy(m)) => {
                assert!(m.contains(&format!("pid {}", std::process::id())), "{m}")
            }
            other => panic!("{other:?}"),
        }
        drop(first);
        assert_eq!(std::fs::read_to_string(dir.path().join(LOCK)).unwrap(), "");
        assert!(RunLock::take(dir.path()).is_ok());
    }

    #[test]
    fn the_lock_and_temporaries_are_ours_a_users_dotfile_is_not() {
        assert!(is_ours_to_ignore(LOCK));
        assert!(is_ours_to_ignore(".manifest.json.tmp123"));
        assert!(!is_ours_to_ignore(".hidden"));
        assert!(!is_ours_to_ignore("summary.csv"));
    }
}
