//! Small scenes and what renders them, for the renderer property tests
//! (`render_*.rs`, `vol_format.rs`): options with every acceleration off, a
//! serial render, TFs from a few points, u8 volumes from a function and a
//! camera looking straight down.

use glam::{UVec3, Vec3};
use raycaster::prelude::*;

/// Options for `mode` at step `step`: no ERT, ESS or shading, black
/// background.
pub fn opts(mode: RenderMode, step: f32) -> RenderOptions {
    RenderOptions {
        mode,
        step: Some(step),
        ert: false,
        ess: false,
        shading: false,
        background: Vec3::ZERO,
        ..RenderOptions::default()
    }
}

/// Renders with the serial renderer.
pub fn render(scene: &Scene, cam: &Camera, tf: &TransferFunction, o: &RenderOptions) -> Frame {
    SerialRenderer::new()
        .render(scene, cam, tf, o)
        .expect("render")
}

/// White at constant `opacity` over 0..=255.
pub fn white_linear_tf(opacity: f32) -> TransferFunction {
    tf_points(
        Interpolation::Linear,
        &[(0.0, [1.0; 3], opacity), (255.0, [1.0; 3], opacity)],
    )
}

/// A TF of `(value, colour, opacity)` points.
pub fn tf_points(interpolation: Interpolation, pts: &[(f32, [f32; 3], f32)]) -> TransferFunction {
    TransferFunction::new(
        interpolation,
        pts.iter()
            .map(|&(value, color, opacity)| TfPoint {
                value,
                color,
                opacity,
            })
            .collect(),
    )
    .unwrap()
}

/// A linear u8 volume of `dims` and `spacing` with the voxels `f` gives.
pub fn u8_volume(dims: [u32; 3], spacing: Vec3, f: impl Fn(UVec3) -> u8) -> AnyVolume {
    AnyVolume::from_fn(Grid::new(UVec3::from_array(dims), spacing), f)
}

/// A camera looking straight down −z at (x, y) from height `z`, with an odd
/// image so the centre pixel's ray is exactly (0, 0, −1).
pub fn down_camera(x: f32, y: f32, z: f32, projection: Projection) -> Camera {
    let mut c = Camera::look_at(Vec3::new(x, y, z), Vec3::new(x, y, 0.0), 33, 33);
    c.projection = projection;
    c.fov_y_deg = 30.0;
    c
}
