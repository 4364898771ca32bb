//! The two ways a command reaches pupper's Python package for its work:
//! flags as JSON to a module's `_cli` function, and the run's report.

use pupper_core::Result;
use pupper_mujoco::bridge;
use pupper_mujoco::bridge::calls::{self, PyCall};

/// A command whose work is in pupper's Python package: its flags as JSON
/// to `module.func`, which returns the files it wrote (said on stderr).
pub(super) fn python_command(call: &PyCall, args_json: &str) -> Result<u8> {
    write_files(call, args_json)
}

/// What a Python command returns after its files to set the exit status
/// (`status:3`: recommend found no gains to name); no item: 0.
const STATUS: &str = "status:";

/// Calls `call` with its one argument (a command's flags as JSON, or a run
/// directory), says each file it wrote on stderr, and returns the exit
/// status it asks for (0 unless it returns `status:N`).
pub(super) fn write_files(call: &PyCall, arg: &str) -> Result<u8> {
    let mut status = 0;
    for p in bridge::call_helper(call, &[arg.to_string()], &serde_json::json!({}))? {
        match p.strip_prefix(STATUS).and_then(|n| n.parse::<u8>().ok()) {
            Some(n) => status = n,
            None => errln!("wrote {p}"),
        }
    }
    Ok(status)
}

/// Writes DIR/report.html. The path crosses as its bytes (hex), so a
/// directory whose name is not UTF-8 is the same directory in Python.
pub(super) fn write_report(dir: &std::path::Path) -> Result<()> {
    use std::os::unix::ffi::OsStrExt;
    let hex: String = dir
        .as_os_str()
        .as_bytes()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    bridge::call_helper(&calls::REPORT, &[hex], &serde_json::json!({}))?;
    Ok(())
}
