//! A DICOM series from its files: listing the directory, reading every
//! header, grouping the files into series and choosing one, then ordering
//! and measuring its slices and describing the result.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{UVec3, Vec3};
use rayon::prelude::*;

use super::geometry::{
    SAME_POSITION_MM, SPACING_TOLERANCE, SliceSpacing, drop_duplicates, order_along, round_noise,
    same_orientation, slice_normal,
};
use super::header::{Header, invalid, read_header, transfer_syntax_name};
use super::pixels::{ReadVolume, Slice, pixel_format, slice_endian};
use crate::error::{Error, FormatError, Result};
use crate::format::samples::{Rescale, SampleLayout};
use crate::format::{FileFormat, Opened, Progress, VolumeInfo};
use crate::volume::{AxisOrder, Grid};

/// Opens the DICOM series in directory `path`, or the series the file
/// `path` belongs to, reporting the fraction of slices read.
pub(super) fn open(
    path: &Path,
    progress: Option<&Progress>,
    max_memory: Option<u64>,
) -> Result<Opened> {
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
                format!(
                    "a folder with no volume file and no DICOM series in it ({checked} {}); \
                     give a volume file, a folder of frames or a DICOM series",
                    if checked == 1 { "file" } else { "files" }
                ),
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
    build(series, notes, progress, max_memory)
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
    let head = crate::format::read_head(path, 132)?;
    Ok(super::looks_like(&head))
}

fn same_file(a: &Path, b: &Path) -> bool {
    a == b
        || match (a.canonicalize(), b.canonicalize()) {
            (Ok(a), Ok(b)) => a == b,
            _ => false,
        }
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
    progress: Option<&Progress>,
    max_memory: Option<u64>,
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
                    "slice format differs from {}: {}x{} {} vs {}x{} {}",
                    file_name(&first.path),
                    f.columns,
                    f.rows,
                    f.describe(),
                    format.columns,
                    format.rows,
                    format.describe(),
                ),
            ));
        }
    }
    let file_bytes: u64 = series.iter().map(|h| h.file_bytes).sum();

    // Order along the normal; spacing between slices.
    let orientation = first.orientation;
    let positioned: Option<Vec<[f64; 3]>> = series.iter().map(|h| h.position).collect();
    let normal = orientation.and_then(|o| slice_normal(&o));
    let (ordered, z_spacing): (Vec<&Header>, f64) = match (normal, positioned) {
        (Some(normal), Some(positions)) => {
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
                    round_noise(s.mean)
                }
                None => single_slice_spacing(first, &mut notes),
            };
            (kept.iter().map(|&(i, _)| series[i]).collect(), z)
        }
        _ => {
            notes.push(
                "slices lack a usable Image Position/Orientation (Patient): ordered by Instance Number, slice spacing from Slice Thickness"
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
        .map(|h| {
            Ok(Slice {
                header: h,
                endian: slice_endian(h)?,
                rescale: rescale_of(h),
            })
        })
        .collect::<Result<_>>()?;
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
    super::super::samples::check_memory(&first.path, layout.byte_len(&first.path)?, max_memory)?;
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
