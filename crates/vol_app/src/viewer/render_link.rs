//! The viewer's connection to the renderer: [`RenderLink::request`] a frame,
//! [`RenderLink::poll`] for finished ones. Frames render on the library's
//! asynchronous front ([`raycaster::render::RendererFront`]), on a thread of
//! its own, so the UI never waits for them.
//!
//! The newest request wins, and nothing stale is queued:
//!
//! - a new request supersedes a full-quality frame in progress at once (the
//!   front cancels it between tiles), so starting to drag the camera never
//!   waits for a slow frame;
//! - while a *preview* frame (the first, fast frame of a changed view, see
//!   [`progressive`](super::progressive)) is in progress, the newest
//!   request waits on this side and replaces any older waiting one; it is
//!   sent when the preview arrives. Previews are fast, so a drag shows a
//!   steady stream of frames instead of cancelling every one of them.
//!
//! A request's [`Level`] (reduced size, coarser step) goes to the front as
//! its [`Quality`]; the frame arrives at the reduced size.
//!
//! The front is respawned when the renderer or its thread count changes, and
//! told about a new volume with `set_scene`.

use std::sync::Arc;

use raycaster::prelude::*;
use raycaster::render::{FrameRequest, FrontEvent, FrontOptions, RendererFront, RendererKind};

use super::metaball_link::{MetaballInfo, MetaballParams, MetaballWorker};
use super::progressive::Level;

/// Everything one frame depends on.
#[derive(Debug, Clone)]
pub struct RenderRequest {
    /// The volume.
    pub scene: Arc<Scene>,
    /// Camera, including the image size at full quality.
    pub camera: Camera,
    /// Transfer function.
    pub tf: TransferFunction,
    /// Mode, step, ERT, ESS, shading.
    pub options: RenderOptions,
    /// Which renderer.
    pub renderer: RendererKind,
    /// Worker threads in all for the parallel renderers.
    pub threads: usize,
    /// Size and step reduction of this frame ([`Level::FULL`]: none).
    pub level: Level,
    /// A preview: the first frame of a changed view, picked to be fast (let
    /// finish rather than cancelled by the next request).
    pub preview: bool,
    /// The Metaballs mode's parameters (used in that mode only).
    pub metaballs: MetaballParams,
}

impl RenderRequest {
    /// The sampling step this request renders with: the options' step times
    /// the level's multiplier.
    pub fn step(&self) -> f32 {
        self.options.step_for(self.scene.grid()) * self.level.step_scale as f32
    }
}

impl PartialEq for RenderRequest {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.scene, &other.scene)
            && self.camera == other.camera
            && self.tf == other.tf
            && self.options == other.options
            && self.renderer == other.renderer
            && self.threads == other.threads
            && self.level == other.level
            && self.preview == other.preview
            && self.metaballs == other.metaballs
    }
}

/// A finished frame and what it was rendered with.
#[derive(Debug, Clone)]
pub struct RenderedFrame {
    /// The number [`RenderLink::request`] returned for it (increasing).
    pub id: u64,
    /// The image and its counters.
    pub frame: Frame,
    /// The camera it was requested with (its size is the full-quality size;
    /// `frame` has the level's).
    pub camera: Camera,
    /// Its size and step reduction.
    pub level: Level,
    /// True for a preview frame.
    pub preview: bool,
    /// The sampling step used.
    pub step: f32,
    /// The renderer that ran (`serial`, `tiles`, `object`).
    pub renderer: &'static str,
    /// Its threads.
    pub threads: usize,
    /// The balls of a Metaballs frame.
    pub metaballs: Option<MetaballInfo>,
}

/// A frame that could not be rendered.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderFailure {
    /// The request's number.
    pub id: u64,
    /// What went wrong.
    pub message: String,
}

type Outcome = Result<RenderedFrame, RenderFailure>;

/// A running front and what it was started with.
struct Front {
    front: RendererFront,
    scene: Arc<Scene>,
    renderer: RendererKind,
    threads: usize,
}

/// A request sent to the front: our number, the front's number, the request.
struct InFlight {
    id: u64,
    front_id: u64,
    request: RenderRequest,
}

/// The handle the UI holds; dropping it cancels the frame in progress and
/// stops the render thread.
pub struct RenderLink {
    wake: Arc<dyn Fn() + Send + Sync>,
    front: Option<Front>,
    /// The Metaballs mode's thread, started by its first request.
    balls: Option<MetaballWorker>,
    in_flight: Option<InFlight>,
    waiting: Option<(u64, RenderRequest)>,
    /// A request that could not even be started, reported at the next poll.
    failed: Option<RenderFailure>,
    next_id: u64,
}

impl std::fmt::Debug for RenderLink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RenderLink")
            .field("in_flight", &self.in_flight.as_ref().map(|i| i.id))
            .field("waiting", &self.waiting.as_ref().map(|w| w.0))
            .finish()
    }
}

impl RenderLink {
    /// A link that calls `wake` (from the render thread) whenever a frame
    /// is ready, to repaint the UI. The render thread starts with the first
    /// request.
    pub fn new(wake: impl Fn() + Send + Sync + 'static) -> Self {
        RenderLink {
            wake: Arc::new(wake),
            front: None,
            balls: None,
            in_flight: None,
            waiting: None,
            failed: None,
            next_id: 0,
        }
    }

    /// Asks for a frame; returns its number. Supersedes every older request
    /// that has not been answered (see the module docs for when a preview in
    /// progress is let finish first).
    pub fn request(&mut self, request: RenderRequest) -> u64 {
        self.next_id += 1;
        let id = self.next_id;
        let same_setup = if is_metaballs(&request) {
            self.in_flight
                .as_ref()
                .is_some_and(|i| is_metaballs(&i.request))
        } else {
            self.front.as_ref().is_some_and(|f| {
                Arc::ptr_eq(&f.scene, &request.scene)
                    && f.renderer == request.renderer
                    && f.threads == request.threads
            })
        };
        if same_setup && self.in_flight.as_ref().is_some_and(|i| i.request.preview) {
            self.waiting = Some((id, request));
        } else {
            self.waiting = None;
            self.send(id, request);
        }
        id
    }

    /// The newest finished frame (or failure) since the last poll, if any.
    pub fn poll(&mut self) -> Option<Outcome> {
        let mut newest = self.failed.take().map(Err);
        while let Some(front) = &self.front {
            let event = match front.front.events().try_recv() {
                Ok(e) => e,
                Err(crossbeam_channel::TryRecvError::Empty) => break,
                Err(crossbeam_channel::TryRecvError::Disconnected) => {
                    self.front = None;
                    if let Some(f) = self.in_flight.take() {
                        newest = Some(Err(RenderFailure {
                            id: f.id,
                            message: "the render thread stopped".into(),
                        }));
                    }
                    break;
                }
            };
            // Events of superseded requests answer nothing.
            let Some(outcome) = self.answer(event) else {
                continue;
            };
            self.in_flight = None;
            newest = Some(outcome);
            if let Some((id, request)) = self.waiting.take() {
                self.send(id, request);
            }
        }
        while let Some(balls) = &self.balls {
            let reply = match balls.replies().try_recv() {
                Ok(r) => r,
                Err(crossbeam_channel::TryRecvError::Empty) => break,
                Err(crossbeam_channel::TryRecvError::Disconnected) => {
                    self.balls = None;
                    if let Some(f) = self.in_flight.take_if(|f| is_metaballs(&f.request)) {
                        newest = Some(Err(RenderFailure {
                            id: f.id,
                            message: "the metaball thread stopped".into(),
                        }));
                    }
                    break;
                }
            };
            let id = match &reply {
                Ok(f) => f.id,
                Err(e) => e.id,
            };
            // Replies to superseded requests answer nothing.
            if self.in_flight.as_ref().is_none_or(|f| f.id != id) {
                continue;
            }
            self.in_flight = None;
            newest = Some(reply);
            if let Some((id, request)) = self.waiting.take() {
                self.send(id, request);
            }
        }
        newest
    }

    /// The outcome of the request in flight, when `event` is its answer.
    fn answer(&self, event: FrontEvent) -> Option<Outcome> {
        let flight = self.in_flight.as_ref()?;
        let front = &self.front.as_ref()?.front;
        match event {
            FrontEvent::Ready { id, .. } if id == flight.front_id => {
                let (frame_id, frame) = front.take_frame()?;
                let r = &flight.request;
                (frame_id == flight.front_id).then(|| {
                    Ok(RenderedFrame {
                        id: flight.id,
                        frame,
                        camera: r.camera,
                        level: r.level,
                        preview: r.preview,
                        step: r.step(),
                        renderer: front.renderer_name(),
                        threads: front.renderer_threads(),
                        metaballs: None,
                    })
                })
            }
            FrontEvent::Failed { id, error } if id == flight.front_id => Some(Err(RenderFailure {
                id: flight.id,
                message: error,
            })),
            _ => None,
        }
    }

    /// True while the newest request has not been answered.
    pub fn is_busy(&self) -> bool {
        self.in_flight.is_some() || self.waiting.is_some() || self.failed.is_some()
    }

    /// Sends `request` to the front, (re)starting the front when the volume's
    /// renderer or thread count changed.
    fn send(&mut self, id: u64, request: RenderRequest) {
        if is_metaballs(&request) {
            if let Err(message) = self.send_metaballs(id, request.clone()) {
                self.in_flight = None;
                self.failed = Some(RenderFailure { id, message });
                return;
            }
            self.in_flight = Some(InFlight {
                id,
                // Matches no event of the volume renderer's front.
                front_id: u64::MAX,
                request,
            });
            return;
        }
        if let Err(message) = self.prepare_front(&request) {
            self.in_flight = None;
            // Reported at the next poll, like any failed frame.
            self.failed = Some(RenderFailure { id, message });
            return;
        }
        let Some(front) = &self.front else { return };
        let front_id = front.front.request(FrameRequest {
            camera: request.camera,
            tf: Arc::new(request.tf.clone()),
            options: request.options.clone(),
            quality: request.level.quality(),
        });
        self.in_flight = Some(InFlight {
            id,
            front_id,
            request,
        });
    }

    /// Queues a Metaballs request on its thread, starting the thread first.
    fn send_metaballs(&mut self, id: u64, request: RenderRequest) -> Result<(), String> {
        if self.balls.is_none() {
            self.balls = Some(MetaballWorker::spawn(self.wake.clone())?);
        }
        match &self.balls {
            Some(b) => b.send(id, request),
            None => Err("the metaball thread did not start".into()),
        }
    }

    /// Makes the running front match `request`'s volume, renderer and
    /// threads.
    fn prepare_front(&mut self, request: &RenderRequest) -> Result<(), String> {
        let reuse = self
            .front
            .as_ref()
            .is_some_and(|f| f.renderer == request.renderer && f.threads == request.threads);
        if !reuse {
            // Dropping the old front cancels its frame and joins its thread.
            self.front = None;
            let renderer = request
                .renderer
                .renderer(request.threads)
                .map_err(|e| e.to_string())?;
            let wake = self.wake.clone();
            let front = RendererFront::spawn(
                renderer,
                request.scene.clone(),
                FrontOptions {
                    wake: Some(Arc::new(move || wake())),
                },
            )
            .map_err(|e| e.to_string())?;
            self.front = Some(Front {
                front,
                scene: request.scene.clone(),
                renderer: request.renderer,
                threads: request.threads,
            });
        }
        if let Some(f) = &mut self.front
            && !Arc::ptr_eq(&f.scene, &request.scene)
        {
            f.front.set_scene(request.scene.clone());
            f.scene = request.scene.clone();
        }
        Ok(())
    }
}
/// Whether `request` is for the Metaballs mode's thread.
fn is_metaballs(request: &RenderRequest) -> bool {
    request.options.mode == RenderMode::Metaballs
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{UVec3, Vec3};
    use std::time::{Duration, Instant};

    fn request(width: u32) -> RenderRequest {
        let grid = Grid::new(UVec3::splat(16), Vec3::ONE);
        let volume = AnyVolume::from_fn(grid, |v| {
            if (v.as_vec3() - Vec3::splat(7.5)).length() < 6.0 {
                200u8
            } else {
                0
            }
        });
        let scene = Arc::new(Scene::new(volume));
        let camera = Camera::framing(&scene.grid().bounds(), width, 32, 45.0);
        RenderRequest {
            scene,
            camera,
            tf: TransferFunction::preset("skull", SampleType::U8).unwrap(),
            options: RenderOptions::default(),
            renderer: RendererKind::Tiles,
            threads: 2,
            level: Level::FULL,
            preview: false,
            metaballs: MetaballParams::default(),
        }
    }

    fn wait(link: &mut RenderLink) -> Outcome {
        let t = Instant::now();
        loop {
            if let Some(o) = link.poll() {
                return o;
            }
            assert!(t.elapsed() < Duration::from_secs(20));
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    #[test]
    fn renders_the_newest_request_and_reports_it() {
        let mut link = RenderLink::new(|| {});
        assert!(!link.is_busy());
        let mut last = 0;
        // A burst of requests: only the newest must be answered last, and
        // nothing older may arrive after it.
        for w in 20..40 {
            last = link.request(request(w));
        }
        assert!(link.is_busy());
        let mut seen = Vec::new();
        while link.is_busy() {
            let f = wait(&mut link).unwrap();
            seen.push(f.id);
        }
        assert_eq!(*seen.last().unwrap(), last);
        assert!(seen.len() < 20, "stale frames were rendered: {seen:?}");
        assert!(seen.windows(2).all(|w| w[0] < w[1]));
    }

    #[test]
    fn a_preview_in_progress_finishes_and_only_the_newest_waiting_request_follows() {
        let mut link = RenderLink::new(|| {});
        let preview = |w| RenderRequest {
            preview: true,
            ..request(w)
        };
        let scene_req = preview(30);
        let first = link.request(scene_req.clone());
        let with_scene = |w| RenderRequest {
            scene: scene_req.scene.clone(),
            ..preview(w)
        };
        let middle = link.request(with_scene(31));
        let last = link.request(with_scene(32));
        let mut seen = Vec::new();
        while link.is_busy() {
            seen.push(wait(&mut link).unwrap().id);
        }
        // Which earlier previews get delivered depends on how fast they
        // render; what must hold whatever the timing: the newest request
        // arrives last, nothing arrives twice or out of order, nothing
        // unrequested arrives.
        assert_eq!(seen.last(), Some(&last), "{seen:?}");
        assert!(seen.windows(2).all(|w| w[0] < w[1]), "{seen:?}");
        assert!(
            seen.iter().all(|id| [first, middle, last].contains(id)),
            "{seen:?}"
        );
    }

    #[test]
    fn each_renderer_choice_renders_the_same_image() {
        let mut link = RenderLink::new(|| {});
        let mut images = Vec::new();
        for choice in RendererKind::ALL {
            link.request(RenderRequest {
                renderer: choice,
                ..request(32)
            });
            let f = wait(&mut link).unwrap();
            assert!(f.frame.pixel(16, 16)[0] > 100);
            images.push(f.frame.rgb);
        }
        assert!(images.windows(2).all(|w| w[0] == w[1]));
    }

    #[test]
    fn a_reduced_level_arrives_smaller_with_a_longer_step() {
        let mut link = RenderLink::new(|| {});
        let full = request(40);
        link.request(full.clone());
        let f = wait(&mut link).unwrap();
        assert_eq!((f.frame.width, f.frame.height), (40, 32));
        assert_eq!(f.step, 0.5);
        let id = link.request(RenderRequest {
            level: Level::new(4, 2),
            preview: true,
            ..full
        });
        let r = wait(&mut link).unwrap();
        assert_eq!(r.id, id);
        assert_eq!((r.frame.width, r.frame.height), (10, 8));
        assert_eq!((r.camera.width, r.camera.height), (40, 32));
        assert_eq!(r.step, 1.0);
        assert_eq!(r.level, Level::new(4, 2));
        // A sixteenth of the rays, each with about half the samples.
        assert!(r.frame.stats.samples * 16 < f.frame.stats.samples);
    }

    #[test]
    fn a_degenerate_camera_is_a_failure_not_a_panic() {
        let mut link = RenderLink::new(|| {});
        let mut r = request(32);
        r.camera.target = r.camera.position;
        let id = link.request(r);
        let e = wait(&mut link).unwrap_err();
        assert_eq!(e.id, id);
        assert!(!link.is_busy());
    }
}
