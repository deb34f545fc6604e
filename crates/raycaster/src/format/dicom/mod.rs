//! DICOM series: a directory of single-frame slices (or one file of it)
//! opened as one volume, x along the rows, y along the columns, z across
//! the slices.
//!
//! Parsing is left to the DICOM-rs crates (`dicom-object`, behind the
//! `dicom` cargo feature); this module groups the files into series, orders
//! the slices and copies the native pixel data into one x-fast array. Its
//! parts: `header` reads what a file's header says, `series` groups,
//! orders and measures the slices (with the pure geometry in `geometry`),
//! `pixels` checks the pixel format and reads the pixel data. Without the
//! feature only detection is compiled, and opening a series is an error
//! naming the missing feature.
//!
//! Supported:
//!
//! - Part 10 files (`DICM` at byte 128, or the file meta group at byte 0);
//!   other files in the directory are skipped silently, as are DICOM files
//!   that hold no image (no Rows/Columns, e.g. a `DICOMDIR`).
//! - Uncompressed transfer syntaxes: implicit and explicit VR little endian,
//!   explicit VR big endian.
//! - Single-frame grey-scale slices (Samples per Pixel 1, MONOCHROME1 or 2)
//!   of 8 or 16 allocated bits, unsigned or signed (u8, i8, u16, i16); when
//!   fewer bits are stored than allocated, the bits above High Bit are
//!   masked off (unsigned) or the sign is extended (signed).
//! - Rescale slope/intercept: one pair for the series goes to
//!   [`samples::from_samples`](super::samples::from_samples) (i16 or f32 data
//!   units); pairs that differ between slices are applied per slice to f32.
//!
//! Grouping and ordering:
//!
//! - Files are grouped by Series Instance UID, Rows, Columns and Image
//!   Orientation (Patient). A directory path opens the group with the most
//!   slices; a file path opens the group that file belongs to. Either way,
//!   when the directory holds several groups `info.notes` says so.
//! - Slices are sorted by ascending position along the normal
//!   `n = row direction × column direction` (`ImagePositionPatient · n`),
//!   never by file name; equal positions keep Instance Number order. When a
//!   slice lacks position or orientation, the series is ordered by Instance
//!   Number instead (noted).
//! - Spacing is (column spacing, row spacing, mean distance between
//!   consecutive slice positions along the unit normal); Pixel Spacing is
//!   stored as (row, column). The slice distance is computed in `f64` and
//!   rounded to 6 significant digits when it lies within a millionth of
//!   such a value (decimal headers give e.g. 3.0000002 for 3).
//!   Slice Thickness is used only for a single slice (1 when absent). A
//!   spacing that varies by more than 1 % is noted (the mean is used).
//! - Duplicate positions (several slices within 0.01 mm, e.g. several
//!   volumes of a diffusion or dynamic series under one UID): the first slice
//!   at each position (by Instance Number, then file name) is kept and the
//!   number dropped is noted.
//! - The orientation is reported in `info.orientation`, not applied.
//!
//! Not supported (a one-line error naming the file): compressed
//! (encapsulated) transfer syntaxes (JPEG, JPEG-LS, JPEG 2000, RLE, ...),
//! deflated data sets, multi-frame files, colour images, Bits Allocated other
//! than 8 or 16. A file that cannot be parsed (e.g. truncated) is an error
//! rather than a silently missing slice.

use std::path::Path;

use super::{Claim, OpenOptions, Opened, Probe, Reader};
use crate::error::Result;

#[cfg(feature = "dicom")]
mod geometry;
#[cfg(feature = "dicom")]
mod guard;
#[cfg(feature = "dicom")]
mod header;
#[cfg(feature = "dicom")]
mod pixels;
#[cfg(feature = "dicom")]
mod series;
#[cfg(all(test, feature = "dicom"))]
mod tests;

/// The reader of DICOM series: a directory, or a file with the Part 10
/// preamble or file meta group, claims firmly; the names `.dcm` and `.ima`
/// claim weakly.
#[derive(Debug, Clone, Copy)]
pub struct DicomReader;

impl Reader for DicomReader {
    fn sniff(&self, probe: &Probe) -> Option<Claim> {
        if probe.is_dir || looks_like(probe.head) {
            Some(Claim::Content)
        } else {
            matches!(probe.extension(), "dcm" | "ima").then_some(Claim::Name)
        }
    }

    /// Opens the series in directory `path`, or the series the file `path`
    /// belongs to (with the other files of its directory), as described in
    /// the module documentation; reports the fraction of slices read.
    fn open(&self, path: &Path, options: &OpenOptions) -> Result<Opened> {
        open_series(path, options)
    }
}

#[cfg(feature = "dicom")]
fn open_series(path: &Path, options: &OpenOptions) -> Result<Opened> {
    series::open(path, options.progress.as_ref(), options.max_memory)
}

#[cfg(not(feature = "dicom"))]
fn open_series(path: &Path, _options: &OpenOptions) -> Result<Opened> {
    Err(crate::error::Error::format(
        path,
        crate::error::FormatError::NotCompiledIn {
            support: "DICOM",
            feature: "dicom",
        },
    ))
}

/// Whether `head` (the first 132 bytes or more) starts like a DICOM Part 10
/// file: `DICM` at byte 128, or (without the preamble) the file meta group.
pub fn looks_like(head: &[u8]) -> bool {
    (head.len() >= 132 && &head[128..132] == b"DICM")
        || (head.len() >= 6 && head[..4] == [0x02, 0x00, 0x00, 0x00] && &head[4..6] == b"UL")
}
