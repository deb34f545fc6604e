//! The `.vol` format (a 26-byte little-endian header, then u8 samples z
//! fastest or in overlapping bricks): linear, bricked and file volumes render
//! identically, the interop files of another implementation agree, files are
//! byte for byte the layout the test encodes independently and read back
//! identical, every bad header is an error naming the file, and garbage never
//! panics the reader.

mod common;

use std::path::Path;

use common::TempFile;
use common::file_bytes::vol_header;
use common::scenes::{opts, render};
use glam::{UVec3, Vec3};
use raycaster::format::vol::{VolHeader, VolLayout};
use raycaster::prelude::*;

/// Every voxel of a u8 volume of any layout, in linear order.
fn voxels_u8(v: &AnyVolume) -> Vec<u8> {
    assert_eq!(v.sample_type(), SampleType::U8, "expected a u8 volume");
    let d = v.grid().dims;
    let mut out = Vec::with_capacity(v.grid().voxel_count() as usize);
    for x in 0..d.x {
        for y in 0..d.y {
            for z in 0..d.z {
                out.push(v.value(UVec3::new(x, y, z)) as u8);
            }
        }
    }
    out
}

// ------------------------------------------------ layouts, files and interop

/// Linear and bricked volumes of the same data, in memory and written to
/// and read back from `.vol` files (mapped and in RAM), render identically.
#[test]
fn linear_bricked_and_file_volumes_render_identically() {
    let dims = [37u32, 29, 23];
    let spacing = Vec3::new(1.0, 0.5, 2.0);
    let f = common::phantom(dims);
    let grid = Grid::new(UVec3::from_array(dims), spacing);
    let linear = AnyVolume::from_fn(grid, |v| f(v.x, v.y, v.z));
    let c = grid.bounds().center();
    let cams = [
        Camera::look_at(c + Vec3::new(20.0, 30.0, 60.0), c, 48, 40),
        Camera::look_at(
            c + Vec3::new(-3.0, 1.0, 4.0),
            c + Vec3::new(10.0, 0.0, -20.0),
            40,
            40,
        ),
    ];
    let tf = TransferFunction::preset("shapes", SampleType::U8).unwrap();
    let modes = [
        (RenderMode::Dvr, true),
        (RenderMode::Mip, true),
        (RenderMode::Avg, false),
        (RenderMode::Iso, false),
    ];
    let images = |scene: &Scene| -> Vec<Vec<u8>> {
        let mut out = Vec::new();
        for cam in &cams {
            for (mode, ess) in modes {
                let o = RenderOptions {
                    ess,
                    ert: true,
                    iso_value: 99.5,
                    ..opts(mode, 0.3)
                };
                out.push(render(scene, cam, &tf, &o).rgb);
                let mut shaded = o.clone();
                shaded.shading = true;
                out.push(render(scene, cam, &tf, &shaded).rgb);
            }
        }
        out
    };
    let want_voxels = linear.samples::<u8>().unwrap().to_vec();
    let want = images(&Scene::new(linear));
    for side in [2u32, 5, 16] {
        let b = AnyVolume::bricked_from_fn(grid, side, |v| f(v.x, v.y, v.z)).unwrap();
        assert_eq!(images(&Scene::new(b)), want, "in-memory bricked B = {side}");
    }
    let source = AnyVolume::from_fn(grid, |v| f(v.x, v.y, v.z));
    for layout in [
        VolLayout::Linear,
        VolLayout::Bricked { side: 2 },
        VolLayout::Bricked { side: 5 },
        VolLayout::Bricked { side: 16 },
        VolLayout::Bricked { side: 255 },
    ] {
        let file = TempFile::new("layout.vol");
        raycaster::format::vol::write(file.path(), &source, layout).unwrap();
        for mode in [LoadMode::Map, LoadMode::Ram] {
            let v = raycaster::format::open(file.path(), mode).unwrap();
            assert_eq!(*v.grid(), grid, "{layout:?}");
            assert_eq!(voxels_u8(&v), want_voxels, "{layout:?} {mode:?}");
            assert_eq!(images(&Scene::new(v)), want, "{layout:?} {mode:?}");
        }
    }
}

const INTEROP: &str = "/work/shared/data/interop";

/// The two files written by another implementation hold the same voxels in
/// the linear and the bricked (B = 16) layout: every voxel reads the same,
/// and the renders are identical.
#[test]
fn interop_files_read_the_same_and_render_identically() {
    let lin_path = Path::new(INTEROP).join("shapes_96x80x64_linear.vol");
    let bri_path = Path::new(INTEROP).join("shapes_96x80x64_block16.vol");
    if !lin_path.exists() || !bri_path.exists() {
        eprintln!("SKIPPED: interop files not found under {INTEROP}");
        return;
    }
    let lin = raycaster::format::open(&lin_path, LoadMode::Map).unwrap();
    let bri = raycaster::format::open(&bri_path, LoadMode::Map).unwrap();
    assert_eq!(lin.grid().dims, UVec3::new(96, 80, 64));
    assert_eq!(bri.grid().dims, UVec3::new(96, 80, 64));
    assert_eq!(lin.grid(), bri.grid());
    assert_eq!(lin.layout(), Layout::Linear);
    assert_eq!(bri.layout(), Layout::Bricked { side: 16 });
    let a = voxels_u8(&lin);
    let b = voxels_u8(&bri);
    let differing = a.iter().zip(&b).filter(|(x, y)| x != y).count();
    assert_eq!(
        differing, 0,
        "{differing} voxels differ between the interop files"
    );
    // The data is the shapes benchmark: some voxels in the shapes TF's range.
    assert!(a.iter().any(|v| (85..115).contains(v)));
    // The linear file's bytes are the voxels after the header, z fastest.
    let raw = std::fs::read(&lin_path).unwrap();
    assert_eq!(&raw[26..], &a[..]);
    let (lin, bri) = (Scene::new(lin), Scene::new(bri));
    let tf = TransferFunction::preset("shapes", SampleType::U8).unwrap();
    let c = lin.grid().bounds().center();
    for (pos, mode) in [
        (Vec3::new(0.0, 0.0, 150.0), RenderMode::Dvr),
        (Vec3::new(90.0, 60.0, 100.0), RenderMode::Dvr),
        (Vec3::new(-80.0, 30.0, -90.0), RenderMode::Mip),
        (Vec3::new(30.0, -90.0, 60.0), RenderMode::Iso),
    ] {
        let cam = Camera::look_at(c + pos, c, 64, 56);
        let o = RenderOptions {
            ess: true,
            ert: true,
            iso_value: 100.0,
            ..opts(mode, 0.5)
        };
        let x = render(&lin, &cam, &tf, &o);
        let y = render(&bri, &cam, &tf, &o);
        assert_eq!(x.rgb, y.rgb, "{mode:?} from {pos}");
        assert!(x.rgb.iter().any(|&v| v > 0), "{mode:?}: empty image");
    }
}

// ---------------------------------------------------------------- .vol bytes

/// The bricked encoding (bricks of side B overlapping by one sample, in
/// x-slowest order; inside a brick z fastest, 0 past the volume's edge),
/// written independently of the library.
fn encode_bricked(dims: [u32; 3], b: u32, voxel: impl Fn(u32, u32, u32) -> u8) -> Vec<u8> {
    let n = |d: u32| if d == 1 { 1 } else { (d - 1).div_ceil(b - 1) };
    let (nx, ny, nz) = (n(dims[0]), n(dims[1]), n(dims[2]));
    let mut out = Vec::new();
    for i in 0..nx {
        for j in 0..ny {
            for k in 0..nz {
                for lx in 0..b {
                    for ly in 0..b {
                        for lz in 0..b {
                            let (x, y, z) = (i * (b - 1) + lx, j * (b - 1) + ly, k * (b - 1) + lz);
                            let inside = x < dims[0] && y < dims[1] && z < dims[2];
                            out.push(if inside { voxel(x, y, z) } else { 0 });
                        }
                    }
                }
            }
        }
    }
    out
}

/// Write then read back, for odd sizes and several brick sides: the file is
/// byte for byte the expected layout (checked against an independent encoder) and reads
/// back voxel-identical.
#[test]
fn vol_round_trip() {
    let mut rng = fastrand::Rng::with_seed(5);
    for dims in [
        [1u32, 1, 1],
        [2, 3, 5],
        [17, 9, 13],
        [31, 1, 7],
        [6, 16, 31],
    ] {
        let spacing = [0.5f32, 1.25, 3.0];
        let data: Vec<u8> = (0..dims.iter().product::<u32>())
            .map(|_| rng.u8(..))
            .collect();
        let voxel = |x: u32, y: u32, z: u32| data[((x * dims[1] + y) * dims[2] + z) as usize];
        let grid = Grid::new(UVec3::from_array(dims), Vec3::from_array(spacing));
        let vol = AnyVolume::from_fn(grid, |v| voxel(v.x, v.y, v.z));
        for layout in [
            VolLayout::Linear,
            VolLayout::Bricked { side: 2 },
            VolLayout::Bricked { side: 3 },
            VolLayout::Bricked { side: 5 },
            VolLayout::Bricked { side: 16 },
            VolLayout::Bricked { side: 255 },
        ] {
            let file = TempFile::new("rt.vol");
            raycaster::format::vol::write(file.path(), &vol, layout).unwrap();
            let bytes = std::fs::read(file.path()).unwrap();
            let (lbyte, extra, body) = match layout {
                VolLayout::Linear => (1, 0, data.clone()),
                VolLayout::Bricked { side } => (2, side, encode_bricked(dims, side as u32, voxel)),
            };
            let mut want = vol_header(dims, spacing, lbyte, extra);
            want.extend_from_slice(&body);
            assert_eq!(bytes.len(), want.len(), "{dims:?} {layout:?}: file length");
            assert!(
                bytes == want,
                "{dims:?} {layout:?}: file bytes differ from the independent encoder"
            );
            for mode in [LoadMode::Map, LoadMode::Ram] {
                let back = raycaster::format::open(file.path(), mode).unwrap();
                assert_eq!(back.grid().dims, UVec3::from_array(dims));
                assert_eq!(back.grid().spacing, Vec3::from_array(spacing));
                assert_eq!(voxels_u8(&back), data, "{dims:?} {layout:?} {mode:?}");
            }
        }
    }
}

/// Every bad header case of the format is an error naming the file, never a panic.
#[test]
fn bad_vol_files_are_errors_that_name_the_file() {
    let ok = |dims: [u32; 3]| vol_header(dims, [1.0; 3], 1, 0);
    let with_body = |mut h: Vec<u8>, n: usize| {
        h.resize(h.len() + n, 7);
        h
    };
    // A 2×2×2 file, header and whole body, with `spacing`, `layout` and `extra`.
    let small = |spacing: [f32; 3], layout: u8, extra: u8| {
        with_body(vol_header([2, 2, 2], spacing, layout, extra), 8)
    };
    let cases: Vec<(&str, Vec<u8>, Vec<&str>)> = vec![
        ("empty file", vec![], vec![]),
        ("10 bytes", vec![1; 10], vec![]),
        ("25 bytes", ok([1, 1, 1])[..25].to_vec(), vec![]),
        ("zero X", with_body(ok([0, 4, 4]), 0), vec![]),
        ("zero Y", with_body(ok([4, 0, 4]), 0), vec![]),
        ("zero Z", with_body(ok([4, 4, 0]), 64), vec![]),
        ("NaN spacing", small([1.0, f32::NAN, 1.0], 1, 0), vec![]),
        (
            "inf spacing",
            small([f32::INFINITY, 1.0, 1.0], 1, 0),
            vec![],
        ),
        (
            "-inf spacing",
            small([1.0, 1.0, f32::NEG_INFINITY], 1, 0),
            vec![],
        ),
        ("zero spacing", small([1.0, 0.0, 1.0], 1, 0), vec![]),
        ("-0 spacing", small([1.0, 1.0, -0.0], 1, 0), vec![]),
        ("negative spacing", small([-1.0, 1.0, 1.0], 1, 0), vec![]),
        ("layout 0", small([1.0; 3], 0, 0), vec![]),
        ("layout 3", small([1.0; 3], 3, 0), vec![]),
        ("layout 255", small([1.0; 3], 255, 0), vec![]),
        ("brick side 0", small([1.0; 3], 2, 0), vec![]),
        ("brick side 1", small([1.0; 3], 2, 1), vec![]),
        ("linear overflow", with_body(ok([u32::MAX; 3]), 16), vec![]),
        (
            "bricked overflow",
            with_body(vol_header([u32::MAX; 3], [1.0; 3], 2, 2), 16),
            vec![],
        ),
        (
            "linear, one byte short",
            with_body(ok([4, 5, 6]), 119),
            vec!["expected", "146", "found", "145"],
        ),
        (
            "linear, one byte long",
            with_body(ok([4, 5, 6]), 121),
            vec!["expected", "146", "found", "147"],
        ),
        (
            "linear, header only",
            ok([4, 5, 6]),
            vec!["expected", "146", "found", "26"],
        ),
        (
            // 2 bricks of 3³ per axis: 8·27 = 216 samples.
            "bricked, short",
            with_body(vol_header([5, 5, 5], [1.0; 3], 2, 3), 215),
            vec!["expected", "242", "found", "241"],
        ),
        (
            // Linear-sized body under a bricked header.
            "bricked, linear-sized body",
            with_body(vol_header([5, 5, 5], [1.0; 3], 2, 3), 125),
            vec!["expected", "242", "found", "151"],
        ),
    ];
    for (what, bytes, must_say) in cases {
        let file = TempFile::new("bad-header.vol");
        std::fs::write(file.path(), &bytes).unwrap();
        let name = file.name();
        for mode in [LoadMode::Map, LoadMode::Ram] {
            let err = match raycaster::format::open(file.path(), mode) {
                Ok(v) => panic!("{what}: opened as {:?}", v.grid()),
                Err(e) => e.to_string(),
            };
            assert!(
                err.contains(&name),
                "{what}: message does not name the file: {err}"
            );
            for word in &must_say {
                assert!(err.contains(word), "{what}: message lacks {word:?}: {err}");
            }
        }
        if bytes.len() >= 26
            && !what.contains("short")
            && !what.contains("long")
            && !what.contains("body")
            && !what.contains("header only")
        {
            assert!(VolHeader::parse(&bytes).is_err(), "{what}: header parsed");
        }
    }
    // Missing files and directories are errors too.
    let missing = TempFile::new("missing.vol");
    let err = raycaster::format::open(missing.path(), LoadMode::Map)
        .unwrap_err()
        .to_string();
    assert!(err.contains("missing.vol"), "{err}");
    // A directory of its own: the system's temporary directory may hold a
    // single volume file, and a folder holding one opens that file.
    let dir = std::env::temp_dir().join(format!("vol_format-dir-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("LICENSE"), "not a volume").unwrap();
    let err = raycaster::format::open(&dir, LoadMode::Map).unwrap_err();
    std::fs::remove_dir_all(&dir).ok();
    assert!(err.to_string().contains("vol_format-dir"), "{err}");
}

/// Random byte strings and randomly corrupted valid files never panic the
/// header parser or the reader.
#[test]
fn vol_reader_never_panics_on_garbage() {
    let mut rng = fastrand::Rng::with_seed(2024);
    // Header parser: pure random bytes, and valid headers with a few bytes changed.
    for i in 0..4000 {
        let bytes: Vec<u8> = if i % 2 == 0 {
            (0..rng.usize(0..200)).map(|_| rng.u8(..)).collect()
        } else {
            let mut h = vol_header(
                [rng.u32(1..40), rng.u32(1..40), rng.u32(1..40)],
                [0.5, 1.0, 2.0],
                rng.u8(1..=2),
                rng.u8(2..20),
            );
            for _ in 0..rng.usize(1..4) {
                let at = rng.usize(0..26);
                h[at] = rng.u8(..);
            }
            h
        };
        let r = std::panic::catch_unwind(|| VolHeader::parse(&bytes));
        assert!(r.is_ok(), "VolHeader::parse panicked on {bytes:?}");
    }
    // The reader, through files: random bytes, and valid small files with a
    // corrupted header byte or a length off by a little.
    let file = TempFile::new("fuzz.vol");
    let mut opened = 0;
    for i in 0..2000 {
        let bytes: Vec<u8> = match i % 3 {
            0 => (0..rng.usize(0..200)).map(|_| rng.u8(..)).collect(),
            _ => {
                let dims = [rng.u32(1..6), rng.u32(1..6), rng.u32(1..6)];
                let bricked = rng.bool();
                let side = rng.u8(2..5);
                let body = if bricked {
                    let n = |d: u32| {
                        if d == 1 {
                            1
                        } else {
                            (d - 1).div_ceil(side as u32 - 1)
                        }
                    };
                    (n(dims[0]) * n(dims[1]) * n(dims[2])) as usize * (side as usize).pow(3)
                } else {
                    dims.iter().product::<u32>() as usize
                };
                let mut b = vol_header(dims, [1.0, 0.5, 2.0], if bricked { 2 } else { 1 }, side);
                b.extend((0..body).map(|_| rng.u8(..)));
                if i % 3 == 1 {
                    let at = rng.usize(0..26);
                    b[at] = rng.u8(..);
                } else if rng.bool() {
                    let n = b.len();
                    b.truncate(n - rng.usize(0..3.min(n)));
                } else {
                    b.extend((0..rng.usize(0..3)).map(|_| 0u8));
                }
                b
            }
        };
        std::fs::write(file.path(), &bytes).unwrap();
        let mode = if i % 2 == 0 {
            LoadMode::Map
        } else {
            LoadMode::Ram
        };
        let path = file.path().to_path_buf();
        let r = std::panic::catch_unwind(move || {
            raycaster::format::open(&path, mode).map(|v| {
                // Whatever opened must be readable everywhere.
                let d = v.grid().dims;
                let _ = voxels_u8(&v);
                d
            })
        });
        match r {
            Err(_) => panic!("format::open panicked on {bytes:?}"),
            Ok(Ok(_)) => opened += 1,
            Ok(Err(e)) => {
                let name = file.name();
                assert!(
                    e.to_string().contains(&name),
                    "error without the file name: {e}"
                );
            }
        }
    }
    assert!(opened > 100, "only {opened} valid files opened");
}
