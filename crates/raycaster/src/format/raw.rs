//! Headerless ("raw") sample files, described by the caller (on the command
//! line: `--raw-dims`, `--raw-type`, ...): dimensions, sample type with byte
//! order, spacing, a byte offset to skip and the axis order (x fastest by
//! default, as most published raw data). Nothing in such a file can be
//! detected, so [`RawReader`] is not in the detection table: it reads the
//! file when [`OpenOptions::raw`](super::OpenOptions::raw) is given.

use std::path::Path;

use glam::{UVec3, Vec3};

use super::samples::{self, Endian, SampleLayout};
use super::{FileFormat, Opened, VolumeInfo};
use crate::error::{Error, FormatError, Result};
use crate::sample::SampleType;
use crate::volume::AxisOrder;

/// The description of a raw file.
#[derive(Debug, Clone, PartialEq)]
pub struct RawOptions {
    /// Samples per axis.
    pub dims: UVec3,
    /// Sample type.
    pub sample: SampleType,
    /// Byte order of multi-byte samples.
    pub endian: Endian,
    /// Spacing per axis (default 1).
    pub spacing: Vec3,
    /// Bytes to skip before the samples (a header of another format).
    pub offset: u64,
    /// Which axis changes fastest (default x).
    pub order: AxisOrder,
}

impl RawOptions {
    /// A raw description with spacing 1, no offset, x fastest.
    pub fn new(dims: UVec3, sample: SampleType, endian: Endian) -> Self {
        RawOptions {
            dims,
            sample,
            endian,
            spacing: Vec3::ONE,
            offset: 0,
            order: AxisOrder::XFast,
        }
    }

    /// The `--raw-type` name of `sample` in `endian` order (`u16be`, `f32le`,
    /// `u8`, ...): what [`RawOptions::parse_type`] reads back.
    pub fn type_name(sample: SampleType, endian: Endian) -> String {
        let suffix = match (sample.size(), endian) {
            (1, _) => "",
            (_, Endian::Little) => "le",
            (_, Endian::Big) => "be",
        };
        format!("{}{suffix}", sample.name())
    }

    /// Parses a `--raw-type` value: `u8`, `i8`, `u16le`, `u16be`, `i16le`,
    /// `i16be`, `f32le`, `f32be` (and `u16`/`i16`/`f32` for little-endian).
    pub fn parse_type(text: &str) -> Option<(SampleType, Endian)> {
        use Endian::*;
        use SampleType::*;
        Some(match text.to_ascii_lowercase().as_str() {
            "u8" | "uint8" => (U8, Little),
            "i8" | "int8" => (I8, Little),
            "u16" | "u16le" => (U16, Little),
            "u16be" => (U16, Big),
            "i16" | "i16le" => (I16, Little),
            "i16be" => (I16, Big),
            "f32" | "f32le" => (F32, Little),
            "f32be" => (F32, Big),
            _ => return None,
        })
    }
}

/// The reader of headerless files described by
/// [`OpenOptions::raw`](super::OpenOptions::raw). The file must hold exactly
/// `offset` + the samples' bytes: a size mismatch usually means wrong
/// dimensions or type, and the error says what was expected.
#[derive(Debug, Clone, Copy)]
pub struct RawReader;

impl super::Reader for RawReader {
    /// Never claims a file: there is no header to recognise.
    fn sniff(&self, _probe: &super::Probe) -> Option<super::Claim> {
        None
    }

    fn open(&self, path: &Path, options: &super::OpenOptions) -> Result<Opened> {
        let Some(raw) = &options.raw else {
            return Err(Error::format(
                path,
                FormatError::Unrecognised(
                    "a headerless file needs a description (--raw-dims and --raw-type)".into(),
                ),
            ));
        };
        if std::fs::metadata(path)
            .map_err(|e| Error::io(path, e))?
            .is_dir()
        {
            return Err(Error::format(
                path,
                FormatError::Invalid("is a directory, not a raw file".into()),
            ));
        }
        let layout = SampleLayout {
            dims: raw.dims,
            spacing: raw.spacing,
            sample: raw.sample,
            endian: raw.endian,
            order: raw.order,
        };
        let volume = samples::from_file(
            path,
            raw.offset,
            &layout,
            None,
            options.mode,
            true,
            options.max_memory,
        )?;
        let mut info = VolumeInfo::new(FileFormat::Raw, &layout, "raw", super::file_len(path)?);
        info.notes.push(match raw.order {
            AxisOrder::XFast => "x fastest".to_string(),
            AxisOrder::ZFast => "z fastest".to_string(),
        });
        if raw.offset > 0 {
            info.notes.push(format!("{} bytes skipped", raw.offset));
        }
        Ok(Opened { volume, info })
    }
}

/// Writes the samples of `volume` as a headerless file in `order` and
/// `endian` order (under a temporary name, renamed when complete): the
/// project's own raw writer, for converters and round-trip tests.
pub fn write(
    path: &Path,
    volume: &crate::volume::AnyVolume,
    order: AxisOrder,
    endian: Endian,
) -> Result<()> {
    super::atomic::write_atomically(path, |w| samples::write_samples(w, volume, order, endian))
}
