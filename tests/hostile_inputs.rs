//! Files that parse but would make a reader or a renderer run forever or
//! allocate without bound (found by fuzzing, issue 17): each now gives a
//! one-line error, or renders in bounded time, through the public path.
//!
//! Every case runs on its own thread with a deadline, so a regression
//! fails the test instead of hanging the suite.

mod common;

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

use common::TempDir;
use common::file_bytes::{NiiHeader, nrrd_header, vol_header};
use glam::{UVec3, Vec3};
use raycaster::format::{self as fmt, Endian, OpenOptions};
use raycaster::prelude::*;

/// Far longer than any case takes; a hang before the fix never ended.
const DEADLINE: Duration = Duration::from_secs(60);

/// Runs `f` on a thread; panics if it does not finish by the deadline.
fn bounded<T: Send + 'static>(what: &str, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(DEADLINE)
        .unwrap_or_else(|e| panic!("{what}: did not finish in {DEADLINE:?} ({e})"))
}

/// Opens `path` and renders a 16×16 frame with `kind` from the default
/// framing camera (and `step` when given); the error's text on failure.
fn open_and_render(path: PathBuf, kind: RendererKind, step: Option<f32>) -> Result<Frame, String> {
    let opened = fmt::open_file(&path, &OpenOptions::default()).map_err(|e| e.to_string())?;
    let scene = Scene::new(opened.volume);
    let camera = Camera::framing(&scene.grid().bounds(), 16, 16, 30.0);
    let options = RenderOptions {
        step,
        ..RenderOptions::default()
    };
    let tf = TransferFunction::preset("ramp", SampleType::U8).expect("ramp preset");
    kind.renderer(2)
        .map_err(|e| e.to_string())?
        .render(&scene, &camera, &tf, &options)
        .map_err(|e| e.to_string())
}

/// A 6×5×4 volume of varied u8 samples with `spacing`, in three formats.
fn files_with_spacing(dir: &Path, spacing: [f32; 3]) -> Vec<PathBuf> {
    let dims = UVec3::new(6, 5, 4);
    let data: Vec<u8> = (0..120u32).map(|i| (i * 37 % 251) as u8).collect();
    let vol = dir.join("v.vol");
    std::fs::write(
        &vol,
        [vol_header(dims.to_array(), spacing, 1, 0), data.clone()].concat(),
    )
    .unwrap();
    let nii = dir.join("v.nii");
    let header = NiiHeader::new(
        dims,
        Vec3::from_array(spacing),
        SampleType::U8,
        Endian::Little,
    );
    std::fs::write(&nii, header.file(&data)).unwrap();
    let nrrd = dir.join("v.nrrd");
    let head = nrrd_header(&[
        ("type", "uchar"),
        ("dimension", "3"),
        ("sizes", "6 5 4"),
        (
            "spacings",
            &format!("{:e} {:e} {:e}", spacing[0], spacing[1], spacing[2]),
        ),
        ("encoding", "raw"),
    ]);
    std::fs::write(&nrrd, [head.into_bytes(), data].concat()).unwrap();
    vec![vol, nii, nrrd]
}

/// Spacings whose default step would take ~10¹⁶ samples a ray, or whose
/// samples f32 cannot tell apart, hung every renderer: now a one-line
/// error about the step, from every format and renderer; the step it
/// suggests renders.
#[test]
fn extreme_spacings_get_a_step_error_not_a_hang() {
    let dir = TempDir::new("hostile-spacing");
    for spacing in [[1.0, 1.5, 1.8e-15], [1e17, 1e17, 1.0], [1.0, 1.5, 1e-6]] {
        for path in files_with_spacing(&dir.0, spacing) {
            for kind in RendererKind::ALL {
                let what = format!("{} {spacing:?} {kind:?}", path.display());
                let p = path.clone();
                let result = bounded(&what, move || open_and_render(p, kind, None));
                let e = result.err().unwrap_or_else(|| panic!("{what}: rendered"));
                assert!(e.contains("step") && !e.contains('\n'), "{what}: {e}");
            }
        }
    }
    // A step the volume can take renders (the flat volume seen edge-on
    // may cover no pixel; it must finish).
    for path in files_with_spacing(&dir.0, [1.0, 1.5, 1.8e-15]) {
        let what = format!("{} with a step of 0.01", path.display());
        let p = path.clone();
        bounded(&what, move || {
            open_and_render(p, RendererKind::Object, Some(0.01))
        })
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    }
}

/// `line skip` on a data file that never ends (`/dev/zero`) read forever
/// into memory; a data file that is not a regular file is now refused, and
/// skipping past a regular file's end is an error.
#[test]
fn line_skip_is_bounded_by_the_data_file() {
    let dir = TempDir::new("hostile-lineskip");
    let fields = |data_file: &str| {
        nrrd_header(&[
            ("type", "uchar"),
            ("dimension", "3"),
            ("sizes", "2 2 2"),
            ("encoding", "raw"),
            ("line skip", "1"),
            ("data file", data_file),
        ])
    };
    let mut cases = vec![];
    if Path::new("/dev/zero").exists() {
        let nhdr = dir.join("zero.nhdr");
        std::fs::write(&nhdr, fields("/dev/zero")).unwrap();
        cases.push((nhdr, "not a regular file"));
    }
    // A regular data file of one line with no newline.
    std::fs::write(dir.join("one_line.raw"), vec![b'x'; 1 << 16]).unwrap();
    let nhdr = dir.join("long.nhdr");
    std::fs::write(&nhdr, fields("one_line.raw")).unwrap();
    cases.push((nhdr, "line skip passes the end of the file"));
    for (path, expect) in cases {
        let what = path.display().to_string();
        let p = path.clone();
        let e = bounded(&what, move || {
            fmt::open_file(&p, &OpenOptions::default())
                .map(|_| ())
                .map_err(|e| e.to_string())
        })
        .expect_err(&what);
        assert!(e.contains(expect) && !e.contains('\n'), "{what}: {e}");
    }
}

/// A mapped volume whose file another program truncates would crash the
/// process with SIGBUS on the next frame: every renderer now checks the
/// open file first and refuses with an error naming it. A file replaced by
/// renaming a new one over it (how this library writes) keeps rendering
/// the old contents from the still-open file.
#[test]
fn a_mapped_file_changed_on_disk_is_refused_not_a_crash() {
    let dir = TempDir::new("hostile-mapped");
    let dims = [24u32, 20, 16];
    let data: Vec<u8> = (0..24 * 20 * 16u32).map(|i| (i * 7 % 253) as u8).collect();
    let bytes = [vol_header(dims, [1.0; 3], 1, 0), data].concat();
    let options = OpenOptions {
        mode: LoadMode::Map,
        ..OpenOptions::default()
    };
    let tf = TransferFunction::preset("ramp", SampleType::U8).expect("ramp preset");
    let render = |scene: &Scene, kind: RendererKind| {
        let camera = Camera::framing(&scene.grid().bounds(), 24, 24, 30.0);
        kind.renderer(2)
            .expect("renderer")
            .render(scene, &camera, &tf, &RenderOptions::default())
            .map_err(|e| e.to_string())
    };
    let open = |path: &Path| {
        let opened = fmt::open_file(path, &options).expect("open");
        assert_eq!(
            opened.volume.storage_kind(),
            raycaster::storage::StorageKind::Mapped
        );
        Scene::new(opened.volume)
    };

    // Truncated in place.
    let path = dir.join("truncated.vol");
    std::fs::write(&path, &bytes).unwrap();
    let scene = open(&path);
    render(&scene, RendererKind::Serial).expect("before the change");
    std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .unwrap()
        .set_len(100)
        .unwrap();
    for kind in RendererKind::ALL {
        let e = render(&scene, kind).expect_err("truncated");
        assert!(
            e.contains("truncated.vol") && e.contains("changed on disk"),
            "{kind:?}: {e}"
        );
    }

    // Rewritten in place, same length: the skip data would be stale.
    let path = dir.join("rewritten.vol");
    std::fs::write(&path, &bytes).unwrap();
    let scene = open(&path);
    std::thread::sleep(Duration::from_millis(20));
    let mut other = bytes.clone();
    other[26..].iter_mut().for_each(|b| *b = 255 - *b);
    std::fs::write(&path, &other).unwrap();
    let e = render(&scene, RendererKind::Object).expect_err("rewritten");
    assert!(e.contains("rewritten.vol") && e.contains("modified"), "{e}");

    // Replaced by rename: the open file is the old one, intact.
    let path = dir.join("replaced.vol");
    std::fs::write(&path, &bytes).unwrap();
    let scene = open(&path);
    let before = render(&scene, RendererKind::Serial).expect("before");
    let tmp = dir.join("replaced.vol.tmp");
    std::fs::write(&tmp, &other).unwrap();
    std::fs::rename(&tmp, &path).unwrap();
    let after = render(&scene, RendererKind::Serial).expect("after a rename");
    assert_eq!(before.rgb, after.rgb, "the old contents still render");
}

/// `OpenOptions::max_memory` refuses a volume that would be decoded or read
/// into RAM beyond the limit, before allocating, naming the file and both
/// sizes; a mapped file does not count, and the same files open without
/// the limit.
#[test]
fn a_decode_larger_than_the_memory_limit_is_refused() {
    use raycaster::format::save::{SaveOptions, save};
    let dir = TempDir::new("max_memory");
    let grid = Grid::new(UVec3::splat(32), Vec3::ONE);
    let volume = AnyVolume::from_fn(grid, |v| (v.x + v.y + v.z) as u16);
    let vol8 = AnyVolume::from_fn(grid, |v| (v.x ^ v.z) as u8);
    let gz = dir.path().join("ball.nrrd");
    let nii_gz = dir.path().join("ball.nii.gz");
    let vol = dir.path().join("ball.vol");
    let gzip = SaveOptions {
        gzip: true,
        ..SaveOptions::default()
    };
    save(&gz, &volume, &gzip).unwrap();
    save(&nii_gz, &volume, &SaveOptions::default()).unwrap();
    save(&vol, &vol8, &SaveOptions::default()).unwrap();
    let limit = 32 * 32 * 32; // bytes: the u8 volume fits, the u16 ones do not
    let open = |path: &Path, mode: LoadMode, max_memory: Option<u64>| {
        fmt::open_file(
            path,
            &OpenOptions {
                mode,
                max_memory,
                ..OpenOptions::default()
            },
        )
        .map(|o| o.volume)
    };
    for path in [&gz, &nii_gz] {
        let err = open(path, LoadMode::Map, Some(limit - 1))
            .unwrap_err()
            .to_string();
        assert!(err.contains(&*path.to_string_lossy()), "{err}");
        assert!(err.contains("more than the limit of"), "{err}");
        assert!(!err.contains('\n'), "{err}");
        assert!(open(path, LoadMode::Map, None).is_ok());
        assert!(open(path, LoadMode::Map, Some(2 * limit)).is_ok());
    }
    // Read into RAM it counts; mapped it does not.
    let err = open(&vol, LoadMode::Ram, Some(limit - 1))
        .unwrap_err()
        .to_string();
    assert!(err.contains("more than the limit of"), "{err}");
    assert!(open(&vol, LoadMode::Ram, Some(limit)).is_ok());
    assert!(open(&vol, LoadMode::Map, Some(1)).is_ok());
}

/// Found by `scripts/fuzz.sh`: a 496-byte DICOM file whose Series Instance
/// UID is stored as FD with 6 bytes. The parser read a whole 8-byte value,
/// lost its place, took the bytes after it for an element header and
/// allocated its made-up length: 1.4 GB of RSS, a libFuzzer timeout under
/// its instrumentation. The length walk now refuses a binary value that is
/// not a whole number of its VR's values, before the parser runs.
#[test]
fn a_dicom_value_of_a_partial_binary_unit_is_refused_before_parsing() {
    // Alone in a directory: a DICOM file opens the series around it.
    let dir = TempDir::new("dicom_fd6");
    let path = dir.path().join("fd6.dcm");
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("fuzz/regressions/dicom/timeout-0ff249e057425a51ee198a32a5149a9917f2d540"),
        &path,
    )
    .unwrap();
    let err = fmt::open_file(&path, &OpenOptions::default())
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("(0020,000E)") && err.contains("not a whole number of 8-byte values"),
        "{err}"
    );
}
