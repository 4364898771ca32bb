//! Files a crash never leaves half-written: a whole file through a
//! temporary renamed into place, an append-only table rolled back to its
//! last consistent length, and nodes that are not regular files refused.

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Writes `bytes` to `path` through a temporary file in the same directory,
/// flushed before the rename (and the directory after it), so a crash never
/// leaves a short file under the final name. The temporary file is removed
/// on every error.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    refuse_non_regular(path)?;
    let tmp = temporary_of(path);
    let written = File::create(&tmp)
        .and_then(|mut f| f.write_all(bytes))
        .map_err(|e| Error::io("write", path, e))
        .and_then(|()| publish(&tmp, path));
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written
}

/// The temporary name a whole file of `path` is written under before
/// [`publish`]: `.NAME.tmpPID` beside it (a killed writer's is removed by
/// the next holder of the run's lock).
pub fn temporary_of(path: &Path) -> PathBuf {
    let dir = path.parent().unwrap_or(Path::new("."));
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("out");
    dir.join(format!(".{name}.tmp{}", std::process::id()))
}

/// Puts the finished temporary file `tmp` in place as `path`: flushed,
/// renamed over it, the directory flushed, so a crash leaves the old file
/// or the new one, never a short one. A `path` that is not a regular file
/// is refused. Every writer of a run's files, Rust's and Python's, ends
/// here.
pub fn publish(tmp: &Path, path: &Path) -> Result<()> {
    refuse_non_regular(path)?;
    File::options()
        .write(true)
        .open(tmp)
        .and_then(|f| f.sync_all())
        .map_err(|e| Error::io("write", path, e))?;
    std::fs::rename(tmp, path).map_err(|e| Error::io("rename into", path, e))?;
    sync_dir(
        path.parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new(".")),
    )
}

/// Refuses a `path` that exists and is not a regular file (a FIFO, a
/// device, a socket, a directory): renaming over it would replace the node
/// itself, and a device or a FIFO is no place for a table.
pub fn refuse_non_regular(path: &Path) -> Result<()> {
    match std::fs::metadata(path) {
        Ok(m) if !m.is_file() => Err(Error::Output(format!(
            "'{}' exists and is not a regular file ({}): pupper writes only regular files; move it away or choose another --out",
            path.display(),
            file_kind(&m)
        ))),
        _ => Ok(()),
    }
}

/// What a file that is not a regular one is, in words.
fn file_kind(m: &std::fs::Metadata) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    let t = m.file_type();
    if t.is_dir() {
        "a directory"
    } else if t.is_fifo() {
        "a FIFO"
    } else if t.is_char_device() || t.is_block_device() {
        "a device"
    } else if t.is_socket() {
        "a socket"
    } else {
        "not a file"
    }
}

pub(crate) fn sync_dir(dir: &Path) -> Result<()> {
    File::open(dir)
        .and_then(|d| d.sync_all())
        .map_err(|e| Error::io("flush", dir, e))
}

/// An append-only file and the length it had at the last consistent point.
pub(crate) struct Appender {
    path: PathBuf,
    file: File,
    len: u64,
}

impl Appender {
    pub(crate) fn open(path: PathBuf) -> Result<Appender> {
        let file = OpenOptions::new()
            .append(true)
            .open(&path)
            .map_err(|e| Error::io("open", &path, e))?;
        let len = file
            .metadata()
            .map_err(|e| Error::io("read", &path, e))?
            .len();
        Ok(Appender { path, file, len })
    }

    pub(crate) fn append(&mut self, bytes: &[u8]) -> Result<()> {
        self.file
            .write_all(bytes)
            .map_err(|e| Error::io("write", &self.path, e))
    }

    /// Back to the last consistent length (frees what a failed write took).
    pub(crate) fn roll_back(&mut self) {
        let _ = self.file.set_len(self.len);
    }

    pub(crate) fn commit(&mut self) -> Result<()> {
        self.len = self
            .file
            .metadata()
            .map_err(|e| Error::io("read", &self.path, e))?
            .len();
        Ok(())
    }

    pub(crate) fn sync(&self) -> Result<()> {
        self.file
            .sync_data()
            .map_err(|e| Error::io("flush", &self.path, e))
    }
}
