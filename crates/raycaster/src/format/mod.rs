//! Volume file formats: parsing headers and bringing samples into memory.
//!
//! [`open`] detects the format from the file's content and extension and
//! returns an [`AnyVolume`], the runtime-typed handle that the command-line
//! tools use; library users who know their format can call the format
//! module's own `open` and get a concretely typed volume.

pub mod vol;

use std::path::Path;

use crate::error::{Error, FormatError, Result};
use crate::storage::LoadMode;
use crate::volume::AnyVolume;

/// The formats this build can read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FileFormat {
    /// The 26-byte-header `.vol` format of SPEC §1.
    Vol,
}

/// Guesses the format of `path` from its extension and first bytes.
pub fn detect(path: &Path) -> Result<FileFormat> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if meta.is_dir() {
        return Err(Error::format(
            path,
            FormatError::Unrecognised("a directory; DICOM series are not supported yet".into()),
        ));
    }
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "vol" | "" => Ok(FileFormat::Vol),
        other => Err(Error::format(
            path,
            FormatError::Unrecognised(format!("extension .{other}; supported: .vol")),
        )),
    }
}

/// Opens a volume file of any supported format.
pub fn open(path: &Path, mode: LoadMode) -> Result<AnyVolume> {
    match detect(path)? {
        FileFormat::Vol => Ok(match vol::open(path, mode)? {
            vol::VolVolume::Linear(v) => AnyVolume::from(v),
            vol::VolVolume::Bricked(v) => AnyVolume::from(v),
        }),
    }
}
