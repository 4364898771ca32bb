//! What the commands print: standard output that never panics (`outp!`,
//! `outln!`) and standard error that drops what it cannot write (`errln!`).

use std::path::PathBuf;

use pupper_core::{Error, Result};

/// Writes to standard output. A stdout that cannot take the text (a full
/// disk) is a one-line error, never a panic; a closed pipe (`| head`) just
/// ends the output.
pub(super) fn out(text: &str) -> Result<()> {
    use std::io::Write;
    let mut o = std::io::stdout().lock();
    match o.write_all(text.as_bytes()).and_then(|()| o.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        r => r.map_err(|source| Error::Io {
            action: "write to",
            path: PathBuf::from(pupper_core::error::STDOUT),
            source,
        }),
    }
}

/// `print!` through [`out`].
macro_rules! outp {
    ($($t:tt)*) => { $crate::cli::console::out(&format!($($t)*))? };
}

/// `println!` through [`out`].
macro_rules! outln {
    ($($t:tt)*) => { $crate::cli::console::out(&format!("{}\n", format_args!($($t)*)))? };
}

/// `eprintln!` that never panics: a line stderr cannot take is dropped
/// (see [`crate::say`]).
macro_rules! errln {
    ($($t:tt)*) => { $crate::say(&format!($($t)*)) };
}
