//! File formats (SPEC §1, §6, §7): the real NRRD and NIfTI volumes in
//! /work/shared/data read right and render a plausible head; round trips
//! through the project's own writers (`.vol`, raw, NRRD, NIfTI) and the UC
//! Davis `.vol` give identical voxels and images; NRRD and NIfTI variants
//! (detached headers, skips, 4-D files, big-endian data, rescaling); and
//! malformed or random files give one-line errors that name the file, never
//! a panic.

mod common;

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use glam::{UVec3, Vec3};
use raycaster::format::davis::DavisHeader;
use raycaster::format::nrrd::{self, Encoding};
use raycaster::format::samples;
use raycaster::format::vol::{self, VolLayout};
use raycaster::format::{
    self as fmt, Endian, FileFormat, OpenOptions, Opened, RawOptions, Rescale, nifti, raw,
};
use raycaster::prelude::*;
use raycaster::volume::AxisOrder;

use common::TempDir;

const DATA: &str = "/work/shared/data";

// ------------------------------------------------------------------ helpers

fn open(path: &Path) -> Opened {
    fmt::open_file(path, &OpenOptions::default())
        .unwrap_or_else(|e| panic!("opening {} failed: {e}", path.display()))
}

fn open_raw(path: &Path, raw: RawOptions) -> Opened {
    let options = OpenOptions {
        raw: Some(raw),
        ..OpenOptions::default()
    };
    fmt::open_file(path, &options)
        .unwrap_or_else(|e| panic!("opening {} as raw failed: {e}", path.display()))
}

fn raw_options(dims: UVec3, sample: SampleType, endian: Endian, order: AxisOrder) -> RawOptions {
    RawOptions {
        order,
        ..RawOptions::new(dims, sample, endian)
    }
}

/// The samples of `v`, x fastest, little-endian: a byte-exact fingerprint of
/// the voxels (and of their type, with [`AnyVolume::sample_type`]).
fn le_bytes(v: &AnyVolume) -> Vec<u8> {
    samples::encode_volume(v, AxisOrder::XFast, Endian::Little)
}

fn voxel_f32(v: &AnyVolume, x: u32, y: u32, z: u32) -> f32 {
    raycaster::dispatch_volume!(v, v => v.voxel(UVec3::new(x, y, z)).to_f32())
}

/// Every voxel as f32, x fastest.
fn all_f32(v: &AnyVolume) -> Vec<f32> {
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

fn min_max(values: &[f32]) -> (f32, f32) {
    values
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        })
}

/// Asserts `got` holds the same sample type, grid and voxels as `want`.
fn assert_same_volume(what: &str, got: &AnyVolume, want: &AnyVolume) {
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

/// The datatype code NIfTI-1 uses for `t`, and its bits per voxel.
fn nifti_code(t: SampleType) -> (i16, i16) {
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
struct NiiHeader {
    endian: Endian,
    sizeof_hdr: i32,
    dim: [i16; 8],
    datatype: i16,
    bitpix: i16,
    pixdim: [f32; 8],
    vox_offset: f32,
    slope: f32,
    inter: f32,
    magic: [u8; 4],
}

impl NiiHeader {
    fn new(dims: UVec3, spacing: Vec3, t: SampleType, endian: Endian) -> Self {
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
    fn bytes(&self) -> Vec<u8> {
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
    fn file(&self, data: &[u8]) -> Vec<u8> {
        let mut b = self.bytes();
        b.extend_from_slice(data);
        b
    }
}

/// An NRRD header: the magic line, `fields` and the blank line.
fn nrrd_header(fields: &[(&str, &str)]) -> String {
    let mut s = String::from("NRRD0004\n");
    for (k, v) in fields {
        s.push_str(&format!("{k}: {v}\n"));
    }
    s.push('\n');
    s
}

/// `base` with `key` replaced by `value` (added when absent, removed when
/// `value` is `None`).
fn with_field<'a>(
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

/// A 7×5×9 u8 NRRD header, raw encoding.
const NRRD_U8: &[(&str, &str)] = &[
    ("type", "uchar"),
    ("dimension", "3"),
    ("sizes", "7 5 9"),
    ("spacings", "0.5 1.25 2"),
    ("encoding", "raw"),
];

/// A 26-byte `.vol` header.
fn vol_header(dims: [u32; 3], spacing: [f32; 3], layout: u8, extra: u8) -> Vec<u8> {
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

/// A gzip stream of `bytes`, made with the project's own NRRD writer (the
/// data after the header of a gzip-encoded NRRD): the suite has no gzip
/// dependency of its own.
fn gzip(dir: &TempDir, bytes: &[u8]) -> Vec<u8> {
    let p = dir.join(".gzip-helper.nrrd");
    let dims = UVec3::new(bytes.len().max(1) as u32, 1, 1);
    nrrd::write(&p, dims, Vec3::ONE, SampleType::U8, bytes, Encoding::Gzip).expect("gzip");
    let all = std::fs::read(&p).expect("read gzip helper");
    let _ = std::fs::remove_file(&p);
    all[header_end(&all).expect("NRRD header end")..].to_vec()
}

/// The byte after the first blank line (`\n\n`).
fn header_end(bytes: &[u8]) -> Option<usize> {
    bytes.windows(2).position(|w| w == b"\n\n").map(|i| i + 2)
}

/// Decompresses with the system's `gzip`, independently of the library;
/// `None` when no `gzip` program is available.
fn gunzip_cli(dir: &TempDir, gz: &[u8]) -> Option<Vec<u8>> {
    let p = dir.file("payload.gz", gz);
    let out = std::process::Command::new("gzip")
        .arg("-dc")
        .arg(&p)
        .output()
        .ok()?;
    out.status.success().then_some(out.stdout)
}

/// Deterministic test data of type `ty` on `dims`, spanning the type's range
/// (both extremes present, negatives for signed types), in a linear volume.
fn synthetic(ty: SampleType, dims: UVec3, spacing: Vec3, seed: u64) -> AnyVolume {
    fn build<S: Sample>(grid: Grid, v: Vec<S>) -> AnyVolume
    where
        AnyVolume: From<LinearVolume<S>>,
    {
        let d = grid.dims;
        LinearVolume::from_fn(grid, |p| v[((p.z * d.y + p.y) * d.x + p.x) as usize]).into()
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

/// A synthetic volume with values that a rescale keeps inside i16 (or not,
/// with `wide`).
fn small_range(ty: SampleType, dims: UVec3, spacing: Vec3) -> AnyVolume {
    let grid = Grid::new(dims, spacing);
    let n = |p: UVec3| ((p.z * dims.y + p.y) * dims.x + p.x) as i32;
    match ty {
        SampleType::U8 => LinearVolume::from_fn(grid, |p| (n(p) * 7 % 256) as u8).into(),
        SampleType::I8 => LinearVolume::from_fn(grid, |p| (n(p) * 7 % 256 - 128) as i8).into(),
        SampleType::U16 => LinearVolume::from_fn(grid, |p| (n(p) * 211 % 4000) as u16).into(),
        SampleType::I16 => {
            LinearVolume::from_fn(grid, |p| (n(p) * 211 % 4000 - 2000) as i16).into()
        }
        SampleType::F32 => {
            LinearVolume::from_fn(grid, |p| (n(p) * 211 % 4000 - 2000) as f32 * 0.25).into()
        }
    }
}

const ALL_TYPES: [SampleType; 5] = [
    SampleType::U8,
    SampleType::I8,
    SampleType::U16,
    SampleType::I16,
    SampleType::F32,
];

/// The u8 volume inside an [`AnyVolume`] (linear), for the `.vol` writer.
fn as_linear_u8(v: &AnyVolume) -> &LinearVolume<u8> {
    match v {
        AnyVolume::LinearU8(v) => v,
        other => panic!("expected a linear u8 volume, got {:?}", other.sample_type()),
    }
}

// --------------------------------------------------------------- rendering

const IMAGE: u32 = 96;

/// The default view of SPEC §6 (framing camera from +z, 45°) at 96×96.
fn framing_camera(scene: &Scene) -> Camera {
    Camera::framing(&scene.grid().bounds(), IMAGE, IMAGE, 45.0)
}

/// `mr-default` for the scene's sample type, default options (shading,
/// ERT and ESS on, black background).
fn render(scene: &Scene, camera: &Camera) -> Frame {
    let tf = TransferFunction::preset("mr-default", scene.volume().sample_type())
        .expect("mr-default preset");
    SerialRenderer::new()
        .render(scene, camera, &tf, &RenderOptions::default())
        .expect("render")
}

/// What a head looks like from the framing camera.
#[derive(Debug)]
struct Silhouette {
    /// Non-background pixels / all pixels.
    fraction: f64,
    /// Inclusive bounding box of non-background pixels: x0, y0, x1, y1.
    bbox: [u32; 4],
    /// Brightest channel of the four corner pixels.
    corner_max: u8,
}

fn silhouette(f: &Frame) -> Silhouette {
    let lit = |x: u32, y: u32| f.pixel(x, y).iter().any(|&c| c > 4);
    let mut count = 0usize;
    let mut bbox = [u32::MAX, u32::MAX, 0, 0];
    for y in 0..f.height {
        for x in 0..f.width {
            if lit(x, y) {
                count += 1;
                bbox = [
                    bbox[0].min(x),
                    bbox[1].min(y),
                    bbox[2].max(x),
                    bbox[3].max(y),
                ];
            }
        }
    }
    let (w, h) = (f.width - 1, f.height - 1);
    let corner_max = [(0, 0), (w, 0), (0, h), (w, h)]
        .iter()
        .flat_map(|&(x, y)| f.pixel(x, y))
        .max()
        .unwrap_or(0);
    Silhouette {
        fraction: count as f64 / (f.width * f.height) as f64,
        bbox,
        corner_max,
    }
}

/// Silhouette bounds of one real volume seen from the framing camera,
/// measured with `mr-default` (FLAIR: 0.193 of the frame, bounding box
/// 40×55 px; MNI: 0.123, 34×43 px) and set wide enough for renderer
/// changes but tight enough to fail the transposed readings that change the
/// outline (see `wrong_readings_of_the_real_volumes_are_caught`).
struct HeadBounds {
    /// Non-background fraction of the frame.
    fraction: (f64, f64),
    /// Bounding box height / width.
    aspect: (f64, f64),
}

const FLAIR_HEAD: HeadBounds = HeadBounds {
    fraction: (0.14, 0.26),
    aspect: (1.15, 1.65),
};
const MNI_HEAD: HeadBounds = HeadBounds {
    fraction: (0.08, 0.18),
    aspect: (1.1, 1.5),
};

/// What is implausible about a frame as the image of a head: a silhouette
/// of the wrong size or shape, a corner that is not background, a bounding
/// box off the centre. Empty when all is well.
fn silhouette_problems(f: &Frame, bounds: &HeadBounds) -> Vec<String> {
    let s = silhouette(f);
    let mut problems = Vec::new();
    let (lo, hi) = bounds.fraction;
    if !(lo..=hi).contains(&s.fraction) {
        problems.push(format!(
            "silhouette covers {:.3} of the frame, expected {lo}..{hi}",
            s.fraction
        ));
    }
    if s.corner_max != 0 {
        problems.push(format!("a corner is not background ({})", s.corner_max));
    }
    let [x0, y0, x1, y1] = s.bbox;
    if x0 > x1 || y0 > y1 {
        problems.push("nothing visible".into());
        return problems;
    }
    let centre = ((x0 + x1) as f64 / 2.0, (y0 + y1) as f64 / 2.0);
    let mid = (f.width - 1) as f64 / 2.0;
    let tol = 0.1 * f.width as f64;
    if (centre.0 - mid).abs() > tol || (centre.1 - mid).abs() > tol {
        problems.push(format!(
            "bounding box centred at {centre:?}, not near {mid}"
        ));
    }
    let (bw, bh) = ((x1 - x0 + 1) as f64, (y1 - y0 + 1) as f64);
    if bw < 0.25 * f.width as f64 || bh < 0.25 * f.height as f64 {
        problems.push(format!("bounding box {bw}×{bh} px is too small"));
    }
    let (alo, ahi) = bounds.aspect;
    if !(alo..=ahi).contains(&(bh / bw)) {
        problems.push(format!(
            "bounding box {bw}×{bh} px has aspect {:.2}, expected {alo}..{ahi}",
            bh / bw
        ));
    }
    if !problems.is_empty() {
        problems.push(format!("{s:?}"));
    }
    problems
}

// ---------------------------------------------------------------- real data

fn data_path(rel: &str) -> Option<PathBuf> {
    let p = Path::new(DATA).join(rel);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("SKIPPED: {} not found", p.display());
        None
    }
}

/// Sums of the central x, y and z slices (at dims / 2).
fn central_slice_sums(v: &AnyVolume) -> [f64; 3] {
    let d = v.grid().dims;
    let c = d / 2;
    let mut s = [0.0f64; 3];
    for z in 0..d.z {
        for y in 0..d.y {
            s[0] += voxel_f32(v, c.x, y, z) as f64;
        }
    }
    for z in 0..d.z {
        for x in 0..d.x {
            s[1] += voxel_f32(v, x, c.y, z) as f64;
        }
    }
    for y in 0..d.y {
        for x in 0..d.x {
            s[2] += voxel_f32(v, x, y, c.z) as f64;
        }
    }
    s
}

// Values below were computed with Python's gzip/struct from the files, x
// fastest (SPEC §7): a reader with a transposed axis order or the wrong
// byte order fails them.
const FLAIR_PROBES: &[([u32; 3], f32)] = &[
    ([62, 80, 70], 170.0),
    ([40, 100, 90], 92.0),
    ([90, 50, 30], 88.0),
    ([31, 121, 101], 81.0),
    ([100, 70, 60], 129.0),
    ([55, 33, 77], 147.0),
    ([70, 130, 50], 0.0),
    ([20, 80, 70], 115.0),
];
const FLAIR_SLICE_SUMS: [f64; 3] = [1_210_830.0, 1_037_244.0, 1_430_455.0];
const FLAIR_TOTAL: f64 = 115_231_646.0;

const MNI_PROBES: &[([u32; 3], f32)] = &[
    ([96, 114, 96], 58.0),
    ([60, 140, 120], 877.0),
    ([130, 80, 50], 890.0),
    ([40, 100, 100], 641.0),
    ([96, 60, 150], 0.0),
    ([150, 170, 80], 416.0),
    ([70, 114, 30], 0.0),
    ([96, 200, 96], 0.0),
];
const MNI_SLICE_SUMS: [f64; 3] = [5_203_435.0, 11_615_903.0, 14_706_070.0];
const MNI_TOTAL: f64 = 1_425_380_419.0;

/// Mismatches of the probe voxels and central slice sums of an independent
/// decoder. Empty when all match.
fn probe_problems(v: &AnyVolume, probes: &[([u32; 3], f32)], sums: [f64; 3]) -> Vec<String> {
    let d = v.grid().dims;
    let mut problems = Vec::new();
    for &([x, y, z], want) in probes {
        if x >= d.x || y >= d.y || z >= d.z {
            problems.push(format!("voxel ({x}, {y}, {z}) is outside {d}"));
            continue;
        }
        let got = voxel_f32(v, x, y, z);
        if got != want {
            problems.push(format!("voxel ({x}, {y}, {z}) is {got}, expected {want}"));
        }
    }
    let got = central_slice_sums(v);
    if got != sums {
        problems.push(format!(
            "central x/y/z slice sums are {got:?}, expected {sums:?}"
        ));
    }
    problems
}

fn total(v: &AnyVolume) -> f64 {
    all_f32(v).iter().map(|&x| x as f64).sum()
}

#[test]
fn flair_nrrd_reads_right_and_renders_a_head() {
    let Some(path) = data_path("mri_flair_nrrd/FLAIR.nrrd") else {
        return;
    };
    let opened = open(&path);
    let info = &opened.info;
    assert_eq!(info.format, FileFormat::Nrrd);
    assert_eq!(info.encoding, "gzip");
    assert_eq!(info.dims, UVec3::new(124, 160, 140));
    assert_eq!(info.stored_type, SampleType::U8);
    assert_eq!(info.byte_order, None);
    assert_eq!(info.rescale, None);
    let orientation = info.orientation.as_deref().expect("orientation reported");
    assert!(
        orientation.contains("space directions"),
        "orientation: {orientation}"
    );
    // Lengths of the oblique space direction vectors: 1.0, 1.0, 1.0 (to 1e-15).
    assert!(
        (info.spacing - Vec3::ONE).abs().max_element() < 1e-3,
        "spacing {}",
        info.spacing
    );
    let v = &opened.volume;
    assert_eq!(v.sample_type(), SampleType::U8);
    assert_eq!(v.grid().dims, info.dims);
    assert_eq!(v.grid().spacing, info.spacing);
    let problems = probe_problems(v, FLAIR_PROBES, FLAIR_SLICE_SUMS);
    assert!(problems.is_empty(), "FLAIR: {problems:#?}");
    assert_eq!(total(v), FLAIR_TOTAL, "FLAIR: sum of all voxels");

    // Every voxel against an independent decoder, when one is installed.
    let dir = TempDir::new("flair");
    let file = std::fs::read(&path).unwrap();
    let start = header_end(&file).expect("NRRD header end");
    if let Some(decoded) = gunzip_cli(&dir, &file[start..]) {
        assert_eq!(decoded.len(), 124 * 160 * 140, "gzip -dc length");
        assert!(le_bytes(v) == decoded, "FLAIR voxels differ from gzip -dc");
    }

    let scene = Scene::new(opened.volume);
    assert_eq!(scene.value_range(), (0.0, 255.0));
    let frame = render(&scene, &framing_camera(&scene));
    let problems = silhouette_problems(&frame, &FLAIR_HEAD);
    assert!(problems.is_empty(), "FLAIR image: {problems:#?}");
}

#[test]
fn mni_nifti_reads_right_and_renders_a_head() {
    let Some(path) = data_path("mri_template_int16/MNI152_2009_template.nii.gz") else {
        return;
    };
    let opened = open(&path);
    let info = &opened.info;
    assert_eq!(info.format, FileFormat::Nifti);
    assert_eq!(info.encoding, "gzip");
    assert_eq!(info.dims, UVec3::new(193, 229, 193));
    assert!(
        (info.spacing - Vec3::ONE).abs().max_element() < 1e-3,
        "spacing {}",
        info.spacing
    );
    assert_eq!(info.stored_type, SampleType::I16);
    assert_eq!(info.byte_order, Some(Endian::Little));
    assert_eq!(info.rescale, None, "scl_slope is 0: no rescale");
    assert!(info.orientation.is_some(), "q/sform reported");
    assert!(info.notes.is_empty(), "notes: {:?}", info.notes);
    let v = &opened.volume;
    assert_eq!(v.sample_type(), SampleType::I16);
    let problems = probe_problems(v, MNI_PROBES, MNI_SLICE_SUMS);
    assert!(problems.is_empty(), "MNI: {problems:#?}");
    assert_eq!(total(v), MNI_TOTAL, "MNI: sum of all voxels");

    let dir = TempDir::new("mni");
    if let Some(decoded) = gunzip_cli(&dir, &std::fs::read(&path).unwrap()) {
        let data = &decoded[3296..]; // vox_offset
        assert_eq!(data.len(), 193 * 229 * 193 * 2, "gzip -dc length");
        assert!(le_bytes(v) == data, "MNI voxels differ from gzip -dc");
    }

    let scene = Scene::new(opened.volume);
    assert_eq!(scene.value_range(), (0.0, 1570.0));
    let frame = render(&scene, &framing_camera(&scene));
    let problems = silhouette_problems(&frame, &MNI_HEAD);
    assert!(problems.is_empty(), "MNI image: {problems:#?}");
}

/// The checks above against readers that get the axis order or the byte
/// order wrong: the real volumes' decoded samples, re-read as raw files with
/// a wrong description. The probes fail for every wrong reading; the image
/// check fails for those that change the outline (the MNI template has
/// X = Z, so reading it z-fast is an x↔z transpose that still looks like a
/// head from +z, and byte-swapped data keeps the head's outline: those are
/// left to the probes).
#[test]
fn wrong_readings_of_the_real_volumes_are_caught() {
    let dir = TempDir::new("wrong-readings");
    type Variant = (&'static str, fn(UVec3) -> UVec3, Endian, AxisOrder, bool);
    let variants: &[Variant] = &[
        ("z fastest", |d| d, Endian::Little, AxisOrder::ZFast, true),
        (
            "x and y swapped",
            |d| UVec3::new(d.y, d.x, d.z),
            Endian::Little,
            AxisOrder::XFast,
            true,
        ),
        (
            "x and z swapped",
            |d| UVec3::new(d.z, d.y, d.x),
            Endian::Little,
            AxisOrder::XFast,
            true,
        ),
        ("big-endian", |d| d, Endian::Big, AxisOrder::XFast, false),
    ];
    type RealVolume<'a> = (&'a str, &'a [([u32; 3], f32)], [f64; 3], &'a HeadBounds);
    let volumes: [RealVolume; 2] = [
        (
            "mri_flair_nrrd/FLAIR.nrrd",
            FLAIR_PROBES,
            FLAIR_SLICE_SUMS,
            &FLAIR_HEAD,
        ),
        (
            "mri_template_int16/MNI152_2009_template.nii.gz",
            MNI_PROBES,
            MNI_SLICE_SUMS,
            &MNI_HEAD,
        ),
    ];
    for (rel, probes, sums, head) in volumes {
        let Some(path) = data_path(rel) else {
            return;
        };
        let right = open(&path);
        let (dims, ty) = (right.info.dims, right.info.stored_type);
        let p = dir.file("samples.raw", &le_bytes(&right.volume));
        drop(right);
        for &(name, permute, endian, order, image_catches) in variants {
            let wrong_dims = permute(dims);
            if ty.size() == 1 && endian == Endian::Big || name != "z fastest" && wrong_dims == dims
            {
                continue; // the same reading as the right one
            }
            let wrong = open_raw(&p, raw_options(wrong_dims, ty, endian, order));
            assert!(
                !probe_problems(&wrong.volume, probes, sums).is_empty(),
                "{rel} read {name}: the probes do not notice"
            );
            if image_catches && !(name == "z fastest" && dims.x == dims.z) {
                let scene = Scene::new(wrong.volume);
                let frame = render(&scene, &framing_camera(&scene));
                assert!(
                    !silhouette_problems(&frame, head).is_empty(),
                    "{rel} read {name}: the image check does not notice ({:?})",
                    silhouette(&frame)
                );
            }
        }
    }
}

// ------------------------------------------------------------- round trips

#[test]
fn flair_written_as_vol_renders_identically() {
    let Some(path) = data_path("mri_flair_nrrd/FLAIR.nrrd") else {
        return;
    };
    let dir = TempDir::new("flair-vol");
    let original = Scene::new(open(&path).volume);
    let camera = framing_camera(&original);
    let want = render(&original, &camera);
    for (name, layout, encoding) in [
        ("linear.vol", VolLayout::Linear, "raw, z fastest"),
        (
            "bricked16.vol",
            VolLayout::Bricked { side: 16 },
            "bricked (B = 16)",
        ),
        (
            "bricked7.vol",
            VolLayout::Bricked { side: 7 },
            "bricked (B = 7)",
        ),
    ] {
        let p = dir.join(name);
        vol::write(&p, as_linear_u8(original.volume()), layout).expect("write .vol");
        let opened = open(&p);
        assert_eq!(opened.info.format, FileFormat::Vol, "{name}");
        assert_eq!(opened.info.encoding, encoding, "{name}");
        assert_same_volume(name, &opened.volume, original.volume());
        let scene = Scene::new(opened.volume);
        assert_eq!(scene.value_range(), original.value_range(), "{name}");
        let got = render(&scene, &camera);
        assert!(got.rgb == want.rgb, "{name}: image differs from the NRRD's");
    }
}

#[test]
fn mni_written_as_raw_in_every_order_and_byte_order_renders_identically() {
    let Some(path) = data_path("mri_template_int16/MNI152_2009_template.nii.gz") else {
        return;
    };
    let dir = TempDir::new("mni-raw");
    let original = Scene::new(open(&path).volume);
    let dims = original.grid().dims;
    let camera = framing_camera(&original);
    let want = render(&original, &camera);
    for order in [AxisOrder::XFast, AxisOrder::ZFast] {
        for endian in [Endian::Little, Endian::Big] {
            let name = format!("mni-{order:?}-{}.raw", endian.name());
            let p = dir.join(&name);
            raw::write(&p, original.volume(), order, endian).expect("raw write");
            let len = std::fs::metadata(&p).unwrap().len();
            assert_eq!(
                len,
                dims.x as u64 * dims.y as u64 * dims.z as u64 * 2,
                "{name}"
            );
            let opened = open_raw(&p, raw_options(dims, SampleType::I16, endian, order));
            assert_eq!(opened.info.format, FileFormat::Raw, "{name}");
            assert_eq!(opened.info.byte_order, Some(endian), "{name}");
            assert_same_volume(&name, &opened.volume, original.volume());
            let scene = Scene::new(opened.volume);
            let got = render(&scene, &camera);
            assert!(
                got.rgb == want.rgb,
                "{name}: image differs from the NIfTI's"
            );
            std::fs::remove_file(&p).unwrap();
        }
    }
}

const SYN_DIMS: UVec3 = UVec3::new(7, 5, 9);
const SYN_SPACING: Vec3 = Vec3::new(0.5, 1.25, 2.0);

/// Checks an opened synthetic volume against the original.
fn check_opened(
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

#[test]
fn synthetic_volumes_of_every_type_round_trip_through_every_writer() {
    let dir = TempDir::new("synthetic");
    for (i, ty) in ALL_TYPES.into_iter().enumerate() {
        let want = synthetic(ty, SYN_DIMS, SYN_SPACING, 11 + i as u64);
        let le = le_bytes(&want);
        let range = min_max(&all_f32(&want));
        let check_range = |what: &str, opened: Opened| {
            assert_eq!(
                Scene::new(opened.volume).value_range(),
                range,
                "{what}: value range"
            );
        };

        for (enc, ext, name) in [
            (Encoding::Raw, "nrrd", "raw"),
            (Encoding::Gzip, "nrrd", "gzip"),
        ] {
            let what = format!("{ty} NRRD {name}");
            let p = dir.join(&format!("{ty}-{name}.{ext}"));
            nrrd::write(&p, SYN_DIMS, SYN_SPACING, ty, &le, enc).expect("nrrd write");
            let opened = open(&p);
            check_opened(&what, &opened, &want, FileFormat::Nrrd, ty);
            assert_eq!(opened.info.encoding, name, "{what}");
            assert!(opened.info.orientation.is_some(), "{what}: orientation");
            check_range(&what, opened);
        }

        for (name, encoding) in [("nii", "raw"), ("nii.gz", "gzip")] {
            let what = format!("{ty} .{name}");
            let p = dir.join(&format!("{ty}.{name}"));
            nifti::write(&p, SYN_DIMS, SYN_SPACING, ty, &le, None).expect("nifti write");
            let opened = open(&p);
            check_opened(&what, &opened, &want, FileFormat::Nifti, ty);
            assert_eq!(opened.info.encoding, encoding, "{what}");
            assert_eq!(opened.info.rescale, None, "{what}");
            check_range(&what, opened);
        }

        for order in [AxisOrder::XFast, AxisOrder::ZFast] {
            for endian in [Endian::Little, Endian::Big] {
                let what = format!("{ty} raw {order:?} {}", endian.name());
                let p = dir.join(&format!("{ty}-{order:?}-{}.raw", endian.name()));
                raw::write(&p, &want, order, endian).expect("raw write");
                let bytes = std::fs::read(&p).unwrap();
                assert_eq!(
                    bytes,
                    samples::encode_volume(&want, order, endian),
                    "{what}: file bytes"
                );
                if order == AxisOrder::XFast && endian == Endian::Little {
                    assert_eq!(
                        bytes, le,
                        "{what}: x-fast little-endian is the NRRD payload"
                    );
                }
                let mut options = raw_options(SYN_DIMS, ty, endian, order);
                options.spacing = SYN_SPACING;
                let opened = open_raw(&p, options.clone());
                check_opened(&what, &opened, &want, FileFormat::Raw, ty);
                check_range(&what, opened);

                // The same samples behind a 37-byte foreign header.
                let mut with_header = vec![0xA5u8; 37];
                with_header.extend_from_slice(&bytes);
                let p = dir.file(
                    &format!("{ty}-{order:?}-{}-offset.bin", endian.name()),
                    &with_header,
                );
                options.offset = 37;
                let opened = open_raw(&p, options);
                check_opened(
                    &format!("{what} offset 37"),
                    &opened,
                    &want,
                    FileFormat::Raw,
                    ty,
                );
            }
        }
    }
}

#[test]
fn u8_volumes_round_trip_through_vol_and_uc_davis() {
    let dir = TempDir::new("vol-davis");
    let want = synthetic(SampleType::U8, SYN_DIMS, SYN_SPACING, 5);

    // SPEC .vol, both layouts.
    for (name, layout) in [
        ("linear.vol", VolLayout::Linear),
        ("bricked.vol", VolLayout::Bricked { side: 3 }),
    ] {
        let p = dir.join(name);
        vol::write(&p, as_linear_u8(&want), layout).unwrap();
        assert_eq!(fmt::detect(&p).unwrap(), FileFormat::Vol, "{name}");
        check_opened(name, &open(&p), &want, FileFormat::Vol, SampleType::U8);
    }

    // UC Davis: 28-byte big-endian header, u8 samples z fastest.
    let davis = |border: u32| {
        let mut b = DavisHeader {
            dims: SYN_DIMS,
            border,
            spacing: SYN_SPACING,
        }
        .to_bytes()
        .to_vec();
        b.extend(samples::encode_volume(&want, AxisOrder::ZFast, Endian::Big));
        b
    };
    for name in ["davis.vol", "DAVIS.VOL", "davis"] {
        let p = dir.file(name, &davis(0));
        assert_eq!(fmt::detect(&p).unwrap(), FileFormat::DavisVol, "{name}");
        let opened = open(&p);
        check_opened(name, &opened, &want, FileFormat::DavisVol, SampleType::U8);
        assert!(
            opened.info.notes.is_empty(),
            "{name}: {:?}",
            opened.info.notes
        );
    }
    let p = dir.file("border.vol", &davis(2));
    let opened = open(&p);
    check_opened(
        "border.vol",
        &opened,
        &want,
        FileFormat::DavisVol,
        SampleType::U8,
    );
    assert!(
        opened.info.notes.iter().any(|n| n.contains("border of 2")),
        "notes: {:?}",
        opened.info.notes
    );

    // The same bytes: a SPEC .vol without extension is still a SPEC .vol.
    let spec = std::fs::read(dir.join("linear.vol")).unwrap();
    let p = dir.file("spec-no-extension", &spec);
    assert_eq!(fmt::detect(&p).unwrap(), FileFormat::Vol);
}

#[test]
fn nifti_rescale_gives_data_units() {
    let dir = TempDir::new("rescale");
    // (stored type, slope, intercept, type after rescaling)
    let cases: &[(SampleType, f32, f32, SampleType)] = &[
        (SampleType::U8, 2.0, -100.0, SampleType::I16),
        (SampleType::U8, 1.0, -128.0, SampleType::I16),
        (SampleType::I8, -1.0, 0.0, SampleType::I16),
        (SampleType::I16, 3.0, -1024.0, SampleType::I16),
        (SampleType::U16, 1.0, -1024.0, SampleType::I16),
        (SampleType::U16, 0.5, 0.0, SampleType::F32),
        (SampleType::U8, 1.0, 0.25, SampleType::F32),
        (SampleType::I16, 20.0, 0.0, SampleType::F32), // 2000·20 leaves i16
        (SampleType::I16, 1.0, 32000.0, SampleType::F32),
        (SampleType::F32, 2.0, 1.0, SampleType::F32),
        (SampleType::I16, -0.125, 10.5, SampleType::F32),
    ];
    for &(ty, slope, inter, result) in cases {
        let stored = small_range(ty, SYN_DIMS, SYN_SPACING);
        let le = le_bytes(&stored);
        let expected: Vec<f32> = all_f32(&stored)
            .iter()
            .map(|&s| (s as f64 * slope as f64 + inter as f64) as f32)
            .collect();
        let rescale = Rescale {
            slope: slope as f64,
            intercept: inter as f64,
        };
        for ext in ["nii", "nii.gz"] {
            let what = format!("{ty} × {slope} + {inter} .{ext}");
            let p = dir.join(&format!("{ty}-{slope}-{inter}.{ext}"));
            nifti::write(&p, SYN_DIMS, SYN_SPACING, ty, &le, Some(rescale)).unwrap();
            let opened = open(&p);
            assert_eq!(opened.info.stored_type, ty, "{what}: stored type");
            assert_eq!(opened.info.rescale, Some(rescale), "{what}: info.rescale");
            assert_eq!(
                opened.volume.sample_type(),
                result,
                "{what}: type after rescaling"
            );
            let got = all_f32(&opened.volume);
            for (i, (&g, &e)) in got.iter().zip(&expected).enumerate() {
                assert!(
                    (g - e).abs() <= 1e-6 * e.abs().max(1.0),
                    "{what}: voxel {i} is {g}, expected {e}"
                );
            }
            let scene = Scene::new(opened.volume);
            let (lo, hi) = min_max(&expected);
            let (rlo, rhi) = scene.value_range();
            assert!(
                (rlo - lo).abs() <= 1e-6 * lo.abs().max(1.0)
                    && (rhi - hi).abs() <= 1e-6 * hi.abs().max(1.0),
                "{what}: value range ({rlo}, {rhi}), expected ({lo}, {hi})"
            );
        }
    }
    // Slope 1 and intercept 0 (and slope 0, "not set") are no rescale.
    for (slope, inter) in [(1.0, 0.0), (0.0, 0.0), (0.0, 5.0)] {
        let stored = small_range(SampleType::I16, SYN_DIMS, SYN_SPACING);
        let mut h = NiiHeader::new(SYN_DIMS, SYN_SPACING, SampleType::I16, Endian::Little);
        h.slope = slope;
        h.inter = inter;
        let p = dir.file("identity.nii", &h.file(&le_bytes(&stored)));
        let opened = open(&p);
        assert_eq!(opened.info.rescale, None, "slope {slope} intercept {inter}");
        assert_same_volume("identity rescale", &opened.volume, &stored);
    }
}

#[test]
fn big_endian_nifti_opens_with_the_same_values() {
    let dir = TempDir::new("nifti-be");
    for (i, ty) in ALL_TYPES.into_iter().enumerate() {
        let want = synthetic(ty, SYN_DIMS, SYN_SPACING, 40 + i as u64);
        let be = samples::encode_volume(&want, AxisOrder::XFast, Endian::Big);
        let h = NiiHeader::new(SYN_DIMS, SYN_SPACING, ty, Endian::Big);
        let file = h.file(&be);
        let p = dir.file(&format!("{ty}-be.nii"), &file);
        assert_eq!(fmt::detect(&p).unwrap(), FileFormat::Nifti);
        let opened = open(&p);
        check_opened(
            &format!("{ty} big-endian .nii"),
            &opened,
            &want,
            FileFormat::Nifti,
            ty,
        );
        if ty.size() > 1 {
            assert_eq!(opened.info.byte_order, Some(Endian::Big), "{ty}");
        }
        let p = dir.file(&format!("{ty}-be.nii.gz"), &gzip(&dir, &file));
        let opened = open(&p);
        check_opened(
            &format!("{ty} big-endian .nii.gz"),
            &opened,
            &want,
            FileFormat::Nifti,
            ty,
        );
        assert_eq!(opened.info.encoding, "gzip");
    }

    // Big-endian rescale fields: the same values as the project's writer's
    // little-endian file.
    let stored = small_range(SampleType::I16, SYN_DIMS, SYN_SPACING);
    let rescale = Rescale {
        slope: 2.0,
        intercept: -3.0,
    };
    let le_path = dir.join("rescaled-le.nii");
    nifti::write(
        &le_path,
        SYN_DIMS,
        SYN_SPACING,
        SampleType::I16,
        &le_bytes(&stored),
        Some(rescale),
    )
    .unwrap();
    let mut h = NiiHeader::new(SYN_DIMS, SYN_SPACING, SampleType::I16, Endian::Big);
    h.slope = 2.0;
    h.inter = -3.0;
    let be_path = dir.file(
        "rescaled-be.nii",
        &h.file(&samples::encode_volume(
            &stored,
            AxisOrder::XFast,
            Endian::Big,
        )),
    );
    let (a, b) = (open(&le_path), open(&be_path));
    assert_eq!(b.info.rescale, Some(rescale));
    assert_same_volume("big-endian rescaled", &b.volume, &a.volume);
}

#[test]
fn nrrd_detached_headers_skips_spacings_and_4d() {
    let dir = TempDir::new("nrrd-variants");
    let want = synthetic(SampleType::U16, SYN_DIMS, SYN_SPACING, 21);
    let le = le_bytes(&want);
    let base: &[(&str, &str)] = &[
        ("type", "unsigned short"),
        ("dimension", "3"),
        ("sizes", "7 5 9"),
        ("spacings", "0.5 1.25 2"),
        ("endian", "little"),
        ("encoding", "raw"),
    ];
    let check = |what: &str, path: &Path, want: &AnyVolume| -> Opened {
        let opened = open(path);
        check_opened(what, &opened, want, FileFormat::Nrrd, want.sample_type());
        opened
    };

    // Detached .nhdr + .raw.
    dir.file("vol.raw", &le);
    let p = dir.file(
        "detached.nhdr",
        nrrd_header(&with_field(base, "data file", Some("vol.raw"))).as_bytes(),
    );
    let opened = check("detached .nhdr", &p, &want);
    assert!(
        opened.info.notes.iter().any(|n| n.contains("vol.raw")),
        "notes: {:?}",
        opened.info.notes
    );
    assert_eq!(
        opened.info.file_bytes,
        std::fs::metadata(&p).unwrap().len() + le.len() as u64
    );
    // A detached header without the final blank line, and the old spelling.
    let mut text = nrrd_header(&with_field(base, "datafile", Some("vol.raw")));
    text.pop();
    let p = dir.file("no-blank-line.nhdr", text.as_bytes());
    check("detached .nhdr without blank line", &p, &want);

    // Detached with line skip and byte skip.
    let mut data = b"first line\nsecond line\n".to_vec();
    data.extend_from_slice(b"12345");
    data.extend_from_slice(&le);
    data.extend_from_slice(b"trailing bytes are allowed");
    dir.file("skips.dat", &data);
    let fields = with_field(base, "data file", Some("skips.dat"));
    let fields = with_field(&fields, "line skip", Some("2"));
    let fields = with_field(&fields, "byte skip", Some("5"));
    let p = dir.file("skips.nhdr", nrrd_header(&fields).as_bytes());
    check("line skip 2 + byte skip 5", &p, &want);

    // Attached, byte skip after the header.
    let mut file = nrrd_header(&with_field(base, "byte skip", Some("3"))).into_bytes();
    file.extend_from_slice(b"abc");
    file.extend_from_slice(&le);
    let p = dir.file("byteskip.nrrd", &file);
    check("attached byte skip 3", &p, &want);

    // Attached, byte skip -1: the samples are the file's last bytes.
    let mut file = nrrd_header(&with_field(base, "byte skip", Some("-1"))).into_bytes();
    file.extend_from_slice(b"junk between header and data");
    file.extend_from_slice(&le);
    let p = dir.file("byteskip-1.nrrd", &file);
    check("attached byte skip -1", &p, &want);

    // Detached gzip data.
    dir.file("vol.raw.gz", &gzip(&dir, &le));
    let fields = with_field(base, "data file", Some("vol.raw.gz"));
    let fields = with_field(&fields, "encoding", Some("gzip"));
    let p = dir.file("detached-gz.nhdr", nrrd_header(&fields).as_bytes());
    check("detached gzip", &p, &want);

    // Spacing from spacings (no orientation) and from oblique space
    // directions (their lengths), with `space origin`.
    let p = dir.file(
        "spacings.nrrd",
        &[nrrd_header(base).into_bytes(), le.clone()].concat(),
    );
    let opened = check("spacings", &p, &want);
    assert_eq!(opened.info.spacing, SYN_SPACING);
    assert_eq!(opened.info.orientation, None);
    let fields = with_field(base, "spacings", None);
    let fields = with_field(&fields, "space", Some("right-anterior-superior"));
    let fields = with_field(
        &fields,
        "space directions",
        Some("(0.3,0.4,0) (0,0,1.25) (-2,0,0)"),
    );
    let fields = with_field(&fields, "space origin", Some("(1,2,3)"));
    let p = dir.file(
        "directions.nrrd",
        &[nrrd_header(&fields).into_bytes(), le.clone()].concat(),
    );
    let opened = check("space directions", &p, &want);
    assert!((opened.info.spacing - SYN_SPACING).abs().max_element() < 1e-6);
    let o = opened.info.orientation.as_deref().unwrap_or("");
    assert!(
        o.contains("(0.3,0.4,0)") && o.contains("(1,2,3)"),
        "orientation: {o}"
    );

    // CRLF line endings.
    let crlf = nrrd_header(base).replace('\n', "\r\n");
    let p = dir.file("crlf.nrrd", &[crlf.into_bytes(), le.clone()].concat());
    check("CRLF header", &p, &want);

    // Big-endian short.
    let signed = synthetic(SampleType::I16, SYN_DIMS, SYN_SPACING, 22);
    let fields = with_field(base, "type", Some("short"));
    let fields = with_field(&fields, "endian", Some("big"));
    let be = samples::encode_volume(&signed, AxisOrder::XFast, Endian::Big);
    let p = dir.file(
        "big.nrrd",
        &[nrrd_header(&fields).into_bytes(), be].concat(),
    );
    let opened = check("big-endian short", &p, &signed);
    assert_eq!(opened.info.byte_order, Some(Endian::Big));

    // 4-D with a size-1 first axis (spacing `nan` there; `none` direction).
    let fields = with_field(base, "dimension", Some("4"));
    let fields = with_field(&fields, "sizes", Some("1 7 5 9"));
    let fields4 = with_field(&fields, "spacings", Some("nan 0.5 1.25 2"));
    let p = dir.file(
        "4d-first.nrrd",
        &[nrrd_header(&fields4).into_bytes(), le.clone()].concat(),
    );
    let opened = check("4-D, size-1 first axis, spacings", &p, &want);
    assert_eq!(opened.info.spacing, SYN_SPACING);
    let fields4 = with_field(&fields, "spacings", None);
    let fields4 = with_field(
        &fields4,
        "space directions",
        Some("none (0.5,0,0) (0,1.25,0) (0,0,2)"),
    );
    let p = dir.file(
        "4d-none.nrrd",
        &[nrrd_header(&fields4).into_bytes(), le.clone()].concat(),
    );
    let opened = check("4-D, size-1 first axis, space directions", &p, &want);
    assert_eq!(opened.info.spacing, SYN_SPACING);

    // 4-D with three volumes along the slowest axis: the first opens.
    let others = [
        synthetic(SampleType::U16, SYN_DIMS, SYN_SPACING, 23),
        synthetic(SampleType::U16, SYN_DIMS, SYN_SPACING, 24),
    ];
    let fields = with_field(base, "dimension", Some("4"));
    let fields = with_field(&fields, "sizes", Some("7 5 9 3"));
    let fields = with_field(&fields, "spacings", Some("0.5 1.25 2 nan"));
    let mut file = nrrd_header(&fields).into_bytes();
    file.extend_from_slice(&le);
    file.extend(le_bytes(&others[0]));
    file.extend(le_bytes(&others[1]));
    let p = dir.file("4d-slowest.nrrd", &file);
    let opened = check("4-D, 3 volumes", &p, &want);
    assert!(
        opened
            .info
            .notes
            .iter()
            .any(|n| n.contains("3 volumes") && n.contains("first")),
        "notes: {:?}",
        opened.info.notes
    );
}

#[test]
fn nifti_4d_opens_the_first_volume() {
    let dir = TempDir::new("nifti-4d");
    let vols: Vec<AnyVolume> = (0..3)
        .map(|k| synthetic(SampleType::I16, SYN_DIMS, SYN_SPACING, 60 + k))
        .collect();
    let data: Vec<u8> = vols.iter().flat_map(le_bytes).collect();
    let mut h = NiiHeader::new(SYN_DIMS, SYN_SPACING, SampleType::I16, Endian::Little);
    h.dim[0] = 4;
    h.dim[4] = 3;
    h.pixdim[4] = 2.5; // repetition time
    let file = h.file(&data);
    for (name, bytes) in [("4d.nii", file.clone()), ("4d.nii.gz", gzip(&dir, &file))] {
        let p = dir.file(name, &bytes);
        let opened = open(&p);
        check_opened(name, &opened, &vols[0], FileFormat::Nifti, SampleType::I16);
        assert!(
            opened
                .info
                .notes
                .iter()
                .any(|n| n.contains("3 volumes") && n.contains("first")),
            "{name}: notes {:?}",
            opened.info.notes
        );
    }
    // dim[0] = 3 ignores dim[4..]: one volume, no note.
    let mut h3 = h.clone();
    h3.dim[0] = 3;
    let p = dir.file("3d-with-dim4.nii", &h3.file(&data));
    let opened = open(&p);
    assert_same_volume("dim[0] = 3", &opened.volume, &vols[0]);
    assert!(
        opened.info.notes.is_empty(),
        "notes {:?}",
        opened.info.notes
    );
    // Non-finite or zero pixdim: spacing 1 there, with a note.
    let mut hn = NiiHeader::new(SYN_DIMS, SYN_SPACING, SampleType::I16, Endian::Little);
    hn.pixdim[2] = f32::NAN;
    hn.pixdim[3] = 0.0;
    let p = dir.file("nan-pixdim.nii", &hn.file(&le_bytes(&vols[0])));
    let opened = open(&p);
    assert_eq!(opened.info.spacing, Vec3::new(0.5, 1.0, 1.0));
    assert!(
        !opened.info.notes.is_empty(),
        "a note on the replaced spacing"
    );
}

// ---------------------------------------------------------- malformed files

/// One malformed file: its name, bytes, extra files next to it, raw options,
/// the substrings its error must contain and the file name the error must
/// name (the file itself unless given).
struct Case {
    what: &'static str,
    file: &'static str,
    bytes: Vec<u8>,
    extra: Vec<(&'static str, Vec<u8>)>,
    raw: Option<RawOptions>,
    expect: Vec<String>,
    names: Option<&'static str>,
}

fn case(what: &'static str, file: &'static str, bytes: Vec<u8>, expect: &[&str]) -> Case {
    Case {
        what,
        file,
        bytes,
        extra: Vec::new(),
        raw: None,
        expect: expect.iter().map(|s| s.to_string()).collect(),
        names: None,
    }
}

fn raw_case(what: &'static str, bytes: Vec<u8>, raw: RawOptions, expect: &[&str]) -> Case {
    Case {
        raw: Some(raw),
        ..case(what, "bad.raw", bytes, expect)
    }
}

/// Opens `path` (with `raw` options if given) expecting an error; returns
/// the message, or a description of what went wrong instead.
fn error_of(path: &Path, raw: Option<RawOptions>) -> Result<String, String> {
    let options = OpenOptions {
        raw,
        ..OpenOptions::default()
    };
    match catch_unwind(AssertUnwindSafe(|| fmt::open_file(path, &options))) {
        Err(p) => Err(format!(
            "PANIC: {}",
            p.downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| p.downcast_ref::<&str>().copied())
                .unwrap_or("?")
        )),
        Ok(Ok(o)) => Err(format!(
            "opened as {} {:?} {}",
            o.info.format, o.info.dims, o.info.stored_type
        )),
        Ok(Err(e)) => Ok(e.to_string()),
    }
}

fn malformed_cases(dir: &TempDir) -> Vec<Case> {
    let u8_data = vec![7u8; 315];
    let hdr = nrrd_header(NRRD_U8);
    let h = hdr.len();
    let nrrd = |fields: &[(&str, &str)], data: &[u8]| {
        [nrrd_header(fields).into_bytes(), data.to_vec()].concat()
    };
    let nrrd_with = |key: &'static str, value: Option<&'static str>| {
        nrrd(&with_field(NRRD_U8, key, value), &u8_data)
    };
    let skip_file = nrrd_with("byte skip", Some("100"));
    let skip_h = header_end(&skip_file).expect("header end");
    let gz_fields = with_field(NRRD_U8, "encoding", Some("gzip"));
    let gz_315 = gzip(dir, &u8_data);
    let nii = |f: &dyn Fn(&mut NiiHeader), data_len: usize| {
        let mut h = NiiHeader::new(SYN_DIMS, SYN_SPACING, SampleType::I16, Endian::Little);
        f(&mut h);
        h.file(&vec![1u8; data_len])
    };
    let nii_ok = nii(&|_| {}, 630);
    let vol = |dims: [u32; 3], spacing: [f32; 3], layout: u8, extra: u8, data: usize| {
        [vol_header(dims, spacing, layout, extra), vec![9u8; data]].concat()
    };
    let raw = |dims: [u32; 3], ty: SampleType| {
        RawOptions::new(UVec3::from_array(dims), ty, Endian::Little)
    };
    let leak = |s: String| -> &'static str { Box::leak(s.into_boxed_str()) };

    let mut cases = vec![
        // ---- NRRD
        case(
            "nrrd: empty file",
            "bad.nrrd",
            vec![],
            &["not an NRRD file"],
        ),
        case(
            "nhdr: empty file",
            "bad.nhdr",
            vec![],
            &["not an NRRD file"],
        ),
        case(
            "nrrd: truncated data",
            "bad.nrrd",
            [hdr.as_bytes(), &u8_data[..100]].concat(),
            &[
                leak(format!("expected {} bytes", h + 315)),
                leak(format!("found {}", h + 100)),
            ],
        ),
        case(
            "nrrd: truncated header, mid-line",
            "bad.nrrd",
            b"NRRD0004\ntype: uchar\ndimensi".to_vec(),
            &["malformed header line", "dimensi"],
        ),
        case(
            "nrrd: truncated header, at a line end",
            "bad.nrrd",
            b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 7 5 9\n".to_vec(),
            &["missing field \"encoding\""],
        ),
        case(
            "nrrd: missing sizes",
            "bad.nrrd",
            nrrd_with("sizes", None),
            &["missing field \"sizes\""],
        ),
        case(
            "nrrd: missing type",
            "bad.nrrd",
            nrrd_with("type", None),
            &["missing field \"type\""],
        ),
        case(
            "nrrd: sizes do not match dimension",
            "bad.nrrd",
            nrrd_with("sizes", Some("7 5")),
            &["dimension is 3 but sizes has 2 entries"],
        ),
        case(
            "nrrd: zero size",
            "bad.nrrd",
            nrrd_with("sizes", Some("7 0 9")),
            &["sizes must be positive"],
        ),
        case(
            "nrrd: negative size",
            "bad.nrrd",
            nrrd_with("sizes", Some("7 -5 9")),
            &["sizes must be positive"],
        ),
        case(
            "nrrd: 5-D",
            "bad.nrrd",
            nrrd(
                &with_field(
                    &with_field(NRRD_U8, "dimension", Some("5")),
                    "sizes",
                    Some("7 5 9 1 1"),
                ),
                &u8_data,
            ),
            &["unsupported", "5-dimensional"],
        ),
        case(
            "nrrd: type double",
            "bad.nrrd",
            nrrd_with("type", Some("double")),
            &["unsupported", "\"double\""],
        ),
        case(
            "nrrd: type int",
            "bad.nrrd",
            nrrd_with("type", Some("int")),
            &["unsupported", "\"int\""],
        ),
        case(
            "nrrd: encoding ascii",
            "bad.nrrd",
            nrrd_with("encoding", Some("ascii")),
            &["unsupported", "\"ascii\""],
        ),
        case(
            "nrrd: encoding bzip2",
            "bad.nrrd",
            nrrd_with("encoding", Some("bzip2")),
            &["unsupported", "\"bzip2\""],
        ),
        case(
            "nrrd: no endian for a 2-byte type",
            "bad.nrrd",
            nrrd(&with_field(NRRD_U8, "type", Some("short")), &[0; 630]),
            &["endian"],
        ),
        case(
            "nrrd: corrupt gzip stream",
            "bad.nrrd",
            nrrd(
                &gz_fields,
                b"\x1f\x8b\x08\x00 this is not deflate data at all",
            ),
            &["gzip"],
        ),
        case(
            "nrrd: not gzip at all",
            "bad.nrrd",
            nrrd(&gz_fields, b"plain text where gzip should be"),
            &["gzip"],
        ),
        case(
            "nrrd: truncated gzip stream",
            "bad.nrrd",
            nrrd(&gz_fields, &gz_315[..gz_315.len() / 2]),
            &["gzip"],
        ),
        case(
            "nrrd: gzip decodes to too few bytes",
            "bad.nrrd",
            nrrd(&gz_fields, &gzip(dir, &u8_data[..100])),
            &["expected 315 bytes", "found 100"],
        ),
        case(
            "nrrd: NaN in space directions",
            "bad.nrrd",
            nrrd(
                &with_field(
                    &with_field(NRRD_U8, "spacings", None),
                    "space directions",
                    Some("(NaN,0,0) (0,1,0) (0,0,1)"),
                ),
                &u8_data,
            ),
            &["spacing X is NaN"],
        ),
        case(
            "nrrd: zero space direction",
            "bad.nrrd",
            nrrd(
                &with_field(
                    &with_field(NRRD_U8, "spacings", None),
                    "space directions",
                    Some("(1,0,0) (0,1,0) (0,0,0)"),
                ),
                &u8_data,
            ),
            &["spacing Z is 0"],
        ),
        case(
            "nrrd: malformed space directions",
            "bad.nrrd",
            nrrd(
                &with_field(
                    &with_field(NRRD_U8, "spacings", None),
                    "space directions",
                    Some("(1,0,0) (0,1,0)"),
                ),
                &u8_data,
            ),
            &["space directions"],
        ),
        case(
            "nrrd: byte skip past the data",
            "bad.nrrd",
            skip_file.clone(),
            &[
                leak(format!("expected {} bytes", skip_h + 100 + 315)),
                leak(format!("found {}", skip_file.len())),
            ],
        ),
        case(
            "nrrd: line skip past the end",
            "bad.nrrd",
            nrrd_with("line skip", Some("1000")),
            &["line skip"],
        ),
        case(
            "nrrd: data split over files",
            "bad.nrrd",
            nrrd_with("data file", Some("LIST")),
            &["unsupported", "several files"],
        ),
        Case {
            names: Some("gone.raw"),
            ..case(
                "nhdr: detached data file missing",
                "bad.nhdr",
                nrrd_header(&with_field(NRRD_U8, "data file", Some("gone.raw"))).into_bytes(),
                &[],
            )
        },
        Case {
            extra: vec![("short.raw", vec![0u8; 200])],
            names: Some("short.raw"),
            ..case(
                "nhdr: detached data file too short",
                "bad.nhdr",
                nrrd_header(&with_field(NRRD_U8, "data file", Some("short.raw"))).into_bytes(),
                &["expected 315 bytes", "found 200"],
            )
        },
        // ---- NIfTI
        case("nii: empty file", "bad.nii", vec![], &["348"]),
        case(
            "nii: truncated header",
            "bad.nii",
            nii_ok[..200].to_vec(),
            &["200 bytes", "348"],
        ),
        case(
            "nii: truncated data",
            "bad.nii",
            nii_ok[..352 + 100].to_vec(),
            &["expected 982 bytes", "found 452"],
        ),
        case(
            "nii: dim[0] = 0",
            "bad.nii",
            nii(&|h| h.dim[0] = 0, 630),
            &["dim[0] is 0"],
        ),
        case(
            "nii: dim[0] = -3",
            "bad.nii",
            nii(&|h| h.dim[0] = -3, 630),
            &["dim[0] is -3"],
        ),
        case(
            "nii: dim[0] = 8",
            "bad.nii",
            nii(&|h| h.dim[0] = 8, 630),
            &["dim[0] is 8"],
        ),
        case(
            "nii: negative dimension",
            "bad.nii",
            nii(&|h| h.dim[2] = -5, 630),
            &["7x-5x9"],
        ),
        case(
            "nii: zero dimension",
            "bad.nii",
            nii(&|h| h.dim[3] = 0, 630),
            &["7x5x0"],
        ),
        case(
            "nii: datatype 64 FLOAT64",
            "bad.nii",
            nii(&|h| (h.datatype, h.bitpix) = (64, 64), 2520),
            &["unsupported", "FLOAT64"],
        ),
        case(
            "nii: datatype 8 INT32",
            "bad.nii",
            nii(&|h| (h.datatype, h.bitpix) = (8, 32), 1260),
            &["unsupported", "INT32"],
        ),
        case(
            "nii: datatype 128 RGB24",
            "bad.nii",
            nii(&|h| (h.datatype, h.bitpix) = (128, 24), 945),
            &["unsupported", "RGB24"],
        ),
        case(
            "nii: unknown datatype",
            "bad.nii",
            nii(&|h| h.datatype = 3, 630),
            &["unsupported", "datatype 3"],
        ),
        case(
            "nii: wrong sizeof_hdr",
            "bad.nii",
            nii(&|h| h.sizeof_hdr = 540, 630),
            &["sizeof_hdr"],
        ),
        case(
            "nii: wrong magic",
            "bad.nii",
            nii(&|h| h.magic = *b"n+2\0", 630),
            &["magic"],
        ),
        case(
            "nii: two-file magic in a .nii",
            "bad.nii",
            nii(&|h| h.magic = *b"ni1\0", 630),
            &[".hdr"],
        ),
        case(
            "nii: vox_offset inside the header",
            "bad.nii",
            nii(&|h| h.vox_offset = 100.0, 630),
            &["vox_offset 100"],
        ),
        case(
            "nii: vox_offset NaN",
            "bad.nii",
            nii(&|h| h.vox_offset = f32::NAN, 630),
            &["vox_offset NaN"],
        ),
        case(
            "nii: vox_offset past the end",
            "bad.nii",
            nii(&|h| h.vox_offset = 4096.0, 630),
            &["expected 4726 bytes", "found 982"],
        ),
        case(
            "nii: vox_offset 1e30",
            "bad.nii",
            nii(&|h| h.vox_offset = 1e30, 630),
            &["expected"],
        ),
        case("nii.gz: empty file", "bad.nii.gz", vec![], &[]),
        case(
            "nii.gz: corrupt gzip stream",
            "bad.nii.gz",
            b"\x1f\x8b\x08\x00 this is not deflate data at all".to_vec(),
            &["header"],
        ),
        case(
            "nii.gz: truncated gzip stream",
            "bad.nii.gz",
            {
                let gz = gzip(dir, &nii(&|_| {}, 630));
                gz[..gz.len() * 2 / 3].to_vec()
            },
            &[],
        ),
        case(
            "nii.gz: truncated data",
            "bad.nii.gz",
            gzip(dir, &nii_ok[..352 + 100]),
            &["expected 982 bytes", "found 452", "decompressed"],
        ),
        case(
            "nii.gz: vox_offset 1e30",
            "bad.nii.gz",
            gzip(dir, &nii(&|h| h.vox_offset = 1e30, 630)),
            &["expected"],
        ),
        case(
            "nii.gz: huge dimensions, tiny stream",
            "bad.nii.gz",
            gzip(
                dir,
                &nii(
                    &|h| {
                        h.dim = [3, 32767, 32767, 32767, 1, 1, 1, 1];
                        (h.datatype, h.bitpix) = (16, 32);
                    },
                    630,
                ),
            ),
            // Rejected before decoding: gzip cannot expand that far.
            &["140724603846652 bytes", "more than"],
        ),
        case(
            "nii: huge dimensions",
            "bad.nii",
            nii(&|h| h.dim = [3, 32767, 32767, 32767, 1, 1, 1, 1], 630),
            &["expected", "found 982"],
        ),
        case(
            "nrrd: gzip, huge sizes, tiny stream",
            "bad.nrrd",
            nrrd(
                &with_field(&gz_fields, "sizes", Some("100000 100000 100000")),
                &gz_315,
            ),
            &["1000000000000000 bytes", "more than"],
        ),
        // ---- .vol (SPEC §1)
        case(
            "vol: empty file",
            "bad.vol",
            vec![],
            &["0 bytes", "26-byte header"],
        ),
        case(
            "vol: truncated header",
            "bad.vol",
            vol_header([7, 5, 9], [1.0; 3], 1, 0)[..10].to_vec(),
            &["10 bytes", "26-byte header"],
        ),
        case(
            "vol: truncated data",
            "bad.vol",
            vol([7, 5, 9], [1.0; 3], 1, 0, 100),
            &["expected 341 bytes", "found 126"],
        ),
        case(
            "vol: one byte too many",
            "bad.vol",
            vol([7, 5, 9], [1.0; 3], 1, 0, 316),
            &["expected 341 bytes", "found 342"],
        ),
        case(
            "vol: zero dimension",
            "bad.vol",
            vol([7, 0, 9], [1.0; 3], 1, 0, 0),
            &["dimension Y is 0"],
        ),
        case(
            "vol: NaN spacing",
            "bad.vol",
            vol([7, 5, 9], [f32::NAN, 1.0, 1.0], 1, 0, 315),
            &["spacing X is NaN"],
        ),
        case(
            "vol: negative spacing",
            "bad.vol",
            vol([7, 5, 9], [1.0, 1.0, -1.0], 1, 0, 315),
            &["spacing Z is -1"],
        ),
        case(
            "vol: unknown layout",
            "bad.vol",
            vol([7, 5, 9], [1.0; 3], 3, 0, 315),
            &["unknown layout byte 3"],
        ),
        case(
            "vol: brick side 1",
            "bad.vol",
            vol([7, 5, 9], [1.0; 3], 2, 1, 315),
            &["brick side 1"],
        ),
        case(
            "vol: bricked, truncated",
            "bad.vol",
            vol([7, 5, 9], [1.0; 3], 2, 4, 100),
            &["expected", "bricks of 4^3", "found 126"],
        ),
        case(
            "vol: dimensions overflow",
            "bad.vol",
            vol([u32::MAX; 3], [1.0; 3], 1, 0, 0),
            &["overflow"],
        ),
        case(
            "vol: UC Davis header, truncated",
            "bad.vol",
            {
                let mut b = DavisHeader {
                    dims: SYN_DIMS,
                    border: 0,
                    spacing: Vec3::ONE,
                }
                .to_bytes()
                .to_vec();
                b.extend_from_slice(&[1u8; 100]);
                b
            },
            &[],
        ),
        // ---- raw
        raw_case(
            "raw: dims larger than the file",
            vec![0; 315],
            raw([7, 5, 10], SampleType::U8),
            &["expected 350 bytes", "found 315"],
        ),
        raw_case(
            "raw: dims smaller than the file",
            vec![0; 315],
            raw([7, 5, 8], SampleType::U8),
            &["expected 280 bytes", "found 315"],
        ),
        raw_case(
            "raw: 2-byte type, half the bytes",
            vec![0; 315],
            raw([7, 5, 9], SampleType::U16),
            &["expected 630 bytes", "found 315"],
        ),
        raw_case(
            "raw: empty file",
            vec![],
            raw([7, 5, 9], SampleType::U8),
            &["expected 315 bytes", "found 0"],
        ),
        raw_case(
            "raw: zero dimension",
            vec![0; 315],
            raw([7, 5, 0], SampleType::U8),
            &["dimension Z is 0"],
        ),
        raw_case(
            "raw: NaN spacing",
            vec![0; 315],
            RawOptions {
                spacing: Vec3::new(1.0, f32::NAN, 1.0),
                ..raw([7, 5, 9], SampleType::U8)
            },
            &["spacing Y is NaN"],
        ),
        raw_case(
            "raw: infinite spacing",
            vec![0; 315],
            RawOptions {
                spacing: Vec3::new(1.0, 1.0, f32::INFINITY),
                ..raw([7, 5, 9], SampleType::U8)
            },
            &["spacing Z is inf"],
        ),
        raw_case(
            "raw: offset past the end",
            vec![0; 315],
            RawOptions {
                offset: 1000,
                ..raw([7, 5, 9], SampleType::U8)
            },
            &["expected 1315 bytes", "found 315"],
        ),
        raw_case(
            "raw: offset near u64::MAX",
            vec![0; 315],
            RawOptions {
                offset: u64::MAX - 5,
                ..raw([7, 5, 9], SampleType::U8)
            },
            &[],
        ),
        raw_case(
            "raw: sizes overflow",
            vec![0; 315],
            raw([1 << 30, 1 << 30, 1 << 30], SampleType::F32),
            &["overflow"],
        ),
        case(
            "raw: no description",
            "bad.raw",
            vec![0; 315],
            &["--raw-dims"],
        ),
        case(
            "unknown extension",
            "bad.xyz",
            vec![0; 315],
            &["unrecognised", ".xyz"],
        ),
    ];
    // UC Davis bytes that cannot be any format under the .vol extension.
    cases.push(case(
        "vol: random 27 bytes",
        "bad.vol",
        (0..27u8).collect(),
        &["unknown layout byte 24"],
    ));
    cases
}

#[test]
fn malformed_files_give_one_line_errors_naming_the_file() {
    let dir = TempDir::new("malformed");
    let mut failures = Vec::new();
    for (i, c) in malformed_cases(&dir).into_iter().enumerate() {
        // Each case in its own directory: extra files don't leak between cases.
        let sub = dir.join(&format!("case{i}"));
        std::fs::create_dir_all(&sub).unwrap();
        let path = sub.join(c.file);
        std::fs::write(&path, &c.bytes).unwrap();
        for (name, bytes) in &c.extra {
            std::fs::write(sub.join(name), bytes).unwrap();
        }
        let msg = match error_of(&path, c.raw.clone()) {
            Ok(m) => m,
            Err(e) => {
                failures.push(format!("{}: {e}", c.what));
                continue;
            }
        };
        let name = c.names.unwrap_or(c.file);
        let mut problems = Vec::new();
        if msg.contains('\n') || msg.trim().is_empty() {
            problems.push("not one line".to_string());
        }
        if !msg.contains(name) {
            problems.push(format!("does not name {name}"));
        }
        for e in &c.expect {
            if !msg.contains(e.as_str()) {
                problems.push(format!("lacks \"{e}\""));
            }
        }
        if !problems.is_empty() {
            failures.push(format!(
                "{}: {} — error was: {msg}",
                c.what,
                problems.join(", ")
            ));
        }
    }
    // A missing file, and a directory given as a raw file.
    let missing = dir.join("missing.nrrd");
    match error_of(&missing, None) {
        Ok(m) if m.contains("missing.nrrd") && !m.contains('\n') => {}
        other => failures.push(format!("missing file: {other:?}")),
    }
    let raw = RawOptions::new(SYN_DIMS, SampleType::U8, Endian::Little);
    match error_of(&dir.0, Some(raw)) {
        Ok(m) if m.contains("directory") && !m.contains('\n') => {}
        other => failures.push(format!("directory as raw: {other:?}")),
    }
    assert!(
        failures.is_empty(),
        "{} case(s) failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

// -------------------------------------------------------------------- fuzz

/// Valid small files of every format, to mutate: (file name, bytes, raw
/// options, whether the header is text).
fn fuzz_seeds(dir: &TempDir) -> Vec<(&'static str, Vec<u8>, Option<RawOptions>, bool)> {
    let u8v = synthetic(SampleType::U8, SYN_DIMS, SYN_SPACING, 90);
    let i16v = synthetic(SampleType::I16, SYN_DIMS, SYN_SPACING, 91);
    let f32v = synthetic(SampleType::F32, SYN_DIMS, SYN_SPACING, 92);
    let written = |name: &str, f: &dyn Fn(&Path)| {
        let p = dir.join(name);
        f(&p);
        std::fs::read(&p).unwrap()
    };
    let nrrd_raw = written("seed.nrrd", &|p| {
        nrrd::write(
            p,
            SYN_DIMS,
            SYN_SPACING,
            SampleType::I16,
            &le_bytes(&i16v),
            Encoding::Raw,
        )
        .unwrap()
    });
    let nrrd_gz = written("seed-gz.nrrd", &|p| {
        nrrd::write(
            p,
            SYN_DIMS,
            SYN_SPACING,
            SampleType::U8,
            &le_bytes(&u8v),
            Encoding::Gzip,
        )
        .unwrap()
    });
    let nii = written("seed.nii", &|p| {
        nifti::write(
            p,
            SYN_DIMS,
            SYN_SPACING,
            SampleType::I16,
            &le_bytes(&i16v),
            None,
        )
        .unwrap()
    });
    let mut be = NiiHeader::new(SYN_DIMS, SYN_SPACING, SampleType::F32, Endian::Big);
    be.slope = 2.0;
    let nii_be = be.file(&samples::encode_volume(
        &f32v,
        AxisOrder::XFast,
        Endian::Big,
    ));
    let nii_gz = written("seed.nii.gz", &|p| {
        let r = Rescale {
            slope: 2.0,
            intercept: 1.0,
        };
        nifti::write(
            p,
            SYN_DIMS,
            SYN_SPACING,
            SampleType::F32,
            &le_bytes(&f32v),
            Some(r),
        )
        .unwrap()
    });
    let vol_linear = written("seed.vol", &|p| {
        vol::write(p, as_linear_u8(&u8v), VolLayout::Linear).unwrap()
    });
    let vol_bricked = written("seed-b.vol", &|p| {
        vol::write(p, as_linear_u8(&u8v), VolLayout::Bricked { side: 4 }).unwrap()
    });
    let mut davis = DavisHeader {
        dims: SYN_DIMS,
        border: 1,
        spacing: SYN_SPACING,
    }
    .to_bytes()
    .to_vec();
    davis.extend(samples::encode_volume(&u8v, AxisOrder::ZFast, Endian::Big));
    // A detached header whose data file sits next to it.
    dir.file("fuzz-data.raw", &le_bytes(&i16v));
    let nhdr = nrrd_header(&[
        ("type", "short"),
        ("dimension", "3"),
        ("sizes", "7 5 9"),
        ("space directions", "(0.5,0,0) (0,1.25,0) (0,0,2)"),
        ("endian", "little"),
        ("encoding", "raw"),
        ("data file", "fuzz-data.raw"),
        ("byte skip", "0"),
    ])
    .into_bytes();
    let raw = RawOptions::new(SYN_DIMS, SampleType::I16, Endian::Big);
    vec![
        ("fuzz.nrrd", nrrd_raw, None, true),
        ("fuzz.nrrd", nrrd_gz, None, true),
        ("fuzz.nhdr", nhdr, None, true),
        ("fuzz.nii", nii, None, false),
        ("fuzz.nii", nii_be, None, false),
        ("fuzz.nii.gz", nii_gz, None, false),
        ("fuzz.vol", vol_linear, None, false),
        ("fuzz.vol", vol_bricked, None, false),
        ("fuzz.vol", davis, None, false),
        ("fuzz.raw", le_bytes(&i16v), Some(raw), false),
    ]
}

/// Values that break naive header parsing.
const TRICKY: &[&str] = &[
    "0",
    "-1",
    "1",
    "2147483648",
    "4294967296",
    "18446744073709551615",
    "99999999999999999999999",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e40",
    "-0",
    "",
    " ",
    "(1,0,0)",
    "none",
    "LIST",
    "gzip",
    "big",
    "double",
    "7 5",
    "7 5 9 3",
    "1 7 5 9",
    "0.5 1.25 2",
    "(nan,0,0) (0,1,0) (0,0,1)",
    "..",
    "/",
    "fuzz-data.raw",
];

/// A random mutation of `seed`.
fn mutate(rng: &mut fastrand::Rng, seed: &[u8], text: bool) -> Vec<u8> {
    let mut b = seed.to_vec();
    match rng.u8(0..6) {
        // Random bytes of a random length.
        0 => (0..rng.usize(0..600)).map(|_| rng.u8(..)).collect(),
        // Truncated.
        1 => {
            b.truncate(rng.usize(0..=b.len()));
            b
        }
        // A few random bytes flipped, mostly in the header.
        2 => {
            for _ in 0..rng.usize(1..6) {
                let end = if rng.bool() {
                    b.len().min(360)
                } else {
                    b.len()
                };
                if end > 0 {
                    let i = rng.usize(0..end);
                    b[i] = rng.u8(..);
                }
            }
            b
        }
        // A header field's value replaced by a tricky one (text), or an
        // aligned 2- or 4-byte header word set to an extreme (binary).
        3 | 4 if text => {
            let Some(end) = header_end(&b) else { return b };
            let head = String::from_utf8_lossy(&b[..end]).into_owned();
            let mut lines: Vec<String> = head.lines().map(str::to_string).collect();
            let n = lines.len().saturating_sub(1).max(1);
            let i = 1 + rng.usize(0..n);
            if let Some(line) = lines.get_mut(i)
                && let Some((k, _)) = line.split_once(": ")
            {
                *line = format!("{k}: {}", TRICKY[rng.usize(0..TRICKY.len())]);
            }
            if rng.u8(0..4) == 0 {
                // Sometimes an extra field.
                let keys = [
                    "byte skip",
                    "line skip",
                    "dimension",
                    "sizes",
                    "endian",
                    "data file",
                    "spacings",
                    "encoding",
                ];
                let k = keys[rng.usize(0..keys.len())];
                lines.insert(1, format!("{k}: {}", TRICKY[rng.usize(0..TRICKY.len())]));
            }
            let mut out = lines.join("\n").into_bytes();
            out.extend_from_slice(b"\n\n");
            out.extend_from_slice(&b[end..]);
            out
        }
        3 | 4 => {
            let words: [u32; 8] = [
                0,
                1,
                u32::MAX,
                0x7fff_ffff,
                0x8000_0000,
                0x7fc0_0000, // NaN
                0x7f80_0000, // inf
                0x4f80_0000, // 2^32 as f32
            ];
            let w = words[rng.usize(0..words.len())].to_le_bytes();
            let limit = b.len().min(352);
            if limit >= 4 {
                let i = rng.usize(0..limit / 2) * 2;
                let k = (if rng.bool() { 2 } else { 4 }).min(limit - i);
                let from = if rng.bool() { 0 } else { 4 - k };
                b[i..i + k].copy_from_slice(&w[from..from + k]);
            }
            b
        }
        // Garbage appended.
        _ => {
            b.extend((0..rng.usize(1..64)).map(|_| rng.u8(..)));
            b
        }
    }
}

#[test]
fn random_and_mutated_files_never_panic() {
    let dir = TempDir::new("fuzz");
    let mut rng = fastrand::Rng::with_seed(0x5EED_F11E);
    let mut failures = Vec::new();
    let mut opened = 0;
    let dir_name = dir.0.display().to_string();
    for (name, seed, raw, text) in fuzz_seeds(&dir) {
        // The unmutated seed opens.
        let p = dir.file(name, &seed);
        let options = OpenOptions {
            raw: raw.clone(),
            ..OpenOptions::default()
        };
        if let Err(e) = fmt::open_file(&p, &options) {
            failures.push(format!("seed {name} does not open: {e}"));
        }
        for i in 0..300 {
            let bytes = mutate(&mut rng, &seed, text);
            std::fs::write(&p, &bytes).unwrap();
            let result = catch_unwind(AssertUnwindSafe(|| {
                fmt::open_file(&p, &options).map(|o| {
                    // Whatever opens must be readable throughout.
                    let scene = Scene::new(o.volume);
                    scene.value_range()
                })
            }));
            let show = || {
                let n = bytes.len().min(96);
                format!(
                    "{name} #{i} ({} bytes, first {n}: {:?})",
                    bytes.len(),
                    String::from_utf8_lossy(&bytes[..n])
                )
            };
            match result {
                Err(_) => failures.push(format!("PANIC on {}", show())),
                Ok(Ok(_)) => opened += 1,
                Ok(Err(e)) => {
                    let m = e.to_string();
                    if m.contains('\n') {
                        failures.push(format!("multi-line error on {}: {m}", show()));
                    }
                    // A detached header's errors may name its (mutated) data file.
                    let detached = name.ends_with(".nhdr") && m.contains(dir_name.as_str());
                    if !m.contains(name) && !detached {
                        failures.push(format!("error without the file name on {}: {m}", show()));
                    }
                }
            }
        }
    }
    assert!(
        opened > 0,
        "no mutated file opened at all: the mutations are too harsh"
    );
    assert!(
        failures.is_empty(),
        "{} failure(s):\n{}",
        failures.len(),
        failures.join("\n")
    );
}
