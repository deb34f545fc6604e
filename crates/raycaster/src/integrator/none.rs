//! [`NoSamples`]: the integrator of a mode that is not rendered from the
//! volume's samples ([`RenderMode::Metaballs`](super::RenderMode::Metaballs),
//! drawn by [`crate::metaballs`]).

use glam::Vec4;

use super::{Fragment, FrameContext, Integrator, Span};
use crate::volume::Volume;

/// Takes no samples; every ray stays transparent. The volume renderers
/// never run it: [`FramePlan`](crate::render) rejects such modes before a
/// frame starts, so it only gives [`RenderMode::visit`](super::RenderMode::visit)
/// a type for every mode.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoSamples;

impl Integrator for NoSamples {
    type Scratch = ();

    const SPLITS_RAYS: bool = false;

    fn integrate<V: Volume>(&mut self, _span: Span<'_, V>) -> u64 {
        0
    }

    fn is_done(&self) -> bool {
        true
    }

    fn resolve<V: Volume>(&self, _ctx: &FrameContext<'_, V>) -> Vec4 {
        Vec4::ZERO
    }

    fn fragment<V: Volume>(&self, _ctx: &FrameContext<'_, V>) -> Fragment {
        Fragment::default()
    }
}
