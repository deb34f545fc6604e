//! Integrators: what happens along one ray (SPEC §5).
//!
//! Every mode walks the same sample positions `t_k = t_in + k·s`, computed
//! from `k` (never by accumulating `t += s`), so any renderer that splits a
//! ray into pieces — per brick, per tile — takes exactly the same samples.
//! A [`RaySegment`] is a range of those indices; the integrators carry their
//! state in a small struct so that a ray can be integrated piece by piece.

mod avg;
mod dvr;
mod iso;
mod mip;
mod shading;

pub use avg::AvgState;
pub use dvr::DvrState;
pub use iso::IsoState;
pub use mip::MipState;
pub use shading::Phong;

use glam::{Vec3, Vec4};

use crate::accel::{MacrocellGrid, SkipGrid};
use crate::geometry::Ray;
use crate::transfer::{TfLut, TransferFunction};
use crate::volume::{Grid, Volume};

/// The rendering mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum RenderMode {
    /// Direct volume rendering: front-to-back compositing.
    #[default]
    #[cfg_attr(
        feature = "clap",
        value(help = "Direct volume rendering (front-to-back compositing)")
    )]
    Dvr,
    /// Maximum intensity projection.
    #[cfg_attr(feature = "clap", value(help = "Maximum intensity projection"))]
    Mip,
    /// Mean value along the ray ("x-ray").
    #[cfg_attr(feature = "clap", value(help = "Mean value along each ray (x-ray)"))]
    Avg,
    /// First crossing of an iso value, shaded.
    #[cfg_attr(feature = "clap", value(help = "Isosurface at --iso"))]
    Iso,
}

impl RenderMode {
    /// The name used on command lines.
    pub fn name(self) -> &'static str {
        match self {
            RenderMode::Dvr => "dvr",
            RenderMode::Mip => "mip",
            RenderMode::Avg => "avg",
            RenderMode::Iso => "iso",
        }
    }
}

/// One ray prepared for marching through a volume: in voxel space, with its
/// sample index range.
#[derive(Debug, Clone, Copy)]
pub struct RaySegment {
    /// Ray origin in voxel space.
    pub origin: Vec3,
    /// Ray direction in voxel space per world unit of `t`.
    pub dir: Vec3,
    /// `1 / dir`, for box exits.
    pub inv_dir: Vec3,
    /// World direction (unit), for shading.
    pub world_dir: Vec3,
    /// Entry parameter into the volume's box.
    pub t_in: f32,
    /// Sampling step (world units).
    pub step: f32,
    /// `1 / step`.
    pub inv_step: f32,
    /// Number of samples on the whole ray: indices `0..count`.
    pub count: u32,
}

impl RaySegment {
    /// Clips a world-space ray (unit direction) against the grid's box;
    /// `None` when it misses.
    #[inline]
    pub fn new(grid: &Grid, ray: &Ray, step: f32) -> Option<Self> {
        let (t_in, t_out) = grid.bounds().intersect(ray)?;
        // Largest k with t_in + k·s <= t_out, computed as the renderers will.
        let mut last = ((t_out - t_in) / step).floor().max(0.0) as u32;
        while last > 0 && t_in + last as f32 * step > t_out {
            last -= 1;
        }
        while t_in + (last + 1) as f32 * step <= t_out {
            last += 1;
        }
        let dir = ray.dir / grid.spacing;
        Some(RaySegment {
            origin: grid.world_to_voxel(ray.origin),
            dir,
            inv_dir: dir.recip(),
            world_dir: ray.dir,
            t_in,
            step,
            inv_step: 1.0 / step,
            count: last + 1,
        })
    }

    /// World parameter of sample `k`.
    #[inline(always)]
    pub fn t(&self, k: u32) -> f32 {
        self.t_in + k as f32 * self.step
    }

    /// Voxel-space position of sample `k`.
    #[inline(always)]
    pub fn pos(&self, k: u32) -> Vec3 {
        self.origin + self.dir * self.t(k)
    }

    /// A sample index at or just before the first sample at or after
    /// parameter `t` (saturating). Callers use it as the end of a run of
    /// samples inside a box whose exit is `t`, or as where to resume after
    /// skipping such a box: it may err by one sample early (harmless: that
    /// sample is taken) but never late (which would skip a sample outside an
    /// empty box).
    #[inline(always)]
    pub fn first_index_at_or_after(&self, t: f32) -> u32 {
        let x = (t - self.t_in) * self.inv_step - 1e-3;
        // ceil without a libm call; `as` saturates negatives and NaN to 0.
        let k = x as u32;
        k + ((k as f32) < x) as u32
    }
}

/// Everything an integrator needs for one frame: the volume, the tabulated
/// TF, the skip structures and the options. Cheap to copy (references).
pub struct FrameContext<'a, V: Volume> {
    /// The volume.
    pub volume: &'a V,
    /// The transfer function as given (evaluated exactly for MIP and iso).
    pub tf: &'a TransferFunction,
    /// The TF tabulated for this frame's step.
    pub lut: &'a TfLut,
    /// Value ranges per macrocell (MIP skipping).
    pub macrocells: &'a MacrocellGrid,
    /// Occupancy for this TF / iso value (DVR and iso skipping).
    pub skip: &'a SkipGrid,
    /// Empty-space skipping on.
    pub ess: bool,
    /// Early ray termination threshold (`None` = off).
    pub ert: Option<f32>,
    /// Phong parameters (`None` = unshaded).
    pub shading: Option<Phong>,
    /// Iso value for [`RenderMode::Iso`].
    pub iso_value: f32,
    /// Divisor of [`RenderMode::Avg`].
    pub avg_norm: f32,
}

/// The state of one ray in any mode, so renderers can hold a buffer of them.
#[derive(Debug, Clone, Copy)]
pub enum RayState {
    /// DVR accumulation.
    Dvr(DvrState),
    /// MIP running maximum.
    Mip(MipState),
    /// Running sum for the mean.
    Avg(AvgState),
    /// Iso search.
    Iso(IsoState),
}

impl RayState {
    /// The initial state for `mode`.
    pub fn new(mode: RenderMode) -> Self {
        match mode {
            RenderMode::Dvr => RayState::Dvr(DvrState::default()),
            RenderMode::Mip => RayState::Mip(MipState::default()),
            RenderMode::Avg => RayState::Avg(AvgState::default()),
            RenderMode::Iso => RayState::Iso(IsoState::default()),
        }
    }

    /// True when nothing more can change this ray (ERT or an iso hit).
    #[inline]
    pub fn is_done(&self) -> bool {
        match self {
            RayState::Dvr(s) => s.terminated,
            RayState::Iso(s) => s.hit.is_some(),
            _ => false,
        }
    }

    /// Integrates samples `k0..k1` of `seg` into the state; returns the
    /// number of samples taken.
    #[inline]
    pub fn integrate<V: Volume>(
        &mut self,
        ctx: &FrameContext<'_, V>,
        seg: &RaySegment,
        k0: u32,
        k1: u32,
    ) -> u64 {
        match self {
            RayState::Dvr(s) => s.integrate(ctx, seg, k0, k1),
            RayState::Mip(s) => s.integrate(ctx, seg, k0, k1),
            RayState::Avg(s) => s.integrate(ctx, seg, k0, k1),
            RayState::Iso(s) => s.integrate(ctx, seg, k0, k1),
        }
    }

    /// Premultiplied colour and opacity of the finished ray.
    pub fn resolve<V: Volume>(&self, ctx: &FrameContext<'_, V>) -> Vec4 {
        match self {
            RayState::Dvr(s) => s.color.extend(s.alpha),
            RayState::Mip(s) => s.resolve(ctx),
            RayState::Avg(s) => s.resolve(ctx),
            RayState::Iso(s) => s.resolve(ctx),
        }
    }
}
