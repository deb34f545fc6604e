//! Criterion benchmarks of the serial reference renderer: the four
//! combinations of early ray termination (ERT) and empty-space skipping (ESS)
//! on a generated "shapes" volume (random balls and boxes with values around
//! 100, rendered with the `shapes` transfer function).
//!
//! Run with `cargo bench --bench serial`.

use criterion::{Criterion, criterion_group, criterion_main};
use glam::{UVec3, Vec3};
use raycaster::prelude::*;

mod common;

fn serial(c: &mut Criterion) {
    let scene = Scene::new(AnyVolume::from_fn(
        Grid::new(UVec3::splat(192), Vec3::ONE),
        common::shapes(192, 40, 2),
    ));
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
