//! `pupper`: physics experiments on the Pupper v3 quadruped in MuJoCo.
//! This crate only parses arguments, calls `pupper_core`, and prints.

mod cli;
mod print;

use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use clap::Parser;
use pupper_core::Error;

fn main() -> ExitCode {
    let args = cli::Cli::parse();
    // Before any Python use: find the project's venv, start the interpreter.
    let python = pupper_core::embed::find_python(option_env!("PUPPER_BUILD_PYTHON"));
    pupper_core::embed::start(python.as_deref());
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        // SIGINT and SIGTERM: finish the current step, keep what is done.
        let _ = ctrlc::set_handler(move || {
            if stop.swap(true, Ordering::SeqCst) {
                // a second Ctrl-C: the user really wants out
                std::process::exit(130);
            }
        });
    }
    match cli::run(args, stop) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            match e {
                Error::Interrupted(_) => ExitCode::from(130),
                e if e.is_user_error() => ExitCode::from(2),
                _ => ExitCode::from(1),
            }
        }
    }
}
