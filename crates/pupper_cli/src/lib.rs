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
    let args: Vec<OsString> = args.into_iter().collect();
    let cli = match cli::Cli::try_parse_from(&args) {
        Ok(c) => c,
        Err(e) => {
            // usage errors: one line, exit 2
            if e.use_stderr() {
                let sub = args.get(1).and_then(|a| a.to_str()).filter(|a| {
                    <cli::Cli as clap::CommandFactory>::command()
                        .find_subcommand(a)
                        .is_some()
                });
                say(&one_line(&e.render().to_string(), sub));
                return 2;
            }
            // --help and --version print and succeed
            let printed = e.print();
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

/// clap's usage error as one line, as pupper's own errors are: its
/// message, the details it lists below it (a missing flag, the possible
/// values), its tips, and where the help is; its blank lines, usage line
/// and "For more information" dropped.
fn one_line(rendered: &str, command: Option<&str>) -> String {
    let mut lines = rendered.lines().map(str::trim).filter(|l| !l.is_empty());
    let mut out = lines
        .next()
        .unwrap_or("error: bad command line")
        .to_string();
    let mut tips = Vec::new();
    let mut help = command.map_or("pupper".to_string(), |c| format!("pupper {c}"));
    for l in lines {
        if let Some(usage) = l.strip_prefix("Usage:") {
            help = usage
                .split_whitespace()
                .take_while(|w| !w.starts_with(['[', '<', '-']))
                .collect::<Vec<_>>()
                .join(" ");
        } else if l.starts_with("tip:") {
            tips.push(l.to_string());
        } else if !l.starts_with("For more information") {
            out.push(' ');
            out.push_str(l);
        }
    }
    // clap reads a value such as -1 as a flag of its own
    let negative = out
        .strip_prefix("error: unexpected argument '")
        .and_then(|r| r.split('\'').next())
        .is_some_and(|a| a.starts_with('-') && a[1..].parse::<f64>().is_ok());
    if negative && tips.is_empty() {
        tips.push("tip: a negative number after a flag is read as a flag; join them with '=' (-j=-1, --kp=-5)".into());
    }
    for t in tips {
        out.push_str("; ");
        out.push_str(&t);
    }
    out.push_str(&format!("; see `{help} --help`"));
    out
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

#[cfg(test)]
mod tests {
    use super::one_line;

    #[test]
    fn a_usage_error_is_one_line_with_its_details_tips_and_help() {
        let clap = "error: unrecognized subcommand 'swep'\n\n  tip: a similar subcommand exists: 'sweep'\n\nUsage: pupper <COMMAND>\n\nFor more information, try '--help'.\n";
        assert_eq!(
            one_line(clap, None),
            "error: unrecognized subcommand 'swep'; tip: a similar subcommand exists: 'sweep'; see `pupper --help`"
        );
        let clap = "error: invalid value 'x' for '--mode <MODE>'\n  [possible values: servo, torque]\n\nFor more information, try '--help'.\n";
        assert_eq!(
            one_line(clap, Some("sweep")),
            "error: invalid value 'x' for '--mode <MODE>' [possible values: servo, torque]; see `pupper sweep --help`"
        );
        let clap = "error: unexpected argument '-1' found\n\nUsage: pupper sweep [OPTIONS]\n\nFor more information, try '--help'.\n";
        let line = one_line(clap, None);
        assert!(
            line.starts_with("error: unexpected argument '-1' found; tip: a negative number"),
            "{line}"
        );
        assert!(line.ends_with("; see `pupper sweep --help`"), "{line}");
        assert!(!line.contains('\n'));
    }
}
