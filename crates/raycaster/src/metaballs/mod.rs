//! Metaballs (seed 004, SPEC §8): implicit surfaces of many particles.
//!
//! The field is `F(p) = Σ K(|p − cᵢ|/Rᵢ)` over balls of centre `cᵢ` and
//! radius `Rᵢ` with a compactly supported kernel `K` ([`Kernel`]: Wyvill's
//! or Murakami's); the surface is `F = T`. The balls come from a volume
//! (one per voxel above a threshold, every `stride`-th voxel per axis) or
//! from a points file ([`Balls`]).
//!
//! A frame, by module:
//!
//! | module | step |
//! |---|---|
//! | `balls.rs` | [`Balls`]: from a volume ([`Extraction`]) or a `.csv`/`.xyz` file, with an optional cap |
//! | `kernel.rs` | [`Kernel`]: `K` as a polynomial in `a²`, composed with a ray's quadratic `a²(t)` |
//! | `tiles.rs` | per-tile candidate lists in two passes (count, fill) from each ball's projected bounding square, sorted by the frame's entry bound `t_lo` |
//! | `ray.rs` | a tile's list tightened to the pyramid of its rays (`tighten_tile`); one ray: entry/exit events, the running polynomial of `F − T` per interval, its first root; shading |
//! | `poly.rs` | polynomials of degree ≤ 6: Taylor shift, Bernstein coefficients, first root |
//! | `shadow.rs` | a uniform grid of all balls, walked by shadow rays towards each light |
//! | `render.rs` | [`MetaballRenderer`]: the lists, the tile loop, serial or on a pool |
//!
//! The hit is the first root of `F − T` along the ray, within
//! 1e-4·R (the contract: 1e-3·R): never past it, never missing a sign
//! change; only two roots within that distance of each other (a ray
//! grazing the surface) may go unnoticed. Normals are the analytic
//! gradient of `F`; the colour is the balls' colours (the TF at their
//! values) blended by their kernel weights at the hit; shading is the iso
//! mode's Phong with its lights and, on request, shadow rays
//! (`shadow.rs`: the balls in a world-space grid walked by 3D DDA).
//!
//! Metaballs are not rendered from a volume's samples, so the volume
//! renderers ([`crate::render`]) reject [`RenderMode::Metaballs`](crate::integrator::RenderMode::Metaballs):
//! a program renders that mode with a [`MetaballRenderer`].
//!
//! ```
//! use glam::Vec3;
//! use raycaster::camera::Camera;
//! use raycaster::metaballs::{Ball, Balls, MetaballOptions, MetaballRenderer};
//! use raycaster::render::RendererKind;
//!
//! let balls = Balls::new(
//!     vec![
//!         Ball { center: Vec3::new(-0.3, 0.0, 0.0), radius: 1.0, value: 0.0 },
//!         Ball { center: Vec3::new(0.3, 0.0, 0.0), radius: 1.0, value: 0.0 },
//!     ],
//!     false,
//! )?;
//! let camera = Camera::look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, 64, 64);
//! let mut renderer = MetaballRenderer::new(RendererKind::Serial, 1)?;
//! let (frame, _) = renderer.render(&balls, &camera, None, &MetaballOptions::default())?;
//! assert!(frame.pixel(32, 32)[0] > 100);
//! assert_eq!(frame.pixel(0, 0), [0, 0, 0]);
//! # Ok::<(), raycaster::Error>(())
//! ```

mod balls;
mod kernel;
mod poly;
mod ray;
mod render;
mod shadow;
mod tiles;

pub use balls::{Ball, Balls, Extraction, POINTS_EXTENSIONS};
pub use kernel::Kernel;
pub use render::{MetaballOptions, MetaballRenderer, MetaballStats, ROOT_TOLERANCE, TILE};

/// Internals exposed for the test suites (the reference checks in
/// `tests/render_metaballs.rs`); not a stable API.
#[doc(hidden)]
pub mod internals {
    pub use super::poly::{bernstein, eval, first_root, shift};
    pub use super::ray::{RayParams, RayResult, Scratch, first_hit, gradient, shade};
    pub use super::tiles::{FrameBall, TileLists};
}
