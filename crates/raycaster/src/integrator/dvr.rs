//! Direct volume rendering: front-to-back compositing with ERT and ESS, and
//! optionally gradient-magnitude opacity ([`GradientOpacity`]).

use glam::{UVec3, Vec3, Vec3A, Vec4};

use super::batch::SampleBatch;
use super::{
    BLOCK, Fragment, FrameContext, GradientOpacity, Integrator, Occupancy, RayBlock, RaySegment,
    Span, integrate_each,
};
use crate::accel::RunKind;
use crate::simd::{self, Isa, Kernel, LANES};
use crate::volume::{CornerGradients, Volume, corner_gradients, interpolate_gradient};

/// The most samples [`DvrState::integrate`] gathers from consecutive runs
/// before marching them.
const MAX_GATHER: u32 = 64 * LANES as u32;

/// How many of a marched run's first samples [`DvrState::integrate`] asks
/// the memory for when it meets the run (one cell per batch; the march
/// asks for the rest, [`SampleBatch::fill`]'s prefetch distance ahead).
const PREFETCH_SAMPLES: u32 = super::batch::PREFETCH_BATCHES * LANES as u32;

/// Corner gradients of a cell where every difference is zero.
const ZERO_GRADIENTS: CornerGradients = [Vec4::ZERO; 8];

/// Accumulated colour (premultiplied) and opacity of a ray.
///
/// The opacity is kept as the transmittance `T = 1 − A`: SPEC §5's
/// `C += (1 − A)·α·c; A += (1 − A)·α` is `C += T·α·c; T ·= 1 − α`, whose
/// chain from sample to sample is one multiplication instead of a
/// subtraction, a multiplication and an addition.
#[derive(Debug, Clone, Copy)]
pub struct DvrState {
    /// `C`, premultiplied.
    pub color: Vec3,
    /// `T = 1 − A`.
    pub transmittance: f32,
    /// Set once `A` reached the ERT threshold.
    pub terminated: bool,
    /// How many samples of consecutive runs [`Integrator::integrate`]
    /// gathers before marching them (0: one batch). It doubles with every
    /// march of the ray, across the spans of a ray split into bricks.
    pub gather: u32,
}

impl Default for DvrState {
    fn default() -> Self {
        DvrState {
            color: Vec3::ZERO,
            transmittance: 1.0,
            terminated: false,
            gather: 0,
        }
    }
}

impl Integrator for DvrState {
    type Scratch = ();

    const CULLS_EMPTY_BRICKS: bool = true;

    const OCCUPANCY: Occupancy = Occupancy::Visible;

    /// The rays come in blocks, set up together in vector instructions,
    /// and blocks the proxy depths cull are passed over whole; they are
    /// integrated one by one (`DvrState::integrate_packet`).
    const PACKETS: bool = true;

    /// One by one, after asking the memory for each ray's first kept
    /// sample's cell: a ray's first march begins as soon as its walk
    /// reaches the data, too soon for the march's own prefetch, so the
    /// block's later rays find their first cells on the way or in the
    /// cache.
    #[inline(always)]
    fn integrate_packet<V: Volume>(
        ctx: &FrameContext<'_, V>,
        rays: &mut [Self; BLOCK],
        block: &RayBlock,
    ) -> u64 {
        for l in simd::lanes_of(block.searched) {
            if !block.is_empty(l) {
                let seg = block.segment(l);
                ctx.volume.prefetch(seg.pos(seg.first));
            }
        }
        integrate_each(ctx, rays, block)
    }

    /// Composites the span's samples front to back. The samples of a
    /// macrocell that all look up one TF entry are composited without being
    /// taken (`DvrState::composite_constant`): a uniform cell's, and,
    /// unshaded, those of a cell whose value range the TF maps to one
    /// colour. Consecutive runs to be marched are marched together (a
    /// growing number of samples at a time), so batches stay full across
    /// macrocell boundaries.
    #[inline]
    fn integrate<V: Volume>(&mut self, span: Span<'_, V>) -> u64 {
        let (ctx, seg) = (span.ctx, span.seg);
        let mut taken = 0u64;
        // ERT stops a ray once `A >= threshold`, that is once `T <= 1 − threshold`.
        let t_stop = ctx.ert.map_or(f32::NEG_INFINITY, |a| 1.0 - a);
        // Samples `pending.0..pending.1` still to march, and how many of
        // them to gather before marching: it starts at one batch and doubles
        // with every march, so a ray stopped by a surface at its entry does
        // not first walk every macrocell of its span, while a long march
        // still keeps its batches full across macrocell boundaries.
        let mut pending = (0u32, 0u32);
        let mut gather = self.gather.max(LANES as u32);
        // Without shading or gradient opacity a sample's colour depends on
        // its value alone, so a cell whose value range the TF maps to one
        // colour needs no sampling either.
        let by_value = ctx.shading.is_none() && ctx.gradient_opacity.is_none();
        // Whether an occupied cell's samples are marched, or all look up the
        // TF entry of its least value. A uniform cell's value is constant
        // and its gradient zero (its neighbours hold the same value), which
        // leaves the colour unshaded; gradient opacity weighs the opacity by
        // that gradient, so then it is marched.
        let marched = |i: usize| {
            let (uniform, flat) = ctx.skip.steady(i);
            !((uniform && ctx.gradient_opacity.is_none()) || (by_value && flat))
        };
        // Consecutive cells that are all marched, or all of one least value
        // (so one TF entry), come as one run.
        let key = |i: usize| {
            Some(if marched(i) {
                u64::MAX
            } else {
                ctx.macrocells.ranges[i].0.to_bits() as u64
            })
        };
        for run in span.runs_merging(key) {
            let march = match run.kind {
                RunKind::Empty => false,
                RunKind::Cell(i) => marched(i),
                RunKind::Unknown => true,
            };
            if march {
                // The cells of the run's first batches are on their way
                // while the runs up to it are walked and marched: a march
                // asks for its samples a few batches ahead, which leaves
                // its own first batches to wait for memory.
                let mut k = run.start;
                while k < run.end.min(run.start + PREFETCH_SAMPLES) {
                    ctx.volume.prefetch(seg.pos(k));
                    k += LANES as u32;
                }
            }
            if march && run.start == pending.1 && pending.1 - pending.0 < gather {
                pending.1 = run.end;
                continue;
            }
            if pending.0 < pending.1 {
                taken += self.march(ctx, seg, pending.0, pending.1, t_stop);
                if self.terminated {
                    return taken;
                }
                gather = gather.saturating_mul(8).min(MAX_GATHER);
                self.gather = gather;
            }
            pending = (run.start, run.start);
            if march {
                pending.1 = run.end;
            } else if let RunKind::Cell(i) = run.kind {
                let v = ctx.macrocells.ranges[i].0;
                taken += self.composite_constant(ctx.lut.lookup(v), run.end - run.start, t_stop);
                if self.terminated {
                    return taken;
                }
                pending = (run.end, run.end);
            }
        }
        taken + self.march(ctx, seg, pending.0, pending.1, t_stop)
    }

    fn is_done(&self) -> bool {
        self.terminated
    }

    fn resolve<V: Volume>(&self, _ctx: &FrameContext<'_, V>) -> Vec4 {
        self.color.extend(self.alpha())
    }

    /// The premultiplied colour and opacity, composited "over" later.
    fn fragment<V: Volume>(&self, ctx: &FrameContext<'_, V>) -> Fragment {
        Fragment {
            rgba: self.resolve(ctx),
            ..Fragment::default()
        }
    }
}

impl DvrState {
    /// The accumulated opacity `A = 1 − T`.
    #[inline(always)]
    pub fn alpha(&self) -> f32 {
        1.0 - self.transmittance
    }

    /// Samples `k..end` in batches, compositing front to back, in the best
    /// instruction set. Returns the samples taken.
    #[inline(always)]
    fn march<V: Volume>(
        &mut self,
        ctx: &FrameContext<'_, V>,
        seg: &RaySegment,
        k: u32,
        end: u32,
        t_stop: f32,
    ) -> u64 {
        if k >= end {
            return 0;
        }
        // Gradient opacity is a separate monomorphised loop, so the default
        // loop carries no test for it.
        match ctx.gradient_opacity {
            None => simd::dispatch(March::<V, false> {
                state: self,
                ctx,
                seg,
                k,
                end,
                t_stop,
                go: GradientOpacity::default(),
            }),
            Some(go) => simd::dispatch(March::<V, true> {
                state: self,
                ctx,
                seg,
                k,
                end,
                t_stop,
                go,
            }),
        }
    }

    /// Composites `n` samples that all look up as `e` (premultiplied,
    /// unshaded), one by one with the marching loop's [`composite`], so
    /// with the same bits and the same ERT sample: skipping on and
    /// off give the same pixels (SPEC §5). A closed form (`T·(1 − α)ⁿ`, with
    /// a logarithm for the ERT sample) moved pixels by a level and was not
    /// faster on runs the length of a macrocell. Returns the samples
    /// composited.
    #[inline]
    fn composite_constant(&mut self, e: Vec4, n: u32, t_stop: f32) -> u64 {
        if e.w <= 0.0 {
            return n as u64;
        }
        // The colour in a whole vector register of its own, so the compiler
        // does not pack the opacity beside it: the opacity's chain from
        // sample to sample then has no shuffles in it.
        let rgb = Vec3A::from(e.truncate());
        let (mut color, mut t) = (Vec3A::from(self.color), self.transmittance);
        let mut taken = n as u64;
        for i in 0..n {
            if composite(&mut color, &mut t, rgb, e.w, t_stop) {
                self.terminated = true;
                taken = i as u64 + 1;
                break;
            }
        }
        self.color = color.into();
        self.transmittance = t;
        taken
    }
}

/// Composites one sample of premultiplied colour `rgb` and opacity `alpha`
/// behind the ray's colour and transmittance `t` (SPEC §5 with `T = 1 −
/// A`); true once ERT stops the ray (`t <= t_stop`). The one place both
/// the marches and the constant runs composite, so they give the same bits.
#[inline(always)]
fn composite(color: &mut Vec3A, t: &mut f32, rgb: Vec3A, alpha: f32, t_stop: f32) -> bool {
    *color += *t * rgb;
    *t *= 1.0 - alpha;
    *t <= t_stop
}

/// [`DvrState::march`]'s loop as a [`Kernel`]; `GO`: with gradient opacity
/// `go`.
struct March<'a, 'c, V: Volume, const GO: bool> {
    state: &'a mut DvrState,
    ctx: &'a FrameContext<'c, V>,
    seg: &'a RaySegment,
    k: u32,
    end: u32,
    t_stop: f32,
    go: GradientOpacity,
}

impl<V: Volume, const GO: bool> Kernel for March<'_, '_, V, GO> {
    type Output = u64;

    /// The marching loop: values and table positions a batch at a time,
    /// then lookup, shading and compositing of the lanes that may be
    /// visible, in order. Works on local copies of the state, so the loop
    /// keeps them in registers.
    #[inline(always)]
    fn run<I: Isa>(self, isa: I) -> u64 {
        let March {
            state,
            ctx,
            seg,
            k,
            end,
            t_stop,
            go,
        } = self;
        let volume = ctx.volume;
        let lut = ctx.lut;
        let shading = ctx.shading;
        // A whole register for the colour, as in `composite_constant`.
        let mut color = Vec3A::from(state.color);
        let mut t = state.transmittance;
        let mut taken = (end - k) as u64;
        let mut done = false;
        let inv_two_spacing = 0.5 / volume.grid().spacing;
        let mut batch = SampleBatch::new(volume.grid());
        // A cell's corner gradients, kept while consecutive visible samples
        // stay in it, and whether they are all zero.
        let (mut grads_cell, mut grads) = (UVec3::splat(u32::MAX), (ZERO_GRADIENTS, true));
        let mut b = k;
        'march: while b < end {
            let len = ((end - b) as usize).min(LANES);
            batch.fill(isa, volume, seg, b, len);
            // The gradient's wing rows of the cell `fill` prefetched. The
            // position is `fill`'s own: after inlining the compiler computes
            // it once (one call with a flag for both measured more
            // instructions).
            if GO || shading.is_some() {
                volume.prefetch_wings(seg.pos(b + PREFETCH_SAMPLES));
            }
            let (x, visible) = lut.visible_lanes(isa, &batch.value);
            let mut lanes = visible & ((1 << len) - 1);
            while lanes != 0 {
                let l = lanes.trailing_zeros() as usize;
                lanes &= lanes - 1;
                let mut e = lut.lookup_at(x[l], batch.value[l]);
                if e.w <= 0.0 {
                    continue;
                }
                // The gradient, only for samples the TF makes visible and
                // only when shading or gradient opacity needs it; `None`
                // when it is exactly zero.
                let g = if GO || shading.is_some() {
                    let cell = batch.cell(l);
                    if grads_cell != cell {
                        grads_cell = cell;
                        // Zero corner differences (inside a homogeneous
                        // region) give a zero gradient, which leaves the
                        // colour unshaded: no arithmetic per sample.
                        // Cells at the grid's faces read clamped wings.
                        let w = volume.wings(cell);
                        let g = corner_gradients(&batch.corners(l), &w);
                        grads = (g, g.iter().all(|d| *d == Vec4::ZERO));
                    }
                    match &grads {
                        (_, true) => None,
                        (g, false) => Some(interpolate_gradient(g, batch.frac(l), inv_two_spacing)),
                    }
                } else {
                    None
                };
                if GO {
                    let w = go.weight(g.map_or(0.0, |g| g.length()));
                    if w <= 0.0 {
                        continue;
                    }
                    if w < 1.0 {
                        e = go.scale(e, w, lut.step());
                    }
                }
                let mut rgb = e.truncate();
                if let Some(ph) = &shading
                    && let Some(g) = g
                    && let Some((diffuse, spec)) = ph.terms(g, seg.world_dir)
                {
                    rgb = rgb * diffuse + Vec3::splat(e.w * spec);
                }
                if composite(&mut color, &mut t, Vec3A::from(rgb), e.w, t_stop) {
                    done = true;
                    taken = (b - k) as u64 + l as u64 + 1;
                    break 'march;
                }
            }
            b += len as u32;
        }
        state.color = color.into();
        state.transmittance = t;
        state.terminated |= done;
        taken
    }
}
