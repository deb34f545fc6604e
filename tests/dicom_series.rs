//! The DICOM series reader on a real 40-slice MRI series: header
//! values, slice order by position along the normal (not by file name),
//! mixed directories, malformed files and a render of the head.
//!
//! The root package has no DICOM writer, so the modified files are made by
//! patching bytes of the real (explicit VR little endian) files at elements
//! located by [`find_element`]; the test checks that encoding first.

mod common;

use common::TempDir;

use std::path::{Path, PathBuf};

use glam::{UVec3, Vec3};
use raycaster::format::{FileFormat, OpenOptions, Opened, open_file};
use raycaster::prelude::*;

const SERIES: &str = "/work/shared/data/dicom_mri_series";

// ------------------------------------------------------------------ helpers

/// The series' files sorted by name, or `None` (test skipped) when the data
/// is not there.
fn series_files() -> Option<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(SERIES)
        .ok()?
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "dcm"))
        .collect();
    files.sort();
    if files.len() == 40 {
        Some(files)
    } else {
        eprintln!("SKIPPED: DICOM series not found under {SERIES}");
        None
    }
}

fn open(path: &Path) -> raycaster::Result<Opened> {
    open_file(path, &OpenOptions::default())
}

/// Every sample of a volume as f32, x fastest (a series' storage order).
fn values(v: &AnyVolume) -> Vec<f32> {
    common::volumes::all_f32(v)
}

/// Where the value of element (`group`, `element`) starts in an explicit VR
/// little-endian file, and its length: the first occurrence of the tag
/// followed by `vr`, searched from the end of the preamble. Test-only: good
/// enough for the known files patched here.
fn find_element(bytes: &[u8], group: u16, element: u16, vr: &[u8; 2]) -> (usize, usize) {
    let mut key = Vec::new();
    key.extend_from_slice(&group.to_le_bytes());
    key.extend_from_slice(&element.to_le_bytes());
    key.extend_from_slice(vr);
    let at = bytes[132..]
        .windows(6)
        .position(|w| w == key.as_slice())
        .map(|p| p + 132)
        .unwrap_or_else(|| panic!("element ({group:04X},{element:04X}) not found"));
    let long = matches!(vr, b"OB" | b"OW" | b"SQ" | b"UN" | b"UT");
    if long {
        let len = u32::from_le_bytes(bytes[at + 8..at + 12].try_into().unwrap());
        (at + 12, len as usize)
    } else {
        let len = u16::from_le_bytes(bytes[at + 6..at + 8].try_into().unwrap());
        (at + 8, len as usize)
    }
}

/// A DS (decimal string) element's numbers.
fn ds_values(bytes: &[u8], group: u16, element: u16) -> Vec<f64> {
    let (at, len) = find_element(bytes, group, element, b"DS");
    std::str::from_utf8(&bytes[at..at + len])
        .unwrap()
        .split('\\')
        .map(|s| s.trim().parse().unwrap())
        .collect()
}

/// Rewrites the Series Instance UID's last digit to `digit` (same length).
fn set_series_uid_digit(bytes: &mut [u8], digit: u8) {
    let (at, len) = find_element(bytes, 0x0020, 0x000E, b"UI");
    let last = (at..at + len)
        .rev()
        .find(|&i| bytes[i].is_ascii_digit())
        .unwrap();
    assert_ne!(bytes[last], digit);
    bytes[last] = digit;
}

// ------------------------------------------------------------------ tests

/// The real series: dims, spacing from the headers, type, value range, and
/// every z slice is the pixel data of the file at that position along the
/// normal; one file of the directory opens the same volume.
#[test]
fn real_series_opens_with_header_geometry() {
    let Some(files) = series_files() else { return };
    let opened = open(Path::new(SERIES)).unwrap();
    let info = &opened.info;
    let grid = *opened.volume.grid();
    eprintln!("{info:#?}");

    assert_eq!(info.format, FileFormat::Dicom);
    assert_eq!(info.encoding, "Explicit VR Little Endian");
    assert_eq!(grid.dims, UVec3::new(64, 64, 40));
    assert_eq!(info.dims, grid.dims);
    assert_eq!(info.stored_type, SampleType::I16);
    assert_eq!(opened.volume.sample_type(), SampleType::I16);
    assert_eq!(info.rescale, None);
    assert!(info.notes.is_empty(), "{:?}", info.notes);
    let total: u64 = files.iter().map(|f| f.metadata().unwrap().len()).sum();
    assert_eq!(info.file_bytes, total);

    // Geometry from the headers, read independently here.
    let headers: Vec<Vec<u8>> = files.iter().map(|f| std::fs::read(f).unwrap()).collect();
    let ps = ds_values(&headers[0], 0x0028, 0x0030); // (row, column) spacing
    let o = ds_values(&headers[0], 0x0020, 0x0037);
    let n = [
        o[1] * o[5] - o[2] * o[4],
        o[2] * o[3] - o[0] * o[5],
        o[0] * o[4] - o[1] * o[3],
    ];
    let mut along: Vec<(f64, usize)> = headers
        .iter()
        .enumerate()
        .map(|(i, h)| {
            let p = ds_values(h, 0x0020, 0x0032);
            (p[0] * n[0] + p[1] * n[1] + p[2] * n[2], i)
        })
        .collect();
    along.sort_by(|a, b| a.0.total_cmp(&b.0));
    let gaps: Vec<f64> = along.windows(2).map(|w| w[1].0 - w[0].0).collect();
    let mean_gap = (along[39].0 - along[0].0) / 39.0;
    assert!(
        gaps.iter().all(|g| (g - mean_gap).abs() < 0.01 * mean_gap),
        "{gaps:?}"
    );
    assert!((mean_gap - 3.0).abs() < 0.01, "slice gap {mean_gap}");
    let want = Vec3::new(ps[1] as f32, ps[0] as f32, mean_gap as f32);
    assert!(
        (grid.spacing - want).abs().max_element() < 1e-4,
        "{} vs {want}",
        grid.spacing
    );
    assert_eq!(info.spacing, grid.spacing);
    let orientation = info.orientation.as_deref().unwrap();
    assert!(
        orientation.starts_with("row (0.8663,0.4995,0)"),
        "{orientation}"
    );

    // Slice k of the volume = pixel data of the k-th file along the normal.
    let v = values(&opened.volume);
    for (k, &(_, i)) in along.iter().enumerate() {
        let (at, len) = find_element(&headers[i], 0x7FE0, 0x0010, b"OW");
        assert_eq!(len, 64 * 64 * 2);
        let file_slice: Vec<f32> = headers[i][at..at + len]
            .chunks_exact(2)
            .map(|c| i16::from_le_bytes([c[0], c[1]]) as f32)
            .collect();
        assert!(
            v[k * 4096..(k + 1) * 4096] == file_slice[..],
            "slice {k} is not {}",
            files[i].display()
        );
    }

    // A plausible MR range: non-negative, bright tissue, dark background.
    let (lo, hi) = v
        .iter()
        .fold((f32::MAX, f32::MIN), |(l, h), &x| (l.min(x), h.max(x)));
    eprintln!("value range {lo}..{hi}");
    assert!(lo >= 0.0 && hi > 1000.0 && hi <= 16383.0, "{lo}..{hi}");
    let dark = v.iter().filter(|&&x| x < 0.05 * hi).count() as f64 / v.len() as f64;
    assert!((0.2..0.9).contains(&dark), "dark fraction {dark}");

    // One file of the directory opens the same series.
    let one = open(&files[17]).unwrap();
    assert_eq!(one.info, opened.info);
    assert_eq!(one.volume.grid(), opened.volume.grid());
    assert!(values(&one.volume) == v);
}

/// Slice order comes from positions, not names: the files under shuffled
/// names (plus a stray non-DICOM file) give the identical volume.
#[test]
fn slice_order_does_not_depend_on_file_names() {
    let Some(files) = series_files() else { return };
    let reference = open(Path::new(SERIES)).unwrap();
    let dir = TempDir::new("dicom-shuffled");
    let mut names: Vec<usize> = (0..files.len()).collect();
    fastrand::Rng::with_seed(7).shuffle(&mut names);
    for (f, n) in files.iter().zip(&names) {
        std::fs::copy(f, dir.path().join(format!("slice{n:02}.dcm"))).unwrap();
    }
    std::fs::write(dir.path().join("README.txt"), "not DICOM\n").unwrap();
    let shuffled = open(dir.path()).unwrap();
    assert_eq!(shuffled.volume.grid(), reference.volume.grid());
    assert_eq!(shuffled.info, reference.info);
    assert!(values(&shuffled.volume) == values(&reference.volume));
}

/// A directory with the series and three of its files under another series
/// UID opens the 40-slice series and says so; one of the three opens the
/// 3-slice series.
#[test]
fn mixed_directory_opens_the_largest_series() {
    let Some(files) = series_files() else { return };
    let dir = TempDir::new("dicom-mixed");
    for f in &files {
        std::fs::copy(f, dir.path().join(f.file_name().unwrap())).unwrap();
    }
    for (k, f) in files[10..13].iter().enumerate() {
        let mut bytes = std::fs::read(f).unwrap();
        set_series_uid_digit(&mut bytes, b'0');
        // Names that sort first, so file order would favour them.
        std::fs::write(dir.path().join(format!("0000_other{k}.dcm")), bytes).unwrap();
    }
    let opened = open(dir.path()).unwrap();
    assert_eq!(opened.volume.grid().dims, UVec3::new(64, 64, 40));
    let note = opened.info.notes.join("; ");
    assert!(
        note.contains("2 series") && note.contains("(40 slices)") && note.contains("largest"),
        "{note}"
    );

    let other = open(&dir.path().join("0000_other1.dcm")).unwrap();
    assert_eq!(other.volume.grid().dims, UVec3::new(64, 64, 3));
    assert!((other.volume.grid().spacing.z - 3.0).abs() < 0.01);
    let note = other.info.notes.join("; ");
    assert!(
        note.contains("2 series") && note.contains("(3 slices)"),
        "{note}"
    );
    // Its slices are files 11..13 of the series.
    let full = values(&opened.volume);
    let part = values(&other.volume);
    let start = (0..38)
        .find(|&k| full[k * 4096..(k + 3) * 4096] == part[..])
        .expect("the three slices appear consecutively in the full series");
    assert!(start < 38);
}

/// Makes a bad file's bytes from a good file's.
type Corrupt = fn(Vec<u8>) -> Vec<u8>;

/// How a malformed case is laid out on disk: the directory gets three good
/// slices (files 20..23 of the series) unless `alone`, plus `bad` made from
/// file 1 of the series (or `None` for a case without a bad file).
struct Case {
    name: &'static str,
    /// The bad file's name and how its bytes are made from a good file's.
    bad: Option<(&'static str, Corrupt)>,
    /// Only the bad file (or nothing) in the directory.
    alone: bool,
    /// What the error message must contain besides the file name.
    expect: &'static str,
}

fn truncate_in_header(b: Vec<u8>) -> Vec<u8> {
    b[..1000].to_vec()
}

fn truncate_in_pixels(b: Vec<u8>) -> Vec<u8> {
    b[..b.len() - 1000].to_vec()
}

fn drop_pixel_data(b: Vec<u8>) -> Vec<u8> {
    let (at, _) = find_element(&b, 0x7FE0, 0x0010, b"OW");
    b[..at - 12].to_vec()
}

fn bits_allocated_12(mut b: Vec<u8>) -> Vec<u8> {
    let (at, len) = find_element(&b, 0x0028, 0x0100, b"US");
    assert_eq!(len, 2);
    b[at..at + 2].copy_from_slice(&12u16.to_le_bytes());
    b
}

fn rle_transfer_syntax(mut b: Vec<u8>) -> Vec<u8> {
    let (at, len) = find_element(&b, 0x0002, 0x0010, b"UI");
    assert_eq!(&b[at..at + len], b"1.2.840.10008.1.2.1\0");
    b[at..at + len].copy_from_slice(b"1.2.840.10008.1.2.5\0");
    b
}

fn colour_image(mut b: Vec<u8>) -> Vec<u8> {
    let (at, _) = find_element(&b, 0x0028, 0x0002, b"US");
    b[at..at + 2].copy_from_slice(&3u16.to_le_bytes());
    b
}

fn not_dicom(_: Vec<u8>) -> Vec<u8> {
    b"P5\n64 64\n255\n".to_vec()
}

/// The malformed cases: each must give an `Err` (never a panic) whose
/// one-line message names the offending file (or the directory).
const CASES: &[Case] = &[
    Case {
        name: "file cut inside the header",
        bad: Some(("cut_header.dcm", truncate_in_header)),
        alone: false,
        expect: "cannot read",
    },
    Case {
        name: "file cut inside the pixel data",
        bad: Some(("cut_pixels.dcm", truncate_in_pixels)),
        alone: false,
        expect: "cannot read",
    },
    Case {
        name: "no Pixel Data element",
        bad: Some(("no_pixels.dcm", drop_pixel_data)),
        alone: false,
        expect: "no Pixel Data",
    },
    Case {
        name: "Bits Allocated 12",
        bad: Some(("bits12.dcm", bits_allocated_12)),
        alone: false,
        expect: "Bits Allocated 12",
    },
    Case {
        name: "compressed transfer syntax",
        bad: Some(("rle.dcm", rle_transfer_syntax)),
        alone: false,
        expect: "RLE Lossless",
    },
    Case {
        name: "3 samples per pixel",
        bad: Some(("rgb.dcm", colour_image)),
        alone: false,
        expect: "samples per pixel",
    },
    Case {
        name: "a directory of non-DICOM files",
        bad: Some(("image.pgm", not_dicom)),
        alone: true,
        expect: "no volume file and no DICOM series",
    },
    Case {
        name: "an empty directory",
        bad: None,
        alone: true,
        expect: "empty",
    },
];

#[test]
fn malformed_series_give_errors_naming_the_file() {
    let Some(files) = series_files() else { return };
    for case in CASES {
        let dir = TempDir::new("dicom-bad");
        if !case.alone {
            for f in &files[20..23] {
                std::fs::copy(f, dir.path().join(f.file_name().unwrap())).unwrap();
            }
        }
        let bad_path = case.bad.map(|(name, make)| {
            let p = dir.path().join(name);
            std::fs::write(&p, make(std::fs::read(&files[0]).unwrap())).unwrap();
            p
        });
        // The directory, and the bad file itself, both fail.
        let mut targets = vec![dir.path().to_path_buf()];
        if !case.alone {
            targets.extend(bad_path.clone());
        }
        for target in targets {
            let result = std::panic::catch_unwind(|| open(&target));
            let Ok(result) = result else {
                panic!("{}: panicked opening {}", case.name, target.display());
            };
            let err = match result {
                Ok(o) => panic!("{}: opened {} as {:?}", case.name, target.display(), o.info),
                Err(e) => e.to_string(),
            };
            eprintln!("{}: {err}", case.name);
            assert!(
                !err.contains('\n'),
                "{}: multi-line message {err:?}",
                case.name
            );
            let named = bad_path
                .as_deref()
                .filter(|_| !case.alone)
                .unwrap_or(dir.path());
            let named = named.file_name().unwrap().to_string_lossy();
            assert!(
                err.contains(&*named),
                "{}: {err:?} does not name {named}",
                case.name
            );
            assert!(
                err.contains(case.expect),
                "{}: {err:?} lacks {:?}",
                case.name,
                case.expect
            );
        }
    }
}

/// The head renders: it covers a reasonable part of the frame, and the
/// corners are background.
#[test]
fn series_renders_a_head() {
    if series_files().is_none() {
        return;
    }
    let opened = open(Path::new(SERIES)).unwrap();
    let v = values(&opened.volume);
    let hi = v.iter().copied().fold(f32::MIN, f32::max);
    // A linear ramp: the dark background transparent, tissue opaque.
    let tf = TransferFunction::new(
        Interpolation::Linear,
        vec![
            TfPoint {
                value: 0.05 * hi,
                color: [1.0; 3],
                opacity: 0.0,
            },
            TfPoint {
                value: 0.4 * hi,
                color: [1.0; 3],
                opacity: 0.3,
            },
        ],
    )
    .unwrap();
    let scene = Scene::new(opened.volume);
    // The default view (from +z, the slice normal), moved in so the head
    // fills more of the frame; the volume's corners stay in view.
    let mut camera = Camera::framing(&scene.grid().bounds(), 96, 96, 30.0);
    camera.position = camera.target + (camera.position - camera.target) * 0.75;
    let options = RenderOptions {
        shading: false,
        background: Vec3::ZERO,
        ..RenderOptions::default()
    };
    let frame = SerialRenderer::new()
        .render(&scene, &camera, &tf, &options)
        .unwrap();
    let lit = |x: u32, y: u32| frame.pixel(x, y).iter().any(|&c| c > 40);
    let covered = (0..96)
        .flat_map(|y| (0..96).map(move |x| (x, y)))
        .filter(|&(x, y)| lit(x, y))
        .count();
    let fraction = covered as f64 / (96.0 * 96.0);
    eprintln!("head covers {:.1}% of the frame", 100.0 * fraction);
    assert!((0.15..0.8).contains(&fraction), "head covers {fraction}");
    for (x, y) in [(0, 0), (95, 0), (0, 95), (95, 95), (2, 2), (93, 93)] {
        assert_eq!(frame.pixel(x, y), [0, 0, 0], "corner ({x}, {y})");
    }
    assert!(lit(48, 48), "centre pixel is background");
}

/// The series written as raw samples with the project's own writer and read
/// back as raw renders the same image as the series itself.
#[test]
fn series_and_its_raw_copy_render_identically() {
    if series_files().is_none() {
        return;
    }
    let dir = TempDir::new("raw");
    let opened = open(Path::new(SERIES)).unwrap();
    let raw_path = dir.path().join("series.raw");
    raycaster::format::raw::write(
        &raw_path,
        &opened.volume,
        raycaster::volume::AxisOrder::XFast,
        raycaster::format::Endian::Big,
    )
    .unwrap();
    let mut raw = raycaster::format::RawOptions::new(
        opened.info.dims,
        opened.volume.sample_type(),
        raycaster::format::Endian::Big,
    );
    raw.spacing = opened.info.spacing;
    let copy = open_file(
        &raw_path,
        &OpenOptions {
            raw: Some(raw),
            ..OpenOptions::default()
        },
    )
    .unwrap();
    assert_eq!(values(&copy.volume), values(&opened.volume));
    let render = |v: AnyVolume| {
        let t = v.sample_type();
        let scene = Scene::new(v);
        let tf = TransferFunction::preset_for_data("mr-default", t, scene.value_range()).unwrap();
        let camera = Camera::framing(&scene.grid().bounds(), 64, 64, 40.0);
        SerialRenderer::new()
            .render(&scene, &camera, &tf, &RenderOptions::default())
            .unwrap()
    };
    let (a, b) = (render(opened.volume), render(copy.volume));
    assert_eq!(a.rgb, b.rgb);
    assert!(a.rgb.iter().any(|&c| c > 50), "the image is not blank");
}
