//! The seed 004 metaball frames (its Table 4.1): N³ lattices of balls
//! spanning the unit cube, R = 0.2, 600×600, Wyvill's kernel, T = 0.5,
//! shaded with a headlight, the camera of `scripts/metaballs_bench.sh`
//! (the cube fills about 80 % of the view). Each frame includes building
//! the tiles' candidate lists, as every frame of a moving camera does.
//!
//! Run with `cargo bench --bench metaballs`; `scripts/metaballs_bench.sh`
//! times the same frames through `vol_app render --mode metaballs` and
//! prints them beside the seed's figures.

use criterion::{Criterion, criterion_group, criterion_main};
use glam::Vec3;
use raycaster::metaballs::{Ball, Balls, MetaballOptions, MetaballRenderer};
use raycaster::prelude::*;

/// `n³` balls of radius 0.2 on a lattice spanning the unit cube.
fn lattice(n: u32) -> Balls {
    let mut balls = Vec::with_capacity((n * n * n) as usize);
    for x in 0..n {
        for y in 0..n {
            for z in 0..n {
                balls.push(Ball {
                    center: Vec3::new(x as f32, y as f32, z as f32) / (n - 1) as f32,
                    radius: 0.2,
                    value: 0.0,
                });
            }
        }
    }
    Balls::new(balls, false).expect("balls")
}

fn metaballs(c: &mut Criterion) {
    let camera = Camera::look_at(Vec3::new(1.5, 1.25, 2.8), Vec3::splat(0.5), 600, 600);
    let options = MetaballOptions::default();
    let mut group = c.benchmark_group("metaballs 600x600, N^3 lattice");
    group.sample_size(10);
    for (kind, threads, label) in [
        (RendererKind::Tiles, 0, "tiles, all cores"),
        (RendererKind::Serial, 1, "serial"),
    ] {
        let mut renderer = MetaballRenderer::new(kind, threads).expect("renderer");
        for n in [5, 10, 20] {
            let balls = lattice(n);
            group.bench_function(format!("{} balls, {label}", n * n * n), |b| {
                b.iter(|| {
                    renderer
                        .render(&balls, &camera, None, &options)
                        .expect("frame")
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, metaballs);
criterion_main!(benches);
