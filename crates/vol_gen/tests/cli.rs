//! End-to-end tests of the `vol_gen` binary: round trips through the
//! library's reader, file sizes (26-byte header plus the samples),
//! determinism, safety (overwrite, bad arguments, Ctrl-C) and the reference
//! implementation's argument spellings (`--dims=X,Y,Z`, `--layout z`, `-o`).

mod common;

use std::path::Path;
use std::time::{Duration, Instant};

use common::{TempDir, args_around, run, run_ok, stderr, vol_gen};

use glam::UVec3;
use raycaster::format::vol;
use raycaster::storage::LoadMode;

const GENERATORS: [&str; 6] = ["shapes", "solid", "noise", "sphere", "sdf", "metaballs"];

/// The file length of the `.vol` format (26 header bytes, then X·Y·Z samples
/// or, bricked, nx·ny·nz·B³), computed independently of the library.
fn spec_len(dims: [u64; 3], side: Option<u64>) -> u64 {
    match side {
        None => 26 + dims[0] * dims[1] * dims[2],
        Some(b) => {
            let n = |d: u64| if d == 1 { 1 } else { (d - 1).div_ceil(b - 1) };
            26 + n(dims[0]) * n(dims[1]) * n(dims[2]) * b * b * b
        }
    }
}

fn voxels(path: &Path) -> (UVec3, Vec<u8>) {
    let v = vol::open(path, LoadMode::Map).unwrap();
    let read = |v: &dyn Fn(UVec3) -> u8, d: UVec3| {
        let mut out = Vec::new();
        for x in 0..d.x {
            for y in 0..d.y {
                for z in 0..d.z {
                    out.push(v(UVec3::new(x, y, z)));
                }
            }
        }
        out
    };
    let d = v.grid().dims;
    (d, read(&|p| v.value(p) as u8, d))
}

#[test]
fn every_generator_round_trips_linear_and_bricked() {
    let dir = TempDir::new("roundtrip");
    let dims = [37u64, 20, 9];
    for generator in GENERATORS {
        let base = format!(
            "--dims 37,20,9 --generator {generator} --seed 11 --quiet --n-of-shapes 6 \
             --object-size 10 --shape 1,1.5,2"
        );
        let linear = dir.path(&format!("{generator}_linear.vol"));
        run_ok(&args_around(&format!("{base} -o"), &linear, ""));
        assert_eq!(
            std::fs::metadata(&linear).unwrap().len(),
            spec_len(dims, None)
        );
        let (d, want) = voxels(&linear);
        assert_eq!(d, UVec3::new(37, 20, 9));
        assert!(want.iter().any(|&v| v != 0), "{generator} is all zero");
        if generator != "solid" {
            assert!(
                want.contains(&0) || generator == "noise",
                "{generator} has no background"
            );
        }
        for side in [2u64, 5, 16] {
            let bricked = dir.path(&format!("{generator}_b{side}.vol"));
            let args = format!("{base} --layout bricked --block-size {side} -o");
            run_ok(&args_around(&args, &bricked, ""));
            assert_eq!(
                std::fs::metadata(&bricked).unwrap().len(),
                spec_len(dims, Some(side)),
                "{generator} B={side}"
            );
            let (_, got) = voxels(&bricked);
            assert!(
                got == want,
                "{generator}: bricked B={side} differs from linear"
            );
        }
    }
}

#[test]
fn degenerate_dimensions_round_trip() {
    let dir = TempDir::new("degenerate");
    for dims in ["1,1,1", "1,7,1", "5,1,3"] {
        let d: Vec<u64> = dims.split(',').map(|s| s.parse().unwrap()).collect();
        let linear = dir.path("l.vol");
        let bricked = dir.path("b.vol");
        let solid = format!("--dims {dims} -g solid --sample 7 -q -f");
        run_ok(&args_around(&format!("{solid} -o"), &linear, ""));
        let args = format!("{solid} --layout z --block-size 3 -o");
        run_ok(&args_around(&args, &bricked, ""));
        assert_eq!(
            std::fs::metadata(&linear).unwrap().len(),
            spec_len([d[0], d[1], d[2]], None)
        );
        assert_eq!(
            std::fs::metadata(&bricked).unwrap().len(),
            spec_len([d[0], d[1], d[2]], Some(3))
        );
        let (_, a) = voxels(&linear);
        let (_, b) = voxels(&bricked);
        assert_eq!(a, b);
        assert!(a.iter().all(|&v| v == 7));
    }
}

#[test]
fn output_does_not_depend_on_the_thread_count() {
    let dir = TempDir::new("threads");
    // Large enough for several batches and many pieces per batch.
    for (generator, layout) in [
        ("shapes", "linear"),
        ("shapes", "z"),
        ("metaballs", "z"),
        ("noise", "linear"),
    ] {
        let mut files = Vec::new();
        for threads in ["1", "2"] {
            let path = dir.path(&format!("{generator}_{layout}_{threads}.vol"));
            let args = format!(
                "--dims 190,150,170 -g {generator} --seed 4 --layout {layout} --block-size 9 \
                 --n-of-shapes 40 --object-size 30 --octaves 2 -q -o"
            );
            let out = vol_gen()
                .env("RAYON_NUM_THREADS", threads)
                .args(args_around(&args, &path, ""))
                .output()
                .unwrap();
            assert!(out.status.success(), "{}", stderr(&out));
            files.push(std::fs::read(&path).unwrap());
        }
        assert!(
            files[0] == files[1],
            "{generator} {layout}: 1 and 2 threads differ"
        );
    }
}

#[test]
fn a_random_seed_is_printed_and_repeats_the_volume() {
    let dir = TempDir::new("seed");
    let a = dir.path("a.vol");
    let shapes = "--dims 30,20,10 -g shapes";
    let out = run_ok(&args_around(&format!("{shapes} -o"), &a, ""));
    let err = stderr(&out);
    let seed = err
        .split_whitespace()
        .skip_while(|w| *w != "seed")
        .nth(1)
        .unwrap_or_else(|| panic!("no seed in {err:?}"))
        .to_string();
    let b = dir.path("b.vol");
    run_ok(&args_around(
        &format!("{shapes} --seed {seed} -q -o"),
        &b,
        "",
    ));
    assert!(std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap());
    let c = dir.path("c.vol");
    let other = (seed.parse::<u64>().unwrap() ^ 1).to_string();
    run_ok(&args_around(
        &format!("{shapes} --seed {other} -q -o"),
        &c,
        "",
    ));
    assert!(std::fs::read(&a).unwrap() != std::fs::read(&c).unwrap());
    // `--quiet` prints nothing on success, a random seed neither.
    let d = dir.path("d.vol");
    let out = run_ok(&args_around(&format!("{shapes} -q -o"), &d, ""));
    assert_eq!(stderr(&out), "");
}

#[test]
fn refuses_to_overwrite_without_force() {
    let dir = TempDir::new("overwrite");
    let path = dir.path("v.vol");
    std::fs::write(&path, b"precious").unwrap();
    let out = run(&args_around("--dims 4,4,4 -g solid -o", &path, ""));
    assert!(!out.status.success());
    assert!(stderr(&out).contains("--force"), "{}", stderr(&out));
    assert_eq!(std::fs::read(&path).unwrap(), b"precious");
    run_ok(&args_around(
        "--dims 4,4,4 -g solid -q --force -o",
        &path,
        "",
    ));
    assert_eq!(std::fs::metadata(&path).unwrap().len(), 26 + 64);
    assert_eq!(dir.entries(), ["v.vol"]);
}

#[test]
fn bad_arguments_give_one_line_and_no_file() {
    let dir = TempDir::new("badargs");
    let out_file = dir.path("x.vol");
    let cases: &[(&str, &str)] = &[
        ("--dims 5,5,5 -g solid --layout z --block-size 1", "2..=255"),
        (
            "--dims 5,5,5 -g solid --layout z --block-size 256",
            "2..=255",
        ),
        ("--dims 0,5,5 -g solid", "at least 1"),
        ("--dims 5,5,0 -g solid", "at least 1"),
        ("--dims 5,5 -g solid", "three"),
        ("--dims 5,5,5 -g solid --shape 1,NaN,1", "finite"),
        ("--dims 5,5,5 -g solid --shape 0,1,1", "finite"),
        ("--dims 5,5,5 -g solid --shape 1,1,inf", "finite"),
        (
            "--dims 4294967295,4294967295,4294967295 -g solid",
            "overflow",
        ),
        (
            "--dims 4294967295,4294967295,4294967295 -g solid --layout z --block-size 2",
            "overflow",
        ),
        ("--dims 100000,100000,100000 -g solid", "free space"),
        ("--dims 5,5,5 -g plasma", "plasma"),
        ("--dims 5,5,5 -g noise --octaves 0", "octaves"),
        ("--dims 5,5,5 -g sdf --band NaN", "band"),
        ("--dims 5,5,5 -g shapes --object-size 0", "object-size"),
        (
            "--dims 5,5,5 -g shapes --n-of-shapes 4000000000",
            "n-of-shapes",
        ),
        ("--dims 5,5,5 -g solid --sample 256", "256"),
        ("-g solid", "--dims"),
    ];
    for (args, needle) in cases {
        let out = run(&args_around(&format!("{args} -o"), &out_file, ""));
        let err = stderr(&out);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
        assert!(err.starts_with("vol_gen: error: "), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err} lacks {needle}");
        assert!(
            !err.contains("panicked") && !err.contains("backtrace"),
            "{err}"
        );
        assert!(
            dir.entries().is_empty(),
            "{args:?} left {:?}",
            dir.entries()
        );
    }
    let missing = run(&args_around(
        "--dims 5,5,5 -g solid -o",
        Path::new("/nonexistent-dir/x.vol"),
        "",
    ));
    assert!(!missing.status.success());
    assert_eq!(stderr(&missing).lines().count(), 1);
}

#[test]
fn help_documents_every_generator_and_its_parameters() {
    let out = run_ok(&["--help"]);
    let help = String::from_utf8_lossy(&out.stdout);
    for g in GENERATORS {
        assert!(help.contains(g), "{g}");
    }
    for option in [
        "--n-of-shapes",
        "--object-size",
        "--sample",
        "--octaves",
        "--band",
        "--block-size",
        "--force",
        "--quiet",
    ] {
        assert!(help.contains(option), "{option}");
    }
}

#[test]
fn thesis_commands_run_unchanged() {
    let dir = TempDir::new("thesis");
    // The command that made shared/data/interop/shapes_96x80x64_*.vol.
    let interop = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/interop");
    for (layout, name) in [("--layout z --block-size 16", "block16"), ("", "linear")] {
        let path = dir.path(&format!("shapes_96x80x64_{name}.vol"));
        run_ok(&args_around(
            "--dims=96,80,64 --generator shapes --seed 3 --n-of-shapes 8 --sample 100 \
             --object-size 24 --output-file",
            &path,
            layout,
        ));
        let ours = std::fs::read(&path).unwrap();
        let reference = interop.join(format!("shapes_96x80x64_{name}.vol"));
        if let Ok(theirs) = std::fs::read(&reference) {
            assert_eq!(ours.len(), theirs.len(), "{name}");
            assert_eq!(ours[..26], theirs[..26], "{name}: header");
        }
        // Shape values within ±8 of --sample, as in the reference output.
        assert!(
            ours[26..]
                .iter()
                .all(|&v| v == 0 || (92..=108).contains(&v))
        );
    }
    // The README's 800³ command, shrunk, with -o.
    let path = dir.path("800shapes_block16.vol");
    run_ok(&args_around(
        "--dims=80,80,80 --generator shapes --seed 2 --n-of-shapes 70 --sample 100 -o",
        &path,
        "--layout z --block-size 16 --object-size 7",
    ));
    assert_eq!(
        std::fs::metadata(&path).unwrap().len(),
        spec_len([80, 80, 80], Some(16))
    );
}

#[cfg(unix)]
#[test]
fn sigint_leaves_no_file() {
    interrupt_midway(libc::SIGINT, "sigint");
}

#[cfg(unix)]
#[test]
fn sigterm_leaves_no_file() {
    interrupt_midway(libc::SIGTERM, "sigterm");
}

/// Starts a long generation, sends `signal` once samples are being written,
/// and checks that vol_gen stops promptly with exit code 130 and no file.
#[cfg(unix)]
fn interrupt_midway(signal: libc::c_int, name: &str) {
    let dir = TempDir::new(name);
    let path = dir.path("big.vol");
    // Slow enough (16 octaves of noise, 216 MB) to be interrupted midway.
    let mut child = vol_gen()
        .args(args_around(
            "--dims 600,600,600 -g noise --octaves 16 --seed 1 -q -o",
            &path,
            "",
        ))
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let temp = dir.path(&format!(".big.vol.partial-{}", child.id()));
    let start = Instant::now();
    // Wait until samples are being written to the temporary file.
    while std::fs::metadata(&temp).map_or(true, |m| m.len() <= 26) {
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "no temporary file appeared"
        );
        assert!(child.try_wait().unwrap().is_none(), "vol_gen ended early");
        std::thread::sleep(Duration::from_millis(20));
    }
    // SAFETY: sending a signal to our own child process.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, signal) }, 0);
    let sent = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if sent.elapsed() > Duration::from_secs(20) {
            let _ = child.kill();
            panic!("vol_gen did not stop after {name}");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    assert_eq!(status.code(), Some(130), "{err}");
    assert_eq!(
        err.trim(),
        "vol_gen: error: interrupted; no file was written"
    );
    assert!(!path.exists(), "output exists after {name}");
    assert!(dir.entries().is_empty(), "left behind: {:?}", dir.entries());
}
