//! The object-parallel renderer: bricks integrated front to back into tiles
//! (the object-parallel design of the project's seed thesis, see the
//! README), with the changes that measured faster on this project.
//!
//! # The algorithm
//!
//! 1. **Bricks.** The volume is cut into cubic bricks of `brick` voxels a
//!    side. They are regions of voxel space, independent of the storage
//!    layout (for a bricked file the automatic size is a whole number of
//!    storage bricks, so a brick's data is contiguous). Brick `i` owns the
//!    half-open range `[i·B, (i+1)·B)` per axis; the first brick also owns
//!    everything below 0 and the last everything above, so every sample
//!    position belongs to exactly one brick.
//! 2. **Visibility (ESS).** In DVR with empty-space skipping on, a brick none
//!    of whose macrocells can show anything under the current TF is never
//!    queued, and a visible brick is projected with the box of its occupied
//!    macrocells only (samples outside it are invisible). In every mode, a
//!    brick that holds no point of the frame's clip region is never queued
//!    (its rays' samples there lie outside their kept range).
//! 3. **Order.** Bricks are sorted front to back. For a perspective camera
//!    the key is the Manhattan distance, in brick coordinates, from the brick
//!    holding the eye; along any ray from the eye every brick coordinate
//!    moves away from the eye's, so the key strictly increases from one brick
//!    to the next on every ray (sorting by distance to brick centres has no
//!    such guarantee). For an orthographic camera the key
//!    is `Σ sign(dᵢ)·brickᵢ`.
//! 4. **Queues.** Each brick's box is projected to the screen (clipped at the
//!    eye, so bricks around a camera inside the volume get tight rectangles
//!    too) and appended to the queue of every tile its rectangle touches;
//!    tiles cover only the screen rectangle of the volume.
//! 5. **Tasks.** A task is (tile, next brick of its queue) and travels with
//!    the tile's buffers — per pixel the ray's `RaySegment` and its
//!    integrator state — through one `crossbeam-channel` queue that all render
//!    threads take from: owning the message is owning the tile, so there is
//!    no shared mutable state and no `unsafe` (no raw tile pointers shared
//!    through `UnsafeCell`). A render thread integrates the
//!    samples of each pixel's ray that lie in the brick, skipping rays
//!    already finished (ERT stays global: the tile carries its opacity from
//!    brick to brick); a tile whose rays are all finished drops the rest of
//!    its queue.
//! 6. **Compositing.** When a task is done, the tile's next brick is issued
//!    as a new task, or — when its queue is empty or all its rays are
//!    finished — the tile is resolved to RGB and counted done; the last tile
//!    ends the frame. With [`ObjectConfig::composite_threads`] > 0 this is
//!    done by dedicated compositing threads that receive finished tasks on a
//!    second channel; with 0 (the default) each render
//!    thread composites its own tasks, which saves a thread — on a 2-core
//!    machine, the difference between one render thread and two.
//! 7. **Task order.** With [`TaskOrder::TileFirst`] (the default) a render
//!    thread that has issued a tile's next brick takes that task itself, so
//!    a tile is integrated brick by brick on one core while the other cores
//!    work on other tiles: the tile's rays and the brick's voxels stay in
//!    that core's caches. [`TaskOrder::Queue`] sends it back through the
//!    queue behind all other tiles. Tile-first measured
//!    faster on the benchmark frame with one and with two threads (the
//!    README has the figures).
//!
//! # Measured defaults
//!
//! On the benchmark frame (800³ shapes, 700×700, step 0.2, ERT+ESS, 2 cores):
//! tiles of 16, 32 and 64 pixels and bricks of 15–64 voxels all came within
//! about 5% of each other with 2 threads (bricks of 15 were 8% slower);
//! 32-pixel tiles and 32-voxel bricks (30 for a file of 16-voxel bricks) are
//! the defaults. A dedicated compositing thread only takes a core from
//! rendering: 2 threads as 1 render + 1 compositing ran at the one-thread
//! speed, and 3 threads as 2 + 1 slower than 2 render threads compositing
//! their own tasks.
//!
//! Threads are scoped to the frame: the calling thread is one of the render
//! threads, the others are started for the frame and joined before
//! `render` returns. A cancelled frame stops between two tasks; a thread
//! that panics ends the frame for the others before the panic is passed on.
//!
//! # Same samples as the serial renderer
//!
//! A pixel's samples keep their indices `k` (`t_k = t_in + k·s`). The samples of a ray
//! in a brick are the `k` whose computed position (`RaySegment::pos`, the
//! same arithmetic the integrators use) lies in the brick's half-open range:
//! each coordinate of the position is monotonic in `k`, so these form one
//! contiguous range, found from the ray/box parameters and then verified (or,
//! rarely, searched) on the computed positions themselves. Adjacent bricks'
//! ranges therefore abut exactly: no sample is repeated or lost at a face.
//! The images equal the serial renderer's except for float rounding where a
//! run of uniform samples is composited in closed form in two pieces.
//!
//! # Modes
//!
//! DVR and x-ray use the bricks. Modes whose integrator says splitting rays
//! does not pay ([`Integrator::SPLITS_RAYS`]: MIP and isosurface), unless a
//! brick size is given explicitly, use a single brick spanning the volume:
//! the renderer then integrates whole rays tile by tile with the tiled
//! renderer's tile loop (`driver::render_tile`), without keeping a tile's
//! rays and states between passes. Neither mode can drop bricks up front
//! (MIP needs every brick that might raise a ray's maximum; an isosurface
//! search must compare the samples on both sides of any region it skips),
//! so splitting their rays only adds per-segment work; measured on the
//! benchmark view, MIP and iso were faster whole, x-ray faster in bricks. All modes keep one state
//! per pixel and visit its bricks front to back; bricks are culled only for
//! integrators that say empty space contributes nothing
//! ([`Integrator::CULLS_EMPTY_BRICKS`]: DVR) with ESS on.

mod bricks;
mod footprint;
mod tasks;
#[cfg(test)]
mod tests;
mod work;

use std::sync::Arc;

use glam::UVec3;

use self::bricks::BrickSet;
use self::work::FrameWork;
use super::ObjectRenderer;
use super::driver::{FrameJob, Schedule};
use super::film::Film;
use super::plan::RenderOptions;
use crate::accel::SkipGrid;
use crate::clip::ClipRegion;
use crate::error::{Error, Result};
use crate::integrator::Integrator;
use crate::scene::Scene;
use crate::transfer::TfLut;
use crate::volume::{Layout, Volume};

/// Options of the object-parallel renderer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ObjectConfig {
    /// Threads that integrate (tile, brick) tasks; the thread calling
    /// `render` is one of them. At least 1.
    pub render_threads: usize,
    /// Threads that only composite (issue a tile's next brick, finish
    /// tiles). 0: the render threads do it as part of each task.
    pub composite_threads: usize,
    /// Tile side in pixels.
    pub tile: u32,
    /// Brick side in voxels; 0 picks [`ObjectConfig::DEFAULT_BRICK`],
    /// rounded to whole storage bricks for a bricked volume.
    pub brick: u32,
    /// Which task a render thread takes after finishing one.
    pub order: TaskOrder,
}

/// Which task a render thread takes next (when it composites its own tasks;
/// with compositing threads every task goes back through the queue).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum TaskOrder {
    /// The same tile's next brick, straight away: a tile is integrated
    /// brick by brick on one thread while the others work on other tiles,
    /// so the tile's rays and the brick's voxels stay in that core's cache.
    /// The default: faster than [`TaskOrder::Queue`] on the benchmark frame
    /// with one and with two threads.
    #[default]
    #[cfg_attr(
        feature = "clap",
        value(help = "A render thread keeps its tile until the tile is done")
    )]
    TileFirst,
    /// Back to the shared queue, behind every other tile's task: all tiles
    /// advance in turn.
    #[cfg_attr(
        feature = "clap",
        value(help = "Every task goes back to the shared queue (the seed thesis's scheme)")
    )]
    Queue,
}

impl ObjectConfig {
    /// Default tile side (pixels), measured on the benchmark frame.
    pub const DEFAULT_TILE: u32 = 32;
    /// Default brick side (voxels), measured on the benchmark frame.
    pub const DEFAULT_BRICK: u32 = 32;

    /// `total` threads (0 = one per core), all rendering and compositing
    /// their own tasks, with the default tile and brick sizes.
    pub fn with_threads(total: usize) -> Self {
        ObjectConfig {
            render_threads: super::resolve_threads(total),
            composite_threads: 0,
            tile: Self::DEFAULT_TILE,
            brick: 0,
            order: TaskOrder::TileFirst,
        }
    }

    /// The brick side used for a volume of `layout` and `dims`.
    ///
    /// With `brick` 0 (automatic), modes whose rays do not pay to split
    /// (`splits_rays` false: MIP and isosurface) use one brick spanning the
    /// volume — the renderer then schedules whole rays per tile, like the
    /// tiled renderer — because neither can drop bricks (see the
    /// [module docs](crate::render::object)).
    pub fn brick_side(&self, layout: Layout, splits_rays: bool, dims: UVec3) -> u32 {
        if self.brick > 0 {
            return self.brick;
        }
        if !splits_rays {
            return dims.max_element().max(1);
        }
        match layout {
            Layout::Bricked { side } if side >= 2 => {
                let s = side - 1;
                let n = (Self::DEFAULT_BRICK as f32 / s as f32).round().max(1.0) as u32;
                n * s
            }
            _ => Self::DEFAULT_BRICK,
        }
    }
}

impl Default for ObjectConfig {
    fn default() -> Self {
        Self::with_threads(0)
    }
}

/// The object renderer's schedule: its options and the visible bricks of
/// the last frame.
#[derive(Debug)]
pub struct Bricks {
    config: ObjectConfig,
    last: Option<(BrickKey, Arc<BrickSet>)>,
}

impl ObjectRenderer {
    /// A renderer with `threads` threads in all (0 = one per core) and the
    /// default options.
    pub fn new(threads: usize) -> Result<Self> {
        Self::with_config(ObjectConfig::with_threads(threads))
    }

    /// A renderer with explicit options (a `tile` of 0 means the default).
    pub fn with_config(mut config: ObjectConfig) -> Result<Self> {
        if config.render_threads == 0 {
            return Err(Error::option(
                "threads",
                "the object renderer needs at least one render thread",
            ));
        }
        const MAX_THREADS: usize = 1024;
        if config.render_threads + config.composite_threads > MAX_THREADS {
            return Err(Error::option(
                "threads",
                format!(
                    "{} render + {} composite threads: at most {MAX_THREADS} in all",
                    config.render_threads, config.composite_threads
                ),
            ));
        }
        if config.tile == 0 {
            config.tile = ObjectConfig::DEFAULT_TILE;
        }
        Ok(ObjectRenderer::with_schedule(Bricks { config, last: None }))
    }

    /// The options in use.
    pub fn config(&self) -> &ObjectConfig {
        &self.schedule().config
    }
}

impl Bricks {
    /// The visible bricks for this scene, TF and mode (cached).
    fn visible<I: Integrator>(
        &mut self,
        scene: &Scene,
        prepared: &Arc<(TfLut, SkipGrid)>,
        options: &RenderOptions,
        clip: Option<&ClipRegion>,
    ) -> Arc<BrickSet> {
        let side =
            self.config
                .brick_side(scene.volume().layout(), I::SPLITS_RAYS, scene.grid().dims);
        let key = BrickKey {
            scene: scene.id(),
            side,
            cull: options.ess && I::CULLS_EMPTY_BRICKS,
            prepared: prepared.clone(),
            clip: clip.cloned(),
        };
        if let Some((k, set)) = &self.last
            && k.same(&key)
        {
            return set.clone();
        }
        let set = Arc::new(BrickSet::build(
            scene.grid(),
            scene.macrocells(),
            &prepared.1,
            side,
            key.cull,
            clip,
        ));
        self.last = Some((key, set.clone()));
        set
    }
}

impl Schedule for Bricks {
    const NAME: &'static str = "object";

    fn threads(&self) -> usize {
        self.config.render_threads + self.config.composite_threads
    }

    fn run<V: Volume, I: Integrator>(&mut self, job: &FrameJob<'_, V>, film: &Film) -> Option<u64> {
        let set = self.visible::<I>(
            job.scene,
            &job.plan.prepared,
            job.options,
            job.plan.clip.as_ref(),
        );
        let work = FrameWork::build(
            &set,
            job.scene.grid(),
            job.camera,
            job.plan,
            self.config.tile,
        );
        let threads = (self.config.render_threads, self.config.composite_threads);
        let whole_rays = !I::SPLITS_RAYS && set.count == UVec3::ONE;
        tasks::run_frame::<V, I>(job, film, &work, threads, whole_rays, self.config.order)
    }
}

/// What a cached [`BrickSet`] was built for.
#[derive(Debug)]
struct BrickKey {
    scene: u64,
    side: u32,
    cull: bool,
    /// The LUT and skip grid (compared by identity; holding the `Arc`
    /// keeps its address from being reused).
    prepared: Arc<(TfLut, SkipGrid)>,
    /// The clip region bricks were dropped for.
    clip: Option<ClipRegion>,
}

impl BrickKey {
    fn same(&self, other: &BrickKey) -> bool {
        self.scene == other.scene
            && self.side == other.side
            && self.cull == other.cull
            && self.clip == other.clip
            && (!self.cull || Arc::ptr_eq(&self.prepared, &other.prepared))
    }
}
