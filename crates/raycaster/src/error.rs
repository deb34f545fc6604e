//! Error types of the library.
//!
//! Every error that comes from a file names the file, so a message printed on
//! its own (as the command-line tools do) tells the user what went wrong where.

use std::path::{Path, PathBuf};

/// Anything that can go wrong while opening, reading or writing a volume or a
/// transfer function.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The operating system refused an operation on a file.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// The file's content does not follow its format.
    #[error("{}: {kind}", path.display())]
    Format {
        /// The file concerned.
        path: PathBuf,
        /// What is wrong with it.
        kind: FormatError,
    },
    /// A transfer function file or value is invalid.
    #[error("{}: {message}", path.display())]
    TransferFunction {
        /// The file concerned (empty when the TF did not come from a file).
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// A file or volume holds more than this machine can address.
    #[error("{}: too large for this machine ({what})", path.display())]
    TooLarge {
        /// The file concerned (empty for a volume built in memory).
        path: PathBuf,
        /// What would not fit.
        what: String,
    },
    /// A part of a file cannot be read on its own (distributed rendering).
    #[error("cannot read part of {}: {reason}", path.display())]
    Partial {
        /// The file.
        path: PathBuf,
        /// Why, and what to do instead.
        reason: String,
    },
    /// Samples, dimensions and layout of a volume built in memory disagree.
    #[error("invalid volume: {0}")]
    InvalidVolume(String),
    /// A rendering option (step, threshold, camera, thread count, ...) is
    /// out of range.
    #[error("invalid {option}: {message}")]
    InvalidOption {
        /// The option, as named on the command line where there is one.
        option: &'static str,
        /// What is wrong with its value.
        message: String,
    },
    /// The operating system would not start a thread.
    #[error("cannot start {count} {role} threads: {source}")]
    Threads {
        /// Threads asked for.
        count: usize,
        /// What they were for (`render`, `renderer front`, ...).
        role: &'static str,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// An image could not be encoded or written.
    #[error("{}: {message}", path.display())]
    Image {
        /// The image file.
        path: PathBuf,
        /// What the encoder said.
        message: String,
    },
    /// A line of a points file (metaballs) cannot be read.
    #[error("{}: line {line}: {message}", path.display())]
    Points {
        /// The points file.
        path: PathBuf,
        /// The line, counted from 1.
        line: usize,
        /// What is wrong with it.
        message: String,
    },
    /// A volume or points file gives more metaballs than the cap allows.
    #[error("{what} gives more than {cap} balls (the cap, --max-balls): {hint}")]
    TooManyBalls {
        /// Where the balls come from.
        what: String,
        /// The cap.
        cap: usize,
        /// How to get fewer balls.
        hint: &'static str,
    },
    /// A frame was cancelled by a caller that cannot see cancellations.
    #[error("the {renderer} renderer stopped a frame that could not be cancelled")]
    Cancelled {
        /// The renderer's name.
        renderer: &'static str,
    },
}

impl Error {
    /// Wraps an I/O error with the path it concerns.
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        Error::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    /// An out-of-range rendering option.
    pub fn option(option: &'static str, message: impl Into<String>) -> Self {
        Error::InvalidOption {
            option,
            message: message.into(),
        }
    }

    /// Wraps a format problem with the path it concerns.
    pub fn format(path: &Path, kind: FormatError) -> Self {
        Error::Format {
            path: path.to_path_buf(),
            kind,
        }
    }
}

/// The ways a volume file can be malformed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FormatError {
    /// The file ends before the header does.
    #[error("file is {found} bytes long, shorter than the {expected}-byte header")]
    TooShortForHeader {
        /// Header length in bytes.
        expected: u64,
        /// File length in bytes.
        found: u64,
    },
    /// A dimension is zero.
    #[error("dimension {axis} is 0 (every dimension must be at least 1)")]
    ZeroDimension {
        /// `'X'`, `'Y'` or `'Z'`.
        axis: char,
    },
    /// A spacing is NaN, infinite, zero or negative.
    #[error("spacing {axis} is {value} (must be finite and greater than 0)")]
    BadSpacing {
        /// `'X'`, `'Y'` or `'Z'`.
        axis: char,
        /// The offending value.
        value: f32,
    },
    /// The layout byte is neither linear nor bricked.
    #[error("unknown layout byte {0} (expected 1 = linear or 2 = bricked)")]
    UnknownLayout(u8),
    /// A bricked file declares a brick side below 2.
    #[error("brick side {0} is invalid (must be 2..=255)")]
    BadBrickSize(u8),
    /// The dimensions describe more bytes than fit in 64 bits.
    #[error("dimensions {x}x{y}x{z} overflow the addressable size")]
    SizeOverflow {
        /// Dimension X.
        x: u64,
        /// Dimension Y.
        y: u64,
        /// Dimension Z.
        z: u64,
    },
    /// The file holds a different number of bytes than the header implies.
    #[error("expected {expected} bytes ({detail}), found {found}")]
    WrongLength {
        /// Byte count implied by the header.
        expected: u64,
        /// Byte count of the file.
        found: u64,
        /// How the expected count was derived.
        detail: String,
    },
    /// A header field is missing, malformed or inconsistent.
    #[error("{0}")]
    Invalid(String),
    /// A valid file uses a feature this reader does not support.
    #[error("unsupported: {0}")]
    Unsupported(String),
    /// The format is not recognised.
    #[error("unrecognised volume format ({0})")]
    Unrecognised(String),
    /// The file needs a codec or reader that this build of the library left
    /// out (a cargo feature of `raycaster` that is off): unlike
    /// [`FormatError::Unsupported`], a build with the feature reads it.
    #[error("{support} support is not compiled in (enable the `{feature}` feature of raycaster)")]
    NotCompiledIn {
        /// What is missing, as the user knows it (`gzip`, `DICOM`).
        support: &'static str,
        /// The cargo feature that adds it.
        feature: &'static str,
    },
}

/// Shorthand for results of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;
