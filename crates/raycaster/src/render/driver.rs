//! The frame driver: the one body every renderer runs a frame through.
//!
//! [`render_frame`] validates the options and prepares the frame (the
//! [`FramePlan`]), reaches the volume's concrete type and the mode's
//! [`Integrator`] (once per frame), times the frame, and assembles the
//! [`Film`]. A renderer supplies only its scheduling, as a [`Schedule`]:
//! which rays are integrated on which threads and in which order. The
//! serial and tiled renderers share the tile loop, [`render_tile`].

use std::time::Instant;

use glam::Vec4;

use super::film::{Film, RayCounts};
use super::plan::{FramePlan, PlanCache, RenderOptions};
use super::{Cancel, Frame, FrameStats, Renderer};
use crate::camera::{Camera, PixelRect, Projection};
use crate::error::Result;
use crate::integrator::{
    BLOCK, FrameContext, Integrator, IntegratorVisitor, PACKET_H, PACKET_W, RayBlock, RaySegment,
    Span, jitter,
};
use crate::scene::Scene;
use crate::simd::{self, Isa, Kernel, lanes_of, mask_of};
use crate::transfer::TransferFunction;
use crate::volume::{Volume, VolumeVisitor};

/// Everything a schedule needs to integrate a frame's rays.
pub struct FrameJob<'a, V: Volume> {
    /// The integrators' view of the frame.
    pub ctx: FrameContext<'a, V>,
    /// Camera frame, screen rectangle, step, prepared tables.
    pub plan: &'a FramePlan,
    /// The scene (for schedules that derive their own structures from it).
    pub scene: &'a Scene,
    /// The camera as given.
    pub camera: &'a Camera,
    /// The options as given.
    pub options: &'a RenderOptions,
    /// When to stop.
    pub cancel: Cancel<'a>,
}

impl<V: Volume> FrameJob<'_, V> {
    /// The ray of pixel `(i, j)` clipped to the volume, `None` when it
    /// misses: jittered and clipped as the frame says, the one place every
    /// schedule gets its rays from. With the frame's proxy depths, the
    /// part searched (exact iso) or the samples kept (DVR) start where the
    /// ray first meets a cell that can hold the surface or that the TF
    /// makes visible, and a ray that meets none keeps no sample (it still
    /// counts as entering the volume).
    #[inline]
    pub fn segment(&self, i: u32, j: u32) -> Option<RaySegment> {
        match self.pixel(i, j) {
            PixelRay::Misses => None,
            PixelRay::Culled(seg) => seg,
            PixelRay::Searched(seg) => Some(seg),
        }
    }

    /// [`FrameJob::segment`], telling apart a ray the proxy depths cull.
    #[inline(always)]
    pub fn pixel(&self, i: u32, j: u32) -> PixelRay {
        self.pixel_in(i, j, false)
    }

    /// [`FrameJob::pixel`] for a pixel of a rectangle whose rays all enter
    /// the volume's box when `all_enter` ([`FrameJob::all_enter`]): a ray
    /// the proxy depths cull is then not traced to the box only to be
    /// counted as entering it.
    #[inline(always)]
    pub fn pixel_in(&self, i: u32, j: u32, all_enter: bool) -> PixelRay {
        let grid = self.ctx.volume.grid();
        let start = self.plan.proxy.as_ref().map(|p| p.at(i, j));
        if start == Some(f32::INFINITY) {
            if all_enter {
                return PixelRay::Culled(None);
            }
            let ray = self.plan.camera.ray(i, j);
            return RaySegment::entering(grid, &ray, self.plan.step)
                .map_or(PixelRay::Misses, |seg| PixelRay::Culled(Some(seg)));
        }
        let ray = self.plan.camera.ray(i, j);
        let Some(mut seg) = RaySegment::with(
            grid,
            &ray,
            self.plan.step,
            self.plan.jitter.map_or(0.0, |seed| jitter(i, j, seed)),
            self.plan.clip.as_ref(),
        ) else {
            return PixelRay::Misses;
        };
        if let Some(t) = start {
            if self.plan.proxy_moves_samples {
                seg.first = first_kept(seg.first, seg.count, seg.t0, seg.inv_step, t);
            } else {
                seg.t_in = seg.t_in.max(t);
            }
        }
        PixelRay::Searched(seg)
    }

    /// [`FrameJob::pixel_in`] for the [`PACKET_W`]×[`PACKET_H`] pixels
    /// from `(i0, j0)` (lane `l` is pixel `(i0 + l % PACKET_W, j0 + l /
    /// PACKET_W)`), into `block`: the same for every pixel, with the
    /// arithmetic of the rays' set-up (directions, box intersection,
    /// voxel-space segment: a dozen divisions and two square roots a ray)
    /// done for all the block's rays at once in vector instructions. The
    /// masks say which lanes are searched (their segments set) and which
    /// culled by the proxy depths (their segments not worked out: the tile
    /// loop reads only whether they enter the box); a ray that misses is
    /// in neither. Returns false, leaving `block` as it was, where only the
    /// pixel-by-pixel way applies: an orthographic camera, a clip region, a
    /// direction component of 0. The block must lie inside the image.
    #[inline]
    pub fn pixel_block(&self, i0: u32, j0: u32, all_enter: bool, block: &mut RayBlock) -> bool {
        if self.plan.camera.projection() != Projection::Perspective || self.plan.clip.is_some() {
            return false;
        }
        simd::dispatch(PixelBlock {
            job: self,
            i0,
            j0,
            all_enter,
            block,
        })
    }

    /// The rays of the pixels of `rect` (at most a block's: lane `l` is the
    /// pixel `(rect.x0 + l % PACKET_W, rect.y0 + l / PACKET_W)`) into
    /// `block`, pixel by pixel ([`FrameJob::pixel_in`]).
    fn pixel_block_in(&self, rect: &PixelRect, all_enter: bool, block: &mut RayBlock) {
        block.searched = 0;
        block.culled = 0;
        for j in rect.y0..rect.y1 {
            for i in rect.x0..rect.x1 {
                let l = ((j - rect.y0) * PACKET_W + i - rect.x0) as usize;
                match self.pixel_in(i, j, all_enter) {
                    PixelRay::Misses => {}
                    PixelRay::Culled(_) => block.culled |= 1 << l,
                    PixelRay::Searched(seg) => {
                        block.set(l, &seg);
                        block.searched |= 1 << l;
                    }
                }
            }
        }
    }

    /// Whether every pixel ray of `rect` enters the volume's box: its four
    /// corner pixels' rays do. The rays of one frame that meet a convex
    /// box form a convex set (a cone from a perspective eye, a convex
    /// region of origins for parallel rays), and a pixel's ray lies between
    /// its rectangle's corner rays, no closer to that set's edge than the
    /// nearest of them.
    pub fn all_enter(&self, rect: &PixelRect) -> bool {
        if rect.is_empty() {
            return false;
        }
        let grid = self.ctx.volume.grid();
        [
            (rect.x0, rect.y0),
            (rect.x1 - 1, rect.y0),
            (rect.x0, rect.y1 - 1),
            (rect.x1 - 1, rect.y1 - 1),
        ]
        .into_iter()
        .all(|(i, j)| {
            RaySegment::entering(grid, &self.plan.camera.ray(i, j), self.plan.step).is_some()
        })
    }
}

/// [`FrameJob::pixel_block`] as a [`Kernel`]: its lane-wise loops over the
/// block's 16 rays compiled 16 wide where the CPU has AVX-512, else 8 wide
/// with AVX2 ([`Kernel::WIDE`]).
struct PixelBlock<'a, 'j, V: Volume> {
    job: &'a FrameJob<'j, V>,
    i0: u32,
    j0: u32,
    all_enter: bool,
    block: &'a mut RayBlock,
}

impl<V: Volume> Kernel for PixelBlock<'_, '_, V> {
    type Output = bool;
    const WIDE: bool = true;

    #[inline(always)]
    fn run<I: Isa>(self, _isa: I) -> Self::Output {
        let PixelBlock {
            job,
            i0,
            j0,
            all_enter,
            block,
        } = self;
        let plan = job.plan;
        let grid = job.ctx.volume.grid();
        let i: [u32; BLOCK] = std::array::from_fn(|l| i0 + l as u32 % PACKET_W);
        let j: [u32; BLOCK] = std::array::from_fn(|l| j0 + l as u32 / PACKET_W);
        let start: [f32; BLOCK] = match &plan.proxy {
            Some(p) => p.block_at(i0, j0),
            None => [f32::NEG_INFINITY; BLOCK],
        };
        // (A block whose rays are all culled in a rectangle known to enter
        // the box never comes here from the tile loop: it passes over such
        // blocks by their proxy depths, `ProxyDepth::culls`.)
        let dir = plan.camera.perspective_dirs(&i, &j);
        if dir.iter().flatten().any(|&d| d == 0.0) {
            return false;
        }
        let origin = plan.camera.position();
        let (t_in, t_out) = grid.bounds().intersect_lanes(origin, &dir);
        // Which lanes are searched and culled. A culled ray of a rectangle
        // not known to enter the box is traced to the box only to be
        // counted (the rectangles along the box's silhouette, and those
        // inside its screen rectangle but off its outline).
        let mut searched = [0u32; BLOCK];
        let mut culled = [0u32; BLOCK];
        for l in 0..BLOCK {
            let enters = t_in[l] <= t_out[l];
            let is_culled = start[l] == f32::INFINITY;
            culled[l] = (is_culled && (all_enter || enters)) as u32;
            searched[l] = (!is_culled && enters) as u32;
        }
        block.searched = mask_of(&searched);
        block.culled = mask_of(&culled);
        if block.searched == 0 {
            return true;
        }
        let jitter: [f32; BLOCK] = match plan.jitter {
            Some(seed) => std::array::from_fn(|l| jitter(i[l], j[l], seed)),
            None => [0.0; BLOCK],
        };
        block.set_up(grid, origin, &dir, (&t_in, &t_out), plan.step, &jitter);
        // `pixel_in`'s raise to the proxy's start (none: −∞): of the first
        // sample kept (DVR), or of where the search starts (exact iso).
        if plan.proxy_moves_samples {
            let inv_step = block.inv_step;
            for (((first, &count), &t0), &start) in block
                .first
                .iter_mut()
                .zip(&block.count)
                .zip(&block.t0)
                .zip(&start)
            {
                *first = first_kept(*first, count, t0, inv_step, start);
            }
        } else {
            for (t_in, &start) in block.t_in.iter_mut().zip(&start) {
                *t_in = t_in.max(start);
            }
        }
        true
    }
}

/// The first sample kept of a ray whose samples `first..count` lie at `t0 +
/// k / inv_step`, raised to the proxy depth `start` (DVR's
/// [`FramePlan::proxy_moves_samples`]): at most one sample early, never
/// late. The one formula of [`FrameJob::pixel_in`] and of the blocks'
/// lane-wise set-up, so both keep the same samples.
#[inline(always)]
fn first_kept(first: u32, count: u32, t0: f32, inv_step: f32, start: f32) -> u32 {
    first.max(RaySegment::index_at_or_after(t0, inv_step, start).min(count))
}

/// What [`FrameJob::pixel`] found for a pixel's ray.
#[derive(Debug, Clone, Copy)]
pub enum PixelRay {
    /// It misses the volume's box.
    Misses,
    /// It enters the box, but the frame's proxy depths say it meets no
    /// cell that can hold the surface or show (exact iso and DVR frames):
    /// its segment keeps no sample, and its pixel shows the background.
    /// `None` when the segment was not worked out (see
    /// [`FrameJob::pixel_in`]).
    Culled(Option<RaySegment>),
    /// The part of it to integrate.
    Searched(RaySegment),
}

/// How a renderer schedules the rays of a frame: the one part in which the
/// renderers differ (see [`FrameRenderer`](super::FrameRenderer)).
pub trait Schedule: Send {
    /// Short name (`serial`, `tiles`, `object`).
    const NAME: &'static str;

    /// Worker threads used.
    fn threads(&self) -> usize;

    /// Integrates the rays of `job.plan.rect` with integrator `I` onto
    /// `film` (each tile put on it by the thread that rendered it);
    /// returns the samples taken, or `None` when `job.cancel` fired.
    fn run<V: Volume, I: Integrator>(&mut self, job: &FrameJob<'_, V>, film: &Film) -> Option<u64>;
}

/// A renderer made of a schedule (which rays are integrated on which
/// threads) and the frame driver every renderer shares: preparation, the
/// dispatch to the volume and integrator types, timing, the film.
#[derive(Debug, Default)]
pub struct FrameRenderer<S> {
    schedule: S,
    cache: PlanCache,
}

impl<S> FrameRenderer<S> {
    pub(crate) fn with_schedule(schedule: S) -> Self {
        FrameRenderer {
            schedule,
            cache: PlanCache::default(),
        }
    }

    pub(crate) fn schedule(&self) -> &S {
        &self.schedule
    }
}

impl<S: Schedule> Renderer for FrameRenderer<S> {
    fn name(&self) -> &'static str {
        S::NAME
    }

    fn threads(&self) -> usize {
        self.schedule.threads()
    }

    /// Renders one frame with the schedule (see the module docs); `Ok(None)`
    /// when cancelled.
    fn render_cancellable(
        &mut self,
        scene: &Scene,
        camera: &Camera,
        tf: &TransferFunction,
        options: &RenderOptions,
        cancel: Cancel<'_>,
    ) -> Result<Option<Frame>> {
        render_frame(
            &mut self.schedule,
            &mut self.cache,
            FrameInputs {
                scene,
                camera,
                tf,
                options,
            },
            cancel,
        )
    }
}

/// What a frame is rendered from.
#[derive(Clone, Copy)]
struct FrameInputs<'a> {
    scene: &'a Scene,
    camera: &'a Camera,
    tf: &'a TransferFunction,
    options: &'a RenderOptions,
}

/// Renders one frame with `schedule`; `Ok(None)` when cancelled.
fn render_frame<S: Schedule>(
    schedule: &mut S,
    cache: &mut PlanCache,
    inputs: FrameInputs<'_>,
    cancel: Cancel<'_>,
) -> Result<Option<Frame>> {
    let start = Instant::now();
    let FrameInputs { scene, options, .. } = inputs;
    let mut plan = FramePlan::new(cache, scene, inputs.camera, inputs.tf, options)?;
    plan.draw_proxy(cache, scene, options);
    let film = Film::new(plan.width, plan.height, options.background);

    struct WithVolume<'a, S> {
        schedule: &'a mut S,
        plan: &'a FramePlan,
        inputs: FrameInputs<'a>,
        cancel: Cancel<'a>,
        film: &'a Film,
    }
    impl<S: Schedule> VolumeVisitor for WithVolume<'_, S> {
        type Output = Option<u64>;
        fn visit<V: Volume>(self, volume: &V) -> Option<u64> {
            let FrameInputs {
                scene,
                camera,
                tf,
                options,
            } = self.inputs;
            let job = FrameJob {
                ctx: self.plan.context(volume, scene, tf, options),
                plan: self.plan,
                scene,
                camera,
                options,
                cancel: self.cancel,
            };
            options.mode.visit(WithIntegrator {
                schedule: self.schedule,
                job: &job,
                film: self.film,
            })
        }
    }
    struct WithIntegrator<'a, 'j, S, V: Volume> {
        schedule: &'a mut S,
        job: &'a FrameJob<'j, V>,
        film: &'a Film,
    }
    impl<S: Schedule, V: Volume> IntegratorVisitor for WithIntegrator<'_, '_, S, V> {
        type Output = Option<u64>;
        fn visit<I: Integrator>(self) -> Option<u64> {
            self.schedule.run::<V, I>(self.job, self.film)
        }
    }

    let samples = scene.volume().visit(WithVolume {
        schedule,
        plan: &plan,
        inputs,
        cancel,
        film: &film,
    });
    let Some(samples) = samples else {
        return Ok(None);
    };
    if cancel.is_cancelled() {
        return Ok(None);
    }
    let counts = film.counts();
    Ok(Some(Frame {
        width: plan.width,
        height: plan.height,
        rgb: film.into_rgb(),
        stats: FrameStats {
            rays: plan.rect.area(),
            rays_in_volume: counts.entered,
            covered: counts.covered,
            samples,
            time: start.elapsed(),
        },
    }))
}

/// The tile loop: integrates every pixel of `rect` whole with `I`, puts
/// the tile on `film` (not a tile the proxy depths show to be background
/// only: the film holds the background already) and returns the samples
/// taken.
///
/// Never inlined: the object renderer calls it from the thread that runs
/// the frame and from the threads it spawns, and inlined into both it
/// became two copies of the integrator's loop that the compiler optimised
/// differently (one slower, with the iso cell test out of line).
#[inline(never)]
pub(crate) fn render_tile<V: Volume, I: Integrator>(
    job: &FrameJob<'_, V>,
    film: &Film,
    rect: &PixelRect,
) -> u64 {
    let all_enter = job.plan.proxy.is_some() && job.all_enter(rect);
    if I::PACKETS {
        return render_tile_packets::<V, I>(job, film, rect, all_enter);
    }
    let mut rgb = Vec::with_capacity(3 * rect.area() as usize);
    let mut samples = 0;
    let mut counts = RayCounts::default();
    let mut scratch = I::Scratch::default();
    for j in rect.y0..rect.y1 {
        for i in rect.x0..rect.x1 {
            let px = match job.pixel_in(i, j, all_enter) {
                PixelRay::Misses => film.background_rgb(),
                // What the iso search of an empty segment ends with, without
                // integrating and resolving nothing.
                PixelRay::Culled(_) => {
                    counts.entered += 1;
                    film.background_rgb()
                }
                PixelRay::Searched(seg) => {
                    let mut ray = I::default();
                    samples += ray.integrate(Span::whole(&job.ctx, &seg));
                    let c = ray.resolve_in(&job.ctx, &mut scratch);
                    counts.add(c);
                    film.composite(c)
                }
            };
            rgb.extend_from_slice(&px);
        }
    }
    film.add_counts(counts);
    film.put_tile(rect, &rgb);
    samples
}

/// [`render_tile`] for an integrator that takes the rays of blocks of
/// [`PACKET_W`]×[`PACKET_H`] pixels together
/// ([`Integrator::integrate_packet`]); the pixels come out as one by one.
fn render_tile_packets<V: Volume, I: Integrator>(
    job: &FrameJob<'_, V>,
    film: &Film,
    rect: &PixelRect,
    all_enter: bool,
) -> u64 {
    let width = rect.x1 - rect.x0;
    let mut samples = 0;
    let mut counts = RayCounts::default();
    // Whether the proxy depths cull every ray of a rectangle whose rays
    // all enter the box: then they only count.
    let culled = |r: &PixelRect| all_enter && job.plan.proxy.as_ref().is_some_and(|p| p.culls(r));
    if culled(rect) {
        // Background only, which the film already holds.
        counts.entered += rect.area();
        film.add_counts(counts);
        return 0;
    }
    // Every pixel starts as the background: most rays of an iso frame
    // miss the box or are culled.
    let mut rgb = film.background_rgb().repeat(rect.area() as usize);
    let mut scratch = I::Scratch::default();
    let mut block = RayBlock::default();
    let mut rays = [I::default(); BLOCK];
    let mut colours = [Vec4::ZERO; BLOCK];
    for by in (rect.y0..rect.y1).step_by(PACKET_H as usize) {
        for bx in (rect.x0..rect.x1).step_by(PACKET_W as usize) {
            let whole = bx + PACKET_W <= rect.x1 && by + PACKET_H <= rect.y1;
            let block_rect = PixelRect {
                x0: bx,
                y0: by,
                x1: (bx + PACKET_W).min(rect.x1),
                y1: (by + PACKET_H).min(rect.y1),
            };
            if culled(&block_rect) {
                counts.entered += block_rect.area();
                continue;
            }
            if !(whole && job.pixel_block(bx, by, all_enter, &mut block)) {
                job.pixel_block_in(&block_rect, all_enter, &mut block);
            }
            counts.entered += block.culled.count_ones() as u64;
            if block.searched == 0 {
                continue;
            }
            for l in lanes_of(block.searched) {
                rays[l] = I::default();
            }
            samples += I::integrate_packet(&job.ctx, &mut rays, &block);
            I::resolve_packet(&rays, block.searched, &job.ctx, &mut scratch, &mut colours);
            for l in lanes_of(block.searched) {
                let c = colours[l];
                counts.add(c);
                let (i, j) = (bx + l as u32 % PACKET_W, by + l as u32 / PACKET_W);
                let at = 3 * ((j - rect.y0) * width + (i - rect.x0)) as usize;
                rgb[at..at + 3].copy_from_slice(&film.composite(c));
            }
        }
    }
    film.add_counts(counts);
    film.put_tile(rect, &rgb);
    samples
}

#[cfg(test)]
mod tests {
    use glam::{UVec3, Vec3};

    use super::*;
    use crate::camera::Projection;
    use crate::integrator::RenderMode;
    use crate::volume::{AnyVolume, Grid};

    /// A schedule that checks a frame's blocks instead of rendering them:
    /// for every whole block of the frame's rectangle, that
    /// [`FrameJob::pixel_block`] gives, to the bit, what
    /// [`FrameJob::pixel_in`] gives pixel by pixel; and for every block,
    /// that its searched rays resolved together
    /// ([`Integrator::resolve_packet`]) give, to the bit, what each gives
    /// resolved alone ([`Integrator::resolve`]).
    #[derive(Default)]
    struct CheckFrame {
        /// Blocks set up lane-wise, and rays searched and culled in them.
        blocks: usize,
        searched: usize,
        culled: usize,
        /// Rays missing the box in blocks with culled rays, not known to
        /// enter the box (traced to it lane-wise).
        culled_misses: usize,
        /// Rays resolved to some opacity.
        covered: usize,
    }

    impl CheckFrame {
        fn block_set_up<V: Volume>(&mut self, job: &FrameJob<'_, V>, bx: u32, by: u32) {
            for all_enter in [false, true] {
                let mut block = RayBlock::default();
                if !job.pixel_block(bx, by, all_enter, &mut block) {
                    continue;
                }
                self.blocks += 1;
                for l in 0..BLOCK {
                    let (i, j) = (bx + l as u32 % PACKET_W, by + l as u32 / PACKET_W);
                    // A block leaves a culled ray's segment out.
                    let want = match job.pixel_in(i, j, all_enter) {
                        PixelRay::Culled(_) => PixelRay::Culled(None),
                        want => want,
                    };
                    let got = if block.searched >> l & 1 != 0 {
                        PixelRay::Searched(block.segment(l))
                    } else if block.culled >> l & 1 != 0 {
                        PixelRay::Culled(None)
                    } else {
                        PixelRay::Misses
                    };
                    assert_eq!(bits(&got), bits(&want), "pixel {i},{j}");
                    self.searched += matches!(got, PixelRay::Searched(_)) as usize;
                    self.culled_misses += (!all_enter
                        && matches!(got, PixelRay::Misses)
                        && block.culled != 0) as usize;
                    self.culled += matches!(got, PixelRay::Culled(_)) as usize;
                }
            }
        }

        fn block_resolved<V: Volume, I: Integrator>(
            &mut self,
            job: &FrameJob<'_, V>,
            rect: &PixelRect,
            scratch: &mut I::Scratch,
        ) {
            let mut block = RayBlock::default();
            job.pixel_block_in(rect, false, &mut block);
            let mut rays = [I::default(); BLOCK];
            I::integrate_packet(&job.ctx, &mut rays, &block);
            let mut together = [Vec4::ZERO; BLOCK];
            I::resolve_packet(&rays, block.searched, &job.ctx, scratch, &mut together);
            for l in lanes_of(block.searched) {
                let alone = rays[l].resolve(&job.ctx);
                assert_eq!(
                    together[l].to_array().map(f32::to_bits),
                    alone.to_array().map(f32::to_bits)
                );
                self.covered += (alone.w > 0.0) as usize;
            }
        }
    }

    impl Schedule for CheckFrame {
        const NAME: &'static str = "check-frame";

        fn threads(&self) -> usize {
            1
        }

        fn run<V: Volume, I: Integrator>(
            &mut self,
            job: &FrameJob<'_, V>,
            _film: &Film,
        ) -> Option<u64> {
            let rect = job.plan.rect;
            let mut scratch = I::Scratch::default();
            for by in (rect.y0..rect.y1).step_by(PACKET_H as usize) {
                for bx in (rect.x0..rect.x1).step_by(PACKET_W as usize) {
                    let block = PixelRect {
                        x0: bx,
                        y0: by,
                        x1: (bx + PACKET_W).min(rect.x1),
                        y1: (by + PACKET_H).min(rect.y1),
                    };
                    if block.x1 - bx == PACKET_W && block.y1 - by == PACKET_H {
                        self.block_set_up(job, bx, by);
                    }
                    self.block_resolved::<V, I>(job, &block, &mut scratch);
                }
            }
            Some(0)
        }
    }

    /// A pixel's ray as numbers: its kind, then every field of its segment.
    fn bits(ray: &PixelRay) -> Vec<u32> {
        let seg = |kind: u32, s: &RaySegment| {
            let mut v = vec![kind];
            for w in [s.origin, s.dir, s.inv_dir, s.world_dir] {
                v.extend(w.to_array().map(f32::to_bits));
            }
            v.extend([s.t_in, s.t_out, s.t0, s.step, s.inv_step].map(f32::to_bits));
            v.extend([s.first, s.count]);
            v
        };
        match ray {
            PixelRay::Misses => vec![0],
            PixelRay::Culled(None) => vec![1],
            PixelRay::Culled(Some(s)) => seg(2, s),
            PixelRay::Searched(s) => seg(3, s),
        }
    }

    /// The blocks' lane-wise set-up agrees with the pixels' for cameras
    /// outside and inside an anisotropic volume, with and without the
    /// proxy depths of the exact iso mode (where the search starts) and of
    /// DVR (the first sample kept), and with jittered samples.
    #[test]
    fn pixel_blocks_set_up_the_rays_pixel_by_pixel_set_up() {
        let grid = Grid::new(UVec3::new(21, 17, 25), Vec3::new(0.7, 1.3, 0.9));
        let centre = grid.extent() * 0.5;
        // A ball that the TF shows in the middle of empty space, so the
        // DVR proxy moves rays' first samples.
        let scene = Scene::new(AnyVolume::from_fn(grid, |v| {
            let p = v.as_vec3() * grid.spacing;
            (60.0 - (p - centre).length() * 10.0).max(0.0)
        }));
        let point = |value, opacity| crate::transfer::TfPoint {
            value,
            color: [1.0; 3],
            opacity,
        };
        let tf = TransferFunction::new(
            crate::transfer::Interpolation::Linear,
            vec![point(0.0, 0.0), point(20.0, 0.0), point(60.0, 1.0)],
        )
        .unwrap();
        let mut rng = fastrand::Rng::with_seed(3);
        let mut checker = FrameRenderer::with_schedule(CheckFrame::default());
        for trial in 0..24 {
            let eye = if trial % 4 == 3 {
                centre + Vec3::new(rng.f32() - 0.5, rng.f32() - 0.5, rng.f32() - 0.5) * 4.0
            } else {
                let d = Vec3::new(rng.f32() - 0.5, rng.f32() - 0.5, rng.f32() - 0.5);
                centre + d.normalize_or(Vec3::Z) * (30.0 + 30.0 * rng.f32())
            };
            let mut camera = Camera::look_at(eye, centre, 37 + rng.u32(0..30), 29 + rng.u32(0..30));
            camera.fov_y_deg = 20.0 + 50.0 * rng.f32();
            let options = RenderOptions {
                mode: if trial % 2 == 0 {
                    RenderMode::Iso
                } else {
                    RenderMode::Dvr
                },
                iso_value: 30.0,
                jitter: trial % 4 == 1,
                seed: trial,
                ..RenderOptions::default()
            };
            crate::render::Renderer::render(&mut checker, &scene, &camera, &tf, &options).unwrap();
        }
        let c = checker.schedule();
        assert!(
            c.blocks > 1000 && c.searched > 5000 && c.culled > 1000 && c.culled_misses > 100,
            "{}/{}/{}/{}",
            c.blocks,
            c.searched,
            c.culled,
            c.culled_misses
        );
        // Orthographic cameras keep to the pixel-by-pixel way.
        let mut camera = Camera::look_at(centre + Vec3::new(3.0, 40.0, 5.0), centre, 40, 40);
        camera.projection = Projection::Orthographic;
        let blocks = c.blocks;
        crate::render::Renderer::render(
            &mut checker,
            &scene,
            &camera,
            &tf,
            &RenderOptions::default(),
        )
        .unwrap();
        assert_eq!(checker.schedule().blocks, blocks);
    }

    /// Exact iso packets shade (normals, lights, shadow rays) as their rays
    /// shade one by one: with a headlight, with lights, with shadows, with
    /// analytic normals, with a mirror bounce.
    #[test]
    fn packets_resolve_as_their_rays_resolve_alone() {
        use crate::integrator::IsoNormals;
        let grid = Grid::new(UVec3::new(26, 22, 24), Vec3::new(1.0, 0.8, 1.2));
        let centre = grid.extent() * 0.5;
        let scene = Scene::new(AnyVolume::from_fn(grid, |v| {
            let p = v.as_vec3() * grid.spacing;
            let bumps = 1.5 * (0.9 * p.x).sin() * (0.7 * p.z).cos();
            ((p - centre).length() + bumps).min(p.y - 3.0 + 6.0)
        }));
        let tf = TransferFunction::preset("ramp", crate::sample::SampleType::F32).unwrap();
        let lights = vec![Vec3::new(0.3, 1.0, 0.2), Vec3::new(-1.0, 0.4, 0.3)];
        let base = RenderOptions {
            mode: RenderMode::Iso,
            iso_value: 6.0,
            ..RenderOptions::default()
        };
        let configs = [
            base.clone(),
            RenderOptions {
                lights: lights.clone(),
                ..base.clone()
            },
            RenderOptions {
                lights: lights.clone(),
                shadows: true,
                ..base.clone()
            },
            RenderOptions {
                lights: lights.clone(),
                shadows: true,
                iso_normals: IsoNormals::Analytic,
                ..base.clone()
            },
            RenderOptions {
                lights,
                reflection: 0.3,
                ..base.clone()
            },
            RenderOptions {
                shading: false,
                ..base
            },
        ];
        let mut checker = FrameRenderer::with_schedule(CheckFrame::default());
        for (k, options) in configs.iter().enumerate() {
            let eye = centre + Vec3::new(20.0 - 9.0 * k as f32, 25.0, 30.0);
            let camera = Camera::look_at(eye, centre, 61, 47);
            let before = checker.schedule().covered;
            crate::render::Renderer::render(&mut checker, &scene, &camera, &tf, options).unwrap();
            assert!(checker.schedule().covered - before > 300, "{k}");
        }
    }
}
