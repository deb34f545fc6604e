//! The generated "shapes" volume both benchmarks render: random balls and
//! boxes with values around 100, like `vol_gen --generator shapes`.

use glam::{UVec3, Vec3};

/// Value of the `n`³ "shapes" volume at `v`: `count` random balls and boxes
/// of value 92..=108 on 0.
pub fn shapes(n: u32, count: usize, seed: u64) -> impl Fn(UVec3) -> u8 {
    let mut rng = fastrand::Rng::with_seed(seed);
    let shapes: Vec<(bool, Vec3, f32, u8)> = (0..count)
        .map(|_| {
            let size = n as f32 * 0.09 * (0.5 + rng.f32());
            let c = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * (n as f32 - 2.0 * size)
                + Vec3::splat(size);
            (rng.bool(), c, size * 0.5, rng.u8(92..=108))
        })
        .collect();
    move |v: UVec3| {
        let p = v.as_vec3();
        for &(ball, c, r, value) in &shapes {
            let inside = if ball {
                (p - c).length() <= r
            } else {
                (p - c).abs().max_element() <= r
            };
            if inside {
                return value;
            }
        }
        0
    }
}
