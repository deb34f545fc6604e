//! NIfTI-1 (`.nii`, `.nii.gz`, and `.hdr` + `.img` pairs): a 348-byte
//! binary header in either byte order, then the samples x fastest.
//!
//! Supported datatypes: `UINT8` (2), `INT16` (4), `FLOAT32` (16), `INT8`
//! (256), `UINT16` (512). Spacing is `pixdim[1..=3]` (absolute values;
//! zero or non-finite ones become 1 with a note). A non-identity
//! `scl_slope`/`scl_inter` is applied (SPEC §7). Files with more than three
//! dimensions open their first volume and say so. The q/sform is reported,
//! not applied. Uncompressed single files in native byte order without
//! scaling are memory-mapped; `.nii.gz` is decoded once.

use std::io::Read;
use std::path::{Path, PathBuf};

use glam::{UVec3, Vec3};

use super::samples::{self, Endian, Rescale, SampleLayout};
use super::{FileFormat, Opened, VolumeInfo};
use crate::error::{Error, FormatError, Result};
use crate::sample::SampleType;
use crate::storage::LoadMode;
use crate::volume::AxisOrder;

/// Header length in bytes.
pub const HEADER_LEN: usize = 348;

/// True when `head` starts a NIfTI-1 header (uncompressed) in either byte
/// order.
pub fn looks_like(head: &[u8]) -> bool {
    head.len() >= HEADER_LEN
        && (head[..4] == 348i32.to_le_bytes() || head[..4] == 348i32.to_be_bytes())
        && matches!(&head[344..348], b"n+1\0" | b"ni1\0")
}

/// The fields of a NIfTI-1 header that matter here.
#[derive(Debug, Clone, PartialEq)]
pub struct NiftiHeader {
    /// Byte order of the header and the data.
    pub endian: Endian,
    /// `dim[0..8]`.
    pub dim: [i16; 8],
    /// NIfTI datatype code.
    pub datatype: i16,
    /// `pixdim[0..8]`.
    pub pixdim: [f32; 8],
    /// Byte offset of the data (in the `.nii`; 0 for a `.img`).
    pub vox_offset: f32,
    /// `scl_slope`.
    pub scl_slope: f32,
    /// `scl_inter`.
    pub scl_inter: f32,
    /// `qform_code`, `sform_code`.
    pub xform_codes: (i16, i16),
    /// Quaternion b, c, d and offsets x, y, z.
    pub quatern: [f32; 6],
    /// `srow_x`, `srow_y`, `srow_z`.
    pub srow: [[f32; 4]; 3],
    /// `true` for a single file (`n+1`), `false` for a `.hdr`/`.img` pair.
    pub single_file: bool,
}

impl NiftiHeader {
    /// Parses 348 header bytes; `Err` says what is wrong.
    pub fn parse(b: &[u8]) -> std::result::Result<Self, String> {
        if b.len() < HEADER_LEN {
            return Err(format!(
                "file is {} bytes, shorter than the 348-byte NIfTI-1 header",
                b.len()
            ));
        }
        let endian = if b[..4] == 348i32.to_le_bytes() {
            Endian::Little
        } else if b[..4] == 348i32.to_be_bytes() {
            Endian::Big
        } else {
            return Err(
                "sizeof_hdr is not 348 (not a NIfTI-1 file; NIfTI-2 is not supported)".into(),
            );
        };
        let single_file = match &b[344..348] {
            b"n+1\0" => true,
            b"ni1\0" => false,
            _ => return Err("magic is neither \"n+1\" nor \"ni1\"".into()),
        };
        let i16_at = |o: usize| {
            let a = [b[o], b[o + 1]];
            match endian {
                Endian::Little => i16::from_le_bytes(a),
                Endian::Big => i16::from_be_bytes(a),
            }
        };
        let f32_at = |o: usize| {
            let a = [b[o], b[o + 1], b[o + 2], b[o + 3]];
            match endian {
                Endian::Little => f32::from_le_bytes(a),
                Endian::Big => f32::from_be_bytes(a),
            }
        };
        Ok(NiftiHeader {
            endian,
            dim: std::array::from_fn(|i| i16_at(40 + 2 * i)),
            datatype: i16_at(70),
            pixdim: std::array::from_fn(|i| f32_at(76 + 4 * i)),
            vox_offset: f32_at(108),
            scl_slope: f32_at(112),
            scl_inter: f32_at(116),
            xform_codes: (i16_at(252), i16_at(254)),
            quatern: std::array::from_fn(|i| f32_at(256 + 4 * i)),
            srow: std::array::from_fn(|r| std::array::from_fn(|c| f32_at(280 + 16 * r + 4 * c))),
            single_file,
        })
    }

    fn sample_type(&self) -> std::result::Result<SampleType, String> {
        Ok(match self.datatype {
            2 => SampleType::U8,
            4 => SampleType::I16,
            16 => SampleType::F32,
            256 => SampleType::I8,
            512 => SampleType::U16,
            other => {
                let name = match other {
                    1 => "BINARY",
                    8 => "INT32",
                    32 => "COMPLEX64",
                    64 => "FLOAT64",
                    128 => "RGB24",
                    768 => "UINT32",
                    1024 => "INT64",
                    1280 => "UINT64",
                    2304 => "RGBA32",
                    _ => "unknown",
                };
                return Err(format!(
                    "datatype {other} ({name}); supported: UINT8, INT8, UINT16, INT16, FLOAT32"
                ));
            }
        })
    }

    /// The rescale, when `scl_slope` is set (non-zero, finite) and not the
    /// identity.
    pub fn rescale(&self) -> Option<Rescale> {
        let (m, c) = (self.scl_slope, self.scl_inter);
        if m == 0.0 || !m.is_finite() {
            return None;
        }
        Rescale::non_identity(m as f64, if c.is_finite() { c as f64 } else { 0.0 })
    }

    fn orientation(&self) -> Option<String> {
        let (q, s) = self.xform_codes;
        let mut parts = Vec::new();
        if q > 0 {
            let [b, c, d, x, y, z] = self.quatern;
            parts.push(format!(
                "qform_code {q}: quaternion ({b}, {c}, {d}), offset ({x}, {y}, {z}), qfac {}",
                self.pixdim[0]
            ));
        }
        if s > 0 {
            let r = |i: usize| {
                let v = self.srow[i];
                format!("({}, {}, {}, {})", v[0], v[1], v[2], v[3])
            };
            parts.push(format!("sform_code {s}: srow {} {} {}", r(0), r(1), r(2)));
        }
        (!parts.is_empty()).then(|| parts.join("; "))
    }
}

fn invalid(path: &Path, msg: impl Into<String>) -> Error {
    Error::format(path, FormatError::Invalid(msg.into()))
}

/// `file.nii.gz` → true.
fn is_gzip_name(path: &Path) -> bool {
    path.to_string_lossy().to_ascii_lowercase().ends_with(".gz")
}

/// Opens a NIfTI-1 file.
pub fn open(path: &Path, mode: LoadMode) -> Result<Opened> {
    open_with(path, mode, None)
}

/// As [`open`], reporting the progress of a gzip decode.
pub fn open_with(
    path: &Path,
    mode: LoadMode,
    progress: Option<&super::Progress>,
) -> Result<Opened> {
    let file_bytes = super::file_len(path)?;
    let gz = is_gzip_name(path) || super::read_head(path, 2)? == [0x1f, 0x8b];
    // The header: from the file, or from the start of the gzip stream.
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut stream: Box<dyn Read> = if gz {
        Box::new(flate2::read::MultiGzDecoder::new(std::io::BufReader::new(
            super::ProgressReader::new(file, file_bytes, progress),
        )))
    } else {
        Box::new(file)
    };
    let mut head = Vec::with_capacity(HEADER_LEN);
    stream
        .by_ref()
        .take(HEADER_LEN as u64)
        .read_to_end(&mut head)
        .map_err(|e| invalid(path, format!("cannot read the header ({e})")))?;
    let h = NiftiHeader::parse(&head).map_err(|m| invalid(path, m))?;
    let ty = h
        .sample_type()
        .map_err(|m| Error::format(path, FormatError::Unsupported(m)))?;

    let ndim = h.dim[0];
    if !(1..=7).contains(&ndim) {
        return Err(invalid(path, format!("dim[0] is {ndim} (must be 1..=7)")));
    }
    let dim_of = |i: usize| if i <= ndim as usize { h.dim[i] } else { 1 };
    let dims: Vec<i64> = (1..=3).map(|i| dim_of(i) as i64).collect();
    if dims.iter().any(|&d| d < 1) {
        return Err(invalid(
            path,
            format!(
                "dimensions {}x{}x{} (each must be at least 1)",
                dims[0], dims[1], dims[2]
            ),
        ));
    }
    let volumes: i64 = (4..=7).map(|i| (dim_of(i) as i64).max(1)).product();
    let mut notes = Vec::new();
    if volumes > 1 {
        notes.push(format!(
            "{ndim}-D file with {volumes} volumes: opened the first"
        ));
    }
    let spacing = Vec3::from_array(std::array::from_fn(|i| {
        let p = h.pixdim[i + 1].abs();
        if p.is_finite() && p > 0.0 { p } else { 0.0 }
    }));
    let spacing = if spacing.min_element() > 0.0 {
        spacing
    } else {
        notes.push(format!(
            "pixdim {:?} has zero or invalid spacing; using 1 there",
            &h.pixdim[1..4]
        ));
        Vec3::select(spacing.cmpgt(Vec3::ZERO), spacing, Vec3::ONE)
    };
    let layout = SampleLayout {
        dims: UVec3::new(dims[0] as u32, dims[1] as u32, dims[2] as u32),
        spacing,
        sample: ty,
        endian: h.endian,
        order: AxisOrder::XFast,
    };
    layout.validate(path)?;
    let rescale = h.rescale();

    let (data_path, offset) = if h.single_file {
        if !(h.vox_offset.is_finite() && h.vox_offset >= HEADER_LEN as f32) {
            return Err(invalid(
                path,
                format!("vox_offset {} (must be at least 348)", h.vox_offset),
            ));
        }
        (path.to_path_buf(), h.vox_offset as u64)
    } else {
        (image_file_for(path)?, h.vox_offset.max(0.0) as u64)
    };
    let volume = if gz {
        // Skip to vox_offset (the single file's stream is past the header
        // already), then decode exactly the first volume.
        let (mut s, skip): (Box<dyn Read>, u64) = if h.single_file {
            (stream, offset.saturating_sub(HEADER_LEN as u64))
        } else {
            let f = std::fs::File::open(&data_path).map_err(|e| Error::io(&data_path, e))?;
            let gz = flate2::read::MultiGzDecoder::new(std::io::BufReader::new(f));
            (Box::new(gz), offset)
        };
        std::io::copy(&mut s.by_ref().take(skip), &mut std::io::sink())
            .map_err(|e| invalid(path, format!("gzip data is corrupt or truncated ({e})")))?;
        let stream = samples::Stream {
            offset,
            max_bytes: Some(super::max_inflated(file_bytes)),
            compression: Some("gzip"),
        };
        samples::from_reader(path, s, &layout, rescale, stream)?
    } else {
        samples::from_file(&data_path, offset, &layout, rescale, mode, false)?
    };
    let mut info = VolumeInfo::new(
        FileFormat::Nifti,
        &layout,
        if gz { "gzip" } else { "raw" },
        file_bytes
            + if h.single_file {
                0
            } else {
                super::file_len(&data_path)?
            },
    );
    info.rescale = rescale;
    info.orientation = h.orientation();
    info.notes = notes;
    Ok(Opened { volume, info })
}

/// The `.img` file of a `.hdr` (same stem, also `.img.gz`).
fn image_file_for(path: &Path) -> Result<PathBuf> {
    let s = path.to_string_lossy();
    let lower = s.to_ascii_lowercase();
    let stem = lower
        .strip_suffix(".hdr.gz")
        .or_else(|| lower.strip_suffix(".hdr"))
        .map(|st| &s[..st.len()])
        .ok_or_else(|| invalid(path, "a two-file NIfTI (\"ni1\") header must be named .hdr"))?;
    [".img", ".img.gz", ".IMG"]
        .iter()
        .map(|e| PathBuf::from(format!("{stem}{e}")))
        .find(|p| p.exists())
        .ok_or_else(|| invalid(path, format!("the image file {stem}.img is missing")))
}

/// Writes `le_bytes` (x fastest, little-endian samples of `sample`) as a
/// single-file NIfTI-1 (`.nii`, or gzip-compressed when `path` ends in
/// `.gz`) with the given rescale: the project's own writer, for converters
/// and round-trip tests.
pub fn write(
    path: &Path,
    dims: UVec3,
    spacing: Vec3,
    sample: SampleType,
    le_bytes: &[u8],
    rescale: Option<Rescale>,
) -> Result<()> {
    write_with(path, dims, spacing, sample, rescale, |w| {
        w.write_all(le_bytes)
    })
}

/// As [`write`], with the samples (x fastest, little-endian) written by
/// `samples` into the file or the gzip stream: a volume can be streamed
/// without a copy of its bytes in memory.
pub fn write_with(
    path: &Path,
    dims: UVec3,
    spacing: Vec3,
    sample: SampleType,
    rescale: Option<Rescale>,
    samples: impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
) -> Result<()> {
    use std::io::Write;
    let mut h = vec![0u8; HEADER_LEN + 4];
    let put_i16 = |h: &mut [u8], o: usize, v: i16| h[o..o + 2].copy_from_slice(&v.to_le_bytes());
    let put_f32 = |h: &mut [u8], o: usize, v: f32| h[o..o + 4].copy_from_slice(&v.to_le_bytes());
    h[..4].copy_from_slice(&348i32.to_le_bytes());
    for (i, d) in [3, dims.x as i16, dims.y as i16, dims.z as i16, 1, 1, 1, 1]
        .into_iter()
        .enumerate()
    {
        put_i16(&mut h, 40 + 2 * i, d);
    }
    let (code, bits) = match sample {
        SampleType::U8 => (2, 8),
        SampleType::I16 => (4, 16),
        SampleType::F32 => (16, 32),
        SampleType::I8 => (256, 8),
        SampleType::U16 => (512, 16),
    };
    put_i16(&mut h, 70, code);
    put_i16(&mut h, 72, bits);
    for (i, p) in [1.0, spacing.x, spacing.y, spacing.z, 1.0, 1.0, 1.0, 1.0]
        .into_iter()
        .enumerate()
    {
        put_f32(&mut h, 76 + 4 * i, p);
    }
    put_f32(&mut h, 108, (HEADER_LEN + 4) as f32);
    let r = rescale.unwrap_or(Rescale {
        slope: 1.0,
        intercept: 0.0,
    });
    put_f32(&mut h, 112, r.slope as f32);
    put_f32(&mut h, 116, r.intercept as f32);
    h[344..348].copy_from_slice(b"n+1\0");
    let gz = is_gzip_name(path);
    super::vol::write_atomically(path, |w| {
        if gz {
            let mut e = flate2::write::GzEncoder::new(w, flate2::Compression::fast());
            e.write_all(&h)?;
            samples(&mut e)?;
            e.finish().map(|_| ())
        } else {
            w.write_all(&h)?;
            samples(w)
        }
    })
}
