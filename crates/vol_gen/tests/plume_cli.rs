//! End-to-end tests of `vol_gen --generator plume --frames N`: the frame
//! directory (names in frame order, f32 NRRD read back by the library),
//! determinism (seed, thread count, a shorter run giving the first frames),
//! closeness of consecutive frames, and the errors (--frames with another
//! generator, a non-empty directory without --force, wrong output names).

mod common;

use std::path::Path;

use common::{TempDir, run, run_ok, stderr};
use glam::{UVec3, Vec3};
use raycaster::format;
use raycaster::sample::SampleType;
use raycaster::storage::LoadMode;

/// `vol_gen` with `args` (words) and `-o out`.
fn gen_args(args: &str, out: &Path) -> Vec<String> {
    let mut v: Vec<String> = args.split_whitespace().map(String::from).collect();
    v.push("-o".into());
    v.push(out.to_str().unwrap().into());
    v
}

fn gen_ok(args: &str, out: &Path) {
    let a = gen_args(args, out);
    run_ok(&a.iter().map(String::as_str).collect::<Vec<_>>());
}

/// The names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Every voxel of an f32 file, x fastest.
fn values(file: &Path) -> (UVec3, Vec3, Vec<f32>) {
    let v = format::open(file, LoadMode::Ram).unwrap();
    assert_eq!(v.sample_type(), SampleType::F32, "{}", file.display());
    let g = *v.grid();
    let mut out = Vec::new();
    for z in 0..g.dims.z {
        for y in 0..g.dims.y {
            for x in 0..g.dims.x {
                out.push(v.value(UVec3::new(x, y, z)));
            }
        }
    }
    (g.dims, g.spacing, out)
}

fn mean_abs_diff(a: &[f32], b: &[f32]) -> f64 {
    let sum: f64 = a.iter().zip(b).map(|(x, y)| f64::from((x - y).abs())).sum();
    sum / a.len() as f64
}

const BASE: &str = "--dims 30,20,18 --shape 1,1,1.5 --generator plume --seed 5 --quiet";

#[test]
fn frames_land_in_a_directory_in_name_order() {
    let dir = TempDir::new("plume-dir");
    let seq = dir.path("seq");
    // A trailing slash and a directory that does not exist yet.
    let slash = format!("{}/", seq.display());
    gen_ok(&format!("{BASE} --frames 12"), Path::new(&slash));
    let want: Vec<String> = (0..12).map(|k| format!("frame_{k:04}.nrrd")).collect();
    assert_eq!(names(&seq), want);
    let frames: Vec<Vec<f32>> = want
        .iter()
        .map(|n| {
            let (dims, spacing, v) = values(&seq.join(n));
            assert_eq!(dims, UVec3::new(30, 20, 18));
            assert_eq!(spacing, Vec3::new(1.0, 1.0, 1.5));
            v
        })
        .collect();
    for (k, f) in frames.iter().enumerate() {
        let lo = f.iter().copied().fold(f32::INFINITY, f32::min);
        let hi = f.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        assert!(lo >= 0.99 && hi <= 1.5, "frame {k}: {lo}..{hi}");
        // A nozzle 4 voxels wide: its centre falls between voxels.
        assert!(hi > 1.2, "frame {k}: no hot plume ({hi})");
    }
    // Every frame differs from the last, by little; the sequence moves.
    let span = 0.51;
    let mut worst: f64 = 0.0;
    for w in frames.windows(2) {
        let d = mean_abs_diff(&w[0], &w[1]);
        assert!(d > 0.0);
        worst = worst.max(d);
    }
    assert!(worst < 0.01 * span, "neighbours differ by {worst}");
    let far = mean_abs_diff(&frames[0], &frames[11]);
    assert!(
        far > 3.0 * worst,
        "frames 0 and 11: {far}, neighbours {worst}"
    );
}

#[test]
fn same_bytes_per_seed_whatever_the_threads_and_the_frame_count() {
    let dir = TempDir::new("plume-det");
    let (a, b, short, other) = (
        dir.path("a"),
        dir.path("b"),
        dir.path("short"),
        dir.path("other"),
    );
    gen_ok(&format!("{BASE} --frames 4 --threads 1"), &a);
    gen_ok(&format!("{BASE} --frames 4 --threads 3"), &b);
    gen_ok(&format!("{BASE} --frames 2 --threads 2"), &short);
    gen_ok(
        &format!("{} --frames 4", BASE.replace("--seed 5", "--seed 6")),
        &other,
    );
    let read = |d: &Path, k: u32| std::fs::read(d.join(format!("frame_{k:04}.nrrd"))).unwrap();
    for k in 0..4 {
        assert_eq!(read(&a, k), read(&b, k), "frame {k}");
        assert_ne!(read(&a, k), read(&other, k), "frame {k}");
    }
    assert_eq!(names(&short).len(), 2);
    for k in 0..2 {
        assert_eq!(read(&a, k), read(&short, k), "frame {k}");
    }
    // One frame into one file: the same bytes as frame 0 of the directory.
    let one = dir.path("one.nrrd");
    gen_ok(BASE, &one);
    assert_eq!(std::fs::read(&one).unwrap(), read(&a, 0));
}

#[test]
fn an_occupied_directory_needs_force_which_replaces_the_old_frames() {
    let dir = TempDir::new("plume-force");
    let seq = dir.path("seq");
    gen_ok(&format!("{BASE} --frames 5"), &seq);
    std::fs::write(seq.join("notes.txt"), "keep me").unwrap();
    let before = std::fs::read(seq.join("frame_0001.nrrd")).unwrap();
    let args = gen_args(
        &format!("{} --frames 2", BASE.replace("--seed 5", "--seed 9")),
        &seq,
    );
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = run(&args);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.contains("not empty") && err.contains("--force"),
        "{err}"
    );
    assert!(err.contains("seq"), "{err}");
    assert_eq!(std::fs::read(seq.join("frame_0001.nrrd")).unwrap(), before);
    assert_eq!(names(&seq).len(), 6);
    let mut forced = args.clone();
    forced.push("--force");
    run_ok(&forced);
    assert_eq!(
        names(&seq),
        ["frame_0000.nrrd", "frame_0001.nrrd", "notes.txt"]
    );
    assert_ne!(std::fs::read(seq.join("frame_0001.nrrd")).unwrap(), before);
}

#[test]
fn bad_requests_are_one_line_and_write_nothing() {
    let dir = TempDir::new("plume-bad");
    let out = dir.path("out");
    let file = dir.path("f.nrrd");
    let cases: [(String, &Path, &str); 7] = [
        (
            "--dims 8,8,8 -g noise --frames 3".into(),
            &out,
            "only --generator plume",
        ),
        (
            "--dims 8,8,8 -g shapes --frames 2 --seed 1".into(),
            &file,
            "only --generator plume",
        ),
        (
            "--dims 8,8,8 -g plume --frames 3".into(),
            &file,
            "directory",
        ),
        (
            "--dims 8,8,8 -g plume".into(),
            &dir.path("f.vol"),
            "float format",
        ),
        (
            "--dims 8,8,8 -g plume --frames 2 --value-range 1.5,1".into(),
            &out,
            "LO < HI",
        ),
        (
            "--dims 8,8,8 -g solid --value-range 1,2".into(),
            &out,
            "--value-range",
        ),
        ("--dims 8,8,8 -g plume --frames 0".into(), &out, "--frames"),
    ];
    for (args, path, expected) in cases {
        let a = gen_args(&args, path);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        let result = run(&a);
        let err = stderr(&result);
        assert!(!result.status.success(), "{args}");
        assert_eq!(err.trim_end().lines().count(), 1, "{args}: {err}");
        assert!(err.contains(expected), "{args}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert_eq!(dir.entries(), Vec::<String>::new(), "{args}");
    }
}

#[test]
fn help_documents_the_plume() {
    let out = run_ok(&["--help"]);
    let help = String::from_utf8_lossy(&out.stdout);
    for word in [
        "plume",
        "--frames",
        "--value-range",
        "frame_0000.nrrd",
        "0.99,1.5",
    ] {
        assert!(help.contains(word), "{word}");
    }
}

/// Ctrl-C in the middle of a long sequence: exit code 130, and the frames
/// already written and the directory this run created are gone.
#[cfg(unix)]
#[test]
fn sigint_removes_the_frames_written() {
    use std::time::{Duration, Instant};
    let dir = TempDir::new("plume-sigint");
    let seq = dir.path("seq");
    let args = gen_args(
        "--dims 64,64,64 -g plume --frames 2000 --seed 1 --quiet",
        &seq,
    );
    let mut child = common::vol_gen()
        .args(&args)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    // Wait until a few frames are complete.
    while !seq.join("frame_0002.nrrd").exists() {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no frames appeared"
        );
        assert!(child.try_wait().unwrap().is_none(), "vol_gen ended early");
        std::thread::sleep(Duration::from_millis(20));
    }
    // SAFETY: sending a signal to our own child process.
    assert_eq!(
        unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) },
        0
    );
    let sent = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if sent.elapsed() > Duration::from_secs(20) {
            let _ = child.kill();
            panic!("vol_gen did not stop after SIGINT");
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
    assert!(dir.entries().is_empty(), "left behind: {:?}", dir.entries());
}

#[test]
fn a_vseq_output_holds_the_directory_frames() {
    let dir = TempDir::new("plume-vseq");
    let frames = dir.path("frames");
    let packed = dir.path("plume.vseq");
    let args = "--dims 12,10,8 -g plume --frames 4 --seed 5 --shape 1,1,2";
    gen_ok(args, &frames);
    gen_ok(args, &packed);
    let open = |p: &Path| raycaster::sequence::Sequence::open(p, &Default::default()).unwrap();
    let (a, b) = (open(&frames), open(&packed));
    assert_eq!(b.frames(), 4);
    assert!(b.packed().is_some());
    for k in 0..4 {
        let file = frames.join(format!("frame_{k:04}.nrrd"));
        let (dims, spacing, want) = values(&file);
        let v = b.frame(k).unwrap();
        assert_eq!((v.grid().dims, v.grid().spacing), (dims, spacing));
        let got: Vec<f32> = (0..dims.z)
            .flat_map(|z| {
                (0..dims.y).flat_map(move |y| (0..dims.x).map(move |x| UVec3::new(x, y, z)))
            })
            .map(|p| v.value(p))
            .collect();
        assert!(got == want, "frame {k}");
        assert_eq!(a.frame(k).unwrap().grid().dims, dims);
    }
    // Not replaced without --force.
    let a = gen_args(args, &packed);
    let result = run(&a.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(!result.status.success());
    assert!(stderr(&result).contains("--force"), "{}", stderr(&result));
}
