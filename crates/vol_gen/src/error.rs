//! The errors `vol_gen` reports, each printed as one line by `main`.

use std::fmt;

/// Why a run failed.
#[derive(Debug)]
pub enum Error {
    /// The command line or a parameter is invalid (exit code 2).
    Usage(String),
    /// SIGINT or SIGTERM arrived before the volume was complete (exit code 130).
    Interrupted,
    /// Anything else: I/O, disk space, an existing output file (exit code 1).
    Failed(String),
}

impl Error {
    /// The process exit code for this error.
    pub fn exit_code(&self) -> u8 {
        match self {
            Error::Usage(_) => 2,
            Error::Interrupted => 130,
            Error::Failed(_) => 1,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Usage(m) | Error::Failed(m) => f.write_str(m),
            Error::Interrupted => f.write_str("interrupted; no file was written"),
        }
    }
}

impl std::error::Error for Error {}

impl From<raycaster::Error> for Error {
    fn from(e: raycaster::Error) -> Self {
        Error::Failed(e.to_string())
    }
}

/// Shorthand for results of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;
