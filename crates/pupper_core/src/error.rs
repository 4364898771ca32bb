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
    #[error("interrupted: {0}")]
    Interrupted(String),
    #[error("{0}")]
    Display(String),
    #[error("cannot {action} {path}: {source}")]
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
            Error::Model(_) => ErrorKind::Model,
            Error::Mujoco(_) => ErrorKind::Mujoco,
            Error::Output(_) | Error::Io { .. } => ErrorKind::Output,
            Error::Interrupted(_) => ErrorKind::Interrupted,
            Error::Display(_) => ErrorKind::Display,
            Error::Internal(_) => ErrorKind::Internal,
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
