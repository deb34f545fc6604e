//! [`RenderOptions`]: what to render and how, beyond the camera and the TF.

use glam::Vec3;

use crate::clip::Clip;
use crate::integrator::{GradientOpacity, IsoNormals, Phong, RenderMode};
use crate::volume::Grid;

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
    /// Directional lights of [`RenderMode::Iso`] (world directions towards
    /// each light, any length but not zero); empty = one headlight.
    pub lights: Vec<Vec3>,
    /// Shadow rays towards each light in [`RenderMode::Iso`] (none for the
    /// headlight, which casts no shadow the eye can see).
    pub shadows: bool,
    /// One mirror bounce in [`RenderMode::Iso`]: the share (0..1) of a
    /// hit's colour that is what the ray reflected about the surface's
    /// normal sees (the surface lit as the primary hit is, shadows
    /// included, or the background), the rest the hit's own; 0 = off.
    pub reflection: f32,
    /// How [`RenderMode::Iso`] finds its normals.
    pub iso_normals: IsoNormals,
    /// Background colour, 0..1.
    pub background: Vec3,
    /// Crop box and clip planes (world coordinates); empty = none.
    pub clip: Clip,
    /// Gradient-magnitude opacity in [`RenderMode::Dvr`] (`None` = off).
    pub gradient_opacity: Option<GradientOpacity>,
    /// Jittered sample positions `t_in + (k + j)·s`, `j` a hash of the
    /// pixel and [`RenderOptions::seed`] (not in [`RenderMode::Iso`], which
    /// finds crossings exactly rather than sampling).
    pub jitter: bool,
    /// Seed of the jitter hash.
    pub seed: u32,
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
            lights: Vec::new(),
            shadows: false,
            reflection: 0.0,
            iso_normals: IsoNormals::Gradient,
            background: Vec3::ZERO,
            clip: Clip::default(),
            gradient_opacity: None,
            jitter: false,
            seed: 0,
        }
    }
}

impl RenderOptions {
    /// The step actually used for `grid`.
    pub fn step_for(&self, grid: &Grid) -> f32 {
        self.step.unwrap_or(grid.spacing.min_element() * 0.5)
    }
}
