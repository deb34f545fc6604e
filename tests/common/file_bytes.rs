//! File bytes made by hand, independently of the library's readers: `.vol`
//! headers, NIfTI-1 headers, NRRD headers, and gzip streams (made
//! with the project's NRRD writer: the suite has no gzip dependency).

use glam::{UVec3, Vec3};
use raycaster::format::Endian;
use raycaster::format::nrrd::{self, Encoding};
use raycaster::format::samples;
use raycaster::prelude::*;

use super::TempDir;

/// A 26-byte `.vol` header: dimensions and spacing, little-endian,
/// then the layout byte and the extra byte (the brick side).
pub fn vol_header(dims: [u32; 3], spacing: [f32; 3], layout: u8, extra: u8) -> Vec<u8> {
    let mut b = Vec::new();
    for d in dims {
        b.extend_from_slice(&d.to_le_bytes());
    }
    for s in spacing {
        b.extend_from_slice(&s.to_le_bytes());
    }
    b.push(layout);
    b.push(extra);
    b
}

/// The datatype code NIfTI-1 uses for `t`, and its bits per voxel.
pub fn nifti_code(t: SampleType) -> (i16, i16) {
    match t {
        SampleType::U8 => (2, 8),
        SampleType::I16 => (4, 16),
        SampleType::F32 => (16, 32),
        SampleType::I8 => (256, 8),
        SampleType::U16 => (512, 16),
    }
}

/// The fields of a hand-made NIfTI-1 header.
#[derive(Clone)]
pub struct NiiHeader {
    pub endian: Endian,
    pub sizeof_hdr: i32,
    pub dim: [i16; 8],
    pub datatype: i16,
    pub bitpix: i16,
    pub pixdim: [f32; 8],
    pub vox_offset: f32,
    pub slope: f32,
    pub inter: f32,
    pub magic: [u8; 4],
}

impl NiiHeader {
    pub fn new(dims: UVec3, spacing: Vec3, t: SampleType, endian: Endian) -> Self {
        let (datatype, bitpix) = nifti_code(t);
        NiiHeader {
            endian,
            sizeof_hdr: 348,
            dim: [3, dims.x as i16, dims.y as i16, dims.z as i16, 1, 1, 1, 1],
            datatype,
            bitpix,
            pixdim: [1.0, spacing.x, spacing.y, spacing.z, 1.0, 1.0, 1.0, 1.0],
            vox_offset: 352.0,
            slope: 0.0,
            inter: 0.0,
            magic: *b"n+1\0",
        }
    }

    /// The 348 header bytes plus 4 zero extension bytes.
    pub fn bytes(&self) -> Vec<u8> {
        let mut h = vec![0u8; 352];
        let big = self.endian == Endian::Big;
        let i16b = |v: i16| {
            if big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            }
        };
        let f32b = |v: f32| {
            if big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            }
        };
        let i32b = if big {
            self.sizeof_hdr.to_be_bytes()
        } else {
            self.sizeof_hdr.to_le_bytes()
        };
        h[0..4].copy_from_slice(&i32b);
        for (i, &d) in self.dim.iter().enumerate() {
            h[40 + 2 * i..42 + 2 * i].copy_from_slice(&i16b(d));
        }
        h[70..72].copy_from_slice(&i16b(self.datatype));
        h[72..74].copy_from_slice(&i16b(self.bitpix));
        for (i, &p) in self.pixdim.iter().enumerate() {
            h[76 + 4 * i..80 + 4 * i].copy_from_slice(&f32b(p));
        }
        h[108..112].copy_from_slice(&f32b(self.vox_offset));
        h[112..116].copy_from_slice(&f32b(self.slope));
        h[116..120].copy_from_slice(&f32b(self.inter));
        h[344..348].copy_from_slice(&self.magic);
        h
    }

    /// A whole `.nii`: header and `data`.
    pub fn file(&self, data: &[u8]) -> Vec<u8> {
        let mut b = self.bytes();
        b.extend_from_slice(data);
        b
    }
}

/// An NRRD header: the magic line, `fields` and the blank line.
pub fn nrrd_header(fields: &[(&str, &str)]) -> String {
    let mut s = String::from("NRRD0004\n");
    for (k, v) in fields {
        s.push_str(&format!("{k}: {v}\n"));
    }
    s.push('\n');
    s
}

/// `base` with `key` replaced by `value` (added when absent, removed when
/// `value` is `None`).
pub fn with_field<'a>(
    base: &[(&'a str, &'a str)],
    key: &'a str,
    value: Option<&'a str>,
) -> Vec<(&'a str, &'a str)> {
    let mut out: Vec<(&str, &str)> = base.iter().copied().filter(|(k, _)| *k != key).collect();
    if let Some(v) = value {
        let at = base
            .iter()
            .position(|(k, _)| *k == key)
            .unwrap_or(out.len());
        out.insert(at.min(out.len()), (key, v));
    }
    out
}

/// A gzip stream of `bytes`, made with the project's own NRRD writer (the
/// data after the header of a gzip-encoded NRRD): the suite has no gzip
/// dependency of its own.
pub fn gzip(dir: &TempDir, bytes: &[u8]) -> Vec<u8> {
    let p = dir.join(".gzip-helper.nrrd");
    let dims = UVec3::new(bytes.len().max(1) as u32, 1, 1);
    nrrd::write(
        &p,
        dims,
        Vec3::ONE,
        SampleType::U8,
        Encoding::Gzip,
        samples::bytes(bytes),
    )
    .expect("gzip");
    let all = std::fs::read(&p).expect("read gzip helper");
    let _ = std::fs::remove_file(&p);
    all[header_end(&all).expect("NRRD header end")..].to_vec()
}

/// The byte after the first blank line (`\n\n`).
pub fn header_end(bytes: &[u8]) -> Option<usize> {
    bytes.windows(2).position(|w| w == b"\n\n").map(|i| i + 2)
}
