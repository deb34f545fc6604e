//! The serial reference renderer: every pixel on the calling thread.

use super::driver::{FrameJob, Schedule, render_frame, render_tile};
use super::film::Film;
use super::plan::{PlanCache, RenderOptions};
use super::{Cancel, Frame, Renderer};
use crate::camera::Camera;
use crate::error::Result;
use crate::integrator::Integrator;
use crate::scene::Scene;
use crate::transfer::TransferFunction;
use crate::volume::Volume;

/// One thread, tile by tile: the reference the parallel renderers match.
#[derive(Debug, Default)]
pub struct SerialRenderer {
    cache: PlanCache,
}

impl SerialRenderer {
    /// A new renderer.
    pub fn new() -> Self {
        Self::default()
    }
}

/// Tile side (pixels) of the serial renderer's traversal order. Square
/// tiles rather than scanlines: neighbouring rays then reuse each other's
/// cache lines, which matters for volumes larger than the caches. The image
/// is the same in any order.
const SERIAL_TILE: u32 = 16;

struct InOrder;

impl Schedule for InOrder {
    fn run<V: Volume, I: Integrator>(
        &mut self,
        job: &FrameJob<'_, V>,
        film: &mut Film,
    ) -> Option<u64> {
        let mut samples = 0;
        for t in job.plan.rect.tiles(SERIAL_TILE) {
            if job.cancel.is_cancelled() {
                return None;
            }
            let (pixels, n) = render_tile::<V, I>(job, film, &t);
            film.put_tile(&t, &pixels);
            samples += n;
        }
        Some(samples)
    }
}

impl Renderer for SerialRenderer {
    fn name(&self) -> &'static str {
        "serial"
    }

    fn threads(&self) -> usize {
        1
    }

    fn render_cancellable(
        &mut self,
        scene: &Scene,
        camera: &Camera,
        tf: &TransferFunction,
        options: &RenderOptions,
        cancel: Cancel<'_>,
    ) -> Result<Option<Frame>> {
        render_frame(
            &mut InOrder,
            &mut self.cache,
            scene,
            camera,
            tf,
            options,
            cancel,
        )
    }
}
