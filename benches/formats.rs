//! Criterion benchmarks of opening volumes: the real scans in
//! ../shared/data (gzip NRRD, gzip NIfTI, a DICOM series; skipped when the
//! data is not on this machine) and a 256³ i16 volume written here as raw
//! (memory-mapped: the cost of opening is the header and the map) and as
//! big-endian raw (read and byte-swapped into RAM). Each open includes the
//! macrocell grid that rendering needs (`Scene::new`). A second group opens
//! a 384³ bricked `.vol` with `Scene::open` with its macrocell cache and
//! without (`CachePolicy::Off`: the brick-order pass over the samples).
//!
//! Run with `cargo bench --bench formats`.

use std::path::{Path, PathBuf};

use criterion::{Criterion, criterion_group, criterion_main};
use glam::UVec3;
use raycaster::format::{Endian, OpenOptions, RawOptions, open_file};
use raycaster::prelude::*;
use raycaster::volume::AxisOrder;

const DATA: &str = "/work/shared/data";

fn open_scene(path: &Path, options: &OpenOptions) -> Scene {
    Scene::new(open_file(path, options).expect("open").volume)
}

fn formats(c: &mut Criterion) {
    let mut group = c.benchmark_group("open + macrocells");
    group.sample_size(10);
    for (name, rel) in [
        (
            "FLAIR 124x160x140 u8 gzip NRRD",
            "mri_flair_nrrd/FLAIR.nrrd",
        ),
        (
            "MNI152 193x229x193 i16 gzip NIfTI",
            "mri_template_int16/MNI152_2009_template.nii.gz",
        ),
        ("DICOM 64x64x40 i16, 40 files", "dicom_mri_series"),
    ] {
        let path = Path::new(DATA).join(rel);
        if !path.exists() {
            eprintln!("SKIPPED: {} not found", path.display());
            continue;
        }
        let options = OpenOptions::default();
        group.bench_function(name, |b| b.iter(|| open_scene(&path, &options)));
    }

    // A synthetic 256³ i16 volume as raw, native and big-endian.
    let dims = UVec3::splat(256);
    let grid = Grid::new(dims, glam::Vec3::ONE);
    let volume = AnyVolume::from_fn(grid, |p| ((p.x * 7 + p.y * 3 + p.z) % 4000) as i16 - 1000);
    let dir = std::env::temp_dir().join(format!("raycaster-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    for (name, endian) in [
        ("raw 256^3 i16 little-endian (mapped)", Endian::Little),
        ("raw 256^3 i16 big-endian (read + swapped)", Endian::Big),
    ] {
        let path: PathBuf = dir.join(format!("{}.raw", endian.name()));
        raycaster::format::raw::write(&path, &volume, AxisOrder::XFast, endian).expect("write");
        let options = OpenOptions {
            raw: Some(RawOptions::new(dims, SampleType::I16, endian)),
            ..OpenOptions::default()
        };
        group.bench_function(name, |b| b.iter(|| open_scene(&path, &options)));
    }
    group.finish();
    std::fs::remove_dir_all(&dir).ok();
}

fn macrocell_cache(c: &mut Criterion) {
    use raycaster::accel::cache::CachePolicy;
    use raycaster::scene::SceneOptions;
    let dir = std::env::temp_dir().join(format!("raycaster-bench-cache-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("shapes384_block16.vol");
    let grid = Grid::new(UVec3::splat(384), glam::Vec3::ONE);
    let volume = AnyVolume::from_fn(grid, |p| {
        let d = (p.as_vec3() - 192.0).length();
        if d < 150.0 { (d as u32 % 97) as u8 } else { 0 }
    });
    let layout = raycaster::format::vol::VolLayout::Bricked { side: 16 };
    raycaster::format::vol::write(&path, &volume, layout).expect("write");
    let mut group = c.benchmark_group("open a 384^3 bricked .vol");
    group.sample_size(10);
    for (name, cache) in [
        ("with its macrocell cache", CachePolicy::Auto),
        ("without (grid built)", CachePolicy::Off),
    ] {
        let options = SceneOptions {
            cache,
            cache_dir: Some(dir.join("user-cache")),
            ..SceneOptions::default()
        };
        // Writes the cache before the timed opens.
        Scene::open(&path, &OpenOptions::default(), &options).expect("open");
        group.bench_function(name, |b| {
            b.iter(|| Scene::open(&path, &OpenOptions::default(), &options).expect("open"))
        });
    }
    group.finish();
    std::fs::remove_dir_all(&dir).ok();
}

criterion_group!(benches, formats, macrocell_cache);
criterion_main!(benches);
