//! Maximum and minimum intensity projection (MIP, MinIP): one integrator,
//! [`ProjectionState`], generic over which extremum it keeps.
//!
//! Skipping: a macrocell's samples are interpolated from its voxels, so they
//! lie within the cell's value range; a cell whose range cannot beat the
//! running extremum is jumped over. Nothing else may be skipped (every cell
//! is occupied for a projection), except clipped space, which the skip grid
//! marks empty.

use std::marker::PhantomData;

use glam::Vec4;

use super::batch::fold_values;
use super::{Fragment, FrameContext, Integrator, Span};
use crate::accel::RunKind;
use crate::transfer::TransferFunction;
use crate::volume::Volume;

/// Which extremum a projection keeps.
pub trait Extremum: Copy + Default + std::fmt::Debug + Send + Sync + 'static {
    /// The value before the first sample: any sample beats it.
    const START: f32;
    /// The better of two values.
    fn pick(a: f32, b: f32) -> f32;
    /// Whether no value in a cell's `(min, max)` range can beat `current`.
    fn cannot_beat(range: (f32, f32), current: f32) -> bool;
}

/// The maximum (MIP).
#[derive(Debug, Clone, Copy, Default)]
pub struct Max;

impl Extremum for Max {
    const START: f32 = f32::NEG_INFINITY;
    #[inline(always)]
    fn pick(a: f32, b: f32) -> f32 {
        a.max(b)
    }
    #[inline(always)]
    fn cannot_beat(range: (f32, f32), current: f32) -> bool {
        range.1 <= current
    }
}

/// The minimum (MinIP).
#[derive(Debug, Clone, Copy, Default)]
pub struct Min;

impl Extremum for Min {
    const START: f32 = f32::INFINITY;
    #[inline(always)]
    fn pick(a: f32, b: f32) -> f32 {
        a.min(b)
    }
    #[inline(always)]
    fn cannot_beat(range: (f32, f32), current: f32) -> bool {
        range.0 >= current
    }
}

/// Running extremum of a ray.
#[derive(Debug, Clone, Copy)]
pub struct ProjectionState<E: Extremum> {
    /// The extremum of the interpolated values so far (`E::START` before
    /// the first sample).
    pub value: f32,
    kind: PhantomData<E>,
}

/// Maximum intensity projection.
pub type MipState = ProjectionState<Max>;
/// Minimum intensity projection.
pub type MinipState = ProjectionState<Min>;

impl<E: Extremum> Default for ProjectionState<E> {
    fn default() -> Self {
        ProjectionState {
            value: E::START,
            kind: PhantomData,
        }
    }
}

impl<E: Extremum> Integrator for ProjectionState<E> {
    type Scratch = ();

    /// Folds the span's samples into the extremum, skipping with ESS the
    /// macrocells whose value range cannot beat it.
    #[inline]
    fn integrate<V: Volume>(&mut self, span: Span<'_, V>) -> u64 {
        let (ctx, seg) = (span.ctx, span.seg);
        let mut taken = 0u64;
        for run in span.runs() {
            if let RunKind::Cell(i) = run.kind
                && E::cannot_beat(ctx.macrocells.ranges[i], self.value)
            {
                continue;
            }
            if run.kind == RunKind::Empty {
                continue;
            }
            self.value = fold_values(ctx.volume, seg, run.start, run.end, self.value, E::pick);
            taken += (run.end - run.start) as u64;
        }
        taken
    }

    /// `C = a·c, A = a` of the TF at the extremum (no step correction).
    fn resolve<V: Volume>(&self, ctx: &FrameContext<'_, V>) -> Vec4 {
        Self::colour(ctx.tf, self.value)
    }

    /// The extremum and whether there was one.
    fn fragment<V: Volume>(&self, _ctx: &FrameContext<'_, V>) -> Fragment {
        Fragment {
            value: self.value,
            count: (self.value != E::START) as u32,
            ..Fragment::default()
        }
    }
}

impl<E: Extremum> ProjectionState<E> {
    /// The pixel of extremum `value` (`E::START`: no sample): `C = a·c,
    /// A = a` of `tf` at it (no step correction).
    pub fn colour(tf: &TransferFunction, value: f32) -> Vec4 {
        if value == E::START {
            return Vec4::ZERO;
        }
        let e = tf.evaluate(value);
        (e.truncate() * e.w).extend(e.w)
    }
}
