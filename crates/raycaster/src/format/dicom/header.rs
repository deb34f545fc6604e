//! What one DICOM file's header says (pass 1 of reading a series: every
//! element before Pixel Data), the errors that name such a file, and the
//! transfer syntaxes this reader can decode.

use std::path::{Path, PathBuf};

use dicom_dictionary_std::tags;
use dicom_object::{DefaultDicomObject, OpenFileOptions};

use crate::error::{Error, FormatError, Result};
use crate::format::samples::Endian;

/// What pass 1 learns from a file's header (everything before Pixel Data).
#[derive(Debug, Clone)]
pub(super) struct Header {
    pub(super) path: PathBuf,
    pub(super) file_bytes: u64,
    pub(super) transfer_syntax: String,
    pub(super) series_uid: String,
    pub(super) rows: u32,
    pub(super) columns: u32,
    pub(super) orientation: Option<[f64; 6]>,
    pub(super) position: Option<[f64; 3]>,
    pub(super) instance: Option<i64>,
    /// (row spacing, column spacing), DICOM order.
    pub(super) pixel_spacing: Option<[f64; 2]>,
    pub(super) slice_thickness: Option<f64>,
    pub(super) bits_allocated: Option<u32>,
    pub(super) bits_stored: Option<u32>,
    pub(super) high_bit: Option<u32>,
    pub(super) pixel_representation: Option<u32>,
    pub(super) samples_per_pixel: Option<u32>,
    pub(super) photometric: Option<String>,
    pub(super) frames: Option<i64>,
    pub(super) slope: Option<f64>,
    pub(super) intercept: Option<f64>,
    /// `CT`, `MR`, ...
    pub(super) modality: Option<String>,
}

/// Reads the header of a DICOM file; `None` for a file without an image.
pub(super) fn read_header(path: &Path) -> Result<Option<Header>> {
    super::guard::check_lengths(path)?;
    let obj = OpenFileOptions::new()
        .read_until(tags::PIXEL_DATA)
        .open_file(path)
        .map_err(|e| unreadable(path, &e))?;
    let (Some(rows), Some(columns)) = (get_u32(&obj, tags::ROWS), get_u32(&obj, tags::COLUMNS))
    else {
        return Ok(None);
    };
    let file_bytes = crate::format::file_len(path)?;
    Ok(Some(Header {
        path: path.to_path_buf(),
        file_bytes,
        transfer_syntax: obj.meta().transfer_syntax().to_string(),
        series_uid: get_str(&obj, tags::SERIES_INSTANCE_UID).unwrap_or_default(),
        rows,
        columns,
        orientation: get_floats(&obj, tags::IMAGE_ORIENTATION_PATIENT),
        position: get_floats(&obj, tags::IMAGE_POSITION_PATIENT),
        instance: get_int(&obj, tags::INSTANCE_NUMBER),
        pixel_spacing: get_floats(&obj, tags::PIXEL_SPACING),
        slice_thickness: get_float(&obj, tags::SLICE_THICKNESS),
        bits_allocated: get_u32(&obj, tags::BITS_ALLOCATED),
        bits_stored: get_u32(&obj, tags::BITS_STORED),
        high_bit: get_u32(&obj, tags::HIGH_BIT),
        pixel_representation: get_u32(&obj, tags::PIXEL_REPRESENTATION),
        samples_per_pixel: get_u32(&obj, tags::SAMPLES_PER_PIXEL),
        photometric: get_str(&obj, tags::PHOTOMETRIC_INTERPRETATION),
        frames: get_int(&obj, tags::NUMBER_OF_FRAMES),
        slope: get_float(&obj, tags::RESCALE_SLOPE),
        intercept: get_float(&obj, tags::RESCALE_INTERCEPT),
        modality: get_str(&obj, tags::MODALITY),
    }))
}

/// The error for a file DICOM-rs could not parse; names an unsupported
/// transfer syntax when that is the cause.
pub(super) fn unreadable(path: &Path, e: &dyn std::error::Error) -> Error {
    if let Some(ts) = meta_transfer_syntax(path)
        && native_endian_of(&ts).is_none()
    {
        return Error::format(path, unsupported_syntax(&ts));
    }
    Error::format(
        path,
        FormatError::Invalid(format!("cannot read the DICOM file ({})", error_chain(e))),
    )
}

/// The transfer syntax in the file meta group, when that much can be read.
fn meta_transfer_syntax(path: &Path) -> Option<String> {
    use std::io::{Read, Seek, SeekFrom};
    let mut f = std::fs::File::open(path).ok()?;
    let mut head = [0u8; 132];
    f.read_exact(&mut head).ok()?;
    if &head[128..] != b"DICM" {
        return None;
    }
    // The meta group is read from its `DICM` marker.
    f.seek(SeekFrom::Start(128)).ok()?;
    let meta = dicom_object::FileMetaTable::from_reader(std::io::BufReader::new(f)).ok()?;
    Some(meta.transfer_syntax().to_string())
}

/// An error and its causes on one line.
fn error_chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(cause) = source {
        let m = cause.to_string();
        if !text.contains(&m) {
            text.push_str(": ");
            text.push_str(&m);
        }
        source = cause.source();
    }
    text.replace(['\n', '\r'], " ")
}

fn get_str(obj: &DefaultDicomObject, tag: dicom_core::Tag) -> Option<String> {
    let e = obj.element_opt(tag).ok()??;
    let s = e.to_str().ok()?;
    let s = s.trim_matches(|c: char| c.is_whitespace() || c == '\0');
    (!s.is_empty()).then(|| s.to_string())
}

fn get_int(obj: &DefaultDicomObject, tag: dicom_core::Tag) -> Option<i64> {
    obj.element_opt(tag).ok()??.to_int::<i64>().ok()
}

fn get_u32(obj: &DefaultDicomObject, tag: dicom_core::Tag) -> Option<u32> {
    get_int(obj, tag).and_then(|v| u32::try_from(v).ok())
}

fn get_float(obj: &DefaultDicomObject, tag: dicom_core::Tag) -> Option<f64> {
    let v = obj.element_opt(tag).ok()??.to_float64().ok()?;
    v.is_finite().then_some(v)
}

fn get_floats<const N: usize>(obj: &DefaultDicomObject, tag: dicom_core::Tag) -> Option<[f64; N]> {
    let v = obj.element_opt(tag).ok()??.to_multi_float64().ok()?;
    let a: [f64; N] = v.try_into().ok()?;
    a.iter().all(|x| x.is_finite()).then_some(a)
}

/// The byte order of a native (uncompressed) transfer syntax.
pub(super) fn native_endian_of(uid: &str) -> Option<Endian> {
    match uid {
        "1.2.840.10008.1.2" | "1.2.840.10008.1.2.1" => Some(Endian::Little),
        "1.2.840.10008.1.2.2" => Some(Endian::Big),
        _ => None,
    }
}

/// The name of a transfer syntax, or its UID when not a common one.
pub(super) fn transfer_syntax_name(uid: &str) -> String {
    let name = match uid {
        "1.2.840.10008.1.2" => "Implicit VR Little Endian",
        "1.2.840.10008.1.2.1" => "Explicit VR Little Endian",
        "1.2.840.10008.1.2.1.98" => "Encapsulated Uncompressed Explicit VR Little Endian",
        "1.2.840.10008.1.2.1.99" => "Deflated Explicit VR Little Endian",
        "1.2.840.10008.1.2.2" => "Explicit VR Big Endian",
        "1.2.840.10008.1.2.4.50" => "JPEG Baseline (Process 1)",
        "1.2.840.10008.1.2.4.51" => "JPEG Extended (Process 2 & 4)",
        "1.2.840.10008.1.2.4.57" => "JPEG Lossless (Process 14)",
        "1.2.840.10008.1.2.4.70" => "JPEG Lossless SV1",
        "1.2.840.10008.1.2.4.80" => "JPEG-LS Lossless",
        "1.2.840.10008.1.2.4.81" => "JPEG-LS Near-Lossless",
        "1.2.840.10008.1.2.4.90" => "JPEG 2000 Lossless",
        "1.2.840.10008.1.2.4.91" => "JPEG 2000",
        "1.2.840.10008.1.2.4.201" => "HTJ2K Lossless",
        "1.2.840.10008.1.2.4.202" => "HTJ2K Lossless RPCL",
        "1.2.840.10008.1.2.4.203" => "HTJ2K",
        "1.2.840.10008.1.2.5" => "RLE Lossless",
        _ => return format!("transfer syntax {uid}"),
    };
    name.to_string()
}

pub(super) fn unsupported_syntax(uid: &str) -> FormatError {
    FormatError::Unsupported(format!(
        "{} ({uid}) is compressed or encapsulated; only uncompressed (native) transfer syntaxes are read",
        transfer_syntax_name(uid)
    ))
}

pub(super) fn invalid(h: &Header, msg: String) -> Error {
    Error::format(&h.path, FormatError::Invalid(msg))
}

pub(super) fn unsupported(h: &Header, msg: String) -> Error {
    Error::format(&h.path, FormatError::Unsupported(msg))
}
