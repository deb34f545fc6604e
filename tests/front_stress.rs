//! The asynchronous renderer front under random command sequences.
//!
//! For each renderer kind (and a renderer that fails or panics on some
//! requests), thousands of random sequences of commands are sent to fronts:
//! render, render again before the first frame is finished, cancel, resize
//! (a request of another size or quality), swap the scene, take frames, and
//! drop the front mid-frame. Checked:
//!
//! - every delivered frame belongs to a request that was made, is complete
//!   (the size the request asks for) and is exactly the image a renderer of
//!   the same kind gives for that request on its own;
//! - the newest request, when nothing supersedes it, is always delivered;
//! - failures are reported as events, and the front keeps working;
//! - nothing deadlocks (the whole run has a deadline, every wait a timeout);
//! - no thread is left behind (`/proc/self/task` returns to its count).
//!
//! Everything runs inside one `#[test]` so that no other test's threads
//! disturb the thread count.

mod common;

use std::collections::HashMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use common::{TestLayout, make_pair, phantom};
use glam::Vec3;
use raycaster::prelude::*;

/// How long any single wait may take before it counts as a deadlock.
const WAIT: Duration = Duration::from_secs(20);

fn thread_count() -> usize {
    std::fs::read_dir("/proc/self/task")
        .map(|d| d.count())
        .unwrap_or(0)
}

/// A request the test can make, and the frames it may produce.
struct Config {
    request: FrameRequest,
    /// Index of the scene it is rendered on.
    scene: usize,
}

/// A renderer that errs on 13-pixel-wide frames and panics on 11-pixel-wide
/// ones, otherwise renders serially.
struct Flaky(SerialRenderer);

impl Renderer for Flaky {
    fn name(&self) -> &'static str {
        "flaky"
    }
    fn threads(&self) -> usize {
        1
    }
    fn render_cancellable(
        &mut self,
        scene: &Scene,
        camera: &Camera,
        tf: &TransferFunction,
        options: &RenderOptions,
        cancel: Cancel<'_>,
    ) -> raycaster::Result<Option<Frame>> {
        match camera.width {
            13 => Err(raycaster::Error::option("test", "13 is unlucky")),
            11 => panic!("11 is worse"),
            _ => self
                .0
                .render_cancellable(scene, camera, tf, options, cancel),
        }
    }
}

/// The renderers under test: a constructor per kind.
#[derive(Debug, Clone, Copy)]
enum Kind {
    Any(RendererKind),
    Flaky,
}

fn configs(scenes: &[Arc<Scene>]) -> Vec<Config> {
    let tf = Arc::new(TransferFunction::preset("skull", SampleType::U8).expect("preset"));
    let mut soft = (*tf).clone();
    soft.points[0].opacity = 0.1;
    let soft = Arc::new(soft);
    let mut v = Vec::new();
    for (s, scene) in scenes.iter().enumerate() {
        let b = scene.grid().bounds();
        let c = b.center();
        let d = (b.max - b.min).length();
        let views = [
            (Vec3::new(0.0, 0.0, 1.2), 24, 20),
            (Vec3::new(0.8, 0.6, 0.7), 31, 17),
            (Vec3::new(-0.9, 0.2, -0.5), 40, 40),
            (Vec3::new(0.1, 0.1, 0.1), 20, 20), // inside
            (Vec3::new(0.5, 1.0, 0.3), 13, 10), // errs with `Flaky`
            (Vec3::new(0.0, -1.0, 0.4), 11, 9), // panics with `Flaky`
            (Vec3::new(0.3, 0.4, 1.0), 96, 96), // heavier: gets superseded
        ];
        for (i, (off, w, h)) in views.into_iter().enumerate() {
            let mut camera = Camera::look_at(c + off * d, c, w, h);
            camera.up = Vec3::new(0.0, 1.0, 0.1);
            let heavy = w == 96;
            v.push(Config {
                request: FrameRequest {
                    camera,
                    tf: if i % 2 == 0 { tf.clone() } else { soft.clone() },
                    options: RenderOptions {
                        step: Some(if heavy { 0.1 } else { 0.6 }),
                        mode: [RenderMode::Dvr, RenderMode::Mip, RenderMode::Dvr][i % 3],
                        ert: i % 4 != 1,
                        ..RenderOptions::default()
                    },
                    quality: if i % 3 == 2 && !heavy {
                        Quality::draft(2)
                    } else {
                        Quality::FULL
                    },
                },
                scene: s,
            });
        }
    }
    v
}

fn make_renderer(kind: Kind) -> AnyOrFlaky {
    match kind {
        Kind::Any(k) => AnyOrFlaky::Any(k.renderer(2).expect("renderer")),
        Kind::Flaky => AnyOrFlaky::Flaky(Flaky(SerialRenderer::new())),
    }
}

enum AnyOrFlaky {
    Any(AnyRenderer),
    Flaky(Flaky),
}

/// What a request should give: `Ok(frame)` or an error.
fn expected(kind: Kind, config: &Config, scenes: &[Arc<Scene>]) -> Result<Frame, ()> {
    let r = &config.request;
    let scene = &scenes[config.scene];
    let mut camera = r.camera;
    let d = r.quality.downscale.max(1);
    camera.width = (camera.width / d).max(1);
    camera.height = (camera.height / d).max(1);
    let mut options = r.options.clone();
    if r.quality.step_scale > 1.0 {
        options.step = Some(options.step_for(scene.grid()) * r.quality.step_scale);
    }
    match make_renderer(kind) {
        AnyOrFlaky::Any(mut x) => Ok(x.render(scene, &camera, &r.tf, &options).expect("render")),
        AnyOrFlaky::Flaky(mut x) => {
            let w = camera.width;
            if w == 13 || w == 11 {
                Err(())
            } else {
                Ok(x.render(scene, &camera, &r.tf, &options).expect("render"))
            }
        }
    }
}

fn spawn(kind: Kind, scene: Arc<Scene>, wakes: Arc<AtomicUsize>) -> RendererFront {
    let options = FrontOptions {
        wake: Some(Arc::new(move || {
            wakes.fetch_add(1, Ordering::Relaxed);
        })),
    };
    match make_renderer(kind) {
        AnyOrFlaky::Any(r) => RendererFront::spawn(r, scene, options),
        AnyOrFlaky::Flaky(r) => RendererFront::spawn(Box::new(r), scene, options),
    }
    .expect("spawn")
}

#[derive(Debug, Default)]
struct Tally {
    sequences: usize,
    requests: usize,
    delivered: usize,
    failed: usize,
    dropped_mid_frame: usize,
}

/// Checks one event against the requests made; returns the id it concerns.
fn check_event(
    event: &FrontEvent,
    issued: &HashMap<u64, usize>,
    expect: &[Result<Frame, ()>],
    tally: &mut Tally,
) -> u64 {
    match event {
        FrontEvent::Ready {
            id,
            width,
            height,
            stats,
        } => {
            let &c = issued
                .get(id)
                .unwrap_or_else(|| panic!("frame {id} belongs to no request"));
            let want = expect[c].as_ref().unwrap_or_else(|_| {
                panic!("request {id} (config {c}) should have failed but was delivered")
            });
            assert_eq!((*width, *height), (want.width, want.height), "frame {id}");
            assert_eq!(stats.rays, want.stats.rays, "frame {id}");
            tally.delivered += 1;
            *id
        }
        FrontEvent::Failed { id, error } => {
            let &c = issued
                .get(id)
                .unwrap_or_else(|| panic!("failure {id} belongs to no request"));
            assert!(
                expect[c].is_err(),
                "request {id} (config {c}) failed: {error}"
            );
            tally.failed += 1;
            *id
        }
    }
}

/// Checks the frame in the shared buffer, if any.
fn check_slot(front: &RendererFront, issued: &HashMap<u64, usize>, expect: &[Result<Frame, ()>]) {
    if let Some((id, frame)) = front.take_frame() {
        let &c = issued
            .get(&id)
            .unwrap_or_else(|| panic!("buffered frame {id} belongs to no request"));
        let want = expect[c].as_ref().expect("a failed request has no frame");
        assert_eq!((frame.width, frame.height), (want.width, want.height));
        assert!(
            frame.rgb == want.rgb,
            "frame {id} (config {c}) is not the image of its request"
        );
    }
}

fn run_sequences(kind: Kind, scenes: &[Arc<Scene>], count: usize, seed: u64) -> Tally {
    let configs = configs(scenes);
    let expect: Vec<Result<Frame, ()>> =
        configs.iter().map(|c| expected(kind, c, scenes)).collect();
    let mut rng = fastrand::Rng::with_seed(seed);
    let mut tally = Tally::default();
    let wakes = Arc::new(AtomicUsize::new(0));
    let mut events_seen = 0usize;
    // Fronts live for several sequences, or for one.
    let mut front: Option<RendererFront> = None;
    let mut issued: HashMap<u64, usize> = HashMap::new();
    let mut current_scene = 0usize;
    for _ in 0..count {
        tally.sequences += 1;
        let f = front.get_or_insert_with(|| {
            issued.clear();
            current_scene = 0;
            spawn(kind, scenes[0].clone(), wakes.clone())
        });
        let mut last: Option<u64> = None;
        // Ids whose event was taken in this sequence.
        let mut seen: Vec<u64> = Vec::new();
        for _ in 0..rng.usize(1..7) {
            match rng.u32(0..100) {
                0..=59 => {
                    // Render (again): a config on the current scene.
                    let candidates: Vec<usize> = (0..configs.len())
                        .filter(|&i| configs[i].scene == current_scene)
                        .collect();
                    let c = candidates[rng.usize(0..candidates.len())];
                    let id = f.request(configs[c].request.clone());
                    assert!(issued.insert(id, c).is_none(), "id {id} reused");
                    tally.requests += 1;
                    last = Some(id);
                }
                60..=69 => {
                    f.cancel();
                    last = None;
                }
                70..=74 => {
                    current_scene = (current_scene + 1) % scenes.len();
                    f.set_scene(scenes[current_scene].clone());
                    last = None;
                }
                75..=89 => {
                    // Let the renderer get going (or finish).
                    std::thread::sleep(Duration::from_micros(rng.u64(0..3000)));
                }
                _ => {
                    while let Ok(e) = f.events().try_recv() {
                        seen.push(check_event(&e, &issued, &expect, &mut tally));
                        events_seen += 1;
                    }
                    check_slot(f, &issued, &expect);
                }
            }
        }
        match (rng.u32(0..10), last) {
            (0..=2, _) => {
                // Go away, perhaps mid-frame: drop must cancel and join.
                tally.dropped_mid_frame += 1;
                let start = Instant::now();
                front = None;
                assert!(start.elapsed() < WAIT, "drop took {:?}", start.elapsed());
            }
            (_, Some(id)) if !seen.contains(&id) => {
                // Nothing supersedes the last request: it must arrive.
                let deadline = Instant::now() + WAIT;
                loop {
                    let left = deadline.saturating_duration_since(Instant::now());
                    let e = f
                        .events()
                        .recv_timeout(left)
                        .unwrap_or_else(|_| panic!("request {id} never finished ({kind:?})"));
                    events_seen += 1;
                    if check_event(&e, &issued, &expect, &mut tally) == id {
                        break;
                    }
                }
                check_slot(f, &issued, &expect);
            }
            _ => {}
        }
        if rng.u32(0..8) == 0 {
            front = None;
        }
    }
    drop(front);
    assert!(
        wakes.load(Ordering::Relaxed) >= events_seen,
        "the wake-up callback ran {} times for {events_seen} events",
        wakes.load(Ordering::Relaxed)
    );
    tally
}

#[test]
fn front_survives_random_command_sequences() {
    let dims = [24, 20, 22];
    let scenes: Vec<Arc<Scene>> = [TestLayout::Linear, TestLayout::Bricked(6)]
        .into_iter()
        .map(|l| Arc::new(make_pair(dims, [1.0; 3], l, phantom(dims)).scene))
        .collect();
    // `Flaky` panics on purpose: keep those messages out of the output.
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let msg = info.payload().downcast_ref::<&str>().copied().unwrap_or("");
        if msg != "11 is worse" {
            default_hook(info);
        }
    }));
    let before = thread_count();
    assert!(before > 0, "/proc/self/task not readable");
    let (done_tx, done_rx) = std::sync::mpsc::channel();
    let runner = std::thread::spawn(move || {
        let mut tallies = Vec::new();
        for (i, kind) in [
            Kind::Any(RendererKind::Serial),
            Kind::Any(RendererKind::Tiles),
            Kind::Any(RendererKind::Object),
            Kind::Flaky,
        ]
        .into_iter()
        .enumerate()
        {
            let n = if matches!(kind, Kind::Flaky) {
                300
            } else {
                700
            };
            tallies.push((kind, run_sequences(kind, &scenes, n, 100 + i as u64)));
        }
        let _ = done_tx.send(tallies);
    });
    let tallies = match done_rx.recv_timeout(Duration::from_secs(120)) {
        Ok(t) => t,
        Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
            // The runner failed a check: report its panic.
            match runner.join() {
                Err(panic) => std::panic::resume_unwind(panic),
                Ok(()) => unreachable!("the runner ended without a result"),
            }
        }
        Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
            panic!("the stress run did not finish in 120 s: deadlock")
        }
    };
    runner.join().expect("runner");
    let mut sequences = 0;
    for (kind, t) in &tallies {
        println!("{kind:?}: {t:?}");
        sequences += t.sequences;
        assert!(t.delivered > 0, "{kind:?}: nothing delivered");
        assert!(
            t.delivered < t.requests,
            "{kind:?}: no request was ever superseded ({t:?})"
        );
    }
    assert!(sequences >= 2000);
    assert!(tallies.iter().any(|(_, t)| t.failed > 0));
    // Renderer threads end shortly after their owners (rayon pools shut down
    // asynchronously): wait for the count to come back.
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        let now = thread_count();
        if now <= before {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "{} threads leaked ({before} before, {now} after)",
            now - before
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}
