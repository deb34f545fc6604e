//! The real volumes in /work/shared/data: the FLAIR NRRD and
//! the MNI NIfTI read right (probe voxels, slice sums, every voxel against an
//! independent decoder) and render a plausible head from the default view;
//! wrong readings are caught; written as `.vol` and raw files they render
//! identically.

mod common;

use std::path::{Path, PathBuf};

use common::TempDir;
use common::file_bytes::header_end;
use common::volumes::{
    all_f32, assert_same_volume, le_bytes, open, open_raw, raw_options, voxel_f32,
};
use glam::{UVec3, Vec3};
use raycaster::format::vol::{self, VolLayout};
use raycaster::format::{Endian, FileFormat, raw};
use raycaster::prelude::*;
use raycaster::volume::AxisOrder;

const DATA: &str = "/work/shared/data";

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

// ----------------------------------------------------------------- rendering

const IMAGE: u32 = 96;

/// The command line's default view (framing camera from +z, 45°) at 96×96.
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

// ----------------------------------------------------------------- real data

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
// fastest, as both formats store them: a reader with a transposed axis order or the wrong
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

// --------------------------------------------------------------- round trips

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
        vol::write(&p, original.volume(), layout).expect("write .vol");
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
