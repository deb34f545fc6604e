//! The built-in default volume: what `vol_app` shows when no file is given.
//!
//! A 160³ scene in the style of the generated benchmark data (`shapes`):
//! balls and boxes whose values (around 100) fall into the three bands of the
//! `shapes` transfer function (faint red, blue, opaque green), around a hollow
//! sphere shell, so the default view shows translucency, occlusion and
//! shading. Generated in memory at start-up, quickly.

use glam::{UVec3, Vec3};
use raycaster::volume::{AnyVolume, Grid};

/// Side of the demo volume in voxels.
pub const DEMO_SIZE: u32 = 160;

/// The transfer function preset that suits the demo volume.
pub const DEMO_TF: &str = "shapes";

/// Builds the demo volume.
pub fn demo_volume() -> AnyVolume {
    let n = DEMO_SIZE as f32;
    let mut rng = fastrand::Rng::with_seed(0x5EED);
    struct Shape {
        ball: bool,
        center: Vec3,
        half: f32,
        value: u8,
    }
    let shapes: Vec<Shape> = (0..26)
        .map(|i| {
            let half = n * (0.035 + 0.05 * rng.f32());
            // Keep shapes clear of the faces so none is cut.
            let center = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * (n - 4.0 * half)
                + Vec3::splat(2.0 * half);
            // Cycle through the three bands of the shapes TF.
            let value = [88u8, 97, 104][i % 3];
            Shape {
                ball: rng.bool(),
                center,
                half,
                value,
            }
        })
        .collect();
    let mid = Vec3::splat((n - 1.0) * 0.5);
    AnyVolume::from_fn(Grid::new(UVec3::splat(DEMO_SIZE), Vec3::ONE), |v| {
        let p = v.as_vec3();
        // A thin translucent shell around everything.
        let r = (p - mid).length();
        if (r - n * 0.47).abs() < 1.5 {
            return 90;
        }
        for s in &shapes {
            let d = (p - s.center).abs();
            // The box test first: cheap, and it rejects most shapes.
            if d.max_element() <= s.half && (!s.ball || d.length() <= s.half) {
                return s.value;
            }
        }
        0
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn demo_holds_all_three_bands_of_the_shapes_tf() {
        let v = demo_volume();
        let mut seen = [false; 256];
        for &s in v.samples::<u8>().expect("u8 samples") {
            seen[s as usize] = true;
        }
        assert!(seen[0] && seen[88] && seen[97] && seen[104] && seen[90]);
        assert_eq!(v.grid().dims, UVec3::splat(DEMO_SIZE));
    }
}
