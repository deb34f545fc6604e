//! NIfTI-1 (`.nii`, `.nii.gz`, and `.hdr` + `.img` pairs): a 348-byte
//! binary header in either byte order, then the samples x fastest.
//!
//! Supported datatypes: `UINT8` (2), `INT16` (4), `FLOAT32` (16), `INT8`
//! (256), `UINT16` (512). Spacing is `pixdim[1..=3]` (absolute values;
//! zero or non-finite ones become 1 with a note). A non-identity
//! `scl_slope`/`scl_inter` is applied, so the volume holds data units
//! (`stored·slope + intercept`). Files with more than three dimensions open
//! their first volume and say so. The q/sform is reported, not applied.
//! Uncompressed files in native byte order without scaling are
//! memory-mapped; gzip-compressed ones (`.nii.gz`, `.img.gz`) are decoded
//! once, which needs the `gzip` feature.

use std::io::Read;
use std::path::{Path, PathBuf};

use glam::{UVec3, Vec3};

use super::gzip::{self, Gzip};
use super::samples::{self, Endian, Rescale, SampleLayout};
use super::{FileFormat, Opened, VolumeInfo};
use crate::error::{Error, FormatError, Result};
use crate::sample::SampleType;
use crate::volume::AxisOrder;

/// Header length in bytes.
pub const HEADER_LEN: usize = 348;

/// True when `head` starts a NIfTI-1 header (uncompressed) in either byte
/// order.
pub fn looks_like(head: &[u8]) -> bool {
    NiftiHeader::parse(head).is_ok()
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
        const READ: [SampleType; 5] = [
            SampleType::U8,
            SampleType::I8,
            SampleType::U16,
            SampleType::I16,
            SampleType::F32,
        ];
        if let Some(t) = READ
            .into_iter()
            .find(|&t| datatype_of(t).0 == self.datatype)
        {
            return Ok(t);
        }
        let name = match self.datatype {
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
        Err(format!(
            "datatype {} ({name}); supported: UINT8, INT8, UINT16, INT16, FLOAT32",
            self.datatype
        ))
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
            let [b, c, d, x, y, z] = self.quatern.map(number);
            parts.push(format!(
                "qform_code {q}: quaternion ({b}, {c}, {d}), offset ({x}, {y}, {z}), qfac {}",
                number(self.pixdim[0])
            ));
        }
        if s > 0 {
            let r = |i: usize| {
                let v = self.srow[i].map(number);
                format!("({}, {}, {}, {})", v[0], v[1], v[2], v[3])
            };
            parts.push(format!("sform_code {s}: srow {} {} {}", r(0), r(1), r(2)));
        }
        (!parts.is_empty()).then(|| parts.join("; "))
    }
}

/// A header number as written, except that a tiny one (float noise such
/// as `-1.9e-26` in a quaternion) shows in scientific notation rather
/// than as 30 decimals.
fn number(v: f32) -> String {
    if v != 0.0 && v.abs() < 1e-4 {
        format!("{v:e}")
    } else {
        v.to_string()
    }
}

/// The NIfTI-1 datatype code of `t` and its bits per voxel.
fn datatype_of(t: SampleType) -> (i16, i16) {
    match t {
        SampleType::U8 => (2, 8),
        SampleType::I16 => (4, 16),
        SampleType::F32 => (16, 32),
        SampleType::I8 => (256, 8),
        SampleType::U16 => (512, 16),
    }
}

fn invalid(path: &Path, msg: impl Into<String>) -> Error {
    Error::format(path, FormatError::Invalid(msg.into()))
}

/// `file.nii.gz` → true.
fn is_gzip_name(path: &Path) -> bool {
    path.to_string_lossy().to_ascii_lowercase().ends_with(".gz")
}

/// Whether `path` is gzip-compressed, by its name or its first bytes.
fn is_compressed(path: &Path) -> Result<bool> {
    Ok(is_gzip_name(path) || gzip::is_gzip(&super::read_head(path, 2)?))
}

/// The reader of NIfTI-1 files. The magic number claims a file; so do the
/// names `.nii.gz` (its header is compressed, so there are no bytes to look
/// at before decoding) and `.hdr` (an Analyze-style header may lack the
/// magic), as firmly as content; a plain `.nii` name claims it weakly.
#[derive(Debug, Clone, Copy)]
pub struct NiftiReader;

impl super::Reader for NiftiReader {
    fn sniff(&self, probe: &super::Probe) -> Option<super::Claim> {
        if probe.is_dir {
            None
        } else if looks_like(probe.head)
            || probe.name.ends_with(".nii.gz")
            || probe.name.ends_with(".hdr")
        {
            Some(super::Claim::Content)
        } else {
            (probe.extension() == "nii").then_some(super::Claim::Name)
        }
    }

    fn open(&self, path: &Path, options: &super::OpenOptions) -> Result<Opened> {
        open(path, options)
    }
}

fn open(path: &Path, options: &super::OpenOptions) -> Result<Opened> {
    let (mode, progress, max_memory) =
        (options.mode, options.progress.as_ref(), options.max_memory);
    let file_bytes = super::file_len(path)?;
    let gz = is_compressed(path)?;
    // The header: from the file, or from the start of the gzip stream.
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut stream: Box<dyn Read> = if gz {
        Gzip::get(path)?.decoder(super::ProgressReader::new(file, file_bytes, progress))
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
    let Described {
        layout,
        volumes,
        mut notes,
    } = describe(path, &h)?;
    let index = super::check_volume_index(path, options.volume, volumes)?;
    if volumes > 1 {
        // First, as before the spacing notes.
        notes.insert(
            0,
            format!(
                "{}-D file with {volumes} volumes: opened volume {index}",
                h.dim[0]
            ),
        );
    }
    let rescale = h.rescale();
    // The volumes follow each other (dimensions 4..7 are the slowest).
    let skip = index.saturating_mul(layout.byte_len(path)?);

    let (volume, data_bytes, data_gz) = if h.single_file {
        if !(h.vox_offset.is_finite() && h.vox_offset >= HEADER_LEN as f32) {
            return Err(invalid(
                path,
                format!("vox_offset {} (must be at least 348)", h.vox_offset),
            ));
        }
        let offset = (h.vox_offset as u64).saturating_add(skip);
        let volume = if gz {
            // The stream is past the header already.
            let data = samples::Stream {
                offset,
                skip: offset.saturating_sub(HEADER_LEN as u64),
                max_memory,
                ..samples::Stream::gzip(file_bytes)
            };
            samples::from_reader(path, stream, &layout, rescale, data)?
        } else {
            samples::from_file(path, offset, &layout, rescale, mode, false, max_memory)?
        };
        (volume, 0, gz)
    } else {
        // The image file is compressed or not whatever the header file is.
        let data_path = image_file_for(path)?;
        let offset = (h.vox_offset.max(0.0) as u64).saturating_add(skip);
        let data_bytes = super::file_len(&data_path)?;
        let data_gz = is_compressed(&data_path)?;
        let volume = if data_gz {
            let gzip = Gzip::get(&data_path)?;
            let f = std::fs::File::open(&data_path).map_err(|e| Error::io(&data_path, e))?;
            let input = gzip.decoder(super::ProgressReader::new(f, data_bytes, progress));
            let data = samples::Stream {
                offset,
                skip: offset,
                max_memory,
                ..samples::Stream::gzip(data_bytes)
            };
            samples::from_reader(&data_path, input, &layout, rescale, data)?
        } else {
            samples::from_file(
                &data_path, offset, &layout, rescale, mode, false, max_memory,
            )?
        };
        (volume, data_bytes, data_gz)
    };
    let mut info = VolumeInfo::new(
        FileFormat::Nifti,
        &layout,
        if data_gz { "gzip" } else { "raw" },
        file_bytes + data_bytes,
    );
    info.rescale = rescale;
    info.orientation = h.orientation();
    info.notes = notes;
    info.volumes = volumes;
    Ok(Opened { volume, info })
}

/// What a parsed header says about the samples.
struct Described {
    /// Dimensions, spacing, type, byte order (x fastest).
    layout: SampleLayout,
    /// Volumes along dimensions 4..7 (1 for a 3-D file).
    volumes: u64,
    /// What was assumed (invalid spacing).
    notes: Vec<String>,
}

/// The sample layout of the header `h` of `path`, validated.
fn describe(path: &Path, h: &NiftiHeader) -> Result<Described> {
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
    let volumes = volumes as u64;
    let mut notes = Vec::new();
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
    Ok(Described {
        layout,
        volumes,
        notes,
    })
}

/// Where the samples of an uncompressed NIfTI file are.
#[derive(Debug, Clone, PartialEq)]
pub struct SampleLocation {
    /// The file holding them (the `.nii`, or the `.img` of a `.hdr`).
    pub data: PathBuf,
    /// Byte offset of the first volume's first sample.
    pub offset: u64,
    /// Dimensions, spacing, type, byte order (x fastest).
    pub layout: SampleLayout,
    /// `stored·slope + intercept`, when not the identity.
    pub rescale: Option<Rescale>,
}

/// Where the samples of the first volume of an uncompressed single-file
/// NIfTI (`.nii`) or `.hdr`/`.img` pair are, for readers of parts of it
/// ([`crate::distributed`]). `Ok(None)` when the data is gzip-compressed.
pub fn locate_samples(path: &Path) -> Result<Option<SampleLocation>> {
    if is_compressed(path)? {
        return Ok(None);
    }
    let head = super::read_head(path, HEADER_LEN)?;
    let h = NiftiHeader::parse(&head).map_err(|m| invalid(path, m))?;
    let described = describe(path, &h)?;
    if h.single_file {
        if !(h.vox_offset.is_finite() && h.vox_offset >= HEADER_LEN as f32) {
            return Err(invalid(
                path,
                format!("vox_offset {} (must be at least 348)", h.vox_offset),
            ));
        }
        Ok(Some(SampleLocation {
            data: path.to_path_buf(),
            offset: h.vox_offset as u64,
            layout: described.layout,
            rescale: h.rescale(),
        }))
    } else {
        let data = image_file_for(path)?;
        if is_compressed(&data)? {
            return Ok(None);
        }
        Ok(Some(SampleLocation {
            data,
            offset: h.vox_offset.max(0.0) as u64,
            layout: described.layout,
            rescale: h.rescale(),
        }))
    }
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

/// Writes a single-file NIfTI-1 (`.nii`, or gzip-compressed when `path`
/// ends in `.gz`) with the given rescale, its samples (x fastest,
/// little-endian, of type `sample`) written by `samples` into the file or
/// the gzip stream ([`samples::bytes`] for samples already in memory): the
/// project's own writer, for converters and round-trip tests.
pub fn write(
    path: &Path,
    dims: UVec3,
    spacing: Vec3,
    sample: SampleType,
    rescale: Option<Rescale>,
    samples: impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
) -> Result<()> {
    if dims.max_element() > i16::MAX as u32 {
        return Err(Error::format(
            path,
            FormatError::Unsupported(format!(
                "dimensions {}x{}x{}: NIfTI-1 dimensions are at most 32767",
                dims.x, dims.y, dims.z
            )),
        ));
    }
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
    let (code, bits) = datatype_of(sample);
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
    // A .nii.gz is the gzip stream of the whole .nii, header included.
    let gzip = is_gzip_name(path).then(|| Gzip::get(path)).transpose()?;
    super::atomic::write_atomically(path, |w| {
        let whole = |w: &mut dyn std::io::Write| {
            w.write_all(&h)?;
            samples(w)
        };
        match gzip {
            Some(gzip) => gzip.encode(w, whole),
            None => whole(w),
        }
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn tiny_header_numbers_show_in_scientific_notation() {
        assert_eq!(super::number(-1.9451068e-26), "-1.9451068e-26");
        assert_eq!(super::number(0.0), "0");
        assert_eq!(super::number(-90.5), "-90.5");
        assert_eq!(super::number(1.0), "1");
    }
}
