//! Soak (issue 17): opens, renders and closes volumes of every format in a
//! loop, through the viewer's loading path (`LoadJob`) and the asynchronous
//! renderer front, with random options, and checks that memory and the
//! thread count come back to their baseline. Ignored by default (it runs
//! for minutes): `scripts/soak.sh [SECONDS]`, or
//! `SOAK_SECONDS=60 cargo test --release --test soak -- --ignored --nocapture`.

mod common;

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::TempDir;
use glam::{UVec3, Vec3};
use raycaster::format::save::{SaveOptions, save};
use raycaster::format::vol::VolLayout;
use raycaster::format::vseq::{PackOptions, pack};
use raycaster::prelude::*;
use raycaster::render::front::{FrameRequest, FrontEvent, FrontOptions, Quality, RendererFront};
use vol_app::viewer::loading::{LoadJob, LoadOptions, Source};

/// `VmRSS` (KiB) and `Threads` of this process, from /proc.
fn rss_and_threads() -> (u64, u64) {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let field = |name: &str| {
        status
            .lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|v| v.parse().ok())
            .unwrap_or(0)
    };
    (field("VmRSS:"), field("Threads:"))
}

/// Files of every writable format holding the same 40×36×32 volume, plus a
/// `.vseq` of it and the DICOM series from ../shared/data when present.
fn files(dir: &Path) -> Vec<PathBuf> {
    let grid = Grid::new(UVec3::new(40, 36, 32), Vec3::new(1.0, 1.2, 0.8));
    let volume = || {
        AnyVolume::from_fn(grid, |p: UVec3| {
            let d = (p.as_vec3() - Vec3::new(20.0, 18.0, 16.0)).length();
            (255.0 - d * 9.0).clamp(0.0, 255.0) as u8
        })
    };
    let mut out = Vec::new();
    for (name, options) in [
        ("linear.vol", SaveOptions::default()),
        (
            "bricked.vol",
            SaveOptions {
                vol_layout: Some(VolLayout::Bricked { side: 8 }),
                ..SaveOptions::default()
            },
        ),
        ("raw.nrrd", SaveOptions::default()),
        (
            "gzip.nrrd",
            SaveOptions {
                gzip: true,
                ..SaveOptions::default()
            },
        ),
        ("plain.nii", SaveOptions::default()),
        ("packed.nii.gz", SaveOptions::default()),
    ] {
        let path = dir.join(name);
        save(&path, &volume(), &options).expect("save");
        out.push(path);
    }
    let seq = dir.join("frames.vseq");
    pack(&seq, 3, |_| Ok(volume()), &PackOptions::default(), None).expect("pack");
    out.push(seq);
    let dicom = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/dicom_mri_series");
    if dicom.is_dir() {
        out.push(dicom);
    }
    out
}

/// One open–render–close cycle with options drawn from `rng`.
fn cycle(path: &Path, rng: &mut fastrand::Rng) -> Result<usize, String> {
    let mode = if rng.bool() {
        LoadMode::Map
    } else {
        LoadMode::Ram
    };
    let job = LoadJob::start(
        Source::File(path.to_path_buf(), mode, None),
        LoadOptions {
            no_cache: rng.bool(),
            ..LoadOptions::default()
        },
        || {},
    );
    let deadline = Instant::now() + Duration::from_secs(60);
    let loaded = loop {
        if let Some(result) = job.poll() {
            break result?;
        }
        if Instant::now() > deadline {
            return Err(format!("{}: load did not finish", path.display()));
        }
        std::thread::sleep(Duration::from_millis(2));
    };
    let kind = RendererKind::ALL[rng.usize(..RendererKind::ALL.len())];
    let renderer = kind.renderer(rng.usize(1..=2)).map_err(|e| e.to_string())?;
    let front = RendererFront::spawn(renderer, loaded.scene.clone(), FrontOptions::default())
        .map_err(|e| e.to_string())?;
    let bounds = loaded.scene.grid().bounds();
    let tf = Arc::new(TransferFunction::preset("ramp", SampleType::U8).expect("ramp"));
    let modes = [
        RenderMode::Dvr,
        RenderMode::Mip,
        RenderMode::Minip,
        RenderMode::Avg,
        RenderMode::Iso,
    ];
    let mut frames = 0;
    let requests = rng.usize(1..=4);
    let mut last = 0;
    for _ in 0..requests {
        let size = rng.u32(24..=96);
        let mut camera = Camera::framing(&bounds, size, size, 30.0 + rng.f32() * 30.0);
        camera.position += Vec3::new(rng.f32() - 0.5, rng.f32() - 0.5, rng.f32() - 0.5) * 20.0;
        let options = RenderOptions {
            mode: modes[rng.usize(..modes.len())],
            shading: rng.bool(),
            ess: rng.bool(),
            iso_value: 128.0,
            ..RenderOptions::default()
        };
        let quality = if rng.bool() {
            Quality::FULL
        } else {
            Quality::draft(rng.u32(2..=4))
        };
        last = front.request(FrameRequest {
            camera,
            tf: tf.clone(),
            options,
            quality,
        });
    }
    // Superseded requests may never report; wait for the last one.
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        match front.events().recv_timeout(Duration::from_millis(100)) {
            Ok(FrontEvent::Ready { id, .. }) => {
                frames += 1;
                if id == last {
                    break;
                }
            }
            Ok(FrontEvent::Failed { id, error }) => {
                if id == last {
                    return Err(format!("{}: {error}", path.display()));
                }
            }
            Err(_) if Instant::now() > deadline => {
                return Err(format!("{}: no frame", path.display()));
            }
            Err(_) => {}
        }
    }
    let _ = front.take_frame();
    front.shutdown();
    Ok(frames)
}

#[test]
#[ignore = "minutes long: scripts/soak.sh"]
fn open_render_close_returns_to_baseline() {
    let seconds: u64 = std::env::var("SOAK_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(60);
    let dir = TempDir::new("soak");
    let files = files(&dir.0);
    let mut rng = fastrand::Rng::with_seed(17);
    // Warm-up: one cycle per file makes the long-lived pools and caches
    // (rayon's global pool, thread-locals, the allocator's arenas).
    for f in &files {
        cycle(f, &mut rng).unwrap_or_else(|e| panic!("warm-up: {e}"));
    }
    // The warm-up's last loader and front threads may still be exiting:
    // take the baseline once the thread count has stopped falling.
    let mut base = rss_and_threads();
    for _ in 0..50 {
        std::thread::sleep(Duration::from_millis(20));
        let now = rss_and_threads();
        if now.1 >= base.1 {
            break;
        }
        base = now;
    }
    let (rss0, threads0) = base;
    let start = Instant::now();
    let (mut cycles, mut frames, mut peak) = (0u64, 0usize, rss0);
    let mut samples = Vec::new();
    while start.elapsed().as_secs() < seconds {
        let f = &files[rng.usize(..files.len())];
        frames += cycle(f, &mut rng).unwrap_or_else(|e| panic!("cycle {cycles}: {e}"));
        cycles += 1;
        let (rss, _) = rss_and_threads();
        peak = peak.max(rss);
        if cycles.is_multiple_of(20) {
            samples.push(rss);
        }
    }
    // Threads of finished jobs and fronts may take a moment to be reaped.
    let mut now = rss_and_threads();
    for _ in 0..50 {
        if now.1 <= threads0 {
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
        now = rss_and_threads();
    }
    let (rss1, threads1) = now;
    // Ten evenly spaced RSS samples show a trend without flooding the log.
    let every = samples.len().div_ceil(10).max(1);
    let samples: Vec<u64> = samples.iter().step_by(every).copied().collect();
    println!(
        "soak: {cycles} cycles, {frames} frames in {:.0} s over {} files; RSS {} -> {} KiB (peak {}), threads {threads0} -> {threads1}; RSS along the way: {samples:?}",
        start.elapsed().as_secs_f64(),
        files.len(),
        rss0,
        rss1,
        peak
    );
    assert!(cycles > 0);
    assert!(
        threads1 <= threads0,
        "threads left behind: {threads0} -> {threads1}"
    );
    // The allocator keeps some freed memory; a leak of a volume a cycle
    // (40×36×32 bytes and more in RAM, plus its scene) would pass this
    // within a few hundred cycles.
    assert!(
        rss1 <= rss0 + 64 * 1024,
        "RSS grew from {rss0} to {rss1} KiB over {cycles} cycles"
    );
}
