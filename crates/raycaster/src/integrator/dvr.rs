//! Direct volume rendering: front-to-back compositing with ERT and ESS.

use glam::{UVec3, Vec3, Vec4};

use super::{FrameContext, Integrator, Occupancy, RaySegment, Span};
use crate::accel::RunKind;
use crate::volume::{Volume, interpolate, stencil_gradient};

/// Accumulated colour (premultiplied) and opacity of a ray.
#[derive(Debug, Clone, Copy, Default)]
pub struct DvrState {
    /// `C`, premultiplied.
    pub color: Vec3,
    /// `A`.
    pub alpha: f32,
    /// Set once `A` reached the ERT threshold.
    pub terminated: bool,
}

impl Integrator for DvrState {
    const CULLS_EMPTY_BRICKS: bool = true;

    const OCCUPANCY: Occupancy = Occupancy::Visible;

    /// Composites the span's samples front to back; uniform macrocells in
    /// closed form.
    #[inline]
    fn integrate<V: Volume>(&mut self, span: Span<'_, V>) -> u64 {
        let (ctx, seg) = (span.ctx, span.seg);
        let mut taken = 0u64;
        let threshold = ctx.ert.unwrap_or(f32::INFINITY);
        for run in span.runs() {
            if self.terminated {
                break;
            }
            let n = run.end - run.start;
            match run.kind {
                RunKind::Empty => {}
                RunKind::Cell(i) if ctx.macrocells.uniform[i] => {
                    let v = ctx.macrocells.ranges[i].0;
                    taken += self.composite_uniform(ctx, v, n, threshold);
                }
                RunKind::Cell(_) | RunKind::Unknown => {
                    let (taken_here, done) = self.march(ctx, seg, run.start, run.end, threshold);
                    taken += taken_here;
                    self.terminated |= done;
                }
            }
        }
        taken
    }

    fn is_done(&self) -> bool {
        self.terminated
    }

    fn resolve<V: Volume>(&self, _ctx: &FrameContext<'_, V>) -> Vec4 {
        self.color.extend(self.alpha)
    }
}

impl DvrState {
    /// Samples `k..end` one by one. Kept apart from the skipping logic and
    /// working on local copies of the state, so the hot loop keeps everything
    /// in registers. Returns (samples taken, terminated).
    #[inline(always)]
    fn march<V: Volume>(
        &mut self,
        ctx: &FrameContext<'_, V>,
        seg: &RaySegment,
        k: u32,
        end: u32,
        threshold: f32,
    ) -> (u64, bool) {
        let volume = ctx.volume;
        let lut = ctx.lut;
        let shading = ctx.shading;
        let (origin, dir, t_in, step) = (seg.origin, seg.dir, seg.t_in, seg.step);
        let mut color = self.color;
        let mut alpha = self.alpha;
        let mut done = false;
        let start = k;
        let mut k = k;
        // Consecutive samples often fall in the same interpolation cell
        // (several per voxel at fine steps): keep its corner values, and its
        // gradient stencil once loaded, instead of re-reading the volume.
        let inv_two_spacing = 0.5 / volume.grid().spacing;
        let no_cell = UVec3::splat(u32::MAX);
        let (mut cell, mut corners) = (no_cell, [0.0f32; 8]);
        let (mut wings_cell, mut wings) = (no_cell, None);
        while k < end {
            let p = origin + dir * (t_in + k as f32 * step);
            k += 1;
            let at = volume.locate(p);
            if at.cell != cell {
                cell = at.cell;
                corners = volume.corners(cell);
            }
            let e = lut.lookup(interpolate(&corners, at.frac));
            if e.w <= 0.0 {
                continue;
            }
            let mut rgb = e.truncate();
            if let Some(ph) = &shading {
                if wings_cell != cell {
                    wings_cell = cell;
                    // A stencil of 32 equal values (inside a homogeneous
                    // region) has a zero gradient: no shading, no arithmetic.
                    wings = volume.wings(cell).map(|w| (w, is_flat(&corners, &w)));
                }
                let g = match &wings {
                    Some((_, true)) => Vec3::ZERO,
                    Some((w, false)) => stencil_gradient(&corners, w, at.frac, inv_two_spacing),
                    None => volume.gradient(p),
                };
                if let Some((diffuse, spec)) = ph.terms(g, seg.world_dir) {
                    rgb = rgb * diffuse + Vec3::splat(e.w * spec);
                }
            }
            let w = 1.0 - alpha;
            color += w * rgb;
            alpha += w * e.w;
            if alpha >= threshold {
                done = true;
                break;
            }
        }
        self.color = color;
        self.alpha = alpha;
        ((k - start) as u64, done)
    }

    /// Composites `n` samples of the constant value `v` in closed form: with
    /// transmittance `T = 1 − A` and `β = 1 − α`, after `n` samples
    /// `T' = T·βⁿ` and `C' = C + c·(T − T')/α` (c premultiplied). With ERT the
    /// run stops at the first sample whose `A` reaches the threshold, as the
    /// sample-by-sample loop would. Returns the samples composited.
    #[inline]
    fn composite_uniform<V: Volume>(
        &mut self,
        ctx: &FrameContext<'_, V>,
        v: f32,
        n: u32,
        threshold: f32,
    ) -> u64 {
        let e = ctx.lut.lookup(v);
        if e.w <= 0.0 || n == 0 {
            return n as u64;
        }
        let t0 = 1.0 - self.alpha;
        let beta = 1.0 - e.w;
        let mut count = n;
        if threshold <= 1.0 {
            // Smallest i with 1 − T·βⁱ >= threshold.
            let stop = if beta <= 0.0 {
                1
            } else {
                let i = ((1.0 - threshold) / t0).ln() / beta.ln();
                (i.ceil().max(1.0) as u32).max(1)
            };
            count = count.min(stop);
        }
        let t1 = t0 * beta.powi(count as i32);
        self.color += e.truncate() * ((t0 - t1) / e.w);
        self.alpha = 1.0 - t1;
        if self.alpha >= threshold || count < n {
            self.terminated = true;
        }
        count as u64
    }
}

/// True when every corner and wing value is the same.
#[inline(always)]
fn is_flat(c: &[f32; 8], w: &[f32; 24]) -> bool {
    let v = c[0];
    c.iter()
        .chain(w.iter())
        .fold(true, |all, &x| all & (x == v))
}
