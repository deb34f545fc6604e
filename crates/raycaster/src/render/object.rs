//! The object-parallel renderer: the seed thesis's algorithm (its §3.1, §4.5
//! and §4.6), with the changes that measured faster on this project.
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
//!    macrocells only (samples outside it are invisible).
//! 3. **Order.** Bricks are sorted front to back. For a perspective camera
//!    the key is the Manhattan distance, in brick coordinates, from the brick
//!    holding the eye; along any ray from the eye every brick coordinate
//!    moves away from the eye's, so the key strictly increases from one brick
//!    to the next on every ray (sorting by distance to brick centres, as the
//!    thesis does, has no such guarantee). For an orthographic camera the key
//!    is `Σ sign(dᵢ)·brickᵢ`.
//! 4. **Queues.** Each brick's box is projected to the screen (clipped at the
//!    eye, so bricks around a camera inside the volume get tight rectangles
//!    too) and appended to the queue of every tile its rectangle touches;
//!    tiles cover only the screen rectangle of the volume.
//! 5. **Tasks.** A task is (tile, next brick of its queue) and travels with
//!    the tile's buffers — per pixel the ray's [`RaySegment`] and
//!    [`RayState`] — through one `crossbeam-channel` queue that all render
//!    threads take from: owning the message is owning the tile, so there is
//!    no shared mutable state and no `unsafe` (the thesis shared raw tile
//!    pointers through `UnsafeCell` instead). A render thread integrates the
//!    samples of each pixel's ray that lie in the brick, skipping rays
//!    already finished (ERT stays global: the tile carries its opacity from
//!    brick to brick); a tile whose rays are all finished drops the rest of
//!    its queue.
//! 6. **Compositing.** When a task is done, the tile's next brick is issued
//!    as a new task, or — when its queue is empty or all its rays are
//!    finished — the tile is resolved to RGB and counted done; the last tile
//!    ends the frame. With [`ObjectConfig::composite_threads`] > 0 this is
//!    done by dedicated compositing threads that receive finished tasks on a
//!    second channel (the thesis's design); with 0 (the default) each render
//!    thread composites its own tasks, which saves a thread — on a 2-core
//!    machine, the difference between one render thread and two.
//! 7. **Task order.** With [`TaskOrder::TileFirst`] (the default) a render
//!    thread that has issued a tile's next brick takes that task itself, so
//!    a tile is integrated brick by brick on one core while the other cores
//!    work on other tiles: the tile's rays and the brick's voxels stay in
//!    that core's caches. [`TaskOrder::Queue`] sends it back through the
//!    queue behind all other tiles, as the thesis does. On the benchmark
//!    frame (2 threads) tile-first took 156 ms on the bricked file and
//!    167 ms on the linear one, queue order 166 ms and 198 ms; with one
//!    thread 312/326 ms against 338/391 ms.
//!
//! # Measured defaults
//!
//! On the benchmark frame (800³ shapes, 700×700, step 0.2, ERT+ESS, 2 cores):
//! tiles of 16, 32 and 64 pixels and bricks of 15–64 voxels all came within
//! about 5% of each other with 2 threads (bricks of 15 were 8% slower);
//! 32-pixel tiles and 32-voxel bricks (30 for a file of 16-voxel bricks) are
//! the defaults. A dedicated compositing thread only takes a core from
//! rendering: 2 threads as 1 render + 1 compositing took 358–391 ms (the
//! one-thread time), 3 threads as 2 + 1 took 200–211 ms, against 156–167 ms
//! for 2 render threads compositing their own tasks.
//!
//! Threads are scoped to the frame: the calling thread is one of the render
//! threads, the others are started for the frame and joined before
//! `render` returns. A cancelled frame stops between two tasks; a thread
//! that panics ends the frame for the others before the panic is passed on.
//!
//! # Same samples as the serial renderer
//!
//! A pixel's samples keep the indices `k` of SPEC §5. The samples of a ray
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
//! DVR and x-ray use the bricks. MIP and isosurface frames, unless a brick
//! size is given explicitly, use a single brick spanning the volume: the
//! renderer then integrates whole rays tile by tile, as the tiled renderer
//! does. Neither mode can drop bricks up front (MIP needs every brick that
//! might raise a ray's maximum; an isosurface search must compare the
//! samples on both sides of any region it skips), so splitting their rays
//! only adds per-segment work: on the benchmark view (step 0.5, 2 threads)
//! MIP took 1147 ms with bricks and 812 ms without, iso 472 ms and 156 ms,
//! while x-ray took 1918 ms with bricks and 2150 ms without. All modes keep
//! one state per pixel and visit its bricks front to back; bricks are culled
//! only in DVR with ESS on.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Instant;

use crossbeam_channel::{Receiver, Sender};
use glam::{UVec3, Vec3};
use parking_lot::Mutex;

use super::plan::{FramePlan, PlanCache, RenderOptions, to_bytes};
use super::{Cancel, Frame, FrameStats, Renderer};
use crate::accel::{MacrocellGrid, SkipGrid};
use crate::camera::{Camera, CameraFrame, PixelRect, Projection};
use crate::error::{Error, Result};
use crate::geometry::Aabb;
use crate::integrator::{FrameContext, RaySegment, RayState, RenderMode};
use crate::scene::{Scene, VolumeSource, VolumeVisitor};
use crate::transfer::{TfLut, TransferFunction};
use crate::volume::{Grid, Layout, Volume};

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
    /// The default: on the benchmark frame 6–16% faster than
    /// [`TaskOrder::Queue`] with 2 threads and 8–17% with one.
    #[default]
    #[cfg_attr(
        feature = "clap",
        value(help = "A render thread keeps its tile until the tile is done")
    )]
    TileFirst,
    /// Back to the shared queue, behind every other tile's task (the
    /// thesis's scheme): all tiles advance in turn.
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
            render_threads: resolve_threads(total),
            composite_threads: 0,
            tile: Self::DEFAULT_TILE,
            brick: 0,
            order: TaskOrder::TileFirst,
        }
    }

    /// The brick side used for a volume of `layout` and `dims` in `mode`.
    ///
    /// With `brick` 0 (automatic), MIP and isosurface frames use one brick
    /// spanning the volume — the renderer then schedules whole rays per tile,
    /// like the tiled renderer — because splitting their rays only adds
    /// work: neither can drop bricks (see the [module docs](crate::render::object)).
    pub fn brick_side(&self, layout: Layout, mode: RenderMode, dims: UVec3) -> u32 {
        if self.brick > 0 {
            return self.brick;
        }
        if matches!(mode, RenderMode::Mip | RenderMode::Iso) {
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

/// `n`, or the number of cores when `n` is 0.
pub(crate) fn resolve_threads(n: usize) -> usize {
    if n == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        n
    }
}

/// Bricks integrated front to back into tiles by render threads fed from
/// one task queue (see the [module docs](crate::render::object)). Threads are started for
/// each frame and joined before `render` returns.
#[derive(Debug)]
pub struct ObjectRenderer {
    config: ObjectConfig,
    cache: PlanCache,
    bricks: Option<(BrickKey, Arc<BrickSet>)>,
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
            return Err(Error::InvalidArgument(
                "the object renderer needs at least one render thread".into(),
            ));
        }
        const MAX_THREADS: usize = 1024;
        if config.render_threads + config.composite_threads > MAX_THREADS {
            return Err(Error::InvalidArgument(format!(
                "{} render + {} composite threads: at most {MAX_THREADS} in all",
                config.render_threads, config.composite_threads
            )));
        }
        if config.tile == 0 {
            config.tile = ObjectConfig::DEFAULT_TILE;
        }
        Ok(ObjectRenderer {
            config,
            cache: PlanCache::default(),
            bricks: None,
        })
    }

    /// The options in use.
    pub fn config(&self) -> &ObjectConfig {
        &self.config
    }

    /// The visible bricks for this scene, TF and mode (cached).
    fn brick_set<V: VolumeSource>(
        &mut self,
        scene: &Scene<V>,
        prepared: &Arc<(TfLut, SkipGrid)>,
        options: &RenderOptions,
    ) -> Arc<BrickSet> {
        let side = self.config.brick_side(
            scene.volume().accept(LayoutOf),
            options.mode,
            scene.grid().dims,
        );
        let key = BrickKey {
            scene: scene.id(),
            side,
            cull: options.ess && options.mode == RenderMode::Dvr,
            prepared: prepared.clone(),
        };
        if let Some((k, set)) = &self.bricks
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
        ));
        self.bricks = Some((key, set.clone()));
        set
    }
}

struct LayoutOf;

impl VolumeVisitor for LayoutOf {
    type Output = Layout;
    fn visit<V: Volume>(self, volume: &V) -> Layout {
        volume.layout()
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
}

impl BrickKey {
    fn same(&self, other: &BrickKey) -> bool {
        self.scene == other.scene
            && self.side == other.side
            && self.cull == other.cull
            && (!self.cull || Arc::ptr_eq(&self.prepared, &other.prepared))
    }
}

/// The brick grid of a volume and the bricks that can contribute.
#[derive(Debug)]
struct BrickSet {
    /// Brick side in voxels.
    side: u32,
    /// Bricks per axis.
    count: UVec3,
    /// Bricks to queue: grid coordinate and the voxel-space box outside
    /// which none of the brick's samples contributes.
    visible: Vec<(UVec3, Aabb)>,
}

impl BrickSet {
    /// All bricks, or with `cull` only those holding an occupied cell of
    /// `skip`, each with the box of its occupied cells.
    fn build(grid: &Grid, cells: &MacrocellGrid, skip: &SkipGrid, side: u32, cull: bool) -> Self {
        let dims = grid.dims;
        // A brick larger than the volume is the volume.
        let side = side.clamp(1, dims.max_element().max(1));
        let n = |d: u32| if d <= 1 { 1 } else { (d - 1).div_ceil(side) };
        let count = UVec3::new(n(dims.x), n(dims.y), n(dims.z));
        let max_coord = grid.max_coord();
        let m = cells.cell.max(1);
        let last_cell = cells.count - UVec3::ONE;
        let mut visible = Vec::new();
        for bx in 0..count.x {
            for by in 0..count.y {
                for bz in 0..count.z {
                    let b = UVec3::new(bx, by, bz);
                    let lo = (b * side).as_vec3().min(max_coord);
                    let hi = ((b + UVec3::ONE) * side).as_vec3().min(max_coord);
                    if !cull {
                        visible.push((b, Aabb::new(lo, hi)));
                        continue;
                    }
                    // The cells holding the brick's sample positions
                    // [b·B, (b+1)·B), clamped to the grid as the sampler
                    // clamps positions.
                    let c0 = (b * side / m).min(last_cell);
                    let c1 = (((b + UVec3::ONE) * side).map(|v| v.div_ceil(m)) - UVec3::ONE)
                        .min(last_cell)
                        .max(c0);
                    let mut occ_lo = UVec3::MAX;
                    let mut occ_hi = UVec3::ZERO;
                    for cx in c0.x..=c1.x {
                        for cy in c0.y..=c1.y {
                            for cz in c0.z..=c1.z {
                                let c = UVec3::new(cx, cy, cz);
                                if skip.is_occupied(c) {
                                    occ_lo = occ_lo.min(c);
                                    occ_hi = occ_hi.max(c);
                                }
                            }
                        }
                    }
                    if occ_lo.x == u32::MAX {
                        continue;
                    }
                    let olo = (occ_lo * m).as_vec3();
                    let ohi = ((occ_hi + UVec3::ONE) * m).as_vec3();
                    visible.push((b, Aabb::new(lo.max(olo), hi.min(ohi).max(lo.max(olo)))));
                }
            }
        }
        BrickSet {
            side,
            count,
            visible,
        }
    }

    /// The half-open voxel-space range brick `b` owns, infinite at the grid's
    /// outer faces.
    fn region(&self, b: UVec3) -> Region {
        let s = self.side as f32;
        let bound = |i: u32, n: u32, upper: bool| -> f32 {
            match (upper, i) {
                (false, 0) => f32::NEG_INFINITY,
                (true, i) if i + 1 >= n => f32::INFINITY,
                (false, i) => (i as f32) * s,
                (true, i) => ((i + 1) as f32) * s,
            }
        };
        Region {
            lo: Vec3::new(
                bound(b.x, self.count.x, false),
                bound(b.y, self.count.y, false),
                bound(b.z, self.count.z, false),
            ),
            hi: Vec3::new(
                bound(b.x, self.count.x, true),
                bound(b.y, self.count.y, true),
                bound(b.z, self.count.z, true),
            ),
        }
    }

    /// The brick whose region holds voxel-space coordinate `x` along an axis
    /// with `n` bricks (the same comparisons as [`BrickSet::region`]).
    fn brick_of(&self, x: f32, n: u32) -> u32 {
        let s = self.side as f32;
        let guess = if x.is_finite() {
            (x / s).floor().clamp(0.0, (n - 1) as f32) as u32
        } else if x > 0.0 {
            n - 1
        } else {
            0
        };
        let mut i = guess;
        while i > 0 && (i as f32) * s > x {
            i -= 1;
        }
        while i + 1 < n && ((i + 1) as f32) * s <= x {
            i += 1;
        }
        i
    }
}

/// The voxel-space range `[lo, hi)` per axis that a brick owns.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Region {
    lo: Vec3,
    hi: Vec3,
}

impl Region {
    #[inline(always)]
    fn contains(&self, p: Vec3) -> bool {
        self.lo.cmple(p).all() && p.cmplt(self.hi).all()
    }
}

/// The indices `k0..k1` of the samples of `seg` whose computed position lies
/// in `r` (empty when `k0 >= k1`).
///
/// Every coordinate of `seg.pos(k)` is monotonic in `k`, so the samples in
/// the region are one contiguous run. The run is estimated from the ray's
/// parameters at the region's faces and accepted only when the positions
/// confirm it (first and last inside, their outer neighbours outside);
/// otherwise each axis's run is found by a search on the positions.
#[inline]
fn sample_range(seg: &RaySegment, r: &Region) -> (u32, u32) {
    let n = seg.count;
    let mut enter = f32::NEG_INFINITY;
    let mut exit = f32::INFINITY;
    let mut inv_sum = 0.0f32;
    for a in 0..3 {
        let d = seg.dir[a];
        let o = seg.origin[a];
        if d == 0.0 {
            // The coordinate is `o` at every sample.
            if !(r.lo[a] <= o && o < r.hi[a]) {
                return (0, 0);
            }
            continue;
        }
        let inv = seg.inv_dir[a];
        if !inv.is_finite() || inv.abs() > 1e12 {
            return exact_range(seg, r);
        }
        let t0 = (r.lo[a] - o) * inv;
        let t1 = (r.hi[a] - o) * inv;
        let (a_in, a_out) = if d > 0.0 { (t0, t1) } else { (t1, t0) };
        enter = enter.max(a_in);
        exit = exit.min(a_out);
        inv_sum += inv.abs();
    }
    let t_end = seg.t(n);
    // A bound on the rounding error of a sample position (voxel units),
    // converted to ray parameter: well above f32's 2⁻²⁴ relative error.
    let scale = 1.0 + seg.origin.abs().max_element() + seg.dir.abs().max_element() * t_end.abs();
    let slack = scale * 1e-5 * inv_sum + 1e-5 * (t_end.abs() + seg.t_in.abs());
    if enter > exit + slack || enter > t_end + slack || exit < seg.t_in - slack {
        // The line misses the region by more than rounding can bridge.
        return (0, 0);
    }
    let index = |t: f32| -> u32 {
        if t == f32::NEG_INFINITY {
            0
        } else if t == f32::INFINITY {
            n
        } else {
            let x = ((t - seg.t_in) * seg.inv_step).ceil();
            // `as` saturates: negative → 0; NaN → 0.
            (x.min(n as f32) as u32).min(n)
        }
    };
    let (k0, k1) = (index(enter), index(exit));
    if k0 < k1 {
        let inside = |k: u32| r.contains(seg.pos(k));
        if inside(k0) && inside(k1 - 1) && (k0 == 0 || !inside(k0 - 1)) && (k1 == n || !inside(k1))
        {
            return (k0, k1);
        }
    }
    exact_range(seg, r)
}

/// [`sample_range`] by a search along each axis on the computed positions.
fn exact_range(seg: &RaySegment, r: &Region) -> (u32, u32) {
    let n = seg.count;
    let mut k0 = 0u32;
    let mut k1 = n;
    for a in 0..3 {
        let d = seg.dir[a];
        let o = seg.origin[a];
        let (lo, hi) = (r.lo[a], r.hi[a]);
        let coord = |k: u32| o + d * seg.t(k);
        if d > 0.0 {
            // Increasing: inside from the first k at or past `lo` up to the
            // first k at or past `hi`.
            if lo > f32::NEG_INFINITY {
                k0 = k0.max(first_true(n, |k| coord(k) >= lo));
            }
            if hi < f32::INFINITY {
                k1 = k1.min(first_true(n, |k| coord(k) >= hi));
            }
        } else if d < 0.0 {
            if hi < f32::INFINITY {
                k0 = k0.max(first_true(n, |k| coord(k) < hi));
            }
            if lo > f32::NEG_INFINITY {
                k1 = k1.min(first_true(n, |k| coord(k) < lo));
            }
        } else if !(lo <= o && o < hi) {
            return (0, 0);
        }
        if k0 >= k1 {
            return (0, 0);
        }
    }
    (k0, k1)
}

/// The smallest `k` in `0..n` for which the monotonic predicate holds, or `n`.
fn first_true(n: u32, pred: impl Fn(u32) -> bool) -> u32 {
    let (mut lo, mut hi) = (0u32, n);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if pred(mid) {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    lo
}

/// The pixels whose rays can pass through the world-space box `b`: the
/// rectangle of its projection grown by 1.5 pixels and clamped to the image,
/// or `None` when no pixel's ray can reach it.
///
/// For a perspective camera the box is clipped at a plane just in front of
/// the eye; anything visible between the eye and that plane lies within a
/// small ball around the eye, and a box reaching into that ball gets the
/// whole image.
fn footprint(frame: &CameraFrame, camera: &Camera, b: &Aabb) -> Option<PixelRect> {
    let (w, h) = (camera.width as f32, camera.height as f32);
    let full = PixelRect {
        x0: 0,
        y0: 0,
        x1: camera.width,
        y1: camera.height,
    };
    let corners = b.corners();
    let mut cam = [Vec3::ZERO; 8];
    for (c, p) in cam.iter_mut().zip(corners) {
        let v = p - camera.position;
        *c = Vec3::new(v.dot(frame.right), v.dot(frame.up), v.dot(frame.forward));
    }
    let size = (b.max - b.min).length();
    let (hx, hy) = (frame.half_height * frame.aspect, frame.half_height);
    let (near, lateral) = match camera.projection {
        Projection::Perspective => {
            let near = 1e-2 * size.max(1e-6);
            // Points in view closer than `near` lie within this radius.
            let radius = near * (1.0 + hx * hx + hy * hy).sqrt();
            let closest = camera.position.clamp(b.min, b.max);
            let tolerance = 1e-5 * (camera.position.abs().max_element() + size);
            if (closest - camera.position).length() <= radius * 1.01 + tolerance {
                return Some(full);
            }
            (near, None)
        }
        Projection::Orthographic => (0.0, Some(frame.distance)),
    };
    let to_pixels = |c: Vec3| -> (f32, f32) {
        let (sx, sy) = match lateral {
            Some(d) => (c.x / d, c.y / d),
            None => (c.x / c.z, c.y / c.z),
        };
        ((sx / hx + 1.0) * 0.5 * w, (1.0 - sy / hy) * 0.5 * h)
    };
    let (mut lo_x, mut lo_y) = (f32::INFINITY, f32::INFINITY);
    let (mut hi_x, mut hi_y) = (f32::NEG_INFINITY, f32::NEG_INFINITY);
    let mut add = |c: Vec3| {
        let (x, y) = to_pixels(c);
        lo_x = lo_x.min(x);
        lo_y = lo_y.min(y);
        hi_x = hi_x.max(x);
        hi_y = hi_y.max(y);
    };
    // Vertices of the box clipped to z >= near: the corners in front and
    // the points where edges cross the plane.
    for c in cam {
        if c.z >= near {
            add(c);
        }
    }
    for i in 0..8usize {
        for bit in [1usize, 2, 4] {
            let j = i | bit;
            if j == i {
                continue;
            }
            let (a, b) = (cam[i], cam[j]);
            if (a.z >= near) != (b.z >= near) {
                let s = ((near - a.z) / (b.z - a.z)).clamp(0.0, 1.0);
                let mut p = a + (b - a) * s;
                p.z = near.max(p.z);
                add(p);
            }
        }
    }
    if !(lo_x <= hi_x && lo_y <= hi_y) {
        return None;
    }
    let clamp_x = |v: f32| v.clamp(0.0, w) as u32;
    let clamp_y = |v: f32| v.clamp(0.0, h) as u32;
    let rect = PixelRect {
        x0: clamp_x((lo_x - 1.5).floor()),
        y0: clamp_y((lo_y - 1.5).floor()),
        x1: clamp_x((hi_x + 1.5).ceil()),
        y1: clamp_y((hi_y + 1.5).ceil()),
    };
    (rect.x0 < rect.x1 && rect.y0 < rect.y1).then_some(rect)
}

/// `a ∩ b`, `None` when empty.
fn intersect(a: &PixelRect, b: &PixelRect) -> Option<PixelRect> {
    let r = PixelRect {
        x0: a.x0.max(b.x0),
        y0: a.y0.max(b.y0),
        x1: a.x1.min(b.x1),
        y1: a.y1.min(b.y1),
    };
    (r.x0 < r.x1 && r.y0 < r.y1).then_some(r)
}

/// One queued brick of a frame.
#[derive(Debug, Clone, Copy)]
struct QueuedBrick {
    region: Region,
    /// Pixels its rays may reach (inside the volume's screen rectangle).
    rect: PixelRect,
}

/// A frame's work: the queued bricks in front-to-back order and, per tile,
/// its queue of bricks (indices into `bricks`), in order.
#[derive(Debug)]
struct FrameWork {
    bricks: Vec<QueuedBrick>,
    tiles: Vec<PixelRect>,
    /// Tile `t`'s queue is `queue[start[t]..start[t + 1]]`.
    start: Vec<u32>,
    queue: Vec<u32>,
}

impl FrameWork {
    fn build(set: &BrickSet, grid: &Grid, camera: &Camera, plan: &FramePlan, tile: u32) -> Self {
        let frame = &plan.camera;
        let rect = plan.rect;
        let tile = tile.max(1);
        let tiles: Vec<PixelRect> = rect.tiles(tile).collect();
        let tiles_x = (rect.x1 - rect.x0).div_ceil(tile);
        // Front-to-back keys.
        let eye = grid.world_to_voxel(camera.position);
        let eye_brick: [i64; 3] =
            std::array::from_fn(|a| set.brick_of(eye[a], set.count[a]) as i64);
        let sign: [i64; 3] = std::array::from_fn(|a| {
            let d = frame.forward[a];
            (d > 0.0) as i64 - (d < 0.0) as i64
        });
        let key = |b: UVec3| -> i64 {
            match camera.projection {
                Projection::Perspective => (0..3).map(|a| (b[a] as i64 - eye_brick[a]).abs()).sum(),
                Projection::Orthographic => (0..3).map(|a| sign[a] * b[a] as i64).sum(),
            }
        };
        let mut order: Vec<(i64, u32, PixelRect)> = Vec::with_capacity(set.visible.len());
        for (i, (b, bounds)) in set.visible.iter().enumerate() {
            let world = Aabb::new(
                grid.voxel_to_world(bounds.min),
                grid.voxel_to_world(bounds.max),
            );
            let Some(fp) = footprint(frame, camera, &world) else {
                continue;
            };
            let Some(fp) = intersect(&fp, &rect) else {
                continue;
            };
            order.push((key(*b), i as u32, fp));
        }
        order.sort_unstable_by_key(|&(k, i, _)| (k, i));
        let bricks: Vec<QueuedBrick> = order
            .iter()
            .map(|&(_, i, fp)| QueuedBrick {
                region: set.region(set.visible[i as usize].0),
                rect: fp,
            })
            .collect();
        // Tile queues (compressed rows): count, prefix sums, fill in order.
        let tiles_of = |r: &PixelRect| {
            let tx = (r.x0 - rect.x0) / tile..=(r.x1 - 1 - rect.x0) / tile;
            let ty = (r.y0 - rect.y0) / tile..=(r.y1 - 1 - rect.y0) / tile;
            ty.flat_map(move |y| tx.clone().map(move |x| (y * tiles_x + x) as usize))
        };
        let mut start = vec![0u32; tiles.len() + 1];
        for b in &bricks {
            for t in tiles_of(&b.rect) {
                start[t + 1] += 1;
            }
        }
        for t in 0..tiles.len() {
            start[t + 1] += start[t];
        }
        let mut fill = start.clone();
        let mut queue = vec![0u32; start[tiles.len()] as usize];
        for (i, b) in bricks.iter().enumerate() {
            for t in tiles_of(&b.rect) {
                queue[fill[t] as usize] = i as u32;
                fill[t] += 1;
            }
        }
        FrameWork {
            bricks,
            tiles,
            start,
            queue,
        }
    }

    fn queue_of(&self, tile: u32) -> &[u32] {
        let t = tile as usize;
        &self.queue[self.start[t] as usize..self.start[t + 1] as usize]
    }
}

/// The rays of one tile, travelling with its tasks.
#[derive(Debug, Default)]
struct TileBuf {
    /// Per pixel (row-major in the tile) the ray, `None` when it misses the
    /// volume. Empty until the tile's first task.
    segs: Vec<Option<RaySegment>>,
    /// Per pixel the integration state.
    states: Vec<RayState>,
    /// Pixels whose ray hits the volume and is not finished.
    live: u32,
}

/// A task: integrate brick `queue_of(tile)[next]` into the tile.
#[derive(Debug)]
struct Task {
    tile: u32,
    next: u32,
    buf: TileBuf,
}

/// A finished tile: its index and RGB bytes, row-major.
type DoneTile = (u32, Vec<u8>);

/// What one thread returns.
#[derive(Debug, Default)]
struct WorkerOut {
    tiles: Vec<DoneTile>,
    samples: u64,
}

/// State shared by the threads of one frame.
struct Shared<'a, V: Volume> {
    ctx: FrameContext<'a, V>,
    plan: &'a FramePlan,
    work: &'a FrameWork,
    mode: RenderMode,
    background: Vec3,
    cancel: Cancel<'a>,
    order: TaskOrder,
    /// Tiles not finished yet.
    remaining: AtomicUsize,
    /// Set when the frame stops early (cancelled, or a thread panicked).
    aborted: AtomicBool,
    /// Render threads also composite (no compositing threads running).
    inline: AtomicBool,
    tasks: (Sender<Task>, Receiver<Task>),
    done: (Sender<Task>, Receiver<Task>),
    /// Dropped (set to `None`) to wake every thread for the end of the frame.
    stop_tx: Mutex<Option<Sender<()>>>,
    stop_rx: Receiver<()>,
}

impl<V: Volume> Shared<'_, V> {
    /// Ends the frame: every thread's wait returns.
    fn stop(&self) {
        self.stop_tx.lock().take();
    }

    fn abort(&self) {
        self.aborted.store(true, Ordering::Relaxed);
        self.stop();
    }

    /// Integrates the task's brick into its tile.
    fn render_task(&self, task: &mut Task, samples: &mut u64) {
        let t = self.work.tiles[task.tile as usize];
        let tw = (t.x1 - t.x0) as usize;
        let buf = &mut task.buf;
        if buf.segs.is_empty() {
            let grid = self.ctx.volume.grid();
            let area = t.area() as usize;
            buf.segs.reserve_exact(area);
            for j in t.y0..t.y1 {
                for i in t.x0..t.x1 {
                    let seg = RaySegment::new(grid, &self.plan.camera.ray(i, j), self.plan.step);
                    buf.live += seg.is_some() as u32;
                    buf.segs.push(seg);
                }
            }
            buf.states = vec![RayState::new(self.mode); area];
        }
        let b = self.work.queue_of(task.tile)[task.next as usize];
        let brick = &self.work.bricks[b as usize];
        task.next += 1;
        let Some(r) = intersect(&brick.rect, &t) else {
            return;
        };
        for j in r.y0..r.y1 {
            // A task can take milliseconds: look for cancellation per row.
            // The tile is left half-done, but a cancelled frame is dropped.
            if self.cancel.is_cancelled() {
                return;
            }
            let row = (j - t.y0) as usize * tw;
            for i in r.x0..r.x1 {
                let p = row + (i - t.x0) as usize;
                let Some(seg) = &buf.segs[p] else { continue };
                let state = &mut buf.states[p];
                if state.is_done() {
                    continue;
                }
                let (k0, k1) = sample_range(seg, &brick.region);
                if k0 < k1 {
                    *samples += state.integrate(&self.ctx, seg, k0, k1);
                    if state.is_done() {
                        buf.live -= 1;
                    }
                }
            }
        }
    }

    /// After a task: the tile's next task, or `None` when the tile is
    /// finished (then resolved into `out`).
    fn composite(&self, task: Task, out: &mut Vec<DoneTile>) -> Option<Task> {
        let len = self.work.queue_of(task.tile).len() as u32;
        if task.next < len && task.buf.live > 0 {
            return Some(task);
        }
        out.push((task.tile, self.resolve(task.tile, &task.buf)));
        if self.remaining.fetch_sub(1, Ordering::AcqRel) == 1 {
            self.stop();
        }
        None
    }

    /// The tile's RGB bytes.
    fn resolve(&self, tile: u32, buf: &TileBuf) -> Vec<u8> {
        let t = self.work.tiles[tile as usize];
        let bg = FramePlan::background_rgb(self.background);
        let area = t.area() as usize;
        if buf.segs.is_empty() {
            return bg.repeat(area);
        }
        let mut rgb = Vec::with_capacity(3 * area);
        for (seg, state) in buf.segs.iter().zip(&buf.states) {
            if seg.is_some() {
                let c = state.resolve(&self.ctx);
                rgb.extend_from_slice(&to_bytes(c.truncate() + (1.0 - c.w) * self.background));
            } else {
                rgb.extend_from_slice(&bg);
            }
        }
        rgb
    }

    fn stopped(&self) -> bool {
        self.aborted.load(Ordering::Relaxed) || self.cancel.is_cancelled()
    }

    /// A render thread: takes tasks until the frame ends.
    fn render_loop(&self) -> WorkerOut {
        let _guard = AbortOnPanic(self);
        let mut out = WorkerOut::default();
        loop {
            let task = crossbeam_channel::select! {
                recv(self.tasks.1) -> t => t,
                recv(self.stop_rx) -> _ => break,
            };
            let Ok(mut task) = task else { break };
            if self.stopped() {
                self.abort();
                break;
            }
            self.render_task(&mut task, &mut out.samples);
            if self.inline.load(Ordering::Relaxed) {
                let keep = self.order == TaskOrder::TileFirst;
                let mut task = task;
                while let Some(next) = self.composite(task, &mut out.tiles) {
                    if keep && !self.stopped() {
                        task = next;
                        self.render_task(&mut task, &mut out.samples);
                        continue;
                    }
                    // The receiver lives in `self`: sending cannot fail.
                    let _ = self.tasks.0.send(next);
                    break;
                }
            } else {
                let _ = self.done.0.send(task);
            }
        }
        out
    }

    /// A compositing thread: takes finished tasks until the frame ends.
    fn composite_loop(&self) -> WorkerOut {
        let _guard = AbortOnPanic(self);
        let mut out = WorkerOut::default();
        loop {
            let task = crossbeam_channel::select! {
                recv(self.done.1) -> t => t,
                recv(self.stop_rx) -> _ => break,
            };
            let Ok(task) = task else { break };
            if self.stopped() {
                self.abort();
                break;
            }
            if let Some(next) = self.composite(task, &mut out.tiles) {
                let _ = self.tasks.0.send(next);
            }
        }
        out
    }
}

/// Ends the frame when a thread unwinds, so the others do not wait forever.
struct AbortOnPanic<'s, 'a, V: Volume>(&'s Shared<'a, V>);

impl<V: Volume> Drop for AbortOnPanic<'_, '_, V> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.abort();
        }
    }
}

struct ObjectPass<'a> {
    plan: &'a FramePlan,
    work: &'a FrameWork,
    cells: &'a MacrocellGrid,
    value_range: (f32, f32),
    tf: &'a TransferFunction,
    options: &'a RenderOptions,
    cancel: Cancel<'a>,
    render_threads: usize,
    composite_threads: usize,
    order: TaskOrder,
}

impl VolumeVisitor for ObjectPass<'_> {
    /// Finished tiles and samples taken; `None` when cancelled.
    type Output = Option<(Vec<DoneTile>, u64)>;

    fn visit<V: Volume>(self, volume: &V) -> Self::Output {
        let plan = self.plan;
        let work = self.work;
        let (stop_tx, stop_rx) = crossbeam_channel::bounded(0);
        let shared = Shared {
            ctx: plan.context(volume, self.cells, self.value_range, self.tf, self.options),
            plan,
            work,
            mode: self.options.mode,
            background: self.options.background,
            cancel: self.cancel,
            order: self.order,
            remaining: AtomicUsize::new(0),
            aborted: AtomicBool::new(false),
            inline: AtomicBool::new(true),
            tasks: crossbeam_channel::unbounded(),
            done: crossbeam_channel::unbounded(),
            stop_tx: Mutex::new(Some(stop_tx)),
            stop_rx,
        };
        // Tiles with nothing queued are background; the others start with
        // the most work first, so the longest chains of bricks do not trail.
        let mut out = WorkerOut::default();
        let mut started: Vec<(u64, u32)> = Vec::new();
        for (t, rect) in work.tiles.iter().enumerate() {
            let n = work.queue_of(t as u32).len() as u64;
            if n == 0 {
                out.tiles
                    .push((t as u32, shared.resolve(t as u32, &TileBuf::default())));
            } else {
                started.push((n * rect.area(), t as u32));
            }
        }
        if started.is_empty() {
            return Some((out.tiles, 0));
        }
        started.sort_unstable_by(|a, b| b.cmp(a));
        shared.remaining.store(started.len(), Ordering::Relaxed);
        for &(_, t) in &started {
            let _ = shared.tasks.0.send(Task {
                tile: t,
                next: 0,
                buf: TileBuf::default(),
            });
        }
        let outs = std::thread::scope(|s| {
            let shared = &shared;
            let mut handles = Vec::new();
            for i in 0..self.composite_threads {
                let spawned = std::thread::Builder::new()
                    .name(format!("raycaster-composite-{i}"))
                    .spawn_scoped(s, move || shared.composite_loop());
                match spawned {
                    Ok(h) => handles.push(h),
                    // Fewer threads than asked for still finish the frame.
                    Err(_) => break,
                }
            }
            shared.inline.store(handles.is_empty(), Ordering::Relaxed);
            for i in 1..self.render_threads {
                let spawned = std::thread::Builder::new()
                    .name(format!("raycaster-object-{i}"))
                    .spawn_scoped(s, move || shared.render_loop());
                match spawned {
                    Ok(h) => handles.push(h),
                    Err(_) => break,
                }
            }
            let mine = shared.render_loop();
            let mut outs = vec![mine];
            for h in handles {
                match h.join() {
                    Ok(o) => outs.push(o),
                    Err(panic) => std::panic::resume_unwind(panic),
                }
            }
            outs
        });
        if shared.aborted.load(Ordering::Relaxed) || self.cancel.is_cancelled() {
            return None;
        }
        let mut samples = 0;
        for o in outs {
            samples += o.samples;
            out.tiles.extend(o.tiles);
        }
        Some((out.tiles, samples))
    }
}

impl Renderer for ObjectRenderer {
    fn name(&self) -> &'static str {
        "object"
    }

    fn threads(&self) -> usize {
        self.config.render_threads + self.config.composite_threads
    }

    fn render_cancellable<V: VolumeSource>(
        &mut self,
        scene: &Scene<V>,
        camera: &Camera,
        tf: &TransferFunction,
        options: &RenderOptions,
        cancel: Cancel<'_>,
    ) -> Result<Option<Frame>> {
        let start = Instant::now();
        let plan = FramePlan::new(&mut self.cache, scene, scene.grid(), camera, tf, options)?;
        let set = self.brick_set(scene, &plan.prepared, options);
        let work = FrameWork::build(&set, scene.grid(), camera, &plan, self.config.tile);
        let pass = ObjectPass {
            plan: &plan,
            work: &work,
            cells: scene.macrocells(),
            value_range: scene.value_range(),
            tf,
            options,
            cancel,
            render_threads: self.config.render_threads,
            composite_threads: self.config.composite_threads,
            order: self.config.order,
        };
        let Some((tiles, samples)) = scene.volume().accept(pass) else {
            return Ok(None);
        };
        let bg_rgb = FramePlan::background_rgb(options.background);
        let mut rgb = bg_rgb.repeat(plan.width as usize * plan.height as usize);
        for (t, pixels) in tiles {
            let t = work.tiles[t as usize];
            let w = 3 * (t.x1 - t.x0) as usize;
            for (row, j) in (t.y0..t.y1).enumerate() {
                let o = 3 * (j as usize * plan.width as usize + t.x0 as usize);
                rgb[o..o + w].copy_from_slice(&pixels[row * w..row * w + w]);
            }
        }
        let stats = FrameStats {
            rays: plan.rect.area(),
            samples,
            time: start.elapsed(),
        };
        Ok(Some(Frame {
            width: plan.width,
            height: plan.height,
            rgb,
            stats,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Ray;

    fn random_unit(rng: &mut fastrand::Rng) -> Vec3 {
        loop {
            let v = Vec3::new(
                rng.f32() * 2.0 - 1.0,
                rng.f32() * 2.0 - 1.0,
                rng.f32() * 2.0 - 1.0,
            );
            if let Some(u) = v.try_normalize() {
                // Now and then an axis-aligned or axis-parallel-plane ray.
                return match rng.u32(0..8) {
                    0 => Vec3::new(u.x, 0.0, 0.0).try_normalize().unwrap_or(Vec3::X),
                    1 => Vec3::new(u.x, u.y, 0.0).try_normalize().unwrap_or(Vec3::Y),
                    _ => u,
                };
            }
        }
    }

    /// Every sample index of random rays falls in exactly one brick's range,
    /// the brick that holds its computed position, and along the ray the
    /// bricks come in increasing front-to-back key.
    #[test]
    fn brick_ranges_partition_every_ray() {
        let mut rng = fastrand::Rng::with_seed(5);
        for trial in 0..300 {
            let dims = UVec3::new(rng.u32(2..70), rng.u32(2..70), rng.u32(1..70));
            let spacing = Vec3::new(0.5 + rng.f32(), 0.5 + rng.f32(), 0.5 + rng.f32());
            let grid = Grid::new(dims, spacing);
            let side = rng.u32(1..24);
            let n = |d: u32| if d <= 1 { 1 } else { (d - 1).div_ceil(side) };
            let set = BrickSet {
                side,
                count: UVec3::new(n(dims.x), n(dims.y), n(dims.z)),
                visible: Vec::new(),
            };
            let ext = grid.extent();
            let inside = trial % 3 == 0;
            let origin = if inside {
                Vec3::new(rng.f32(), rng.f32(), rng.f32()) * ext
            } else {
                ext * 0.5 + random_unit(&mut rng) * (ext.length() + 5.0)
            };
            // Aim at a random point of the box (or a face plane now and then).
            let mut target = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * ext;
            if trial % 5 == 1 {
                target.x = 0.0;
            }
            let dir = if inside {
                random_unit(&mut rng)
            } else {
                (target - origin).try_normalize().unwrap_or(Vec3::Z)
            };
            let ray = Ray { origin, dir };
            let step = [0.05, 0.2, 0.37, 1.0][rng.usize(0..4)];
            let Some(seg) = RaySegment::new(&grid, &ray, step) else {
                continue;
            };
            let mut owner = vec![u32::MAX; seg.count as usize];
            let mut bricks = Vec::new();
            for bx in 0..set.count.x {
                for by in 0..set.count.y {
                    for bz in 0..set.count.z {
                        let b = UVec3::new(bx, by, bz);
                        let r = set.region(b);
                        let (k0, k1) = sample_range(&seg, &r);
                        assert_eq!(
                            (k0 < k1).then_some((k0, k1)),
                            {
                                let (e0, e1) = exact_range(&seg, &r);
                                (e0 < e1).then_some((e0, e1))
                            },
                            "fast and exact ranges differ"
                        );
                        if k0 >= k1 {
                            continue;
                        }
                        bricks.push((k0, b));
                        for k in k0..k1 {
                            assert_eq!(
                                owner[k as usize],
                                u32::MAX,
                                "sample {k} in two bricks (trial {trial})"
                            );
                            owner[k as usize] = bx * 10000 + by * 100 + bz;
                            let p = seg.pos(k);
                            let want = UVec3::new(
                                set.brick_of(p.x, set.count.x),
                                set.brick_of(p.y, set.count.y),
                                set.brick_of(p.z, set.count.z),
                            );
                            assert_eq!(want, b, "sample {k} at {p} assigned to the wrong brick");
                        }
                    }
                }
            }
            assert!(
                owner.iter().all(|&o| o != u32::MAX),
                "trial {trial}: a sample in no brick"
            );
            // Front-to-back: keys strictly increase along the ray.
            bricks.sort_by_key(|&(k0, _)| k0);
            let eye = grid.world_to_voxel(origin);
            let key = |b: UVec3| -> i64 {
                (0..3)
                    .map(|a| (b[a] as i64 - set.brick_of(eye[a], set.count[a]) as i64).abs())
                    .sum()
            };
            for w in bricks.windows(2) {
                assert!(key(w[0].1) < key(w[1].1), "order broken at {:?}", w);
            }
        }
    }

    /// Every pixel whose ray hits a box lies in the box's footprint, for
    /// cameras outside, beside and inside the box, in both projections.
    #[test]
    fn footprints_hold_every_hitting_pixel() {
        let mut rng = fastrand::Rng::with_seed(9);
        let mut full = 0;
        for n in 0..400 {
            let lo = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 10.0 - 5.0;
            let b = Aabb::new(
                lo,
                lo + Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 4.0 + 0.1,
            );
            let pos = match n % 3 {
                0 => b.center() + (Vec3::new(rng.f32(), rng.f32(), rng.f32()) - 0.5) * 2.0,
                _ => Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 24.0 - 12.0,
            };
            let target = pos + random_unit(&mut rng);
            let mut cam = Camera::look_at(pos, target, 48, 36);
            cam.fov_y_deg = 20.0 + rng.f32() * 120.0;
            if n % 4 == 3 {
                cam.projection = Projection::Orthographic;
            }
            let Some(f) = cam.frame() else { continue };
            let fp = footprint(&f, &cam, &b);
            if fp.is_some_and(|r| r.area() == 48 * 36) {
                full += 1;
            }
            for j in 0..36 {
                for i in 0..48 {
                    if b.intersect(&f.ray(i, j)).is_some() {
                        let r = fp.unwrap_or_else(|| {
                            panic!("pixel {i},{j} hits {b:?} but no footprint ({cam:?})")
                        });
                        assert!(r.contains(i, j), "pixel {i},{j} outside {r:?} ({cam:?})");
                    }
                }
            }
        }
        // Most boxes are not around the eye: footprints are usually partial.
        assert!(full < 250, "{full} full-screen footprints");
    }
}
