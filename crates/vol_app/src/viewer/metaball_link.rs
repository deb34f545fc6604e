//! The viewer's Metaballs mode (issue 14): frames rendered by the library's
//! [`MetaballRenderer`] from balls made of the volume on screen, on a thread
//! of their own, so the UI never waits.
//!
//! [`RenderLink`](super::render_link::RenderLink) sends a request here
//! instead of to the volume renderer's front when its mode is
//! [`RenderMode::Metaballs`](raycaster::integrator::RenderMode::Metaballs).
//! The thread renders the newest request it has (older ones waiting behind
//! it are dropped) and keeps what it built between frames, rebuilding only
//! what a change needs:
//!
//! - the balls (`Balls::from_volume`) when the volume, the ball threshold,
//!   stride, radius or cap change;
//! - the [`MetaballRenderer`] when the renderer or its threads change;
//! - nothing else: the kernel, the field threshold, lights, shading, TF and
//!   camera only change the frame.

use std::sync::Arc;
use std::time::Instant;

use crossbeam_channel::{Receiver, Sender};
use raycaster::metaballs::{Balls, Extraction, Kernel, MetaballOptions, MetaballRenderer};
use raycaster::render::RendererKind;

use super::render_link::{RenderFailure, RenderRequest, RenderedFrame};

/// The parameters of the Metaballs mode, in data and world units (the
/// viewer's panel turns its settings into these).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MetaballParams {
    /// A voxel gives a ball when its value exceeds this (data units).
    pub threshold: f32,
    /// Every `stride`-th voxel per axis (≥ 1).
    pub stride: u32,
    /// Ball radius, world units.
    pub radius: f32,
    /// The kernel.
    pub kernel: Kernel,
    /// The surface is where the summed field equals this (> 0).
    pub field_threshold: f32,
    /// More balls than this is an error that says how to get fewer.
    pub max_balls: usize,
}

impl Default for MetaballParams {
    fn default() -> Self {
        MetaballParams {
            threshold: 0.0,
            stride: 2,
            radius: 1.0,
            kernel: Kernel::Wyvill,
            field_threshold: 0.5,
            max_balls: MAX_BALLS,
        }
    }
}

/// The viewer's cap on balls (as `vol_app render`'s default `--max-balls`).
pub const MAX_BALLS: usize = 2_000_000;

/// What a metaball frame adds to [`RenderedFrame`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MetaballInfo {
    /// Balls in the frame.
    pub balls: usize,
    /// Time the balls took to make (when this frame made them).
    pub build_ms: f64,
    /// How many times this thread has made balls so far (a frame whose
    /// change did not need new balls leaves it unchanged).
    pub builds: u64,
}

/// One request and the link's number for it.
struct Job {
    id: u64,
    request: RenderRequest,
}

/// The answer to a `Job`.
pub type Reply = Result<RenderedFrame, RenderFailure>;

/// The handle [`RenderLink`](super::render_link::RenderLink) holds; dropping
/// it ends the thread after the frame in progress.
pub struct MetaballWorker {
    jobs: Sender<Job>,
    replies: Receiver<Reply>,
}

impl MetaballWorker {
    /// Starts the thread; it calls `wake` after each reply.
    pub fn spawn(wake: Arc<dyn Fn() + Send + Sync>) -> Result<Self, String> {
        let (jobs, job_rx) = crossbeam_channel::unbounded::<Job>();
        let (reply_tx, replies) = crossbeam_channel::unbounded();
        std::thread::Builder::new()
            .name("vol_app-metaballs".into())
            .spawn(move || {
                let mut state = State::default();
                while let Ok(mut job) = job_rx.recv() {
                    // The newest request wins.
                    while let Ok(newer) = job_rx.try_recv() {
                        job = newer;
                    }
                    let reply = state.render(&job);
                    if reply_tx.send(reply).is_err() {
                        break;
                    }
                    wake();
                }
            })
            .map_err(|e| format!("cannot start the metaball thread: {e}"))?;
        Ok(MetaballWorker { jobs, replies })
    }

    /// Queues request `id`.
    pub fn send(&self, id: u64, request: RenderRequest) -> Result<(), String> {
        self.jobs
            .send(Job { id, request })
            .map_err(|_| "the metaball thread stopped".to_string())
    }

    /// The replies received so far, oldest first.
    pub fn replies(&self) -> &Receiver<Reply> {
        &self.replies
    }
}

/// What the balls were made from.
#[derive(Debug, Clone, PartialEq)]
struct BallsKey {
    scene: u64,
    threshold: f32,
    stride: u32,
    radius: f32,
    max_balls: usize,
}

/// What the thread keeps between frames.
#[derive(Default)]
struct State {
    balls: Option<(BallsKey, Balls)>,
    renderer: Option<(RendererKind, usize, MetaballRenderer)>,
    builds: u64,
}

impl State {
    fn render(&mut self, job: &Job) -> Reply {
        let fail = |message: String| RenderFailure {
            id: job.id,
            message,
        };
        let r = &job.request;
        let p = r.metaballs;
        let key = BallsKey {
            scene: r.scene.id(),
            threshold: p.threshold,
            stride: p.stride,
            radius: p.radius,
            max_balls: p.max_balls,
        };
        let mut build_ms = 0.0;
        if self.balls.as_ref().is_none_or(|(k, _)| *k != key) {
            // Free the old balls before making new ones.
            self.balls = None;
            let start = Instant::now();
            let ex = Extraction {
                threshold: p.threshold,
                stride: p.stride,
                radius: Some(p.radius),
                max_balls: Some(p.max_balls),
            };
            let balls = Balls::from_volume(r.scene.volume(), &ex).map_err(|e| match e {
                // The library's message names the command line's options.
                raycaster::Error::TooManyBalls { cap, .. } => fail(format!(
                    "more than {cap} balls: raise the ball threshold or the stride"
                )),
                e => fail(e.to_string()),
            })?;
            build_ms = start.elapsed().as_secs_f64() * 1e3;
            self.builds += 1;
            self.balls = Some((key, balls));
        }
        if self
            .renderer
            .as_ref()
            .is_none_or(|(k, t, _)| *k != r.renderer || *t != r.threads)
        {
            let renderer =
                MetaballRenderer::new(r.renderer, r.threads).map_err(|e| fail(e.to_string()))?;
            self.renderer = Some((r.renderer, r.threads, renderer));
        }
        let (Some((_, balls)), Some((_, _, renderer))) = (&self.balls, &mut self.renderer) else {
            return Err(fail("no balls or renderer".into()));
        };
        // The level's reduced size, as the volume renderer's front makes it.
        let mut camera = r.camera;
        [camera.width, camera.height] = r.level.size([camera.width, camera.height]);
        let options = MetaballOptions {
            kernel: p.kernel,
            field_threshold: p.field_threshold,
            shading: r.options.shading,
            phong: None,
            lights: r.options.lights.clone(),
            background: r.options.background,
            shadows: r.options.shadows,
        };
        let (frame, _) = renderer
            .render(balls, &camera, Some(&r.tf), &options)
            .map_err(|e| fail(e.to_string()))?;
        Ok(RenderedFrame {
            id: job.id,
            frame,
            camera: r.camera,
            level: r.level,
            preview: r.preview,
            step: 0.0,
            renderer: renderer.name(),
            threads: renderer.threads(),
            metaballs: Some(MetaballInfo {
                balls: balls.len(),
                build_ms,
                builds: self.builds,
            }),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{UVec3, Vec3};
    use raycaster::prelude::*;

    use crate::viewer::progressive::Level;

    fn request(params: MetaballParams) -> RenderRequest {
        let grid = Grid::new(UVec3::splat(12), Vec3::ONE);
        let volume = AnyVolume::from_fn(grid, |v| {
            if (v.as_vec3() - Vec3::splat(5.5)).length() < 4.0 {
                200u8
            } else {
                0
            }
        });
        let scene = Arc::new(Scene::new(volume));
        let camera = Camera::framing(&scene.grid().bounds(), 24, 24, 45.0);
        RenderRequest {
            scene,
            camera,
            tf: TransferFunction::preset("ramp", SampleType::U8).unwrap(),
            options: RenderOptions {
                mode: raycaster::integrator::RenderMode::Metaballs,
                ..RenderOptions::default()
            },
            renderer: RendererKind::Serial,
            threads: 1,
            level: Level::new(2, 1),
            preview: true,
            metaballs: params,
        }
    }

    /// Too many balls is a message in the viewer's terms; a frame comes at
    /// the level's size and counts its balls.
    #[test]
    fn frames_come_at_the_levels_size_and_too_many_balls_is_a_viewer_message() {
        let params = MetaballParams {
            threshold: 100.0,
            stride: 1,
            radius: 1.5,
            ..MetaballParams::default()
        };
        let mut state = State::default();
        let job = |params| Job {
            id: 7,
            request: request(params),
        };
        let f = state.render(&job(params)).unwrap();
        assert_eq!((f.id, f.frame.width, f.frame.height), (7, 12, 12));
        let info = f.metaballs.unwrap();
        assert!(info.balls > 100 && info.builds == 1, "{info:?}");
        let e = state
            .render(&job(MetaballParams {
                max_balls: 10,
                ..params
            }))
            .unwrap_err();
        assert_eq!(e.id, 7);
        assert!(
            e.message.contains("raise the ball threshold or the stride")
                && !e.message.contains("--"),
            "{}",
            e.message
        );
    }
}
