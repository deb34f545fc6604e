//! Criterion benchmarks of every renderer kind — serial, screen-parallel
//! tiles and object-parallel bricks, the parallel ones with 1 and 2 threads —
//! on a generated "shapes" volume (random balls and boxes with values around
//! 100, the `shapes` transfer function, ERT and ESS on), linear and bricked.
//!
//! Run with `cargo bench --bench parallel`. The full-size benchmark frame
//! (800³, 700×700) is measured with `vol_app render ... --repeat N --stats`
//! instead (see the README).

use criterion::{Criterion, criterion_group, criterion_main};
use glam::{UVec3, Vec3};
use raycaster::prelude::*;

mod common;
use common::shapes;

fn parallel(c: &mut Criterion) {
    let n = 192;
    let grid = Grid::new(UVec3::splat(n), Vec3::ONE);
    let volumes: [(&str, AnyVolume); 2] = [
        ("linear", AnyVolume::from_fn(grid, shapes(n, 40, 2))),
        (
            "block16",
            AnyVolume::bricked_from_fn(grid, 16, shapes(n, 40, 2)).expect("bricked volume"),
        ),
    ];
    let tf = TransferFunction::preset("shapes", SampleType::U8).expect("preset");
    let mut camera = Camera::look_at(Vec3::splat(270.0), Vec3::ZERO, 256, 256);
    camera.fov_y_deg = 60.0;
    let options = RenderOptions {
        step: Some(0.5),
        ..RenderOptions::default()
    };
    for (name, volume) in volumes {
        let scene = Scene::new(volume);
        let mut group = c.benchmark_group(format!("{name} 192^3 shapes 256x256 step 0.5 ERT+ESS"));
        group.sample_size(10);
        let mut renderers: Vec<(String, AnyRenderer)> = vec![(
            "serial".into(),
            RendererKind::Serial.renderer(1).expect("serial"),
        )];
        for kind in [RendererKind::Tiles, RendererKind::Object] {
            for threads in [1, 2] {
                renderers.push((
                    format!("{} {threads}t", kind.name()),
                    kind.renderer(threads).expect("renderer"),
                ));
            }
        }
        for (label, mut renderer) in renderers {
            group.bench_function(label, |b| {
                b.iter(|| {
                    renderer
                        .render(&scene, &camera, &tf, &options)
                        .expect("render")
                })
            });
        }
        group.finish();
    }
}

criterion_group!(benches, parallel);
criterion_main!(benches);
