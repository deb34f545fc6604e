//! Sampling throughput: samples per second on one core with nothing
//! skipped (ESS and ERT off), on a volume larger than the caches, as a
//! pure figure for the hot loop (trilinear interpolation, TF lookup,
//! compositing; and with shading, gradient and Phong).
//!
//! Run with `cargo bench --bench sampling`; criterion reports samples/s as
//! "elem/s". `RAYCASTER_SIMD=portable cargo bench --bench sampling` measures
//! the portable copy of the loop instead of the AVX2 one.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::{UVec3, Vec3};
use raycaster::prelude::*;

fn sampling(c: &mut Criterion) {
    // 512³ u8 (128 MiB): a smooth field with fine detail, every value
    // visible under `ramp`, so every sample is looked up and composited.
    let n = 512;
    let scene = Scene::new(AnyVolume::from_fn(
        Grid::new(UVec3::splat(n), Vec3::ONE),
        |v: UVec3| {
            let p = v.as_vec3() * 0.05;
            (128.0 + 60.0 * p.x.sin() * p.y.cos() + 50.0 * (p.z * 1.7).sin()) as u8
        },
    ));
    let tf = TransferFunction::preset("ramp", SampleType::U8).unwrap();
    let mut camera = Camera::look_at(Vec3::splat(720.0), Vec3::splat(256.0), 160, 160);
    camera.fov_y_deg = 40.0;
    let mut group = c.benchmark_group("sampling 512^3, ESS and ERT off, serial");
    group.sample_size(10);
    for shading in [false, true] {
        let options = RenderOptions {
            step: Some(0.25),
            ert: false,
            ess: false,
            shading,
            ..RenderOptions::default()
        };
        let mut renderer = SerialRenderer::new();
        let samples = renderer
            .render(&scene, &camera, &tf, &options)
            .expect("the frame renders")
            .stats
            .samples;
        group.throughput(Throughput::Elements(samples));
        let name = if shading { "shaded" } else { "unshaded" };
        group.bench_function(name, |b| {
            b.iter(|| renderer.render(&scene, &camera, &tf, &options).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, sampling);
criterion_main!(benches);
