//! The macrocell cache of `Scene::open`: a grid read from the cache is the
//! grid built from the samples, a changed file or another macrocell side
//! gets a fresh grid, a damaged cache is a warning, a directory that cannot
//! be written sends the cache to the fallback directory, and frames
//! rendered with the cache are the frames rendered without it.

mod common;

use std::path::{Path, PathBuf};

use common::TempDir;
use glam::{UVec3, Vec3};
use raycaster::accel::MacrocellGrid;
use raycaster::accel::cache::{self, CachePolicy};
use raycaster::format::vol::{self, VolLayout};
use raycaster::format::{OpenOptions, RawOptions};
use raycaster::prelude::*;
use raycaster::scene::{OpenedScene, SceneOptions};

/// Balls of 100 and 200 in empty space: cells of every kind (empty,
/// uniform inside a ball, mixed on its surface).
fn balls(v: UVec3) -> u8 {
    let p = v.as_vec3();
    if (p - Vec3::new(20.0, 15.0, 22.0)).length() < 11.0 {
        200
    } else if (p - Vec3::new(50.0, 30.0, 30.0)).length() < 14.0 {
        100
    } else {
        (v.x * 7 + v.y * 3 + v.z) as u8 % 2
    }
}

const DIMS: UVec3 = UVec3::new(70, 45, 53);

fn write_vol(path: &Path, side: u8, f: impl FnMut(UVec3) -> u8) {
    let volume = AnyVolume::from_fn(Grid::new(DIMS, Vec3::new(1.0, 1.5, 0.5)), f);
    let layout = if side == 0 {
        VolLayout::Linear
    } else {
        VolLayout::Bricked { side }
    };
    vol::write(path, &volume, layout).expect("write .vol");
}

/// Options with the fallback cache directory `fallback`.
fn options(fallback: &Path) -> SceneOptions {
    SceneOptions {
        cache_dir: Some(fallback.to_path_buf()),
        ..SceneOptions::default()
    }
}

fn open(path: &Path, options: &SceneOptions) -> OpenedScene {
    Scene::open(path, &OpenOptions::default(), options)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The scene of the file built from its samples without a cache; its grid
/// checked against the row-by-row pass of `MacrocellGrid::build`.
fn fresh(path: &Path, cell: u32) -> Scene {
    struct Rows(u32);
    impl VolumeVisitor for Rows {
        type Output = MacrocellGrid;
        fn visit<V: Volume>(self, v: &V) -> MacrocellGrid {
            MacrocellGrid::build(v, self.0)
        }
    }
    let volume = raycaster::format::open(path, LoadMode::Map).expect("open");
    let rows = volume.visit(Rows(cell));
    let scene = Scene::with_macrocell(volume, cell);
    assert!(
        scene.macrocells().ranges == rows.ranges,
        "{}",
        path.display()
    );
    assert!(
        scene.macrocells().uniform == rows.uniform,
        "{}",
        path.display()
    );
    scene
}

fn assert_same_grid(what: &str, got: &Scene, want: &Scene) {
    let (g, w) = (got.macrocells(), want.macrocells());
    assert_eq!((g.cell, g.count), (w.cell, w.count), "{what}");
    assert!(g.ranges == w.ranges, "{what}: ranges differ");
    assert!(g.uniform == w.uniform, "{what}: uniform flags differ");
    assert_eq!(got.value_range(), want.value_range(), "{what}");
}

fn render(scene: &Scene) -> Vec<u8> {
    let mut camera = Camera::framing(&scene.grid().bounds(), 48, 40, 45.0);
    camera.position = Vec3::new(120.0, 90.0, -60.0);
    let tf = TransferFunction::preset("shapes", SampleType::U8).expect("preset");
    let frame = SerialRenderer::new()
        .render(scene, &camera, &tf, &RenderOptions::default())
        .expect("render");
    frame.rgb
}

#[test]
fn the_cache_round_trips_and_equals_a_fresh_build() {
    let dir = TempDir::new("cache-round-trip");
    let fallback = dir.join("user-cache");
    for side in [0u8, 16, 7] {
        for cell in [4u32, 8, 3] {
            let path = dir.join(&format!("balls-{side}.vol"));
            write_vol(&path, side, balls);
            let opts = SceneOptions {
                macrocell: Some(cell),
                ..options(&fallback)
            };
            let what = format!("B = {side}, cell {cell}");
            let first = open(&path, &opts);
            let sidecar = cache::sidecar_path(&path, cell);
            assert_eq!(first.cache.loaded, None, "{what}");
            assert_eq!(first.cache.saved.as_deref(), Some(&*sidecar), "{what}");
            assert!(first.cache.warnings.is_empty(), "{what}");
            let second = open(&path, &opts);
            assert_eq!(second.cache.loaded.as_deref(), Some(&*sidecar), "{what}");
            assert_eq!(second.cache.saved, None, "{what}");
            let want = fresh(&path, cell);
            assert_same_grid(&format!("{what}, built"), &first.scene, &want);
            assert_same_grid(&format!("{what}, cached"), &second.scene, &want);
            assert_eq!(render(&second.scene), render(&want), "{what}");
        }
    }
    // One cache per macrocell side, none in the fallback directory.
    let caches = std::fs::read_dir(dir.path())
        .unwrap()
        .filter(|e| e.as_ref().unwrap().path().extension() == Some("rcidx".as_ref()))
        .count();
    assert_eq!(caches, 9);
    assert!(!fallback.exists());
}

#[test]
fn a_changed_file_gets_a_fresh_grid() {
    let dir = TempDir::new("cache-stale");
    let fallback = dir.join("user-cache");
    let opts = options(&fallback);
    let path = dir.join("v.vol");
    write_vol(&path, 16, balls);
    let cell = open(&path, &opts).scene.macrocells().cell;
    assert!(open(&path, &opts).cache.loaded.is_some());
    let mtime = std::fs::metadata(&path).unwrap().modified().unwrap();
    let set_mtime = |t: std::time::SystemTime| {
        let f = std::fs::File::options().write(true).open(&path).unwrap();
        f.set_modified(t).unwrap();
    };
    let check = |what: &str, f: &dyn Fn(UVec3) -> u8| {
        let got = open(&path, &opts);
        assert!(
            got.cache.loaded.is_none(),
            "{what}: the stale cache was used"
        );
        assert!(got.cache.saved.is_some(), "{what}: not rewritten");
        assert!(
            got.cache.warnings.is_empty(),
            "{what}: {:?}",
            got.cache.warnings
        );
        assert_same_grid(what, &got.scene, &fresh(&path, cell));
        let again = open(&path, &opts);
        assert!(
            again.cache.loaded.is_some(),
            "{what}: rewritten cache unused"
        );
        // The grid is that of the new data, not of the old.
        let want = Scene::with_macrocell(AnyVolume::from_fn(Grid::new(DIMS, Vec3::ONE), f), cell);
        assert!(
            again.scene.macrocells().ranges == want.macrocells().ranges,
            "{what}"
        );
    };

    // New modification time, same bytes.
    set_mtime(mtime + std::time::Duration::from_secs(10));
    check("touched", &balls);

    // Other samples, same length, and the old modification time put back:
    // the sampled blocks catch it. (A ball of 255 fills the volume's
    // middle, which every sampled block lies in.)
    let mtime = std::fs::metadata(&path).unwrap().modified().unwrap();
    let other = |v: UVec3| {
        if v.x > 5 && v.x < 65 { 255 } else { balls(v) }
    };
    write_vol(&path, 16, other);
    set_mtime(mtime);
    check("same length and time, other samples", &other);

    // A header byte (the spacing), with the old modification time.
    let mtime = std::fs::metadata(&path).unwrap().modified().unwrap();
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[12..16].copy_from_slice(&2.0f32.to_le_bytes());
    std::fs::write(&path, &bytes).unwrap();
    set_mtime(mtime);
    check("header changed", &other);

    // Other dimensions (another length).
    let volume = AnyVolume::from_fn(Grid::new(DIMS - UVec3::X, Vec3::ONE), balls);
    vol::write(&path, &volume, VolLayout::Bricked { side: 16 }).unwrap();
    let got = open(&path, &opts);
    assert!(got.cache.loaded.is_none() && got.cache.saved.is_some());
    assert_same_grid("resized", &got.scene, &fresh(&path, cell));
}

#[test]
fn a_damaged_cache_is_a_warning_and_is_rebuilt() {
    let dir = TempDir::new("cache-damaged");
    let opts = options(&dir.join("user-cache"));
    let path = dir.join("v.vol");
    write_vol(&path, 16, balls);
    let built = open(&path, &opts);
    let sidecar = built.cache.saved.clone().unwrap();
    let good = std::fs::read(&sidecar).unwrap();
    let want = fresh(&path, built.scene.macrocells().cell);
    let damages: [(&str, Vec<u8>); 4] = [
        ("truncated", good[..good.len() / 2].to_vec()),
        ("empty", Vec::new()),
        ("flipped", {
            let mut b = good.clone();
            let mid = b.len() / 2;
            b[mid] ^= 0xff;
            b
        }),
        ("foreign", b"not a cache at all, just some text".to_vec()),
    ];
    for (what, bytes) in damages {
        std::fs::write(&sidecar, &bytes).unwrap();
        let got = open(&path, &opts);
        assert!(got.cache.loaded.is_none(), "{what}");
        assert_eq!(
            got.cache.warnings.len(),
            1,
            "{what}: {:?}",
            got.cache.warnings
        );
        let w = &got.cache.warnings[0];
        assert!(
            w.contains("damaged") && w.contains("v.vol.m"),
            "{what}: {w}"
        );
        assert_eq!(got.cache.saved.as_deref(), Some(&*sidecar), "{what}");
        assert_same_grid(what, &got.scene, &want);
        assert_eq!(
            std::fs::read(&sidecar).unwrap(),
            good,
            "{what}: not rewritten"
        );
    }
}

/// Makes `dir` read-only by its permissions, which the cache respects
/// even where the process may write anyway (root).
fn make_unwritable(dir: &Path) {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o555)).unwrap();
}

fn make_writable(dir: &Path) {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o755)).unwrap();
}

#[test]
fn an_unwritable_directory_sends_the_cache_to_the_fallback_directory() {
    let dir = TempDir::new("cache-read-only");
    let data = dir.join("data");
    std::fs::create_dir_all(&data).unwrap();
    let path = data.join("v.vol");
    write_vol(&path, 16, balls);
    let fallback = dir.join("user-cache");
    let opts = options(&fallback);
    let cell = raycaster::scene::default_macrocell(DIMS);
    make_unwritable(&data);
    let first = open(&path, &opts);
    let second = open(&path, &opts);
    make_writable(&data);
    let expected: PathBuf = cache::cache_path_in(&fallback, &path, cell);
    assert!(
        first.cache.warnings.is_empty(),
        "{:?}",
        first.cache.warnings
    );
    assert_eq!(first.cache.saved.as_deref(), Some(&*expected));
    assert_eq!(second.cache.loaded.as_deref(), Some(&*expected));
    assert_same_grid("fallback", &second.scene, &fresh(&path, cell));
    assert!(!cache::sidecar_path(&path, cell).exists());

    // Nowhere to write: a warning naming the volume; the scene is whole.
    let nowhere = dir.file("a-file", b"x").join("sub");
    make_unwritable(&data);
    let got = open(&path, &options(&nowhere));
    make_writable(&data);
    assert!(got.cache.saved.is_none() && got.cache.loaded.is_none());
    assert_eq!(got.cache.warnings.len(), 1, "{:?}", got.cache.warnings);
    assert!(got.cache.warnings[0].contains("could not save"));
    assert!(got.cache.warnings[0].contains("v.vol"));
    assert_same_grid("unsaved", &got.scene, &fresh(&path, cell));
}

#[test]
fn off_neither_reads_nor_writes_and_raw_readings_are_told_apart() {
    let dir = TempDir::new("cache-off");
    let fallback = dir.join("user-cache");
    let path = dir.join("v.vol");
    write_vol(&path, 0, balls);
    let off = SceneOptions {
        cache: CachePolicy::Off,
        ..options(&fallback)
    };
    let got = open(&path, &off);
    assert_eq!(got.cache, Default::default());
    assert!(std::fs::read_dir(dir.path()).unwrap().count() == 1);

    // The same bytes read as raw with two descriptions are two volumes.
    let bin = dir.file("v.bin", &std::fs::read(&path).unwrap()[26..]);
    let read = |dims: UVec3| {
        let open_options = OpenOptions {
            raw: Some(RawOptions {
                order: AxisOrder::ZFast,
                ..RawOptions::new(dims, SampleType::U8, raycaster::format::Endian::Little)
            }),
            ..OpenOptions::default()
        };
        let opts = SceneOptions {
            macrocell: Some(4),
            ..options(&fallback)
        };
        Scene::open(&bin, &open_options, &opts).unwrap()
    };
    let a = read(DIMS);
    let b = read(UVec3::new(DIMS.z, DIMS.y, DIMS.x));
    assert!(a.cache.saved.is_some() && b.cache.saved.is_some());
    assert!(
        b.cache.loaded.is_none(),
        "a cache of another reading was used"
    );
    assert!(
        read(UVec3::new(DIMS.z, DIMS.y, DIMS.x))
            .cache
            .loaded
            .is_some()
    );
    assert_eq!(b.scene.grid().dims, UVec3::new(DIMS.z, DIMS.y, DIMS.x));
}

/// A cache whose uniform flags come from the ranges alone (what a
/// distributed run's first pass writes: its parts cannot read the voxel
/// shells across their borders) is completed by the next open, which
/// finds the cells the shells make uniform and writes the cache again; the
/// open after that reads it as it is.
#[test]
fn a_cache_of_ranges_alone_is_completed_and_kept() {
    let dir = TempDir::new("cache-shells");
    let fallback = dir.join("user-cache");
    for side in [0u8, 16] {
        let path = dir.join(&format!("balls-{side}.vol"));
        write_vol(&path, side, balls);
        let opts = SceneOptions {
            macrocell: Some(4),
            ..options(&fallback)
        };
        let first = open(&path, &opts);
        let want = fresh(&path, 4);
        let built = first.scene.macrocells();
        assert!(built.shells_found);
        let ranges_only = MacrocellGrid::from_ranges(built.cell, built.count, built.ranges.clone());
        let more = (built.uniform.iter().filter(|&&u| u).count())
            - (ranges_only.uniform.iter().filter(|&&u| u).count());
        assert!(more > 10, "B = {side}: the shells found {more} cells");
        let key = cache::CacheKey::of(&path, first.info.format.name()).expect("key");
        let shape = cache::GridShape {
            sample_type: SampleType::U8,
            dims: DIMS,
            cell: 4,
        };
        let sidecar = cache::sidecar_path(&path, 4);
        cache::store(&sidecar, &key, shape, &ranges_only).expect("store");
        let second = open(&path, &opts);
        assert_eq!(
            second.cache.loaded.as_deref(),
            Some(&*sidecar),
            "B = {side}"
        );
        assert_eq!(second.cache.saved.as_deref(), Some(&*sidecar), "B = {side}");
        assert_same_grid(&format!("B = {side}, completed"), &second.scene, &want);
        let third = open(&path, &opts);
        assert_eq!(third.cache.loaded.as_deref(), Some(&*sidecar), "B = {side}");
        assert_eq!(third.cache.saved, None, "B = {side}");
        assert!(third.scene.macrocells().shells_found);
        assert_same_grid(&format!("B = {side}, read again"), &third.scene, &want);
    }
}
