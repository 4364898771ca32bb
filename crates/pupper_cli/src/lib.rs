//! `pupper`: physics experiments on the Pupper v3 quadruped in MuJoCo.
//! This crate only parses arguments, calls `pupper_core`, and prints. It is
//! a library so that the same CLI runs from the `pupper` binary (embedding
//! CPython) and from the wheel's `pupper` console script (inside the host
//! interpreter, through `pupper_core._native.cli_main`).

mod cli;
mod print;
mod pyargs;

use std::ffi::OsString;
use std::sync::atomic::{AtomicBool, Ordering};

use clap::Parser;
use pupper_core::Error;

/// Where the CLI runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Host {
    /// The `pupper` binary: find the project's Python (or the one it was
    /// built with) and start it.
    Embedded { built_with: Option<&'static str> },
    /// A Python process that is already running (the console script).
    Interpreter,
}

/// Set by SIGINT/SIGTERM: finish the current step, keep what is done.
static STOP: AtomicBool = AtomicBool::new(false);

/// Parses `args` (the program name first) and runs the command. Returns the
/// exit status: 0 success, 2 bad input, 130 interrupted, 1 internal error.
pub fn main(args: impl IntoIterator<Item = OsString>, host: Host) -> u8 {
    let cli = match cli::Cli::try_parse_from(args) {
        Ok(c) => c,
        Err(e) => {
            // --help and --version print and succeed; usage errors exit 2
            let printed = e.print();
            if e.use_stderr() {
                return 2;
            }
            // help that could not be written is no success (a full disk)
            return match printed {
                Err(io) if io.kind() != std::io::ErrorKind::BrokenPipe => {
                    say(&format!(
                        "error: {}",
                        Error::io("write to", pupper_core::error::STDOUT, io)
                    ));
                    2
                }
                _ => 0,
            };
        }
    };
    if let Host::Embedded { built_with } = host {
        // Before any Python use: find the project's venv, start the interpreter.
        let python = pupper_mujoco::embed::find_python(built_with);
        pupper_mujoco::embed::start(python.as_deref());
    }
    // What Python prints keeps its place among Rust's and stderr's lines
    // whatever the buffering (the console script's host included).
    pupper_mujoco::embed::line_buffered_stdout();
    // A second handler in one process is refused; the first one sets STOP too.
    let _ = ctrlc::set_handler(|| {
        if STOP.swap(true, Ordering::SeqCst) {
            // a second Ctrl-C: the user really wants out
            say("error: interrupted again: stopped at once, without finishing the current step");
            std::process::exit(130);
        }
    });
    STOP.store(false, Ordering::SeqCst);
    match cli::run(cli, &STOP) {
        Ok(code) => code,
        Err(e) => {
            say(&format!("error: {e}"));
            match e {
                Error::Interrupted(_) => 130,
                e if e.is_user_error() => 2,
                _ => 1,
            }
        }
    }
}

/// A line on standard error. One that cannot be written (a full disk, a
/// closed stream) is dropped: there is nowhere left to say it, and the exit
/// status still tells what happened; `eprintln!` would panic instead.
pub(crate) fn say(line: &str) {
    use std::io::Write;
    let mut e = std::io::stderr().lock();
    let _ = e
        .write_all(line.as_bytes())
        .and_then(|()| e.write_all(b"\n"));
}
