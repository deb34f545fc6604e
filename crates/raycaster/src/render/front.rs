//! The asynchronous renderer front: any renderer on its own thread behind a
//! handle that takes commands and delivers finished frames, with newer
//! requests superseding unfinished ones.
//!
//! ```text
//!   client ──request/cancel/set_scene──▶ commands ──▶ render thread
//!   client ◀── take_frame ── shared buffer ◀── finished frame ──┘
//!   client ◀── events (+ wake-up callback) ◀── Ready / Failed ──┘
//! ```
//!
//! - [`RendererFront::request`] asks for a frame with a camera, TF, options
//!   and [`Quality`]; it returns the request's id. A newer request
//!   supersedes an unfinished one: a generation counter moves on, the
//!   renderer sees it between tiles or tasks and drops the frame, and older
//!   requests still waiting are skipped — a UI dragging the camera never
//!   queues stale frames.
//! - A finished frame is put into a shared buffer (replacing one the client
//!   has not taken yet; the lock is held only for that swap, never across a
//!   frame) and announced by a [`FrontEvent`] on a channel and by the
//!   optional wake-up callback, for a UI event loop.
//! - Dropping the front (or [`RendererFront::shutdown`]) cancels the frame in
//!   progress, stops the thread and joins it.
//!
//! [`AnyRenderer`] chooses the renderer at run time.
//!
//! # Example
//!
//! ```
//! use std::sync::Arc;
//! use std::time::Duration;
//! use glam::{UVec3, Vec3};
//! use raycaster::prelude::*;
//!
//! let grid = Grid::new(UVec3::splat(32), Vec3::ONE);
//! let volume = AnyVolume::from_fn(grid, |v| {
//!     if (v.as_vec3() - Vec3::splat(15.5)).length() < 10.0 { 200u8 } else { 0 }
//! });
//! let scene = Arc::new(Scene::new(volume));
//! let renderer = RendererKind::Object.renderer(2)?;
//! let front = RendererFront::spawn(renderer, scene.clone(), FrontOptions::default())?;
//!
//! let tf = Arc::new(TransferFunction::preset("skull", SampleType::U8).unwrap());
//! let camera = Camera::framing(&scene.grid().bounds(), 64, 64, 45.0);
//! let request = FrameRequest {
//!     camera,
//!     tf,
//!     options: RenderOptions::default(),
//!     quality: Quality::draft(2),
//! };
//! // A UI would send a request per mouse move; each supersedes the last.
//! front.request(request.clone());
//! let id = front.request(FrameRequest { quality: Quality::FULL, ..request });
//! loop {
//!     match front.events().recv_timeout(Duration::from_secs(10)).expect("a frame") {
//!         FrontEvent::Ready { id: done, .. } if done == id => break,
//!         FrontEvent::Ready { .. } => continue, // the draft, if it finished first
//!         FrontEvent::Failed { error, .. } => panic!("{error}"),
//!     }
//! }
//! let (got, frame) = front.take_frame().expect("the frame is in the buffer");
//! assert_eq!((got, frame.width, frame.height), (id, 64, 64));
//! assert!(frame.pixel(32, 32)[0] > 100);
//! # Ok::<(), raycaster::Error>(())
//! ```

use std::panic::AssertUnwindSafe;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::thread::JoinHandle;

use crossbeam_channel::{Receiver, Sender, TrySendError};
use parking_lot::Mutex;

use super::{AnyRenderer, Cancel, Frame, FrameStats, RenderOptions};
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::scene::Scene;
use crate::transfer::TransferFunction;
use crate::volume::Grid;

/// How much work a frame may cost: full quality, or a draft for
/// interaction (a coarser step, fewer pixels).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quality {
    /// Multiplies the sampling step (1 = as the options say; 2 = half the
    /// samples). Values below 1 or not finite count as 1.
    pub step_scale: f32,
    /// Divides the image size (1 = full size; 2 = a quarter of the pixels).
    /// The delivered frame has the reduced size. 0 counts as 1.
    pub downscale: u32,
}

impl Quality {
    /// Full quality.
    pub const FULL: Quality = Quality {
        step_scale: 1.0,
        downscale: 1,
    };

    /// A draft: step × `factor`, image ÷ `factor` (at least 1).
    pub fn draft(factor: u32) -> Self {
        let f = factor.max(1);
        Quality {
            step_scale: f as f32,
            downscale: f,
        }
    }

    /// The camera and options that render `request` at this quality.
    fn apply(
        &self,
        camera: &Camera,
        options: &RenderOptions,
        grid: &Grid,
    ) -> (Camera, RenderOptions) {
        let mut camera = *camera;
        let d = self.downscale.max(1);
        camera.width = (camera.width / d).max(1);
        camera.height = (camera.height / d).max(1);
        let mut options = options.clone();
        let s = self.step_scale;
        if s.is_finite() && s > 1.0 {
            options.step = Some(options.step_for(grid) * s);
        }
        (camera, options)
    }
}

impl Default for Quality {
    fn default() -> Self {
        Quality::FULL
    }
}

/// One frame to render.
#[derive(Debug, Clone)]
pub struct FrameRequest {
    /// The view (its size is the frame's size at full quality).
    pub camera: Camera,
    /// The transfer function (shared: requests are cheap to make).
    pub tf: Arc<TransferFunction>,
    /// Mode, step, ERT/ESS, shading, background.
    pub options: RenderOptions,
    /// Full or draft.
    pub quality: Quality,
}

/// What the render thread reports.
#[derive(Debug, Clone, PartialEq)]
pub enum FrontEvent {
    /// The frame of request `id` is in the shared buffer
    /// ([`RendererFront::take_frame`]) unless a newer one replaced it.
    Ready {
        /// The request's id.
        id: u64,
        /// Frame width in pixels.
        width: u32,
        /// Frame height in pixels.
        height: u32,
        /// Counters and time of the frame.
        stats: FrameStats,
    },
    /// Request `id` could not be rendered.
    Failed {
        /// The request's id.
        id: u64,
        /// Why.
        error: String,
    },
}

/// A wake-up callback: called on the render thread after each event, e.g. to
/// make a UI event loop repaint. It must return promptly.
pub type WakeFn = Arc<dyn Fn() + Send + Sync>;

/// Options of a [`RendererFront`].
#[derive(Clone, Default)]
pub struct FrontOptions {
    /// Called after each [`FrontEvent`] is sent.
    pub wake: Option<WakeFn>,
}

impl std::fmt::Debug for FrontOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FrontOptions")
            .field("wake", &self.wake.as_ref().map(|_| "Fn()"))
            .finish()
    }
}

/// Events kept for a client that does not read them; beyond this, events
/// are dropped (the shared buffer still holds the latest frame).
const EVENT_BACKLOG: usize = 256;

enum Command {
    Render { id: u64, request: Box<FrameRequest> },
    SetScene(Arc<Scene>),
    Shutdown,
}

/// The latest finished frame and its request id.
type FrameSlot = Arc<Mutex<Option<(u64, Frame)>>>;

/// A renderer running on its own thread (see the [module docs](crate::render::front)).
pub struct RendererFront {
    commands: Sender<Command>,
    generation: Arc<AtomicU64>,
    slot: FrameSlot,
    events: Receiver<FrontEvent>,
    thread: Option<JoinHandle<()>>,
    name: &'static str,
    threads: usize,
}

impl std::fmt::Debug for RendererFront {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RendererFront")
            .field("renderer", &self.name)
            .field("threads", &self.threads)
            .field("generation", &self.generation.load(Ordering::Relaxed))
            .finish()
    }
}

impl RendererFront {
    /// Starts `renderer` on a new thread, rendering `scene`.
    pub fn spawn(renderer: AnyRenderer, scene: Arc<Scene>, options: FrontOptions) -> Result<Self> {
        let (commands, command_rx) = crossbeam_channel::unbounded();
        let (event_tx, events) = crossbeam_channel::bounded(EVENT_BACKLOG);
        let generation = Arc::new(AtomicU64::new(0));
        let slot: FrameSlot = Arc::new(Mutex::new(None));
        let name = renderer.name();
        let threads = renderer.threads();
        let worker = Worker {
            renderer,
            scene,
            commands: command_rx,
            events: event_tx,
            generation: generation.clone(),
            slot: slot.clone(),
            wake: options.wake,
        };
        let thread = std::thread::Builder::new()
            .name(format!("raycaster-front-{name}"))
            .spawn(move || worker.run())
            .map_err(|e| Error::Threads {
                count: 1,
                role: "renderer front",
                source: e,
            })?;
        Ok(RendererFront {
            commands,
            generation,
            slot,
            events,
            thread: Some(thread),
            name,
            threads,
        })
    }

    /// Asks for a frame; returns the request's id (increasing). Any frame
    /// in progress or waiting is superseded.
    pub fn request(&self, request: FrameRequest) -> u64 {
        let id = self.generation.fetch_add(1, Ordering::AcqRel) + 1;
        // The thread only ends on `Shutdown` (sent on drop) or a panic
        // outside a frame; either way there is nobody to render for.
        let _ = self.commands.send(Command::Render {
            id,
            request: Box::new(request),
        });
        id
    }

    /// Drops the frame in progress and any waiting request.
    pub fn cancel(&self) {
        self.generation.fetch_add(1, Ordering::AcqRel);
    }

    /// Renders `scene` from the next request on; cancels the frame in
    /// progress.
    pub fn set_scene(&self, scene: Arc<Scene>) {
        self.generation.fetch_add(1, Ordering::AcqRel);
        let _ = self.commands.send(Command::SetScene(scene));
    }

    /// The id of the newest request (0 before the first); a frame with this
    /// id is current.
    pub fn latest_request(&self) -> u64 {
        self.generation.load(Ordering::Acquire)
    }

    /// Takes the latest finished frame out of the shared buffer, with its
    /// request id.
    pub fn take_frame(&self) -> Option<(u64, Frame)> {
        self.slot.lock().take()
    }

    /// Notifications of finished (or failed) frames.
    pub fn events(&self) -> &Receiver<FrontEvent> {
        &self.events
    }

    /// The renderer's name.
    pub fn renderer_name(&self) -> &'static str {
        self.name
    }

    /// The renderer's thread count.
    pub fn renderer_threads(&self) -> usize {
        self.threads
    }

    /// Cancels the frame in progress, stops the render thread and waits for
    /// it (also done on drop).
    pub fn shutdown(mut self) {
        self.stop();
    }

    fn stop(&mut self) {
        self.generation.fetch_add(1, Ordering::AcqRel);
        let _ = self.commands.send(Command::Shutdown);
        if let Some(t) = self.thread.take() {
            // A panic on the render thread was reported as an event
            // already (or happened while shutting down): nothing to add.
            let _ = t.join();
        }
    }
}

impl Drop for RendererFront {
    fn drop(&mut self) {
        self.stop();
    }
}

/// The render thread's state.
struct Worker {
    renderer: AnyRenderer,
    scene: Arc<Scene>,
    commands: Receiver<Command>,
    events: Sender<FrontEvent>,
    generation: Arc<AtomicU64>,
    slot: FrameSlot,
    wake: Option<WakeFn>,
}

impl Worker {
    fn run(mut self) {
        // Ends on `Shutdown` or when the front is gone.
        while let Ok(first) = self.commands.recv() {
            // Take everything waiting: the newest render request wins.
            let mut render = None;
            let mut next = Some(first);
            while let Some(cmd) = next {
                match cmd {
                    Command::Render { id, request } => render = Some((id, request)),
                    Command::SetScene(scene) => self.scene = scene,
                    Command::Shutdown => return,
                }
                next = self.commands.try_recv().ok();
            }
            let Some((id, request)) = render else {
                continue;
            };
            if self.generation.load(Ordering::Acquire) != id {
                continue; // superseded or cancelled before it started
            }
            self.render(id, &request);
        }
    }

    fn render(&mut self, id: u64, request: &FrameRequest) {
        let (camera, options) =
            request
                .quality
                .apply(&request.camera, &request.options, self.scene.grid());
        let cancel = Cancel::generation(&self.generation, id);
        let scene = &*self.scene;
        let renderer = &mut self.renderer;
        let result = std::panic::catch_unwind(AssertUnwindSafe(|| {
            renderer.render_cancellable(scene, &camera, &request.tf, &options, cancel)
        }));
        let event = match result {
            Ok(Ok(Some(frame))) => {
                let event = FrontEvent::Ready {
                    id,
                    width: frame.width,
                    height: frame.height,
                    stats: frame.stats,
                };
                *self.slot.lock() = Some((id, frame));
                event
            }
            Ok(Ok(None)) => return, // cancelled
            Ok(Err(e)) => FrontEvent::Failed {
                id,
                error: e.to_string(),
            },
            Err(panic) => FrontEvent::Failed {
                id,
                error: format!("the renderer panicked: {}", panic_message(&panic)),
            },
        };
        match self.events.try_send(event) {
            Ok(()) | Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {}
        }
        if let Some(wake) = &self.wake {
            wake();
        }
    }
}

fn panic_message(panic: &Box<dyn std::any::Any + Send>) -> String {
    panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}
