//! Slices (`raycaster::volume::slice`) against direct reads of the voxels:
//! the expected values come from the `.vol` file's bytes indexed by SPEC §1
//! (`index = (x·Y + y)·Z + z`), not from the library's addressing, for
//! linear and bricked files, memory-mapped, with non-uniform spacing.

mod common;

use common::TempDir;
use glam::{UVec3, Vec3};
use raycaster::format::vol::{self, VolLayout};
use raycaster::storage::LoadMode;
use raycaster::volume::slice::{SliceAxis, slice_image, value_at};
use raycaster::volume::{AnyVolume, Grid};

const DIMS: [u32; 3] = [13, 9, 7];
const SPACING: Vec3 = Vec3::new(0.7, 1.3, 2.5);

/// A hash of the coordinate, so that a swapped axis or an off-by-one plane
/// gives different values.
fn value(x: u32, y: u32, z: u32) -> u8 {
    (x.wrapping_mul(73) ^ y.wrapping_mul(151) ^ z.wrapping_mul(31)).wrapping_add(x * y + z) as u8
}

/// The volume written as `layout` and opened memory-mapped, and the bytes
/// of the linear file it was written from (the direct reads).
fn files(dir: &TempDir, layout: VolLayout) -> (AnyVolume, Vec<u8>) {
    let grid = Grid::new(UVec3::from_array(DIMS), SPACING);
    let source = AnyVolume::from_fn(grid, |v| value(v.x, v.y, v.z));
    let linear = dir.join("linear.vol");
    vol::write(&linear, &source, VolLayout::Linear).unwrap();
    let path = dir.join("slice.vol");
    vol::write(&path, &source, layout).unwrap();
    let volume = vol::open(&path, LoadMode::Map).unwrap();
    let bytes = std::fs::read(&linear).unwrap()[vol::HEADER_LEN..].to_vec();
    (volume, bytes)
}

fn read(bytes: &[u8], v: [u32; 3]) -> f64 {
    let [x, y, z] = v.map(|c| c as usize);
    let (ny, nz) = (DIMS[1] as usize, DIMS[2] as usize);
    f64::from(bytes[(x * ny + y) * nz + z])
}

/// Every pixel of every axis's slice at `positions` (world units along the
/// normal) against the two voxel planes around it, interpolated in f64.
fn check(volume: &AnyVolume, bytes: &[u8], positions: &[f32]) {
    for axis in SliceAxis::ALL {
        let n = axis.normal();
        let (u_axis, v_axis) = axis.in_plane();
        for &p in positions {
            let s = slice_image(volume, axis, p);
            assert_eq!(
                (s.width, s.height),
                (DIMS[u_axis], DIMS[v_axis]),
                "{axis:?}"
            );
            assert_eq!(s.pixel_size, [SPACING[u_axis], SPACING[v_axis]]);
            let t = (f64::from(p) / f64::from(SPACING[n])).clamp(0.0, f64::from(DIMS[n] - 1));
            let lower = (t.floor() as u32).min(DIMS[n] - 2);
            let f = t - f64::from(lower);
            for v in 0..s.height {
                for u in 0..s.width {
                    let mut at = [0; 3];
                    at[u_axis] = u;
                    at[v_axis] = v;
                    at[n] = lower;
                    let a = read(bytes, at);
                    at[n] = lower + 1;
                    let b = read(bytes, at);
                    let want = a + (b - a) * f;
                    let got = f64::from(s.get(u, v).unwrap());
                    assert!(
                        (got - want).abs() < 1e-3,
                        "{axis:?} at {p}: pixel ({u}, {v}) is {got}, the voxels give {want}"
                    );
                }
            }
        }
    }
}

/// On voxel planes, between planes, at the faces and outside (clamped).
const POSITIONS: [f32; 7] = [0.0, 1.3, 2.5, 3.9, 7.0, 15.0, -4.0];

#[test]
fn slices_of_a_linear_file_are_its_voxels() {
    let dir = TempDir::new("slices-linear");
    let (volume, bytes) = files(&dir, VolLayout::Linear);
    check(&volume, &bytes, &POSITIONS);
}

#[test]
fn slices_of_a_bricked_file_are_its_voxels() {
    let dir = TempDir::new("slices-bricked");
    let (volume, bytes) = files(&dir, VolLayout::Bricked { side: 4 });
    assert!(matches!(
        volume.layout(),
        raycaster::volume::Layout::Bricked { .. }
    ));
    check(&volume, &bytes, &POSITIONS);
}

#[test]
fn a_slice_on_a_voxel_plane_is_exactly_that_plane() {
    let dir = TempDir::new("slices-exact");
    let (volume, bytes) = files(&dir, VolLayout::Bricked { side: 5 });
    // z = 3 lies at 3·2.5 world units.
    let s = slice_image(&volume, SliceAxis::Axial, 7.5);
    assert_eq!(s.position, 7.5);
    for y in 0..DIMS[1] {
        for x in 0..DIMS[0] {
            assert_eq!(f64::from(s.get(x, y).unwrap()), read(&bytes, [x, y, 3]));
        }
    }
}

#[test]
fn the_value_under_a_point_is_the_trilinear_interpolation() {
    let dir = TempDir::new("slices-value");
    let (volume, bytes) = files(&dir, VolLayout::Linear);
    // Voxel-space (2.5, 4, 1.2): halfway in x, on a plane in y.
    let p = Vec3::new(2.5, 4.0, 1.2) * SPACING;
    let (a0, a1) = (read(&bytes, [2, 4, 1]), read(&bytes, [3, 4, 1]));
    let (b0, b1) = (read(&bytes, [2, 4, 2]), read(&bytes, [3, 4, 2]));
    let want = (0.5 * (a0 + a1)) * 0.8 + (0.5 * (b0 + b1)) * 0.2;
    let got = f64::from(value_at(&volume, p).unwrap());
    assert!((got - want).abs() < 1e-3, "{got} vs {want}");
    assert_eq!(value_at(&volume, Vec3::new(-1.0, 0.0, 0.0)), None);
    assert_eq!(value_at(&volume, Vec3::new(0.0, 0.0, 16.0)), None);
}

/// Timing and pages touched of the three slices of a large file, mapped:
/// `SLICE_FILE=big.vol cargo test --release --test volume_slices -- --ignored --nocapture`
/// (drop the file from the page cache first to see a cold read, e.g. with
/// `python3 -c "import os; f=os.open('big.vol', os.O_RDONLY); os.posix_fadvise(f, 0, 0, os.POSIX_FADV_DONTNEED)"`).
#[test]
#[ignore = "a measurement on a file given by SLICE_FILE"]
fn slice_timing() {
    let Some(path) = std::env::var_os("SLICE_FILE") else {
        eprintln!("set SLICE_FILE to a volume file");
        return;
    };
    // Resident file-backed memory of this process (kB): grows with every
    // page of the mapping a slice faults in.
    let rss_file = || {
        std::fs::read_to_string("/proc/self/status")
            .ok()
            .and_then(|s| {
                s.lines()
                    .find(|l| l.starts_with("RssFile:"))
                    .and_then(|l| l.split_whitespace().nth(1)?.parse::<u64>().ok())
            })
            .unwrap_or(0)
    };
    let volume = raycaster::format::open(std::path::Path::new(&path), LoadMode::Map).unwrap();
    let bytes = volume.memory_bytes();
    let centre = volume.grid().bounds().center();
    eprintln!(
        "{}: {} {:?}, {} MB",
        std::path::Path::new(&path).display(),
        volume.grid().dims,
        volume.layout(),
        bytes >> 20
    );
    for axis in SliceAxis::ALL {
        for pass in ["first", "again"] {
            let before = rss_file();
            let t = std::time::Instant::now();
            let s = slice_image(&volume, axis, centre[axis.normal()]);
            let ms = t.elapsed().as_secs_f64() * 1e3;
            let touched = rss_file().saturating_sub(before);
            eprintln!(
                "{axis:?} {}x{} {pass}: {ms:.2} ms, {touched} kB of the file faulted in ({:.1} % of it)",
                s.width,
                s.height,
                100.0 * (touched * 1024) as f64 / bytes as f64
            );
        }
    }
}
