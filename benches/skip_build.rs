//! Building the skip grid of a transfer function (what a TF edit in the
//! viewer waits for): the macrocell grid of an 800³ volume (200³ cells of
//! side 4, 8 M cells) classified under the `shapes` TF, with its distance
//! field, on rayon pools of 1 and 2 threads (the classification and the
//! coarse level run in x-slabs on the pool; the distance field's raster
//! passes are sequential).
//!
//! Run with `cargo bench --bench skip_build`.

use criterion::{Criterion, criterion_group, criterion_main};
use glam::UVec3;
use raycaster::accel::{MacrocellGrid, SkipGrid};

fn skip_build(c: &mut Criterion) {
    // Value ranges like the benchmark volume's: mostly empty space, shapes
    // of value 95 and 100 scattered through it.
    let count = UVec3::splat(200);
    let mut rng = fastrand::Rng::with_seed(5);
    let ranges: Vec<(f32, f32)> = (0..count.element_product())
        .map(|_| match rng.u32(0..100) {
            0..=79 => (0.0, 0.0),
            80..=89 => (0.0, 100.0),
            90..=94 => (95.0, 95.0),
            _ => (100.0, 100.0),
        })
        .collect();
    let cells = MacrocellGrid::from_ranges(4, count, ranges);
    // The `shapes` TF is visible for 85 < v < 115.
    let visible = |lo: f32, hi: f32| hi > 85.0 && lo < 115.0;
    let mut group = c.benchmark_group("skip grid, 200^3 macrocells");
    group.sample_size(10);
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a thread pool");
        group.bench_function(format!("{threads} thread(s)"), |b| {
            b.iter(|| pool.install(|| SkipGrid::build(&cells, visible)))
        });
    }
    group.finish();
}

criterion_group!(benches, skip_build);
criterion_main!(benches);
