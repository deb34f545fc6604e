//! The serial reference renderer: every pixel on the calling thread, in order.

use std::time::Instant;

use super::plan::{FramePlan, PlanCache, RenderOptions, render_pixel};
use super::{Cancel, Frame, FrameStats, Renderer};
use crate::camera::Camera;
use crate::error::Result;
use crate::scene::Scene;
use crate::transfer::TransferFunction;
use crate::volume::Volume;
use crate::volume::VolumeVisitor;

/// One thread, pixel by pixel: the reference the parallel renderers match.
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

/// Tile side (pixels) of the serial renderer's traversal order.
const SERIAL_TILE: u32 = 16;

struct SerialPass<'a> {
    plan: &'a FramePlan,
    cells: &'a crate::accel::MacrocellGrid,
    value_range: (f32, f32),
    tf: &'a TransferFunction,
    options: &'a RenderOptions,
    cancel: Cancel<'a>,
}

impl VolumeVisitor for SerialPass<'_> {
    type Output = Option<(Vec<u8>, FrameStats)>;

    fn visit<V: Volume>(self, volume: &V) -> Self::Output {
        let plan = self.plan;
        let ctx = plan.context(volume, self.cells, self.value_range, self.tf, self.options);
        let bg = self.options.background;
        let bg_rgb = FramePlan::background_rgb(bg);
        let mut rgb = bg_rgb.repeat(plan.width as usize * plan.height as usize);
        let mut stats = FrameStats::default();
        // Square tiles rather than scanlines: neighbouring rays then reuse
        // each other's cache lines, which matters for volumes larger than
        // the caches. The image is the same in any order.
        for t in plan.rect.tiles(SERIAL_TILE) {
            if self.cancel.is_cancelled() {
                return None;
            }
            for j in t.y0..t.y1 {
                for i in t.x0..t.x1 {
                    let px = render_pixel(&ctx, plan, self.options.mode, bg, i, j, &mut stats);
                    let o = 3 * (j as usize * plan.width as usize + i as usize);
                    rgb[o..o + 3].copy_from_slice(&px);
                }
            }
        }
        Some((rgb, stats))
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
        let start = Instant::now();
        let plan = FramePlan::new(&mut self.cache, scene, scene.grid(), camera, tf, options)?;
        let Some((rgb, mut stats)) = scene.volume().visit(SerialPass {
            plan: &plan,
            cells: scene.macrocells(),
            value_range: scene.value_range(),
            tf,
            options,
            cancel,
        }) else {
            return Ok(None);
        };
        stats.time = start.elapsed();
        Ok(Some(Frame {
            width: plan.width,
            height: plan.height,
            rgb,
            stats,
        }))
    }
}
