//! Criterion benchmarks of the serial reference renderer: the four
//! combinations of early ray termination (ERT) and empty-space skipping (ESS)
//! on a generated "shapes" volume (random balls and boxes with values around
//! 100, rendered with the `shapes` transfer function as in the seed thesis).
//!
//! Run with `cargo bench --bench serial`.

use criterion::{Criterion, criterion_group, criterion_main};
use glam::{UVec3, Vec3};
use raycaster::prelude::*;

/// A `n`³ volume with `count` random balls and boxes of value 92..=108.
fn shapes_volume(n: u32, count: usize, seed: u64) -> LinearVolume<u8> {
    let mut rng = fastrand::Rng::with_seed(seed);
    let shapes: Vec<(bool, Vec3, f32, u8)> = (0..count)
        .map(|_| {
            let size = n as f32 * 0.09 * (0.5 + rng.f32());
            let c = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * (n as f32 - 2.0 * size)
                + Vec3::splat(size);
            (rng.bool(), c, size * 0.5, rng.u8(92..=108))
        })
        .collect();
    LinearVolume::from_fn(Grid::new(UVec3::splat(n), Vec3::ONE), |v| {
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
    })
}

fn serial(c: &mut Criterion) {
    let scene = Scene::new(shapes_volume(192, 40, 2));
    let tf = TransferFunction::preset("shapes", SampleType::U8).unwrap();
    let mut camera = Camera::look_at(Vec3::splat(270.0), Vec3::ZERO, 256, 256);
    camera.fov_y_deg = 60.0;
    let mut group = c.benchmark_group("serial 192^3 shapes 256x256 step 0.5");
    group.sample_size(10);
    for (name, ert, ess) in [
        ("none", false, false),
        ("ERT", true, false),
        ("ESS", false, true),
        ("ERT+ESS", true, true),
    ] {
        let options = RenderOptions {
            step: Some(0.5),
            ert,
            ess,
            ..RenderOptions::default()
        };
        let mut renderer = SerialRenderer::new();
        group.bench_function(name, |b| {
            b.iter(|| renderer.render(&scene, &camera, &tf, &options).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, serial);
criterion_main!(benches);
