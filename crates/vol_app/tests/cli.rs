//! End-to-end tests of the `vol_app` binary: arguments, errors, outputs.

mod common;

use std::path::PathBuf;
use std::process::Output;

use common::{
    TempDir, assert_one_line_error, output, radial_vol_file, run_ok, vol_app, vol_app_on,
};
use glam::UVec3;
use raycaster::format::vol::VolLayout;

/// A 24³ ball of value 200 in a `.vol` file.
fn ball_file(dir: &TempDir, layout: VolLayout) -> PathBuf {
    let name = format!("ball_{layout:?}.vol").replace([' ', '{', '}', ':'], "");
    radial_vol_file(dir, &name, UVec3::splat(24), layout, |d| {
        if d < 8.0 { 200 } else { 0 }
    })
}

/// Every one of `needles` is in what the run printed on stdout.
fn assert_stdout_mentions(out: &Output, needles: &[&str]) {
    let text = String::from_utf8_lossy(&out.stdout);
    for needle in needles {
        assert!(text.contains(needle), "'{needle}' not in:\n{text}");
    }
}

/// `vol_app SUBCOMMAND MISSING` fails with one line naming the file.
fn assert_missing_file_error(subcommand: &str, missing: &str) {
    assert_one_line_error(&output(vol_app().args([subcommand, missing])), missing);
}

#[test]
fn help_exits_zero_and_documents_options() {
    let out = vol_app().args(["render", "--help"]).output().unwrap();
    assert!(out.status.success());
    let options = [
        "--camera-pos",
        "--look-at",
        "--fov",
        "--ortho",
        "--step",
        "--tf-preset",
        "--mode",
        "--iso",
        "--shading",
        "--ert",
        "--ess",
        "--renderer",
        "--threads",
        "--background",
        "--repeat",
        "--stats",
        "--progressive",
    ];
    assert_stdout_mentions(&out, &options);
    assert!(vol_app().arg("--help").output().unwrap().status.success());
}

#[test]
fn renders_a_png_with_the_ball_in_the_middle() {
    let dir = TempDir::new("png");
    for layout in [VolLayout::Linear, VolLayout::Bricked { side: 8 }] {
        let file = ball_file(&dir, layout);
        let png = dir.path("out.png");
        run_ok(
            vol_app_on("render", &file)
                .args(["--size", "64x48", "--tf-preset", "skull", "--out"])
                .arg(&png),
        );
        let img = image::open(&png).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (64, 48));
        assert!(img.get_pixel(32, 24)[0] > 100, "centre is dark");
        assert_eq!(img.get_pixel(0, 0).0, [0, 0, 0], "corner is not background");
    }
}

#[test]
fn stats_is_one_json_object_with_the_spec_fields() {
    let dir = TempDir::new("stats");
    let file = ball_file(&dir, VolLayout::Linear);
    for renderer in ["serial", "tiles", "object"] {
        let out = run_ok(vol_app_on("render", &file).args([
            "--size",
            "40x30",
            "--repeat",
            "3",
            "--stats",
            "--renderer",
            renderer,
            "--threads",
            "2",
        ]));
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["width"], 40);
        assert_eq!(v["height"], 30);
        assert_eq!(v["frame_ms"].as_array().unwrap().len(), 3);
        for key in [
            "renderer",
            "threads",
            "frame_ms_median",
            "load_ms",
            "rays",
            "samples",
            "peak_rss_mb",
        ] {
            assert!(!v[key].is_null(), "{key} missing in {v}");
        }
        assert!(v["samples"].as_u64().unwrap() > 0);
        assert!(v["rays"].as_u64().unwrap() > 0);
        if renderer == "serial" {
            assert_eq!(v["threads"], 1);
        }
    }
}

#[test]
fn progressive_reproduces_the_viewers_previews_then_refinement() {
    let dir = TempDir::new("progressive");
    let file = ball_file(&dir, VolLayout::Linear);
    let png = dir.path("final.png");
    let out = run_ok(
        vol_app_on("render", &file)
            .args([
                "--size",
                "400x300",
                "--progressive",
                "4",
                "--stats",
                "--renderer",
                "tiles",
                "--out",
            ])
            .arg(&png),
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        (v["width"].as_u64(), v["height"].as_u64()),
        (Some(400), Some(300))
    );
    assert!(v["preview_ms_median"].as_f64().unwrap() > 0.0);
    let frames = v["frames"].as_array().unwrap();
    let stage = |f: &serde_json::Value| f["stage"].as_str().unwrap().to_string();
    let field = |f: &serde_json::Value, k: &str| f[k].as_u64().unwrap();
    // Four previews, the first at the untimed guess (¼ size, step ×2).
    assert!(frames[..4].iter().all(|f| stage(f) == "preview"), "{v}");
    assert_eq!(
        (
            field(&frames[0], "downscale"),
            field(&frames[0], "step_scale")
        ),
        (4, 2)
    );
    // Each frame has its level's size; the refinement gets finer and ends
    // at full quality (unless a preview was full quality already).
    for f in frames {
        let d = field(f, "downscale");
        assert_eq!(
            (field(f, "width"), field(f, "height")),
            (400 / d, 300 / d),
            "{f}"
        );
    }
    let refined: Vec<u64> = frames[4..].iter().map(|f| field(f, "downscale")).collect();
    assert!(refined.iter().all(|d| [4, 2, 1].contains(d)), "{v}");
    assert!(refined.windows(2).all(|w| w[1] < w[0]), "{v}");
    let last = frames.last().unwrap();
    assert_eq!(
        (field(last, "downscale"), field(last, "step_scale")),
        (1, 1)
    );
    // The saved image is the final, full-size frame.
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (400, 300));
}

#[test]
fn negative_vector_values_are_accepted() {
    let dir = TempDir::new("neg");
    let file = ball_file(&dir, VolLayout::Linear);
    run_ok(vol_app_on("render", &file).args([
        "--size",
        "16x16",
        "--camera-pos",
        "-30.5,-20,-40",
        "--stats",
    ]));
}

fn header(dims: [u32; 3], spacing: [f32; 3], layout: u8, extra: u8) -> Vec<u8> {
    let mut b = Vec::new();
    dims.iter()
        .for_each(|d| b.extend_from_slice(&d.to_le_bytes()));
    spacing
        .iter()
        .for_each(|s| b.extend_from_slice(&s.to_le_bytes()));
    b.extend_from_slice(&[layout, extra]);
    b
}

#[test]
fn bad_vol_files_give_one_line_errors_naming_the_file() {
    let dir = TempDir::new("bad");
    let mut cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "short.vol",
            vec![1, 2, 3],
            "shorter than the 26-byte header",
        ),
        (
            "zero.vol",
            header([0, 2, 2], [1.0; 3], 1, 0),
            "dimension X is 0",
        ),
        (
            "nan.vol",
            header([2, 2, 2], [1.0, f32::NAN, 1.0], 1, 0),
            "spacing Y",
        ),
        (
            "neg.vol",
            header([2, 2, 2], [1.0, 1.0, -2.0], 1, 0),
            "spacing Z",
        ),
        (
            "layout.vol",
            header([2, 2, 2], [1.0; 3], 7, 0),
            "unknown layout byte 7",
        ),
        (
            "brick.vol",
            header([2, 2, 2], [1.0; 3], 2, 1),
            "brick side 1",
        ),
        (
            "overflow.vol",
            header([u32::MAX; 3], [1.0; 3], 1, 0),
            "overflow",
        ),
    ];
    let mut truncated = header([4, 4, 4], [1.0; 3], 1, 0);
    truncated.extend(vec![0u8; 63]);
    cases.push(("trunc.vol", truncated, "expected 90 bytes"));
    let mut long = header([2, 2, 2], [1.0; 3], 2, 4);
    long.extend(vec![0u8; 65]);
    cases.push(("long.vol", long, "expected 90 bytes"));
    for (name, bytes, needle) in cases {
        let p = dir.write(name, &bytes);
        let out = output(vol_app_on("render", &p).args(["--size", "8x8", "--stats"]));
        assert_one_line_error(&out, needle);
        assert_one_line_error(&out, name);
    }
    assert_missing_file_error("render", "/nonexistent/x.vol");
}

#[test]
fn object_renderer_threads_split_into_render_and_composite() {
    let dir = TempDir::new("composite");
    let file = ball_file(&dir, VolLayout::Linear);
    let stats_threads = |threads: &str, composite: &str| {
        let out = run_ok(vol_app_on("render", &file).args([
            "--size",
            "16x16",
            "--stats",
            "--renderer",
            "object",
            "--threads",
            threads,
            "--composite-threads",
            composite,
        ]));
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        v["threads"].as_u64().unwrap()
    };
    // The threads in all, whichever of them only composite.
    assert_eq!(stats_threads("3", "1"), 3);
    assert_eq!(stats_threads("2", "0"), 2);
    // 0: one per core.
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    assert_eq!(stats_threads("0", "0"), cores as u64);
    let out = output(vol_app_on("render", &file).args([
        "--renderer",
        "object",
        "--threads",
        "2",
        "--composite-threads",
        "2",
        "--stats",
    ]));
    assert_one_line_error(&out, "leaves no render thread of --threads 2");
}

#[test]
fn bad_arguments_give_one_line_errors() {
    let dir = TempDir::new("args");
    let file = ball_file(&dir, VolLayout::Linear);
    let f = file.to_str().unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["--size", "10"], "WIDTHxHEIGHT"),
        (vec!["--camera-pos", "1,2"], "three"),
        (
            vec!["--tf-preset", "nope"],
            "unknown transfer function preset",
        ),
        (vec!["--step", "0"], "--step"),
        (vec!["--mode", "fancy"], "fancy"),
        (
            vec!["--camera-pos", "12,12,12", "--look-at", "12,12,12"],
            "degenerate",
        ),
        (vec!["--tf", "/nonexistent/tf.json"], "/nonexistent/tf.json"),
        (vec!["--repeat", "0"], "0"),
        (
            vec!["--mode", "iso", "--light", "0,0,0"],
            "invalid light: direction",
        ),
        (vec!["--normals", "bumpy"], "bumpy"),
        (vec!["--clip-box", "5,0,0,4,9,9"], "--clip-box"),
        (vec!["--clip-box", "1,2,3"], "--clip-box"),
        (vec!["--clip-plane", "0,0,0,1"], "--clip-plane"),
        (vec!["--clip-plane", "1,0,nan,1"], "--clip-plane"),
        (
            vec![
                "--clip-plane",
                "1,0,0,1",
                "--clip-plane",
                "1,0,0,2",
                "--clip-plane",
                "1,0,0,3",
                "--clip-plane",
                "1,0,0,4",
                "--clip-plane",
                "1,0,0,5",
                "--clip-plane",
                "1,0,0,6",
                "--clip-plane",
                "1,0,0,7",
            ],
            "--clip-plane",
        ),
        (vec!["--gradient-opacity", "5,5"], "--gradient-opacity"),
        (vec!["--gradient-opacity", "9,2"], "--gradient-opacity"),
        (
            vec!["--gradient-opacity", "1,2", "--mode", "mip"],
            "--gradient-opacity applies to --mode dvr only, not mip",
        ),
        (vec!["--jitter", "maybe"], "--jitter"),
    ];
    for (args, needle) in cases {
        let out = output(vol_app().args(["render", f]).args(&args).args(["--stats"]));
        assert_one_line_error(&out, needle);
    }
    let bad_tf = dir.write(
        "bad.json",
        br#"{"points": [{"value": 1, "color": [1,1,1], "opacity": 3}]}"#,
    );
    let out = output(
        vol_app()
            .args(["render", f, "--stats", "--tf"])
            .arg(&bad_tf),
    );
    assert_one_line_error(&out, "bad.json");
}

#[test]
fn clipping_gradient_opacity_minip_and_jitter_render() {
    let dir = TempDir::new("s8");
    let file = ball_file(&dir, VolLayout::Linear);
    let png = |name: &str, args: &[&str]| {
        let out = dir.path(name);
        run_ok(
            vol_app_on("render", &file)
                .args(["--size", "48x48", "--tf-preset", "skull", "--out"])
                .arg(&out)
                .args(args),
        );
        image::open(&out).unwrap().to_rgb8()
    };
    let plain = png("plain.png", &[]);
    // A box that holds nothing of the volume: background only.
    let empty = png("empty.png", &["--clip-box", "-100,-100,-100,-50,-50,-50"]);
    assert!(empty.pixels().all(|p| p.0 == [0, 0, 0]));
    let plane = png("plane.png", &["--clip-plane", "-1,0,0,-1e6"]);
    assert!(plane.pixels().all(|p| p.0 == [0, 0, 0]));
    let keep_all = png("all.png", &["--clip-plane", "1,0,0,1e6", "--jitter", "off"]);
    assert_eq!(keep_all, plain);
    let jitter = png(
        "jitter.png",
        &["--jitter", "on", "--seed", "3", "--step", "2"],
    );
    let again = png(
        "jitter2.png",
        &["--jitter", "on", "--seed", "3", "--step", "2"],
    );
    assert_eq!(jitter, again);
    png("go.png", &["--gradient-opacity", "0,20"]);
    png("minip.png", &["--mode", "minip"]);
}

#[test]
fn without_a_display_the_viewer_fails_with_one_line() {
    // No subcommand opens the viewer; with no display to open it on, that is
    // a one-line error that points to `vol_app render`.
    let out = output(
        vol_app()
            .env_remove("DISPLAY")
            .env_remove("WAYLAND_DISPLAY"),
    );
    assert_one_line_error(&out, "vol_app render");
}

#[test]
fn viewer_arguments_are_checked_before_a_window_opens() {
    let out = output(vol_app().args(["--tf-preset", "nope"]));
    assert_one_line_error(&out, "nope");
    let dir = TempDir::new("viewer_args");
    let bad_tf = dir.write("bad_viewer.json", b"{");
    let out = output(vol_app().arg("--tf").arg(&bad_tf));
    assert_one_line_error(&out, "bad_viewer.json");
    // A FILE that cannot be opened is what the error names, not the display.
    let no_display = |file: &std::path::Path| {
        output(
            vol_app()
                .arg(file)
                .env_remove("DISPLAY")
                .env_remove("WAYLAND_DISPLAY"),
        )
    };
    let out = no_display("/nonexistent/nope.vol".as_ref());
    assert_one_line_error(&out, "/nonexistent/nope.vol");
    let out = no_display(&dir.write("notes.txt", b"not a volume"));
    assert_one_line_error(&out, "notes.txt");
}

/// A file of the shared test data (../shared/data next to the repository,
/// or `$RAYCASTER_DATA`), or `None` with a note when it is not on this machine.
fn shared_data(rel: &str) -> Option<PathBuf> {
    let roots = [
        std::env::var_os("RAYCASTER_DATA").map(PathBuf::from),
        Some(PathBuf::from(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../../shared/data"
        ))),
        Some(PathBuf::from("/work/shared/data")),
    ];
    let found = roots
        .into_iter()
        .flatten()
        .map(|r| r.join(rel))
        .find(|p| p.exists());
    if found.is_none() {
        eprintln!("SKIPPED: {rel} not found (set RAYCASTER_DATA to the shared data directory)");
    }
    found
}

#[test]
fn info_describes_a_real_nrrd_file_as_text_and_json() {
    let Some(flair) = shared_data("mri_flair_nrrd/FLAIR.nrrd") else {
        return;
    };
    let out = run_ok(&mut vol_app_on("info", &flair));
    let facts = [
        "NRRD",
        "124 x 160 x 140",
        "u8, gzip",
        "space directions",
        "0 .. 255",
    ];
    assert_stdout_mentions(&out, &facts);
    let out = output(vol_app_on("info", &flair).arg("--json"));
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["dims"], serde_json::json!([124, 160, 140]));
    assert_eq!(v["stored_type"], "u8");
    assert_eq!(v["encoding"], "gzip");
    assert_eq!(v["file_bytes"], std::fs::metadata(&flair).unwrap().len());
    assert_missing_file_error("info", "/nonexistent/head.nii.gz");
}

#[test]
fn a_folder_with_one_scan_and_its_licence_opens_the_scan() {
    // A temporary folder: a volume and two files without extensions.
    let dir = TempDir::new("folder");
    let vol = ball_file(&dir, VolLayout::Linear);
    dir.write("LICENSE", b"Permission is hereby granted");
    dir.write("README", b"a ball");
    let folder = vol.parent().unwrap().to_path_buf();
    let out = run_ok(&mut vol_app_on("info", &folder));
    assert_stdout_mentions(&out, &["24 x 24 x 24", &vol.display().to_string()]);
    let png = dir.path("folder.png");
    run_ok(
        vol_app_on("render", &folder)
            .args(["--size", "16x16", "--out"])
            .arg(&png),
    );
    // The shared data ships each scan in a folder with its licence.
    let Some(flair) = shared_data("mri_flair_nrrd") else {
        return;
    };
    let out = run_ok(&mut vol_app_on("info", &flair));
    assert_stdout_mentions(&out, &["NRRD", "124 x 160 x 140", "FLAIR.nrrd"]);
}

#[test]
fn raw_options_read_headerless_files_in_either_order() {
    let dir = TempDir::new("raw");
    let vol_file = ball_file(&dir, VolLayout::Linear);
    // The .vol's samples are z fastest: the same bytes as a raw z-fast file.
    let bytes = std::fs::read(&vol_file).unwrap();
    let raw_z = dir.write("ball_z.raw", &bytes[26..]);
    // And transposed to x fastest, as 16-bit big-endian.
    let mut xfast = Vec::new();
    for z in 0..24 {
        for y in 0..24 {
            for x in 0..24 {
                let v = bytes[26 + (x * 24 + y) * 24 + z] as u16;
                xfast.extend_from_slice(&v.to_be_bytes());
            }
        }
    }
    let raw_x = dir.write("ball_x.bin", &xfast);
    let render = |file: &PathBuf, extra: &[&str], png: &str| {
        let out_png = dir.path(png);
        run_ok(
            vol_app_on("render", file)
                .args(["--size", "32x32", "--tf-preset", "skull", "--out"])
                .arg(&out_png)
                .args(extra),
        );
        std::fs::read(out_png).unwrap()
    };
    let want = render(&vol_file, &[], "vol.png");
    let z = render(
        &raw_z,
        &[
            "--raw-dims",
            "24,24,24",
            "--raw-type",
            "u8",
            "--raw-order",
            "zfast",
        ],
        "z.png",
    );
    let x = render(
        &raw_x,
        &["--raw-dims", "24,24,24", "--raw-type", "u16be"],
        "x.png",
    );
    assert_eq!(z, want, "z-fast raw differs from the .vol");
    assert_eq!(x, want, "x-fast u16be raw differs from the .vol");
    // Wrong dimensions: the error says what was expected and found.
    let out = output(vol_app_on("render", &raw_z).args([
        "--raw-dims",
        "24,24,25",
        "--raw-type",
        "u8",
        "--size",
        "8x8",
    ]));
    assert_one_line_error(&out, "expected 14400 bytes");
    assert_one_line_error(&out, "ball_z.raw");
    let out =
        output(vol_app_on("render", &raw_z).args(["--raw-dims", "24,24,24", "--raw-type", "u12"]));
    assert_one_line_error(&out, "unknown raw type 'u12'");
    // A .raw without a description says how to give one.
    let out = output(&mut vol_app_on("info", &raw_z));
    assert_one_line_error(&out, "--raw-dims");
}

#[test]
fn convert_round_trips_through_every_output_format() {
    let dir = TempDir::new("convert");
    let original = ball_file(&dir, VolLayout::Linear);
    let convert = |input: &PathBuf, output: &str, extra: &[&str]| {
        let out_path = dir.path(output);
        run_ok(vol_app_on("convert", input).arg(&out_path).args(extra));
        out_path
    };
    let nii = convert(&original, "a.nii.gz", &[]);
    let nrrd = convert(&nii, "b.nrrd", &["--gzip"]);
    let raw = convert(&nrrd, "c.raw", &[]);
    let vol = convert(
        &raw,
        "d.vol",
        &[
            "--raw-dims",
            "24,24,24",
            "--raw-type",
            "u8",
            "--layout",
            "bricked",
            "--block-size",
            "7",
        ],
    );
    let open = |p: &PathBuf| raycaster::format::open(p, raycaster::storage::LoadMode::Map).unwrap();
    let (a, b) = (open(&original), open(&vol));
    assert_eq!(b.layout(), raycaster::volume::Layout::Bricked { side: 7 });
    let voxels = |v: &raycaster::volume::AnyVolume| -> Vec<f32> {
        let d = v.grid().dims;
        (0..d.x)
            .flat_map(|x| (0..d.y).flat_map(move |y| (0..d.z).map(move |z| UVec3::new(x, y, z))))
            .map(|p| v.value(p))
            .collect()
    };
    assert_eq!(voxels(&a), voxels(&b), "the chain changed the voxels");
    // Never overwrites without --force; a bad window or name is one line.
    let convert_fails = |output_file: &str, extra: &[&str]| {
        output(
            vol_app_on("convert", &original)
                .arg(dir.path(output_file))
                .args(extra),
        )
    };
    assert_one_line_error(&convert_fails("a.nii.gz", &[]), "already exists");
    assert_one_line_error(
        &convert_fails("e.vol", &["--window", "5,5"]),
        "LO must be below HI",
    );
    assert_one_line_error(
        &convert_fails("e.png", &[]),
        "cannot tell the output format",
    );
}

/// `render` and `info` write the macrocell cache next to the file once and
/// then read it (same value range), `--no-cache` neither reads nor writes
/// one, and a damaged cache is one warning line, not a failure.
#[test]
fn the_macrocell_cache_is_written_once_and_a_damaged_one_is_a_warning() {
    let dir = TempDir::new("macrocell_cache");
    let file = ball_file(&dir, VolLayout::Bricked { side: 8 });
    let caches = || -> Vec<PathBuf> {
        std::fs::read_dir(file.parent().unwrap())
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension() == Some("rcidx".as_ref()))
            .collect()
    };
    let range = |out: &Output| -> serde_json::Value {
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        v["value_range"].clone()
    };
    let uncached = run_ok(vol_app_on("info", &file).args(["--json", "--no-cache"]));
    assert_eq!(range(&uncached), serde_json::json!([0.0, 200.0]));
    run_ok(vol_app_on("render", &file).args(["--stats", "--size", "16x16", "--no-cache"]));
    assert!(caches().is_empty(), "--no-cache wrote {:?}", caches());
    run_ok(vol_app_on("render", &file).args(["--stats", "--size", "16x16"]));
    let written = caches();
    assert_eq!(written.len(), 1);
    assert!(written[0].to_string_lossy().ends_with(".vol.m4.rcidx"));
    let bytes = std::fs::read(&written[0]).unwrap();
    let cached = run_ok(vol_app_on("info", &file).arg("--json"));
    assert_eq!(range(&cached), range(&uncached));
    assert_eq!(std::fs::read(&written[0]).unwrap(), bytes, "rewritten");
    std::fs::write(&written[0], &bytes[..bytes.len() - 9]).unwrap();
    let out = run_ok(vol_app_on("render", &file).args(["--stats", "--size", "16x16"]));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.starts_with("vol_app: warning: ") && err.contains("damaged"),
        "{err}"
    );
    assert_eq!(std::fs::read(&written[0]).unwrap(), bytes, "not repaired");
}

/// A directory of three `.vol` frames: balls of radius 4, 6 and 8.
fn frame_directory(dir: &TempDir) -> PathBuf {
    let frames = dir.path("frames");
    std::fs::create_dir_all(&frames).unwrap();
    for (k, r) in [4.0f32, 6.0, 8.0].into_iter().enumerate() {
        radial_vol_file(
            dir,
            &format!("frames/f{k}.vol"),
            UVec3::splat(20),
            VolLayout::Linear,
            |d| if d < r { 200 } else { 0 },
        );
    }
    frames
}

#[test]
fn pack_info_and_render_frames_of_a_sequence() {
    let dir = TempDir::new("cli-seq");
    let frames = frame_directory(&dir);
    let packed = dir.path("balls.vseq");
    let out = run_ok(
        vol_app()
            .arg("pack")
            .arg(&frames)
            .arg("-o")
            .arg(&packed)
            .args(["--codec", "zstd", "--key-interval", "2", "--json"]),
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["frames"], 3);
    assert!(report["percent"].as_f64().unwrap() < 20.0, "{report}");
    // Not replaced without --force, and the message says so.
    assert_one_line_error(
        &output(vol_app().arg("pack").arg(&frames).arg("-o").arg(&packed)),
        "--force",
    );
    // --frames writes into a directory: an image's name is refused, not
    // made a directory.
    let png_out = dir.path("movie.png");
    assert_one_line_error(
        &output(
            vol_app_on("render", &packed)
                .args(["--frames", "0..2", "--out"])
                .arg(&png_out),
        ),
        "a directory",
    );
    assert!(!png_out.exists());
    for source in [&frames, &packed] {
        let out = run_ok(vol_app_on("info", source).arg("--json"));
        let info: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(info["frames"], 3, "{}", source.display());
        assert_eq!(info["dims"], serde_json::json!([20, 20, 20]));
    }
    // Frame K from the packed file is frame K from the directory.
    let png = |name: &str| dir.path(name);
    for k in 0..3 {
        let k = k.to_string();
        run_ok(
            vol_app_on("render", &frames)
                .args(["--frame", &k, "--size", "40x40", "--out"])
                .arg(png("d.png")),
        );
        run_ok(
            vol_app_on("render", &packed)
                .args(["--frame", &k, "--size", "40x40", "--out"])
                .arg(png("p.png")),
        );
        assert_eq!(
            std::fs::read(png("d.png")).unwrap(),
            std::fs::read(png("p.png")).unwrap(),
            "frame {k}"
        );
    }
    // --frames writes one PNG per frame, the same images.
    let movie = dir.path("movie");
    run_ok(
        vol_app_on("render", &packed)
            .args(["--frames", "1..", "--size", "40x40", "--out"])
            .arg(&movie),
    );
    let mut written: Vec<_> = std::fs::read_dir(&movie)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    written.sort();
    assert_eq!(written, ["frame_0001.png", "frame_0002.png"]);
    assert_eq!(
        std::fs::read(movie.join("frame_0002.png")).unwrap(),
        std::fs::read(png("p.png")).unwrap()
    );
    let out = run_ok(
        vol_app_on("render", &packed).args(["--frames", "0..=2", "--size", "40x40", "--stats"]),
    );
    let stats: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(stats["frames"], 3);
    assert_eq!(stats["render_ms"].as_array().unwrap().len(), 3);
    assert!(stats["fps"].as_f64().unwrap() > 0.0);
    // Errors: one line each, naming the problem.
    assert_one_line_error(
        &output(vol_app_on("render", &packed).args(["--frame", "3"])),
        "volume 3 asked for, but the file holds 3",
    );
    assert_one_line_error(
        &output(vol_app_on("render", &packed).args(["--frames", "2..5"])),
        "has 3 frames",
    );
    assert_one_line_error(
        &output(vol_app_on("render", &packed).args(["--frames", "2..1"])),
        "is empty",
    );
    assert_one_line_error(
        &output(vol_app().arg("render").args(["--frame", "1"])),
        "needs a sequence",
    );
    // A frame of other dimensions in the directory is named.
    radial_vol_file(
        &dir,
        "frames/f3.vol",
        UVec3::new(20, 20, 19),
        VolLayout::Linear,
        |_| 0,
    );
    assert_one_line_error(&output(&mut vol_app_on("info", &frames)), "f3.vol");
    assert_one_line_error(
        &output(
            vol_app()
                .arg("pack")
                .arg(&frames)
                .arg("-o")
                .arg(dir.path("bad.vseq")),
        ),
        "frame 3 is 20x20x19",
    );
    assert!(!dir.path("bad.vseq").exists());
}

#[test]
fn metaballs_render_from_points_files_and_volumes() {
    let dir = TempDir::new("metaballs");
    let pts = dir.write(
        "two.csv",
        b"# two balls\nx,y,z,radius,value\n-0.4,0,0,1,100\n0.4,0,0,1,200\n",
    );
    // Every renderer gives the same PNG; --stats reports the balls.
    let mut pngs = Vec::new();
    for renderer in ["serial", "tiles", "object"] {
        let png = dir.path(&format!("{renderer}.png"));
        let out = run_ok(
            vol_app_on("render", &pts)
                .args([
                    "--mode",
                    "metaballs",
                    "--size",
                    "48x40",
                    "--renderer",
                    renderer,
                    "--threads",
                    "2",
                    "--tf-preset",
                    "ramp",
                    "--repeat",
                    "2",
                    "--stats",
                    "--out",
                ])
                .arg(&png),
        );
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["balls"], 2);
        assert_eq!(v["frame_ms"].as_array().unwrap().len(), 2);
        assert!(v["covered"].as_u64().unwrap() > 100, "{v}");
        for key in ["build_ms", "lists_ms_median", "list_entries", "peak_rss_mb"] {
            assert!(!v[key].is_null(), "{key} missing in {v}");
        }
        pngs.push(std::fs::read(&png).unwrap());
    }
    assert!(pngs.windows(2).all(|w| w[0] == w[1]));

    // A volume: one ball per voxel above the threshold; the cap's error.
    let vol = ball_file(&dir, VolLayout::Linear);
    let out = run_ok(vol_app_on("render", &vol).args([
        "--mode",
        "metaballs",
        "--size",
        "32x32",
        "--ball-threshold",
        "100",
        "--ball-stride",
        "2",
        "--kernel",
        "murakami",
        "--shading",
        "off",
        "--stats",
    ]));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(v["balls"].as_u64().unwrap() > 10, "{v}");
    assert!(v["covered"].as_u64().unwrap() > 0, "{v}");
    let out = output(vol_app_on("render", &vol).args([
        "--mode",
        "metaballs",
        "--ball-threshold",
        "100",
        "--max-balls",
        "5",
        "--stats",
    ]));
    assert_one_line_error(&out, "gives more than 5 balls (the cap, --max-balls)");

    // Bad points files and options: one line naming the file and line.
    let bad = dir.write("bad.xyz", b"0 0 0 1\n1 1\n");
    let out = output(vol_app_on("render", &bad).args(["--mode", "metaballs", "--stats"]));
    assert_one_line_error(&out, "bad.xyz: line 2: expected x,y,z");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["--field-threshold", "0"], "--field-threshold"),
        (vec!["--ball-radius", "-1"], "--ball-radius"),
        (vec!["--kernel", "blinn"], "blinn"),
        (vec!["--light", "0,0,0"], "invalid light"),
    ];
    for (args, needle) in cases {
        let out = output(
            vol_app_on("render", &pts)
                .args(["--mode", "metaballs", "--stats"])
                .args(&args),
        );
        assert_one_line_error(&out, needle);
    }
}

/// Without the `mpi` feature `--distributed` is one line saying how to get
/// it; `--distributed-read` and `--composite` need `--distributed`.
#[test]
#[cfg(not(feature = "mpi"))]
fn distributed_without_the_mpi_feature_says_how_to_build_it() {
    let dir = TempDir::new("distributed");
    let file = ball_file(&dir, VolLayout::Linear);
    let out = output(vol_app_on("render", &file).arg("--distributed"));
    assert_one_line_error(&out, "--features vol_app/mpi");
    let out = output(vol_app_on("render", &file).args(["--distributed-read", "whole"]));
    assert!(!out.status.success());
    let out = output(vol_app_on("render", &file).args(["--composite", "binary-swap"]));
    assert!(!out.status.success());
}

/// A reader that stops reading (`vol_app info FILE | head -1`) is not an
/// error: no panic, no message, success.
#[test]
fn output_into_a_closed_pipe_is_not_an_error() {
    let dir = TempDir::new("cli-pipe");
    let file = ball_file(&dir, VolLayout::Linear);
    for json in [false, true] {
        let mut cmd = vol_app_on("info", &file);
        if json {
            cmd.arg("--json");
        }
        let mut child = cmd
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // Closed before the program opens the file, so its first write
        // meets a closed pipe.
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "json {json}: {err}");
        assert!(err.is_empty(), "json {json}: {err}");
    }
}
