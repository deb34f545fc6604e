//! DICOM series: a directory of single-frame slices (or one file of it)
//! opened as one volume (SPEC §7).
//!
//! Parsing is left to the DICOM-rs crates (`dicom-object`); this module
//! groups the files into series, orders the slices and copies the native
//! pixel data into one x-fast array.
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
//!   consecutive slice positions); Pixel Spacing is stored as (row, column).
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

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use dicom_core::value::{DicomValueType, PrimitiveValue, Value};
use dicom_dictionary_std::tags;
use dicom_object::{DefaultDicomObject, OpenFileOptions};
use glam::{UVec3, Vec3};
use rayon::prelude::*;

use super::samples::{self, Endian, Rescale, SampleLayout};
use super::{FileFormat, Opened, VolumeInfo};
use crate::error::{Error, FormatError, Result};
use crate::sample::{Sample, SampleType};
use crate::volume::{AnyVolume, AxisOrder, Grid};

/// Slices closer than this along the normal (mm) are at the same position.
const SAME_POSITION_MM: f64 = 0.01;
/// Relative deviation of the slice spacing from its mean that is noted.
const SPACING_TOLERANCE: f64 = 0.01;
/// Orientation cosines that differ by less than this are the same.
const ORIENTATION_TOLERANCE: f64 = 1e-3;

/// Opens the DICOM series in directory `path`, or the series the file
/// `path` belongs to (with the other files of its directory), as described in
/// the module documentation.
pub fn open(path: &Path) -> Result<Opened> {
    open_with(path, None)
}

/// As [`open`], reporting the fraction of slices read.
pub fn open_with(path: &Path, progress: Option<&super::Progress>) -> Result<Opened> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    let (dir, chosen_file) = if meta.is_dir() {
        (path.to_path_buf(), None)
    } else {
        let dir = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        if !is_dicom_file(path)? {
            return Err(Error::format(
                path,
                FormatError::Invalid(
                    "not a DICOM file (no DICM marker at byte 128 and no file meta group)".into(),
                ),
            ));
        }
        (dir, Some(path.to_path_buf()))
    };

    // Pass 1: the headers of every DICOM file of the directory.
    let files = list_files(&dir)?;
    let checked = files.len();
    let dicom: Vec<PathBuf> = files
        .into_par_iter()
        .map(|f| Ok(is_dicom_file(&f)?.then_some(f)))
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .flatten()
        .collect();
    let headers: Vec<Header> = dicom
        .par_iter()
        .map(|f| read_header(f))
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .flatten()
        .collect();
    if headers.is_empty() {
        let no_image = "DICOM file without an image (no Rows/Columns)";
        let (at, what) = match &chosen_file {
            Some(file) => (file.as_path(), no_image.to_string()),
            None if checked == 0 => (dir.as_path(), "the directory is empty".to_string()),
            None if dicom.is_empty() => (
                dir.as_path(),
                format!("no DICOM files among its {checked} files"),
            ),
            None => (
                dir.as_path(),
                format!(
                    "no DICOM image files ({} DICOM files, none with Rows/Columns)",
                    dicom.len()
                ),
            ),
        };
        return Err(Error::format(at, FormatError::Invalid(what)));
    }

    // Group into series and pick one.
    let groups = group_series(&headers);
    let pick = match &chosen_file {
        Some(file) => {
            let at = headers.iter().position(|h| same_file(&h.path, file));
            let Some(at) = at else {
                return Err(Error::format(
                    file,
                    FormatError::Invalid("DICOM file without an image (no Rows/Columns)".into()),
                ));
            };
            groups
                .iter()
                .position(|g| g.contains(&at))
                .unwrap_or_default()
        }
        None => largest_group(&groups, &headers),
    };
    let mut notes = Vec::new();
    if groups.len() > 1 {
        let uids: std::collections::HashSet<&str> =
            headers.iter().map(|h| h.series_uid.as_str()).collect();
        let split = if uids.len() < groups.len() {
            " (some share a series UID but differ in size or orientation)"
        } else {
            ""
        };
        let first = &headers[groups[pick][0]];
        let why = if chosen_file.is_some() {
            "the one holding the file given"
        } else {
            "the largest"
        };
        notes.push(format!(
            "directory holds {} series{split}; opened {} ({} slices), {why}",
            groups.len(),
            display_uid(&first.series_uid),
            groups[pick].len()
        ));
    }
    let series: Vec<&Header> = groups[pick].iter().map(|&i| &headers[i]).collect();
    build(series, notes, progress)
}

/// What pass 1 learns from a file's header (everything before Pixel Data).
#[derive(Debug, Clone)]
struct Header {
    path: PathBuf,
    file_bytes: u64,
    transfer_syntax: String,
    series_uid: String,
    rows: u32,
    columns: u32,
    orientation: Option<[f64; 6]>,
    position: Option<[f64; 3]>,
    instance: Option<i64>,
    /// (row spacing, column spacing), DICOM order.
    pixel_spacing: Option<[f64; 2]>,
    slice_thickness: Option<f64>,
    bits_allocated: Option<u32>,
    bits_stored: Option<u32>,
    high_bit: Option<u32>,
    pixel_representation: Option<u32>,
    samples_per_pixel: Option<u32>,
    photometric: Option<String>,
    frames: Option<i64>,
    slope: Option<f64>,
    intercept: Option<f64>,
    /// `CT`, `MR`, ...
    modality: Option<String>,
}

/// The directory's regular files (symbolic links followed), by name.
fn list_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
        let entry = entry.map_err(|e| Error::io(dir, e))?;
        let p = entry.path();
        if std::fs::metadata(&p).map(|m| m.is_file()).unwrap_or(false) {
            files.push(p);
        }
    }
    files.sort();
    Ok(files)
}

/// Whether `path` starts like a DICOM Part 10 file.
fn is_dicom_file(path: &Path) -> Result<bool> {
    let head = super::read_head(path, 132)?;
    Ok(looks_like(&head))
}

/// Whether `head` (the first 132 bytes or more) starts like a DICOM Part 10
/// file: `DICM` at byte 128, or (without the preamble) the file meta group.
pub fn looks_like(head: &[u8]) -> bool {
    (head.len() >= 132 && &head[128..132] == b"DICM")
        || (head.len() >= 6 && head[..4] == [0x02, 0x00, 0x00, 0x00] && &head[4..6] == b"UL")
}

fn same_file(a: &Path, b: &Path) -> bool {
    a == b
        || match (a.canonicalize(), b.canonicalize()) {
            (Ok(a), Ok(b)) => a == b,
            _ => false,
        }
}

/// Reads the header of a DICOM file; `None` for a file without an image.
fn read_header(path: &Path) -> Result<Option<Header>> {
    let obj = OpenFileOptions::new()
        .read_until(tags::PIXEL_DATA)
        .open_file(path)
        .map_err(|e| unreadable(path, &e))?;
    let (Some(rows), Some(columns)) = (get_u32(&obj, tags::ROWS), get_u32(&obj, tags::COLUMNS))
    else {
        return Ok(None);
    };
    let file_bytes = super::file_len(path)?;
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
fn unreadable(path: &Path, e: &dyn std::error::Error) -> Error {
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
    let n = f.read(&mut head).ok()?;
    let start = if n >= 132 && &head[128..132] == b"DICM" {
        128
    } else {
        return None;
    };
    f.seek(SeekFrom::Start(start)).ok()?;
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

/// Groups header indices by series UID, size and orientation (in the order
/// the headers come).
fn group_series(headers: &[Header]) -> Vec<Vec<usize>> {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut by_key: HashMap<(&str, u32, u32), Vec<usize>> = HashMap::new();
    for (i, h) in headers.iter().enumerate() {
        let candidates = by_key
            .entry((h.series_uid.as_str(), h.rows, h.columns))
            .or_default();
        let found = candidates
            .iter()
            .copied()
            .find(|&g| same_orientation(headers[groups[g][0]].orientation, h.orientation));
        match found {
            Some(g) => groups[g].push(i),
            None => {
                candidates.push(groups.len());
                groups.push(vec![i]);
            }
        }
    }
    groups
}

fn same_orientation(a: Option<[f64; 6]>, b: Option<[f64; 6]>) -> bool {
    match (a, b) {
        (Some(a), Some(b)) => a
            .iter()
            .zip(b)
            .all(|(x, y)| (x - y).abs() <= ORIENTATION_TOLERANCE),
        (None, None) => true,
        _ => false,
    }
}

/// The group with most slices; ties go to the one whose first file sorts
/// first.
fn largest_group(groups: &[Vec<usize>], headers: &[Header]) -> usize {
    (0..groups.len())
        .min_by(|&a, &b| {
            groups[b]
                .len()
                .cmp(&groups[a].len())
                .then_with(|| headers[groups[a][0]].path.cmp(&headers[groups[b][0]].path))
        })
        .unwrap_or_default()
}

fn display_uid(uid: &str) -> &str {
    if uid.is_empty() {
        "(no series UID)"
    } else {
        uid
    }
}

/// The slice normal `row × column` of an Image Orientation (Patient).
fn slice_normal(o: &[f64; 6]) -> [f64; 3] {
    let (r, c) = ([o[0], o[1], o[2]], [o[3], o[4], o[5]]);
    [
        r[1] * c[2] - r[2] * c[1],
        r[2] * c[0] - r[0] * c[2],
        r[0] * c[1] - r[1] * c[0],
    ]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Indices of `positions` in ascending order of their projection on
/// `normal`, with the projections; equal projections keep input order.
fn order_along(positions: &[[f64; 3]], normal: [f64; 3]) -> Vec<(usize, f64)> {
    let mut order: Vec<(usize, f64)> = positions
        .iter()
        .enumerate()
        .map(|(i, &p)| (i, dot(p, normal)))
        .collect();
    order.sort_by(|a, b| a.1.total_cmp(&b.1));
    order
}

/// Keeps the first of each run of sorted projections closer than `tol`;
/// returns the kept entries and how many were dropped.
fn drop_duplicates(sorted: &[(usize, f64)], tol: f64) -> (Vec<(usize, f64)>, usize) {
    let mut kept: Vec<(usize, f64)> = Vec::with_capacity(sorted.len());
    for &(i, d) in sorted {
        match kept.last() {
            Some(&(_, last)) if d - last < tol => {}
            _ => kept.push((i, d)),
        }
    }
    let dropped = sorted.len() - kept.len();
    (kept, dropped)
}

/// The distances between consecutive slices of ascending positions.
#[derive(Debug, Clone, Copy, PartialEq)]
struct SliceSpacing {
    mean: f64,
    min: f64,
    max: f64,
}

impl SliceSpacing {
    /// `None` for fewer than two positions.
    fn of(sorted: &[f64]) -> Option<SliceSpacing> {
        let (&first, &last) = (sorted.first()?, sorted.last()?);
        if sorted.len() < 2 {
            return None;
        }
        let (mut min, mut max) = (f64::INFINITY, f64::NEG_INFINITY);
        for w in sorted.windows(2) {
            let d = w[1] - w[0];
            min = min.min(d);
            max = max.max(d);
        }
        Some(SliceSpacing {
            mean: (last - first) / (sorted.len() - 1) as f64,
            min,
            max,
        })
    }

    /// Whether some gap differs from the mean by more than `tol` (relative).
    fn varies(&self, tol: f64) -> bool {
        (self.max - self.mean).abs() > tol * self.mean
            || (self.mean - self.min).abs() > tol * self.mean
    }
}

/// How the pixel data of every slice is stored.
#[derive(Debug, Clone, Copy, PartialEq)]
struct PixelFormat {
    rows: u32,
    columns: u32,
    bits_allocated: u32,
    bits_stored: u32,
    signed: bool,
}

impl PixelFormat {
    fn sample_type(&self) -> SampleType {
        match (self.bits_allocated, self.signed) {
            (8, false) => SampleType::U8,
            (8, true) => SampleType::I8,
            (16, false) => SampleType::U16,
            _ => SampleType::I16,
        }
    }

    fn pixels(&self) -> usize {
        self.rows as usize * self.columns as usize
    }

    /// Masks the bits above Bits Stored off, or extends the sign from there.
    #[inline]
    fn fix(&self, word: u16) -> u16 {
        if self.bits_stored >= self.bits_allocated {
            return word;
        }
        let mask = (1u32 << self.bits_stored) as u16 - 1;
        let w = word & mask;
        if self.signed && (w >> (self.bits_stored - 1)) & 1 == 1 {
            let sign = if self.bits_allocated == 8 {
                0xff
            } else {
                0xffff
            };
            (w | !mask) & sign
        } else {
            w
        }
    }
}

/// One slice to read: its file, byte order and rescale.
#[derive(Debug, Clone)]
struct Slice<'a> {
    header: &'a Header,
    endian: Endian,
    rescale: (f64, f64),
}

/// The byte order of a native (uncompressed) transfer syntax.
fn native_endian_of(uid: &str) -> Option<Endian> {
    match uid {
        "1.2.840.10008.1.2" | "1.2.840.10008.1.2.1" => Some(Endian::Little),
        "1.2.840.10008.1.2.2" => Some(Endian::Big),
        _ => None,
    }
}

/// The name of a transfer syntax, or its UID when not a common one.
fn transfer_syntax_name(uid: &str) -> String {
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

fn unsupported_syntax(uid: &str) -> FormatError {
    FormatError::Unsupported(format!(
        "{} ({uid}) is compressed or encapsulated; only uncompressed (native) transfer syntaxes are read",
        transfer_syntax_name(uid)
    ))
}

fn invalid(h: &Header, msg: String) -> Error {
    Error::format(&h.path, FormatError::Invalid(msg))
}

fn unsupported(h: &Header, msg: String) -> Error {
    Error::format(&h.path, FormatError::Unsupported(msg))
}

/// The pixel format of one slice, checked against what this reader handles.
fn pixel_format(h: &Header) -> Result<PixelFormat> {
    if native_endian_of(&h.transfer_syntax).is_none() {
        return Err(Error::format(
            &h.path,
            unsupported_syntax(&h.transfer_syntax),
        ));
    }
    let spp = h.samples_per_pixel.unwrap_or(1);
    if spp != 1 {
        return Err(unsupported(
            h,
            format!("{spp} samples per pixel (only grey-scale images, 1 sample per pixel)"),
        ));
    }
    match h.photometric.as_deref() {
        None | Some("MONOCHROME1") | Some("MONOCHROME2") => {}
        Some(p) => {
            return Err(unsupported(
                h,
                format!("photometric interpretation {p} (only MONOCHROME1/MONOCHROME2)"),
            ));
        }
    }
    if let Some(n) = h.frames
        && n != 1
    {
        return Err(unsupported(
            h,
            format!("multi-frame file ({n} frames); only single-frame slices are read"),
        ));
    }
    let Some(bits_allocated) = h.bits_allocated else {
        return Err(invalid(h, "Bits Allocated (0028,0100) is missing".into()));
    };
    if bits_allocated != 8 && bits_allocated != 16 {
        return Err(unsupported(
            h,
            format!("Bits Allocated {bits_allocated} (only 8 or 16)"),
        ));
    }
    let bits_stored = h.bits_stored.unwrap_or(bits_allocated);
    if bits_stored == 0 || bits_stored > bits_allocated {
        return Err(invalid(
            h,
            format!("Bits Stored {bits_stored} with Bits Allocated {bits_allocated}"),
        ));
    }
    if let Some(hb) = h.high_bit
        && hb + 1 != bits_stored
    {
        return Err(unsupported(
            h,
            format!(
                "High Bit {hb} with Bits Stored {bits_stored} (only High Bit = Bits Stored - 1)"
            ),
        ));
    }
    let signed = match h.pixel_representation.unwrap_or(0) {
        0 => false,
        1 => true,
        p => {
            return Err(invalid(
                h,
                format!("Pixel Representation {p} (must be 0 or 1)"),
            ));
        }
    };
    if h.rows == 0 || h.columns == 0 {
        return Err(invalid(
            h,
            format!("image of {} rows x {} columns", h.rows, h.columns),
        ));
    }
    Ok(PixelFormat {
        rows: h.rows,
        columns: h.columns,
        bits_allocated,
        bits_stored,
        signed,
    })
}

fn fmt_num(v: f64) -> String {
    let s = format!("{:.4}", v);
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

fn fmt_vec(v: &[f64]) -> String {
    let parts: Vec<String> = v.iter().map(|&x| fmt_num(x)).collect();
    format!("({})", parts.join(","))
}

/// Orders, checks and reads one series.
fn build(
    mut series: Vec<&Header>,
    mut notes: Vec<String>,
    progress: Option<&super::Progress>,
) -> Result<Opened> {
    // Instance Number, then file name, decides between equal positions.
    series.sort_by(|a, b| {
        (a.instance.is_none(), a.instance, &a.path).cmp(&(
            b.instance.is_none(),
            b.instance,
            &b.path,
        ))
    });
    let first = series[0];
    let format = pixel_format(first)?;
    for h in &series[1..] {
        let f = pixel_format(h)?;
        if f != format {
            return Err(invalid(
                h,
                format!(
                    "slice format differs from {}: {}x{} {}-bit ({} stored, {}) vs {}x{} {}-bit ({} stored, {})",
                    file_name(&first.path),
                    f.columns,
                    f.rows,
                    f.bits_allocated,
                    f.bits_stored,
                    if f.signed { "signed" } else { "unsigned" },
                    format.columns,
                    format.rows,
                    format.bits_allocated,
                    format.bits_stored,
                    if format.signed { "signed" } else { "unsigned" },
                ),
            ));
        }
    }
    let file_bytes: u64 = series.iter().map(|h| h.file_bytes).sum();

    // Order along the normal; spacing between slices.
    let orientation = first.orientation;
    let positioned: Option<Vec<[f64; 3]>> = series.iter().map(|h| h.position).collect();
    let (ordered, z_spacing): (Vec<&Header>, f64) = match (orientation, positioned) {
        (Some(o), Some(positions)) => {
            let normal = slice_normal(&o);
            let sorted = order_along(&positions, normal);
            let (kept, dropped) = drop_duplicates(&sorted, SAME_POSITION_MM);
            if dropped > 0 {
                notes.push(format!(
                    "{dropped} of {} slices share a position with another; kept the first at each position (by Instance Number), {} slices",
                    sorted.len(),
                    kept.len()
                ));
            }
            let along: Vec<f64> = kept.iter().map(|k| k.1).collect();
            let z = match SliceSpacing::of(&along) {
                Some(s) => {
                    if s.varies(SPACING_TOLERANCE) {
                        notes.push(format!(
                            "slice spacing varies from {} to {} mm; using the mean {} mm",
                            fmt_num(s.min),
                            fmt_num(s.max),
                            fmt_num(s.mean)
                        ));
                    }
                    s.mean
                }
                None => single_slice_spacing(first, &mut notes),
            };
            (kept.iter().map(|&(i, _)| series[i]).collect(), z)
        }
        _ => {
            notes.push(
                "slices lack Image Position/Orientation (Patient): ordered by Instance Number, slice spacing from Slice Thickness"
                    .into(),
            );
            let z = if series.len() == 1 {
                single_slice_spacing(first, &mut notes)
            } else {
                first.slice_thickness.filter(|t| *t > 0.0).unwrap_or(1.0)
            };
            (series.clone(), z)
        }
    };

    // In-plane spacing: Pixel Spacing is (row spacing, column spacing).
    let (sx, sy) = match first.pixel_spacing {
        Some([row, col]) if row > 0.0 && col > 0.0 => (col, row),
        _ => {
            notes.push("no valid Pixel Spacing: 1 mm assumed in-plane".into());
            (1.0, 1.0)
        }
    };
    if first.photometric.as_deref() == Some("MONOCHROME1") {
        notes.push(
            "MONOCHROME1: low values are meant to display bright (values kept as stored)".into(),
        );
    }

    // Rescale: one for the series, or per slice.
    let rescale_of = |h: &Header| (h.slope.unwrap_or(1.0), h.intercept.unwrap_or(0.0));
    let r0 = rescale_of(ordered[0]);
    let uniform = ordered.iter().all(|h| rescale_of(h) == r0);
    let slices: Vec<Slice> = ordered
        .iter()
        .map(|h| Slice {
            header: h,
            endian: native_endian_of(&h.transfer_syntax).unwrap_or(Endian::Little),
            rescale: rescale_of(h),
        })
        .collect();
    let series_rescale = if uniform {
        Rescale::non_identity(r0.0, r0.1)
    } else {
        notes.push(
            "rescale slope/intercept differ between slices: applied per slice, values as f32"
                .into(),
        );
        None
    };

    let dims = UVec3::new(format.columns, format.rows, slices.len() as u32);
    let spacing = Vec3::new(sx as f32, sy as f32, z_spacing as f32);
    let layout = SampleLayout {
        dims,
        spacing,
        sample: format.sample_type(),
        endian: slices[0].endian,
        order: AxisOrder::XFast,
    };
    layout.validate(&first.path)?;
    let grid = Grid::new(dims, spacing);
    let volume = format.sample_type().visit(ReadVolume {
        grid,
        format: &format,
        slices: &slices,
        uniform,
        rescale: series_rescale,
        progress,
    })?;

    let mut info = VolumeInfo::new(
        FileFormat::Dicom,
        &layout,
        &transfer_syntax_name(&first.transfer_syntax),
        file_bytes,
    );
    info.rescale = series_rescale;
    info.orientation = orientation.map(|o| {
        let mut s = format!("row {} col {}", fmt_vec(&o[..3]), fmt_vec(&o[3..]));
        if let Some(p) = slices[0].header.position {
            s.push_str(&format!("; first slice at {} mm", fmt_vec(&p)));
        }
        s
    });
    info.notes = notes;
    info.modality = first.modality.clone();
    Ok(Opened { volume, info })
}

fn single_slice_spacing(h: &Header, notes: &mut Vec<String>) -> f64 {
    match h.slice_thickness.filter(|t| *t > 0.0) {
        Some(t) => {
            notes.push(format!(
                "single slice: slice spacing = Slice Thickness {} mm",
                fmt_num(t)
            ));
            t
        }
        None => {
            notes.push("single slice without Slice Thickness: slice spacing 1 mm".into());
            1.0
        }
    }
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| p.display().to_string())
}

/// The sample built from a (fixed) 8- or 16-bit pixel word: its low byte
/// for 8-bit types, the word for 16-bit ones.
#[inline]
fn from_word<S: Sample>(w: u16) -> S {
    S::decode(
        &[w.to_le_bytes()[0], w.to_le_bytes()[1], 0, 0],
        Endian::Little,
    )
}

/// Pass 2 with the Rust type of the stored samples.
struct ReadVolume<'a> {
    grid: Grid,
    format: &'a PixelFormat,
    slices: &'a [Slice<'a>],
    uniform: bool,
    rescale: Option<Rescale>,
    progress: Option<&'a super::Progress>,
}

impl crate::sample::SampleTypeVisitor for ReadVolume<'_> {
    type Output = Result<AnyVolume>;
    fn visit<S: Sample>(self) -> Result<AnyVolume> {
        read_volume::<S>(
            self.grid,
            self.format,
            self.slices,
            self.uniform,
            self.rescale,
            self.progress,
        )
    }
}

/// Pass 2: reads every slice's pixel data (in parallel) into one x-fast
/// array and builds the volume.
fn read_volume<S: Sample>(
    grid: Grid,
    format: &PixelFormat,
    slices: &[Slice],
    uniform: bool,
    rescale: Option<Rescale>,
    progress: Option<&super::Progress>,
) -> Result<AnyVolume> {
    let per_slice = format.pixels();
    let total = per_slice
        .checked_mul(slices.len())
        .ok_or_else(|| invalid(slices[0].header, "series too large for this machine".into()))?;
    let mut data = vec![S::zeroed(); total];
    let read = std::sync::atomic::AtomicUsize::new(0);
    data.par_chunks_mut(per_slice)
        .zip(slices.par_iter())
        .try_for_each(|(out, slice)| {
            read_slice(slice, format, out)?;
            if let Some(p) = progress {
                let done = read.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                p.report(done as f32 / slices.len() as f32);
            }
            Ok::<(), Error>(())
        })?;
    if uniform {
        return samples::from_samples(grid, data, AxisOrder::XFast, rescale);
    }
    let mut values = Vec::with_capacity(total);
    for (chunk, slice) in data.chunks(per_slice).zip(slices) {
        let (m, c) = slice.rescale;
        values.extend(chunk.iter().map(|&s| (s.to_f32() as f64 * m + c) as f32));
    }
    samples::from_samples::<f32>(grid, values, AxisOrder::XFast, None)
}

/// Reads one slice's native pixel data into `out` (rows × columns samples).
fn read_slice<S: Sample>(slice: &Slice, format: &PixelFormat, out: &mut [S]) -> Result<()> {
    let h = slice.header;
    let obj = OpenFileOptions::new()
        .read_to(tags::PIXEL_DATA)
        .open_file(&h.path)
        .map_err(|e| unreadable(&h.path, &e))?;
    let Some(element) = obj.element_opt(tags::PIXEL_DATA).ok().flatten() else {
        return Err(invalid(h, "no Pixel Data element (7FE0,0010)".into()));
    };
    let n = out.len();
    let short = |found: usize, unit: &str| {
        Error::format(
            &h.path,
            FormatError::WrongLength {
                expected: (n * format.bits_allocated as usize / 8) as u64,
                found: found as u64,
                detail: format!(
                    "pixel data of {}x{} {}-bit samples, found {unit}",
                    format.columns, format.rows, format.bits_allocated
                ),
            },
        )
    };
    let prim = match element.value() {
        Value::Primitive(p) => p,
        Value::PixelSequence(_) => {
            return Err(Error::format(
                &h.path,
                unsupported_syntax(&h.transfer_syntax),
            ));
        }
        Value::Sequence(_) => return Err(invalid(h, "Pixel Data is a sequence".into())),
    };
    let put = |out: &mut [S], words: &mut dyn Iterator<Item = u16>| {
        for (o, w) in out.iter_mut().zip(words) {
            *o = from_word::<S>(format.fix(w));
        }
    };
    match (prim, format.bits_allocated) {
        (PrimitiveValue::Empty, _) => {
            return Err(invalid(h, "Pixel Data (7FE0,0010) is empty".into()));
        }
        // Bytes as the file stores them (OB, or OW kept as bytes).
        (PrimitiveValue::U8(bytes), 8) => {
            if bytes.len() < n {
                return Err(short(bytes.len(), "bytes"));
            }
            put(out, &mut bytes.iter().map(|&b| b as u16));
        }
        (PrimitiveValue::U8(bytes), _) => {
            if bytes.len() < 2 * n {
                return Err(short(bytes.len(), "bytes"));
            }
            let e = slice.endian;
            put(out, &mut bytes.chunks_exact(2).map(|c| u16::decode(c, e)));
        }
        // Words already decoded in the transfer syntax's byte order.
        (PrimitiveValue::U16(words), 16) => {
            if words.len() < n {
                return Err(short(2 * words.len(), "bytes"));
            }
            put(out, &mut words.iter().copied());
        }
        (PrimitiveValue::I16(words), 16) => {
            if words.len() < n {
                return Err(short(2 * words.len(), "bytes"));
            }
            put(out, &mut words.iter().map(|&w| w as u16));
        }
        // 8-bit samples in OW words: back to the byte stream.
        (PrimitiveValue::U16(words), _) => {
            if 2 * words.len() < n {
                return Err(short(2 * words.len(), "bytes"));
            }
            let e = slice.endian;
            let bytes = words.iter().flat_map(|&w| match e {
                Endian::Little => w.to_le_bytes(),
                Endian::Big => w.to_be_bytes(),
            });
            put(out, &mut bytes.map(|b| b as u16));
        }
        (other, _) => {
            return Err(invalid(
                h,
                format!(
                    "Pixel Data holds {:?} values, not 8- or 16-bit samples",
                    other.value_type()
                ),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_is_row_cross_column() {
        assert_eq!(
            slice_normal(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0]),
            [0.0, 0.0, 1.0]
        );
        // Sagittal: rows along y, columns along -z: normal along -x.
        assert_eq!(
            slice_normal(&[0.0, 1.0, 0.0, 0.0, 0.0, -1.0]),
            [-1.0, 0.0, 0.0]
        );
    }

    #[test]
    fn slices_sort_by_projection_not_input_order() {
        let n = slice_normal(&[0.0, 1.0, 0.0, 0.0, 0.0, -1.0]); // -x
        let positions = [
            [3.0, 5.0, 1.0],
            [-3.0, 0.0, 0.0],
            [0.0, 9.0, 9.0],
            [6.0, 0.0, 0.0],
        ];
        let order: Vec<usize> = order_along(&positions, n).iter().map(|o| o.0).collect();
        // Projections: -3, 3, 0, -6 → ascending: 3, 0, 2, 1.
        assert_eq!(order, [3, 0, 2, 1]);
    }

    #[test]
    fn oblique_normal_projection() {
        let c = std::f64::consts::FRAC_1_SQRT_2;
        let o = [1.0, 0.0, 0.0, 0.0, c, -c];
        let n = slice_normal(&o);
        let positions: Vec<[f64; 3]> = [2.0, 0.0, 1.0]
            .iter()
            .map(|&t| [5.0, t * n[1], t * n[2]])
            .collect();
        let sorted = order_along(&positions, n);
        assert_eq!(sorted.iter().map(|o| o.0).collect::<Vec<_>>(), [1, 2, 0]);
        assert!((sorted[2].1 - 2.0).abs() < 1e-12);
    }

    #[test]
    fn duplicates_keep_first_in_input_order() {
        let positions = [
            [0.0, 0.0, 3.0],
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 3.004],
            [0.0, 0.0, 6.0],
        ];
        let sorted = order_along(&positions, [0.0, 0.0, 1.0]);
        let (kept, dropped) = drop_duplicates(&sorted, SAME_POSITION_MM);
        assert_eq!(dropped, 1);
        assert_eq!(kept.iter().map(|k| k.0).collect::<Vec<_>>(), [1, 0, 3]);
    }

    #[test]
    fn spacing_is_mean_gap_and_detects_variation() {
        let s = SliceSpacing::of(&[0.0, 3.0, 6.0, 9.0]).unwrap();
        assert_eq!(s.mean, 3.0);
        assert!(!s.varies(SPACING_TOLERANCE));
        let s = SliceSpacing::of(&[0.0, 3.0, 6.01, 9.0]).unwrap();
        assert!(!s.varies(SPACING_TOLERANCE), "{s:?}");
        let s = SliceSpacing::of(&[0.0, 3.0, 9.0, 12.0]).unwrap();
        assert_eq!(s.mean, 4.0);
        assert_eq!((s.min, s.max), (3.0, 6.0));
        assert!(s.varies(SPACING_TOLERANCE));
        assert!(SliceSpacing::of(&[1.0]).is_none());
        assert!(SliceSpacing::of(&[]).is_none());
    }

    #[test]
    fn bits_stored_masks_or_sign_extends() {
        let mut f = PixelFormat {
            rows: 1,
            columns: 1,
            bits_allocated: 16,
            bits_stored: 12,
            signed: false,
        };
        assert_eq!(f.fix(0xf123), 0x0123);
        f.signed = true;
        assert_eq!(f.fix(0x0800) as i16, -2048);
        assert_eq!(f.fix(0xf7ff) as i16, 2047);
        f.bits_stored = 16;
        assert_eq!(f.fix(0xf123), 0xf123);
        let g = PixelFormat {
            bits_allocated: 8,
            bits_stored: 7,
            signed: true,
            ..f
        };
        assert_eq!(g.fix(0x40) as u8 as i8, -64);
    }

    #[test]
    fn transfer_syntaxes() {
        assert_eq!(native_endian_of("1.2.840.10008.1.2"), Some(Endian::Little));
        assert_eq!(native_endian_of("1.2.840.10008.1.2.2"), Some(Endian::Big));
        assert_eq!(native_endian_of("1.2.840.10008.1.2.4.70"), None);
        let e = unsupported_syntax("1.2.840.10008.1.2.4.70").to_string();
        assert!(e.contains("JPEG Lossless SV1"), "{e}");
    }

    #[test]
    fn dicom_magic() {
        let mut head = vec![0u8; 132];
        assert!(!looks_like(&head));
        head[128..132].copy_from_slice(b"DICM");
        assert!(looks_like(&head));
        assert!(looks_like(&[2, 0, 0, 0, b'U', b'L', 4, 0]));
    }

    // ------------------------------------------- synthetic series on disk

    use dicom_core::{DataElement, VR};
    use dicom_object::{FileMetaTableBuilder, InMemDicomObject};

    const EXPLICIT_LE: &str = "1.2.840.10008.1.2.1";
    const IMPLICIT_LE: &str = "1.2.840.10008.1.2";
    const EXPLICIT_BE: &str = "1.2.840.10008.1.2.2";

    /// A temporary directory, removed on drop.
    struct TempDir(PathBuf);

    impl TempDir {
        fn new() -> Self {
            use std::sync::atomic::{AtomicU32, Ordering};
            static N: AtomicU32 = AtomicU32::new(0);
            let p = std::env::temp_dir().join(format!(
                "raycaster-dicom-unit-{}-{}",
                std::process::id(),
                N.fetch_add(1, Ordering::Relaxed)
            ));
            std::fs::create_dir_all(&p).unwrap();
            TempDir(p)
        }
    }

    impl Drop for TempDir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    /// One synthetic slice: 4 columns x 3 rows.
    #[derive(Clone)]
    struct Synth {
        ts: &'static str,
        series: &'static str,
        instance: i32,
        /// Position along the normal of the oblique orientation below.
        along: f64,
        bits: u16,
        stored: u16,
        signed: bool,
        rescale: Option<(&'static str, &'static str)>,
        /// 16-bit data written as OB bytes in the transfer syntax's order.
        as_ob: bool,
        /// The words (8-bit data: low bytes), rows of 4.
        words: Vec<u16>,
    }

    /// Row direction, column direction; normal = row x col.
    const ORIENT: [f64; 6] = [0.6, 0.8, 0.0, 0.0, 0.0, -1.0];

    impl Synth {
        fn new(ts: &'static str, instance: i32, along: f64) -> Self {
            Synth {
                ts,
                series: "1.2.3.4",
                instance,
                along,
                bits: 16,
                stored: 16,
                signed: false,
                rescale: None,
                as_ob: false,
                words: (0..12).map(|i| (instance as u16) * 100 + i).collect(),
            }
        }

        fn write(&self, path: &Path) {
            let n = slice_normal(&ORIENT);
            let p: Vec<String> = (0..3)
                .map(|i| format!("{}", 10.0 + n[i] * self.along))
                .collect();
            let s = |t, vr, v: &str| DataElement::new(t, vr, PrimitiveValue::from(v));
            let us = |t, v: u16| DataElement::new(t, VR::US, PrimitiveValue::from(v));
            let sop = format!("{}.{}", self.series, self.instance);
            let mut elements = vec![
                s(tags::SOP_CLASS_UID, VR::UI, "1.2.840.10008.5.1.4.1.1.4"),
                s(tags::SOP_INSTANCE_UID, VR::UI, &sop),
                s(tags::SLICE_THICKNESS, VR::DS, "5"),
                s(tags::SERIES_INSTANCE_UID, VR::UI, self.series),
                s(tags::INSTANCE_NUMBER, VR::IS, &self.instance.to_string()),
                s(tags::IMAGE_POSITION_PATIENT, VR::DS, &p.join("\\")),
                s(
                    tags::IMAGE_ORIENTATION_PATIENT,
                    VR::DS,
                    "0.6\\0.8\\0\\0\\0\\-1",
                ),
                us(tags::SAMPLES_PER_PIXEL, 1),
                s(tags::PHOTOMETRIC_INTERPRETATION, VR::CS, "MONOCHROME2"),
                us(tags::ROWS, 3),
                us(tags::COLUMNS, 4),
                s(tags::PIXEL_SPACING, VR::DS, "0.5\\0.75"),
                us(tags::BITS_ALLOCATED, self.bits),
                us(tags::BITS_STORED, self.stored),
                us(tags::HIGH_BIT, self.stored - 1),
                us(tags::PIXEL_REPRESENTATION, self.signed as u16),
            ];
            if let Some((slope, intercept)) = self.rescale {
                elements.push(s(tags::RESCALE_INTERCEPT, VR::DS, intercept));
                elements.push(s(tags::RESCALE_SLOPE, VR::DS, slope));
            }
            let big = self.ts == EXPLICIT_BE;
            let pixels = if self.bits == 8 {
                let b: Vec<u8> = self.words.iter().map(|&w| w as u8).collect();
                DataElement::new(tags::PIXEL_DATA, VR::OB, PrimitiveValue::from(b))
            } else if self.as_ob {
                let b: Vec<u8> = self
                    .words
                    .iter()
                    .flat_map(|&w| {
                        if big {
                            w.to_be_bytes()
                        } else {
                            w.to_le_bytes()
                        }
                    })
                    .collect();
                DataElement::new(tags::PIXEL_DATA, VR::OB, PrimitiveValue::from(b))
            } else {
                DataElement::new(
                    tags::PIXEL_DATA,
                    VR::OW,
                    PrimitiveValue::U16(self.words.clone().into()),
                )
            };
            elements.push(pixels);
            InMemDicomObject::from_element_iter(elements)
                .with_meta(FileMetaTableBuilder::new().transfer_syntax(self.ts))
                .unwrap()
                .write_to_file(path)
                .unwrap();
        }
    }

    /// Writes `slices` as `s<index>.dcm` (names in the order given).
    fn write_all(dir: &TempDir, slices: &[Synth]) {
        for (i, s) in slices.iter().enumerate() {
            s.write(&dir.0.join(format!("s{i}.dcm")));
        }
    }

    fn samples_f32(v: &AnyVolume) -> Vec<f32> {
        let d = v.grid().dims;
        let mut out = Vec::new();
        for z in 0..d.z {
            for y in 0..d.y {
                for x in 0..d.x {
                    out.push(v.value(glam::UVec3::new(x, y, z)));
                }
            }
        }
        out
    }

    /// Files written in reverse position order under increasing names, with
    /// bits above Bits Stored set: every native transfer syntax (and OB
    /// instead of OW) reads the same, in position order, masked.
    #[test]
    fn native_transfer_syntaxes_read_alike() {
        let mut reference: Option<Vec<f32>> = None;
        for (ts, as_ob, name) in [
            (EXPLICIT_LE, false, "Explicit VR Little Endian"),
            (IMPLICIT_LE, false, "Implicit VR Little Endian"),
            (EXPLICIT_BE, false, "Explicit VR Big Endian"),
            (EXPLICIT_BE, true, "Explicit VR Big Endian"),
            (EXPLICIT_LE, true, "Explicit VR Little Endian"),
        ] {
            let dir = TempDir::new();
            let slices: Vec<Synth> = (0..5)
                .map(|k| {
                    let mut s = Synth::new(ts, k + 1, 2.5 * (4 - k) as f64 - 7.0);
                    s.stored = 12;
                    s.as_ob = as_ob;
                    s.words.iter_mut().for_each(|w| *w |= 0xa000);
                    s
                })
                .collect();
            write_all(&dir, &slices);
            let o = open(&dir.0).unwrap();
            assert_eq!(o.info.encoding, name);
            assert_eq!(o.info.dims, UVec3::new(4, 3, 5));
            assert!(
                (o.info.spacing - Vec3::new(0.75, 0.5, 2.5))
                    .abs()
                    .max_element()
                    < 1e-5
            );
            assert_eq!(o.info.stored_type, SampleType::U16);
            assert!(o.info.notes.is_empty(), "{:?}", o.info.notes);
            let v = samples_f32(&o.volume);
            // z = 0 is the lowest position: instance 5; x-fast rows of 4.
            for z in 0..5 {
                for i in 0..12 {
                    let want = ((5 - z) * 100 + i) as f32;
                    assert_eq!(v[z * 12 + i], want, "{ts} ob={as_ob} z={z} i={i}");
                }
            }
            match &reference {
                None => reference = Some(v),
                Some(r) => assert_eq!(r, &v),
            }
        }
    }

    #[test]
    fn eight_bit_signed_with_rescale_and_per_slice_rescale() {
        let dir = TempDir::new();
        let slices: Vec<Synth> = (0..3)
            .map(|k| {
                let mut s = Synth::new(EXPLICIT_LE, k + 1, 3.0 * k as f64);
                s.bits = 8;
                s.stored = 8;
                s.signed = true;
                s.words = (0..12).map(|i| (i as i8 - 6) as u8 as u16).collect();
                s.rescale = Some(("2", "-100"));
                s
            })
            .collect();
        write_all(&dir, &slices);
        let o = open(&dir.0).unwrap();
        assert_eq!(o.info.stored_type, SampleType::I8);
        assert_eq!(o.info.rescale, Rescale::non_identity(2.0, -100.0));
        assert_eq!(o.volume.sample_type(), SampleType::I16);
        let v = samples_f32(&o.volume);
        assert_eq!(v[0], -112.0);
        assert_eq!(v[11], -90.0);

        // Slopes that differ per slice: values in f32, per slice.
        let dir = TempDir::new();
        let mut slices = slices;
        slices[1].rescale = Some(("0.5", "1"));
        write_all(&dir, &slices);
        let o = open(&dir.0).unwrap();
        assert_eq!(o.info.rescale, None);
        assert_eq!(o.volume.sample_type(), SampleType::F32);
        assert!(o.info.notes.iter().any(|n| n.contains("per slice")));
        let v = samples_f32(&o.volume);
        assert_eq!((v[0], v[12], v[24]), (-112.0, -2.0, -112.0));
    }

    #[test]
    fn series_choice_duplicates_gaps_and_single_slices() {
        let dir = TempDir::new();
        let mut slices: Vec<Synth> = (0..6)
            .map(|k| Synth::new(EXPLICIT_LE, k + 1, 2.0 * k as f64))
            .collect();
        // Another series of 2 slices, a duplicate position (a later
        // instance), and a gap: positions 0 2 4 6 8 10, drop 8.
        for k in 0..2 {
            let mut s = Synth::new(EXPLICIT_LE, k + 1, 5.0 * k as f64);
            s.series = "1.2.3.5";
            slices.push(s);
        }
        let mut dup = Synth::new(EXPLICIT_LE, 9, 4.0);
        dup.words = vec![7; 12];
        slices.push(dup);
        slices.remove(4);
        write_all(&dir, &slices);

        let o = open(&dir.0).unwrap();
        let notes = o.info.notes.join("; ");
        assert_eq!(o.info.dims.z, 5, "{notes}");
        assert!(
            notes.contains("directory holds 2 series; opened 1.2.3.4 (6 slices), the largest"),
            "{notes}"
        );
        assert!(notes.contains("1 of 6 slices share a position"), "{notes}");
        assert!(
            notes.contains("varies from 2 to 4 mm; using the mean 2.5 mm"),
            "{notes}"
        );
        assert!((o.info.spacing.z - 2.5).abs() < 1e-6);
        // The duplicate (instance 9) lost to instance 3 at position 4.
        let v = samples_f32(&o.volume);
        assert_eq!(v[2 * 12], 300.0);

        // A file of the small series opens that series.
        let small = dir.0.join(format!("s{}.dcm", 5));
        let o = open(&small).unwrap();
        assert_eq!(o.info.dims.z, 2);
        assert!((o.info.spacing.z - 5.0).abs() < 1e-6);
        assert!(
            o.info.notes[0].contains("opened 1.2.3.5 (2 slices), the one holding the file given")
        );

        // One slice: spacing from Slice Thickness.
        let one = TempDir::new();
        write_all(&one, &[Synth::new(IMPLICIT_LE, 1, 0.0)]);
        let o = open(&one.0).unwrap();
        assert_eq!(o.info.dims, UVec3::new(4, 3, 1));
        assert_eq!(o.info.spacing.z, 5.0);
        assert!(
            o.info
                .orientation
                .as_deref()
                .unwrap()
                .starts_with("row (0.6,0.8,0) col (0,0,-1)")
        );
    }
}
