//! Per-frame preparation shared by all renderers: options, the tabulated TF
//! and the skip grid (cached while TF, step and mode stay the same).

use std::sync::Arc;

use glam::Vec3;

use crate::accel::SkipGrid;
use crate::camera::{Camera, CameraFrame, PixelRect};
use crate::error::{Error, Result};
use crate::integrator::{FrameContext, Phong, RaySegment, RayState, RenderMode};
use crate::render::FrameStats;
use crate::scene::Scene;
use crate::transfer::{TfLut, TransferFunction};
use crate::volume::{Grid, Volume};

/// What to render and how.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderOptions {
    /// Integration mode.
    pub mode: RenderMode,
    /// Sampling step in world units; `None` = half the smallest spacing.
    pub step: Option<f32>,
    /// Early ray termination.
    pub ert: bool,
    /// Opacity at which ERT stops a ray.
    pub ert_threshold: f32,
    /// Empty-space skipping.
    pub ess: bool,
    /// Phong shading.
    pub shading: bool,
    /// Phong coefficients; `None` = defaults scaled to the data's range.
    pub phong: Option<Phong>,
    /// Iso value for [`RenderMode::Iso`].
    pub iso_value: f32,
    /// Background colour, 0..1.
    pub background: Vec3,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            mode: RenderMode::Dvr,
            step: None,
            ert: true,
            ert_threshold: 0.99,
            ess: true,
            shading: true,
            phong: None,
            iso_value: 128.0,
            background: Vec3::ZERO,
        }
    }
}

impl RenderOptions {
    /// The step actually used for `grid`.
    pub fn step_for(&self, grid: &Grid) -> f32 {
        self.step.unwrap_or(grid.spacing.min_element() * 0.5)
    }
}

/// Identity of what the cached LUT and skip grid were built for.
#[derive(Debug, Clone, PartialEq)]
struct PlanKey {
    scene: u64,
    tf: TransferFunction,
    step: u32,
    mode: RenderMode,
    iso: u32,
}

/// The TF table and skip grid of the last frame, reused while they still apply.
#[derive(Debug, Default)]
pub struct PlanCache {
    last: Option<(PlanKey, Arc<(TfLut, SkipGrid)>)>,
}

impl PlanCache {
    /// The LUT and skip grid for this scene, TF, step and mode.
    pub(crate) fn get(
        &mut self,
        scene: &Scene,
        tf: &TransferFunction,
        step: f32,
        options: &RenderOptions,
    ) -> Arc<(TfLut, SkipGrid)> {
        let key = PlanKey {
            scene: scene.id(),
            tf: tf.clone(),
            step: step.to_bits(),
            mode: options.mode,
            iso: options.iso_value.to_bits(),
        };
        if let Some((k, v)) = &self.last
            && *k == key
        {
            return v.clone();
        }
        let lut = TfLut::new(tf, step);
        let cells = scene.macrocells();
        let skip = match options.mode {
            RenderMode::Dvr => SkipGrid::build(cells, |lo, hi| lut.any_visible(lo, hi)),
            RenderMode::Iso => {
                let iso = options.iso_value;
                SkipGrid::build(cells, |lo, hi| lo <= iso && iso <= hi)
            }
            // MIP skips with the macrocell maxima directly; avg never skips.
            RenderMode::Mip | RenderMode::Avg => SkipGrid::all_occupied(cells),
        };
        let v = Arc::new((lut, skip));
        self.last = Some((key, v.clone()));
        v
    }
}

/// Validated per-frame inputs common to every renderer.
pub(crate) struct FramePlan {
    pub camera: CameraFrame,
    pub rect: PixelRect,
    pub step: f32,
    pub prepared: Arc<(TfLut, SkipGrid)>,
    pub width: u32,
    pub height: u32,
}

impl FramePlan {
    pub fn new(
        cache: &mut PlanCache,
        scene: &Scene,
        grid: &Grid,
        camera: &Camera,
        tf: &TransferFunction,
        options: &RenderOptions,
    ) -> Result<Self> {
        let frame = camera.frame().ok_or_else(|| {
            Error::InvalidArgument(format!(
                "degenerate camera (position {}, look-at {}, up {}, fov {}, size {}x{})",
                camera.position,
                camera.target,
                camera.up,
                camera.fov_y_deg,
                camera.width,
                camera.height
            ))
        })?;
        let step = options.step_for(grid);
        if !(step.is_finite() && step > 0.0) {
            return Err(Error::InvalidArgument(format!(
                "step {step} must be finite and > 0"
            )));
        }
        if !(options.ert_threshold > 0.0 && options.ert_threshold <= 1.0) {
            return Err(Error::InvalidArgument(format!(
                "ERT threshold {} must be in (0, 1]",
                options.ert_threshold
            )));
        }
        let prepared = cache.get(scene, tf, step, options);
        Ok(FramePlan {
            rect: frame.screen_rect(&grid.bounds()),
            camera: frame,
            step,
            prepared,
            width: camera.width,
            height: camera.height,
        })
    }

    /// The integrator context for this frame.
    pub fn context<'a, V: Volume>(
        &'a self,
        volume: &'a V,
        scene_cells: &'a crate::accel::MacrocellGrid,
        value_range: (f32, f32),
        tf: &'a TransferFunction,
        options: &RenderOptions,
    ) -> FrameContext<'a, V> {
        let shading = options.shading.then(|| {
            options
                .phong
                .unwrap_or_else(|| Phong::for_value_range(value_range.1 - value_range.0))
        });
        FrameContext {
            volume,
            tf,
            lut: &self.prepared.0,
            macrocells: scene_cells,
            skip: &self.prepared.1,
            ess: options.ess,
            ert: options.ert.then_some(options.ert_threshold),
            shading,
            iso_value: options.iso_value,
            avg_norm: <V::Sample as crate::sample::Sample>::TYPE.max_value(),
        }
    }

    /// Background colour as bytes.
    pub fn background_rgb(background: Vec3) -> [u8; 3] {
        let b = to_bytes(background);
        [b[0], b[1], b[2]]
    }
}

/// Integrates the ray of pixel `(i, j)` and composites it over `background`.
#[inline]
pub(crate) fn render_pixel<V: Volume>(
    ctx: &FrameContext<'_, V>,
    plan: &FramePlan,
    mode: RenderMode,
    background: Vec3,
    i: u32,
    j: u32,
    stats: &mut FrameStats,
) -> [u8; 3] {
    stats.rays += 1;
    let ray = plan.camera.ray(i, j);
    let Some(seg) = RaySegment::new(ctx.volume.grid(), &ray, plan.step) else {
        return FramePlan::background_rgb(background);
    };
    let mut state = RayState::new(mode);
    stats.samples += state.integrate(ctx, &seg, 0, seg.count);
    let c = state.resolve(ctx);
    to_bytes(c.truncate() + (1.0 - c.w) * background)
}

/// `round(255·clamp(x, 0, 1))` per channel.
#[inline]
pub(crate) fn to_bytes(c: Vec3) -> [u8; 3] {
    let q = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
    [q(c.x), q(c.y), q(c.z)]
}
