//! Shared helpers of the end-to-end tests: the f64 reference renderer, test
//! volumes built identically for the library and the reference, conversions,
//! image comparison and temporary files; in submodules, the small scenes of
//! the renderer property tests (`scenes`), single rays (`rays`), hand-made
//! file bytes (`file_bytes`) and the volumes of the file format tests
//! (`volumes`).
//!
//! Every test binary compiles all of it and uses a part: hence the
//! `dead_code` allowance.

#![allow(dead_code)]

pub mod file_bytes;
pub mod rays;
pub mod reference;
pub mod scenes;
pub mod volumes;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use glam::{UVec3, Vec3};
use raycaster::prelude::*;

use reference::{RefCamera, RefProjection, RefTf, RefVolume, V3};

/// A library scene and the reference volume holding the same samples.
pub struct Pair {
    pub scene: Scene,
    pub reference: RefVolume,
}

/// How to lay a test volume out in the library.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TestLayout {
    Linear,
    Bricked(u32),
}

/// Builds the same u8 data as a library volume (linear or bricked) and as a
/// reference volume.
pub fn make_pair(
    dims: [u32; 3],
    spacing: V3,
    layout: TestLayout,
    f: impl Fn(u32, u32, u32) -> u8,
) -> Pair {
    make_pair_typed(dims, spacing, [0.0; 3], layout, f)
}

/// As [`make_pair`] for any sample type and a grid origin.
pub fn make_pair_typed<S>(
    dims: [u32; 3],
    spacing: V3,
    origin: V3,
    layout: TestLayout,
    f: impl Fn(u32, u32, u32) -> S,
) -> Pair
where
    S: Sample + Into<f64>,
{
    let mut grid = Grid::new(UVec3::from_array(dims), v3f(spacing));
    grid.origin = v3f(origin);
    let any: AnyVolume = match layout {
        TestLayout::Linear => AnyVolume::from_fn(grid, |v| f(v.x, v.y, v.z)),
        TestLayout::Bricked(side) => {
            AnyVolume::bricked_from_fn(grid, side, |v| f(v.x, v.y, v.z)).expect("bricked volume")
        }
    };
    let mut reference = RefVolume::from_fn(
        [dims[0] as usize, dims[1] as usize, dims[2] as usize],
        spacing,
        S::TYPE.max_value() as f64,
        |x, y, z| f(x as u32, y as u32, z as u32).into(),
    );
    reference.origin = origin;
    Pair {
        scene: Scene::new(any),
        reference,
    }
}

/// Smooth-ish test data on a grid of `dims`, values spanning 0..=255: three
/// balls with a parabolic falloff (peaks 250, 190, 140), a hard-edged cube of
/// 110 and a faint gradient of 0..12 along y. Positions are normalised to the
/// grid, so the same objects appear at any resolution.
pub fn phantom(dims: [u32; 3]) -> impl Fn(u32, u32, u32) -> u8 + Copy {
    move |x, y, z| {
        let n = |c: u32, d: u32| c as f64 / (d.max(2) - 1) as f64;
        let u = [n(x, dims[0]), n(y, dims[1]), n(z, dims[2])];
        let ball = |c: V3, r: f64, peak: f64| {
            let d2 =
                ((u[0] - c[0]).powi(2) + (u[1] - c[1]).powi(2) + (u[2] - c[2]).powi(2)) / (r * r);
            if d2 >= 1.0 { 0.0 } else { peak * (1.0 - d2) }
        };
        let inside = |lo: f64, hi: f64, v: f64| (lo..=hi).contains(&v);
        let cube = if inside(0.1, 0.32, u[0]) && inside(0.6, 0.86, u[1]) && inside(0.12, 0.45, u[2])
        {
            110.0
        } else {
            0.0
        };
        let v = ball([0.36, 0.42, 0.5], 0.36, 250.0)
            .max(ball([0.72, 0.64, 0.36], 0.26, 190.0))
            .max(ball([0.64, 0.26, 0.76], 0.2, 140.0))
            .max(cube)
            .max(12.0 * u[1]);
        v.round().clamp(0.0, 255.0) as u8
    }
}

/// A grid of `dims` and `spacing`, and the [`phantom`] on it by voxel.
pub fn phantom_on_grid(dims: [u32; 3], spacing: Vec3) -> (Grid, impl Fn(UVec3) -> u8 + Copy) {
    let f = phantom(dims);
    (
        Grid::new(UVec3::from_array(dims), spacing),
        move |v: UVec3| f(v.x, v.y, v.z),
    )
}

pub fn v3f(v: V3) -> Vec3 {
    Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32)
}

/// A background colour as the bytes both renderers write.
pub fn to_rgb8(c: V3) -> [u8; 3] {
    c.map(|x| (255.0 * x.clamp(0.0, 1.0)).round() as u8)
}

/// The library camera with the same parameters as a reference camera.
pub fn lib_camera(c: &RefCamera) -> Camera {
    Camera {
        position: v3f(c.position),
        target: v3f(c.target),
        up: v3f(c.up),
        fov_y_deg: c.fov_deg as f32,
        width: c.width,
        height: c.height,
        projection: match c.projection {
            RefProjection::Perspective => Projection::Perspective,
            RefProjection::Orthographic => Projection::Orthographic,
        },
    }
}

/// The library TF with the same points as a reference TF.
pub fn lib_tf(tf: &RefTf) -> TransferFunction {
    let points = tf
        .points
        .iter()
        .map(|p| TfPoint {
            value: p.value as f32,
            color: [p.color[0] as f32, p.color[1] as f32, p.color[2] as f32],
            opacity: p.opacity as f32,
        })
        .collect();
    let interpolation = if tf.step {
        Interpolation::Step
    } else {
        Interpolation::Linear
    };
    TransferFunction::new(interpolation, points).expect("valid TF")
}

/// How two RGB8 images differ.
#[derive(Debug, Clone, Copy)]
pub struct ImageDiff {
    /// Largest absolute channel difference.
    pub max: u8,
    /// Peak signal-to-noise ratio over all channels (∞ when identical).
    pub psnr: f64,
    /// Pixels with some channel differing by more than the threshold given.
    pub over: usize,
    /// Pixels in the image.
    pub pixels: usize,
}

impl std::fmt::Display for ImageDiff {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "max diff {:3}, PSNR {:6.1} dB, {:3}/{} px over threshold",
            self.max, self.psnr, self.over, self.pixels
        )
    }
}

pub fn compare_images(a: &[u8], b: &[u8], threshold: u8) -> ImageDiff {
    assert_eq!(a.len(), b.len(), "image sizes differ");
    let mut max = 0u8;
    let mut se = 0.0f64;
    let mut over = 0;
    for (pa, pb) in a.chunks_exact(3).zip(b.chunks_exact(3)) {
        let mut worst = 0u8;
        for (&x, &y) in pa.iter().zip(pb) {
            let d = x.abs_diff(y);
            worst = worst.max(d);
            se += (d as f64).powi(2);
        }
        max = max.max(worst);
        if worst > threshold {
            over += 1;
        }
    }
    let mse = se / a.len() as f64;
    let psnr = if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    };
    ImageDiff {
        max,
        psnr,
        over,
        pixels: a.len() / 3,
    }
}

/// A unique path in the system's temporary directory, removed on drop.
pub struct TempFile(pub PathBuf);

/// A unique directory in the system's temporary directory (named as
/// [`TempFile`]), removed with its content on drop.
pub struct TempDir(pub PathBuf);

impl TempDir {
    pub fn new(tag: &str) -> Self {
        // The TempFile only names the directory; forget it so its drop does
        // not try to remove the path as a file.
        let name = std::mem::ManuallyDrop::new(TempFile::new(tag));
        std::fs::create_dir_all(name.path()).expect("create temp dir");
        TempDir(name.path().to_path_buf())
    }

    pub fn path(&self) -> &Path {
        &self.0
    }

    /// The path of `name` inside the directory.
    pub fn join(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    /// Writes `bytes` to `name` in the directory and returns the path.
    pub fn file(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let p = self.join(name);
        std::fs::write(&p, bytes).expect("write temp file");
        p
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

impl TempFile {
    pub fn new(tag: &str) -> Self {
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        TempFile(std::env::temp_dir().join(format!(
            "raycaster-suite-{}-{n}-{nanos}-{tag}",
            std::process::id()
        )))
    }

    pub fn path(&self) -> &Path {
        &self.0
    }

    /// The file's name (the last component of its path): what error
    /// messages about the file must contain.
    pub fn name(&self) -> String {
        self.0
            .file_name()
            .expect("a file name")
            .to_string_lossy()
            .into_owned()
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}
