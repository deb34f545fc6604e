//! `vol_app render --turntable N`: frames against plain renders with the
//! same (or a hand-rotated) camera, the animated GIF decoded back, and the
//! errors.

mod common;

use std::path::{Path, PathBuf};

use common::{TempDir, assert_one_line_error, output, run_ok, vol_app, vol_app_on};
use glam::{UVec3, Vec3};
use image::AnimationDecoder;
use raycaster::format::vol::{self, VolLayout};
use raycaster::volume::{AnyVolume, Grid};

/// An L-shaped object (no symmetry a quarter turn could hide): a bar along
/// x, a shorter one along y, and a blob on the +z side, in a 32×28×24
/// volume with non-uniform spacing.
fn asymmetric_file(dir: &TempDir) -> PathBuf {
    let grid = Grid::new(UVec3::new(32, 28, 24), Vec3::new(1.0, 1.2, 0.9));
    let v = AnyVolume::from_fn(grid, |p| {
        let bar_x = (4..28).contains(&p.x) && (10..16).contains(&p.y) && (8..14).contains(&p.z);
        let bar_y = (4..10).contains(&p.x) && (10..26).contains(&p.y) && (8..14).contains(&p.z);
        let blob = (20..26).contains(&p.x) && (4..10).contains(&p.y) && (14..22).contains(&p.z);
        match (bar_x || bar_y, blob) {
            (_, true) => 250u8,
            (true, _) => 120,
            _ => 0,
        }
    });
    let path = dir.path("l.vol");
    vol::write(&path, &v, VolLayout::Linear).unwrap();
    path
}

/// The volume's centre: half of (dims − 1)·spacing.
const CENTRE: Vec3 = Vec3::new(15.5, 16.2, 10.35);

const COMMON: [&str; 8] = [
    "--size",
    "72x64",
    "--tf-preset",
    "skull",
    "--threads",
    "2",
    "--renderer",
    "tiles",
];

fn vec(v: Vec3) -> String {
    format!("{},{},{}", v.x, v.y, v.z)
}

fn render(file: &Path, out: &Path, pos: Vec3, up: Vec3) -> image::RgbImage {
    run_ok(
        vol_app_on("render", file)
            .args(COMMON)
            .args(["--camera-pos", &vec(pos), "--up", &vec(up), "--out"])
            .arg(out),
    );
    image::open(out).unwrap().to_rgb8()
}

/// Pixels whose channels differ by more than 2.
fn differing(a: &image::RgbImage, b: &image::RgbImage) -> usize {
    assert_eq!(a.dimensions(), b.dimensions());
    a.pixels()
        .zip(b.pixels())
        .filter(|(p, q)| p.0.iter().zip(q.0).any(|(x, y)| x.abs_diff(y) > 2))
        .count()
}

#[test]
fn frames_are_renders_of_the_orbiting_camera() {
    let dir = TempDir::new("frames");
    let file = asymmetric_file(&dir);
    let start = CENTRE + Vec3::new(20.0, 14.0, 60.0);
    let frames = dir.path("frames/");
    run_ok(
        vol_app_on("render", &file)
            .args(COMMON)
            .args([
                "--turntable",
                "8",
                "--axis",
                "z",
                "--camera-pos",
                &vec(start),
            ])
            .arg("--out")
            .arg(&frames),
    );
    let names: Vec<_> = (0..8)
        .map(|k| frames.join(format!("frame_{k:04}.png")))
        .collect();
    assert!(names.iter().all(|p| p.exists()));
    assert!(!frames.join("frame_0008.png").exists());
    let frame = |k: usize| image::open(&names[k]).unwrap().to_rgb8();

    // Frame 0 is the start camera itself, bit for bit.
    let plain = render(&file, &dir.path("plain.png"), start, Vec3::Y);
    assert_eq!(frame(0), plain, "frame 0 differs from a plain render");

    // Frame 2 of 8 is a quarter turn about +z: (x, y) → (−y, x) about the
    // centre, the up vector +y → −x.
    let r = start - CENTRE;
    let quarter = CENTRE + Vec3::new(-r.y, r.x, r.z);
    let turned = render(&file, &dir.path("q.png"), quarter, Vec3::NEG_X);
    let pixels = (72 * 64) as usize;
    let d = differing(&frame(2), &turned);
    assert!(
        d * 200 < pixels,
        "frame 2: {d} pixels differ from the 90° render"
    );
    // The other way round is a different picture (the test can fail).
    let back = CENTRE + Vec3::new(r.y, -r.x, r.z);
    let wrong = render(&file, &dir.path("w.png"), back, Vec3::X);
    let d = differing(&frame(2), &wrong);
    assert!(
        d * 20 > pixels,
        "a −90° turn gives the same frame ({d} pixels differ)"
    );
    assert!(differing(&frame(0), &frame(1)) * 20 > pixels);
}

#[test]
fn the_default_axis_is_y_and_keeps_distance_and_elevation() {
    let dir = TempDir::new("axis-y");
    let file = asymmetric_file(&dir);
    let start = CENTRE + Vec3::new(0.0, 25.0, 70.0);
    let frames = dir.path("y/");
    run_ok(
        vol_app_on("render", &file)
            .args(COMMON)
            .args(["--turntable", "4", "--camera-pos", &vec(start), "--out"])
            .arg(&frames),
    );
    // A quarter turn about +y: (x, z) → (z, −x), same height.
    let quarter = CENTRE + Vec3::new(70.0, 25.0, 0.0);
    let turned = render(&file, &dir.path("q.png"), quarter, Vec3::Y);
    let got = image::open(frames.join("frame_0001.png"))
        .unwrap()
        .to_rgb8();
    let d = differing(&got, &turned);
    assert!(d * 200 < 72 * 64, "{d} pixels differ");
}

#[test]
fn a_gif_holds_every_frame() {
    let dir = TempDir::new("gif");
    let file = asymmetric_file(&dir);
    let gif = dir.path("turn.gif");
    run_ok(
        vol_app_on("render", &file)
            .args(COMMON)
            .args(["--turntable", "6", "--fps", "20", "--out"])
            .arg(&gif),
    );
    let decoder = image::codecs::gif::GifDecoder::new(std::io::BufReader::new(
        std::fs::File::open(&gif).unwrap(),
    ))
    .unwrap();
    let frames = decoder.into_frames().collect_frames().unwrap();
    assert_eq!(frames.len(), 6);
    for f in &frames {
        assert_eq!(f.buffer().dimensions(), (72, 64));
        assert_eq!(f.delay().numer_denom_ms(), (50, 1));
    }
    // The frames are the turntable's (quantised): frame 1 is not frame 0.
    let (a, b) = (frames[0].buffer(), frames[1].buffer());
    let changed = a.pixels().zip(b.pixels()).filter(|(p, q)| p != q).count();
    assert!(
        changed > 100,
        "frames 0 and 1 are alike ({changed} pixels differ)"
    );
    // Nothing else is left in the directory (the write is atomic; the
    // macrocell cache sits beside the volume).
    let mut names: Vec<String> = std::fs::read_dir(dir.path(""))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !n.ends_with(".rcidx"))
        .collect();
    names.sort();
    assert_eq!(names, ["l.vol", "turn.gif"]);
}

#[test]
fn bad_turntables_give_one_line_errors_naming_the_option() {
    let dir = TempDir::new("errors");
    let file = asymmetric_file(&dir);
    let f = file.to_str().unwrap();
    let out_dir = dir.path("o/");
    let o = out_dir.to_str().unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["--turntable", "0", "--out", o], "--turntable"),
        (
            vec!["--turntable", "4", "--frames", "0..2", "--out", o],
            "--turntable",
        ),
        (
            vec!["--turntable", "4", "--out", "movie.png"],
            "--out movie.png",
        ),
        (vec!["--turntable", "4"], "--out"),
        (
            vec!["--turntable", "4", "--axis", "w", "--out", o],
            "--axis",
        ),
        (
            vec!["--turntable", "4", "--fps", "0", "--out", "m.gif"],
            "--fps",
        ),
        (vec!["--axis", "x"], "--turntable"),
    ];
    for (args, needle) in cases {
        let out = output(vol_app().args(["render", f]).args(&args));
        assert_one_line_error(&out, needle);
    }
    assert!(!out_dir.exists());
}
