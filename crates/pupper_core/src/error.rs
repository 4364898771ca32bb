//! Typed errors. Every user mistake maps to one line that names the problem
//! and the fix; the CLI exits 2 on those, the Python module raises the
//! matching `PupperError` subclass.

use std::path::PathBuf;

/// Which family an error belongs to; decides the Python exception type and
/// the CLI exit status.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorKind {
    /// A bad `--grid` / grid dict.
    Grid,
    /// A bad schedule, pose or option value.
    Config,
    /// A model that is missing, unreadable, invalid or unsuitable.
    Model,
    /// The `mujoco` Python package is missing or the wrong version.
    Mujoco,
    /// The output directory or a resume check.
    Output,
    /// The run was interrupted (SIGINT/SIGTERM/KeyboardInterrupt).
    Interrupted,
    /// Rendering or a viewer cannot be used here.
    Display,
    /// A Ray cluster: missing, unreachable, or a node unfit to run pupper.
    Cluster,
    /// Something went wrong inside pupper or MuJoCo: a bug, not a user error.
    Internal,
}

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("{0}")]
    Grid(String),
    #[error("{0}")]
    Config(String),
    #[error("{0}")]
    Model(String),
    #[error("{0}")]
    Mujoco(String),
    #[error("{0}")]
    Output(String),
    /// A model file that does not exist.
    #[error("{0}")]
    ModelNotFound(String),
    /// A run directory (or its manifest) that does not exist.
    #[error("{0}")]
    RunNotFound(String),
    /// `--out` exists and neither --force nor --resume was given.
    #[error("{0}")]
    RunExists(String),
    /// A resume whose inputs differ from the run's.
    #[error("{0}")]
    ResumeMismatch(String),
    /// Another process is writing the run directory.
    #[error("{0}")]
    RunBusy(String),
    #[error("interrupted: {0}")]
    Interrupted(String),
    #[error("{0}")]
    Display(String),
    #[error("{0}")]
    Cluster(String),
    #[error("cannot {action} {}: {source}{}", path.display(), io_fix(source, path))]
    Io {
        action: &'static str,
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("internal error: {0}")]
    Internal(String),
}

impl Error {
    pub fn kind(&self) -> ErrorKind {
        match self {
            Error::Grid(_) => ErrorKind::Grid,
            Error::Config(_) => ErrorKind::Config,
            Error::Model(_) | Error::ModelNotFound(_) => ErrorKind::Model,
            Error::Mujoco(_) => ErrorKind::Mujoco,
            Error::Output(_)
            | Error::RunNotFound(_)
            | Error::RunExists(_)
            | Error::ResumeMismatch(_)
            | Error::RunBusy(_)
            | Error::Io { .. } => ErrorKind::Output,
            Error::Interrupted(_) => ErrorKind::Interrupted,
            Error::Display(_) => ErrorKind::Display,
            Error::Cluster(_) => ErrorKind::Cluster,
            Error::Internal(_) => ErrorKind::Internal,
        }
    }

    /// A stable name for this error, finer than its kind, for programs to
    /// match on (Python's `PupperError.kind`): `grid`, `config`, `model`,
    /// `model_not_found`, `mujoco`, `output`, `run_not_found`, `run_exists`,
    /// `resume_mismatch`, `run_busy`, `not_found`, `permission`, `disk_full`, `io`,
    /// `interrupted`, `display`, `cluster`, `internal`.
    pub fn code(&self) -> &'static str {
        match self {
            Error::Grid(_) => "grid",
            Error::Config(_) => "config",
            Error::Model(_) => "model",
            Error::ModelNotFound(_) => "model_not_found",
            Error::Mujoco(_) => "mujoco",
            Error::Output(_) => "output",
            Error::RunNotFound(_) => "run_not_found",
            Error::RunExists(_) => "run_exists",
            Error::ResumeMismatch(_) => "resume_mismatch",
            Error::RunBusy(_) => "run_busy",
            Error::Io { source, .. } => match source.kind() {
                std::io::ErrorKind::NotFound => "not_found",
                std::io::ErrorKind::PermissionDenied | std::io::ErrorKind::ReadOnlyFilesystem => {
                    "permission"
                }
                std::io::ErrorKind::StorageFull | std::io::ErrorKind::QuotaExceeded => "disk_full",
                _ => "io",
            },
            Error::Interrupted(_) => "interrupted",
            Error::Display(_) => "display",
            Error::Cluster(_) => "cluster",
            Error::Internal(_) => "internal",
        }
    }

    /// True for mistakes the user can fix (exit status 2 in the CLI).
    pub fn is_user_error(&self) -> bool {
        !matches!(self.kind(), ErrorKind::Internal | ErrorKind::Interrupted)
    }

    pub fn io(action: &'static str, path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            action,
            path: path.into(),
            source,
        }
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

/// The path an error names when standard output could not be written.
pub const STDOUT: &str = "standard output";

/// The fix for an I/O failure a user can act on.
fn io_fix(e: &std::io::Error, path: &std::path::Path) -> &'static str {
    match e.kind() {
        // what was printed has no run directory to resume
        std::io::ErrorKind::StorageFull | std::io::ErrorKind::QuotaExceeded
            if path == std::path::Path::new(STDOUT) =>
        {
            "; free some space or send the output elsewhere"
        }
        std::io::ErrorKind::StorageFull | std::io::ErrorKind::QuotaExceeded => {
            "; free some space, then continue with --resume (finished cells are kept)"
        }
        std::io::ErrorKind::PermissionDenied | std::io::ErrorKind::ReadOnlyFilesystem => {
            "; choose an --out you can write to"
        }
        _ => "",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn io_errors_are_named_by_their_cause() {
        let io = |k: std::io::ErrorKind| Error::io("write", "/x", std::io::Error::from(k));
        assert_eq!(io(std::io::ErrorKind::NotFound).code(), "not_found");
        assert_eq!(
            io(std::io::ErrorKind::PermissionDenied).code(),
            "permission"
        );
        assert_eq!(io(std::io::ErrorKind::StorageFull).code(), "disk_full");
        assert_eq!(io(std::io::ErrorKind::Other).code(), "io");
        assert_eq!(io(std::io::ErrorKind::Other).kind(), ErrorKind::Output);
        assert_eq!(Error::RunExists("x".into()).kind(), ErrorKind::Output);
        assert_eq!(Error::ModelNotFound("x".into()).kind(), ErrorKind::Model);
        assert!(!Error::Internal("x".into()).is_user_error());
    }
}
