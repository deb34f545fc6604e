//! The serial reference renderer: every pixel on the calling thread.

use super::SerialRenderer;
use super::driver::{FrameJob, Schedule, render_tile};
use super::film::Film;
use crate::integrator::Integrator;
use crate::volume::Volume;

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

/// The serial renderer's schedule: tiles in order on the calling thread.
#[derive(Debug, Default)]
pub struct InOrder;

impl Schedule for InOrder {
    const NAME: &'static str = "serial";

    fn threads(&self) -> usize {
        1
    }

    fn run<V: Volume, I: Integrator>(&mut self, job: &FrameJob<'_, V>, film: &Film) -> Option<u64> {
        let mut samples = 0;
        for t in job.plan.rect.tiles(SERIAL_TILE) {
            if job.cancel.is_cancelled() {
                return None;
            }
            samples += render_tile::<V, I>(job, film, &t);
        }
        Some(samples)
    }
}
