//! Volumes for the file format tests: synthetic data of every sample type,
//! opening files, and byte-exact comparison of what opened with what was
//! written.

use std::path::Path;

use glam::{UVec3, Vec3};
use raycaster::format::samples;
use raycaster::format::{self as fmt, Endian, FileFormat, OpenOptions, Opened, RawOptions};
use raycaster::prelude::*;
use raycaster::volume::AxisOrder;

/// The grid of the synthetic volumes: odd sizes, spacing differing per axis.
pub const SYN_DIMS: UVec3 = UVec3::new(7, 5, 9);
pub const SYN_SPACING: Vec3 = Vec3::new(0.5, 1.25, 2.0);

/// Every sample type the formats carry.
pub const ALL_TYPES: [SampleType; 5] = [
    SampleType::U8,
    SampleType::I8,
    SampleType::U16,
    SampleType::I16,
    SampleType::F32,
];

/// Deterministic test data of type `ty` on `dims`, spanning the type's range
/// (both extremes present, negatives for signed types), in a linear volume.
pub fn synthetic(ty: SampleType, dims: UVec3, spacing: Vec3, seed: u64) -> AnyVolume {
    fn build<S: Sample>(grid: Grid, v: Vec<S>) -> AnyVolume {
        let d = grid.dims;
        AnyVolume::from_fn(grid, |p| v[((p.z * d.y + p.y) * d.x + p.x) as usize])
    }
    fn ends<S: Copy>(mut v: Vec<S>, lo: S, hi: S) -> Vec<S> {
        let n = v.len();
        v[n / 3] = lo;
        v[2 * n / 3] = hi;
        v
    }
    let n = (dims.x * dims.y * dims.z) as usize;
    let grid = Grid::new(dims, spacing);
    let mut rng = fastrand::Rng::with_seed(seed);
    match ty {
        SampleType::U8 => build(grid, ends((0..n).map(|_| rng.u8(..)).collect(), 0, 255)),
        SampleType::I8 => build(
            grid,
            ends((0..n).map(|_| rng.i8(..)).collect(), i8::MIN, i8::MAX),
        ),
        SampleType::U16 => build(
            grid,
            ends((0..n).map(|_| rng.u16(..)).collect(), 0, u16::MAX),
        ),
        SampleType::I16 => build(
            grid,
            ends((0..n).map(|_| rng.i16(..)).collect(), i16::MIN, i16::MAX),
        ),
        SampleType::F32 => {
            let mut v: Vec<f32> = (0..n).map(|_| (rng.f32() - 0.5) * 2.0e4).collect();
            v[1] = 1.0e-30;
            v[2] = -7.25;
            v[3] = 0.0;
            build(grid, ends(v, -3.0e38, 3.0e38))
        }
    }
}

/// Opens `path` by its format, panicking with the error.
pub fn open(path: &Path) -> Opened {
    fmt::open_file(path, &OpenOptions::default())
        .unwrap_or_else(|e| panic!("opening {} failed: {e}", path.display()))
}

/// Opens `path` as a raw file described by `raw`, panicking with the error.
pub fn open_raw(path: &Path, raw: RawOptions) -> Opened {
    let options = OpenOptions {
        raw: Some(raw),
        ..OpenOptions::default()
    };
    fmt::open_file(path, &options)
        .unwrap_or_else(|e| panic!("opening {} as raw failed: {e}", path.display()))
}

/// Raw options for `dims`, `sample`, `endian` and axis `order` (spacing 1,
/// offset 0).
pub fn raw_options(
    dims: UVec3,
    sample: SampleType,
    endian: Endian,
    order: AxisOrder,
) -> RawOptions {
    RawOptions {
        order,
        ..RawOptions::new(dims, sample, endian)
    }
}

/// The samples of `v`, x fastest, little-endian: a byte-exact fingerprint of
/// the voxels (and of their type, with [`AnyVolume::sample_type`]).
pub fn le_bytes(v: &AnyVolume) -> Vec<u8> {
    samples::encode_volume(v, AxisOrder::XFast, Endian::Little)
}

pub fn voxel_f32(v: &AnyVolume, x: u32, y: u32, z: u32) -> f32 {
    v.value(UVec3::new(x, y, z))
}

/// Every voxel as f32, x fastest.
pub fn all_f32(v: &AnyVolume) -> Vec<f32> {
    let d = v.grid().dims;
    let mut out = Vec::with_capacity((d.x * d.y * d.z) as usize);
    for z in 0..d.z {
        for y in 0..d.y {
            for x in 0..d.x {
                out.push(voxel_f32(v, x, y, z));
            }
        }
    }
    out
}

pub fn min_max(values: &[f32]) -> (f32, f32) {
    values
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        })
}

/// Asserts `got` holds the same sample type, grid and voxels as `want`.
pub fn assert_same_volume(what: &str, got: &AnyVolume, want: &AnyVolume) {
    assert_eq!(got.sample_type(), want.sample_type(), "{what}: sample type");
    assert_eq!(got.grid().dims, want.grid().dims, "{what}: dims");
    let ds = (got.grid().spacing - want.grid().spacing)
        .abs()
        .max_element();
    assert!(
        ds <= 1e-6,
        "{what}: spacing {} != {}",
        got.grid().spacing,
        want.grid().spacing
    );
    let (a, b) = (le_bytes(got), le_bytes(want));
    if a != b {
        let size = want.sample_type().size();
        let first = a
            .chunks(size)
            .zip(b.chunks(size))
            .position(|(p, q)| p != q)
            .unwrap_or(0);
        let d = want.grid().dims;
        let (x, y, z) = (
            first as u32 % d.x,
            first as u32 / d.x % d.y,
            first as u32 / (d.x * d.y),
        );
        panic!(
            "{what}: voxels differ, first at ({x}, {y}, {z}): {} instead of {}",
            voxel_f32(got, x, y, z),
            voxel_f32(want, x, y, z)
        );
    }
}

/// Whether one of the notes on an opened file contains all of `words`.
pub fn has_note(opened: &Opened, words: &[&str]) -> bool {
    opened
        .info
        .notes
        .iter()
        .any(|n| words.iter().all(|w| n.contains(w)))
}

/// Checks an opened synthetic volume against the original.
pub fn check_opened(
    what: &str,
    opened: &Opened,
    want: &AnyVolume,
    format: FileFormat,
    stored: SampleType,
) {
    assert_eq!(opened.info.format, format, "{what}: format");
    assert_eq!(opened.info.dims, want.grid().dims, "{what}: info.dims");
    assert_eq!(opened.info.stored_type, stored, "{what}: info.stored_type");
    assert_same_volume(what, &opened.volume, want);
}
