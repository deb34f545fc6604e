//! Renderers: how the rays of a frame are scheduled.
//!
//! What happens along one ray lives in [`crate::integrator`]; this module
//! decides which rays are cast and on which threads:
//!
//! - [`SerialRenderer`] is the reference: one thread, pixel by pixel.
//! - [`TiledRenderer`] (screen-parallel) cuts the screen rectangle the volume
//!   covers into tiles and integrates them on a thread pool, each ray whole
//!   on one thread.
//! - [`ObjectRenderer`] (object-parallel) cuts the volume into bricks and
//!   integrates (tile, brick) tasks front to back, each tile carrying its rays'
//!   state from brick to brick.
//!
//! All three take the same samples (at `t_in + k·step` along every ray), so
//! they give the same images.
//! [`AnyRenderer`] picks one at run time ([`RendererKind::default`] is the
//! tiled renderer, the fastest measured), and [`RendererFront`] runs any
//! renderer on its own thread behind an asynchronous handle.
//!
//! Every renderer runs its frames through one frame driver (`driver.rs`):
//! it prepares the frame, picks the volume and integrator types once,
//! times the frame and assembles the film; a renderer supplies only its
//! scheduling. The README compares the renderers' speed.

mod any;
pub(crate) mod bins;
mod driver;
pub(crate) mod film;
mod frame;
pub mod front;
pub mod object;
mod options;
pub(crate) mod plan;
pub mod proxy;
mod serial;
mod tiled;

pub use any::{AnyRenderer, RendererKind};
pub use driver::FrameRenderer;
pub use frame::{Frame, FrameStats};
pub use front::{FrameRequest, FrontEvent, FrontOptions, Quality, RendererFront, WakeFn};
pub use object::{ObjectConfig, TaskOrder};
pub use plan::{PlanCache, RenderOptions};

/// One thread, tile by tile: the reference the parallel renderers match.
pub type SerialRenderer = FrameRenderer<serial::InOrder>;
/// Screen tiles on a thread pool, each ray whole on one thread.
pub type TiledRenderer = FrameRenderer<tiled::TilePool>;
/// Bricks integrated front to back into tiles by render threads fed from
/// one task queue (see [`object`]).
pub type ObjectRenderer = FrameRenderer<object::Bricks>;

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use crate::camera::Camera;
use crate::error::Result;
use crate::scene::Scene;
use crate::transfer::TransferFunction;

/// A renderer: turns a scene, camera, TF and options into a frame.
///
/// An implementation provides [`Renderer::render_cancellable`];
/// [`Renderer::render`] is the same frame without a way to stop it.
pub trait Renderer: Send {
    /// Short name (`serial`, `tiles`, `object`).
    fn name(&self) -> &'static str;
    /// Worker threads used.
    fn threads(&self) -> usize;

    /// Renders one frame unless `cancel` fires first; `Ok(None)` when it
    /// did. The renderers of this crate check `cancel` between pieces of work
    /// (tiles, tasks), so a superseded frame stops within one piece; a
    /// renderer that cannot stop midway may check it only at the start.
    fn render_cancellable(
        &mut self,
        scene: &Scene,
        camera: &Camera,
        tf: &TransferFunction,
        options: &RenderOptions,
        cancel: Cancel<'_>,
    ) -> Result<Option<Frame>>;

    /// Renders one frame.
    fn render(
        &mut self,
        scene: &Scene,
        camera: &Camera,
        tf: &TransferFunction,
        options: &RenderOptions,
    ) -> Result<Frame> {
        match self.render_cancellable(scene, camera, tf, options, Cancel::never())? {
            Some(frame) => Ok(frame),
            None => Err(crate::Error::Cancelled {
                renderer: self.name(),
            }),
        }
    }
}

/// `n`, or the number of cores when `n` is 0.
pub(crate) fn resolve_threads(n: usize) -> usize {
    if n == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        n
    }
}

/// A rayon pool of `threads` render workers (0 = one per core) named
/// `raycaster-{name}-i`, and its thread count: the one way renderers make
/// their pools.
pub(crate) fn render_pool(
    threads: usize,
    name: &'static str,
) -> Result<(rayon::ThreadPool, usize)> {
    let threads = resolve_threads(threads);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(move |i| format!("raycaster-{name}-{i}"))
        .build()
        .map_err(|e| crate::error::Error::Threads {
            count: threads,
            role: "render",
            source: std::io::Error::other(e),
        })?;
    Ok((pool, threads))
}

/// When a frame in progress should stop: never, when a flag is raised, or
/// when a generation counter moves on from the value the frame was started
/// with. Cheap to copy and to check (one relaxed atomic load).
#[derive(Debug, Clone, Copy, Default)]
pub struct Cancel<'a> {
    how: CancelHow<'a>,
}

#[derive(Debug, Clone, Copy, Default)]
enum CancelHow<'a> {
    #[default]
    Never,
    Flag(&'a AtomicBool),
    Generation(&'a AtomicU64, u64),
}

impl<'a> Cancel<'a> {
    /// Never cancels.
    pub fn never() -> Self {
        Cancel::default()
    }

    /// Cancels once `flag` is `true`.
    pub fn flag(flag: &'a AtomicBool) -> Self {
        Cancel {
            how: CancelHow::Flag(flag),
        }
    }

    /// Cancels once `counter` no longer holds `generation` (a newer request
    /// was made).
    pub fn generation(counter: &'a AtomicU64, generation: u64) -> Self {
        Cancel {
            how: CancelHow::Generation(counter, generation),
        }
    }

    /// True when the frame should stop.
    #[inline]
    pub fn is_cancelled(&self) -> bool {
        match self.how {
            CancelHow::Never => false,
            CancelHow::Flag(f) => f.load(Ordering::Relaxed),
            CancelHow::Generation(c, g) => c.load(Ordering::Relaxed) != g,
        }
    }
}
