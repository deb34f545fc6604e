//! Sample generators: "virtual volumes" that give every voxel a value.
//!
//! A generator is a pure function of the voxel coordinate and of parameters
//! drawn from the seed when it is built. The writer asks it to fill boxes of
//! voxels ([`Region`]) in whatever order and on whatever thread suits the file
//! layout, so the bytes written never depend on the thread count or on the
//! layout: the linear and the bricked file of one seed hold the same values.
//!
//! Generators whose objects are local (`shapes`, `metaballs`) keep them in
//! [`bins::Bins`], a coarse grid of cells, so filling a region only looks at
//! the objects that can touch it and the cost per voxel does not grow with the
//! number of objects.

pub mod bins;
pub mod metaballs;
pub mod noise;
pub mod sdf;
pub mod shapes;
pub mod solid;
pub mod sphere;

use glam::{UVec3, Vec3};

/// The generators of the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum GeneratorKind {
    /// Random spheres and cuboids, each of one value near --sample (the thesis's benchmark data)
    Shapes,
    /// Every voxel --sample
    Solid,
    /// Smooth fractal value noise in 0..=--sample
    Noise,
    /// One centred ball with a smooth radial falloff from --sample to 0
    Sphere,
    /// Signed distance field of a CSG scene, 128 on the surface, larger inside
    Sdf,
    /// Density of Wyvill-kernel balls, 128 on the iso surface
    Metaballs,
    /// Signed distance field (f32, negative inside) of the triangle mesh --mesh
    Mesh,
    /// A time series (f32, --frames N): a hot jet with puffs and drifting turbulence
    Plume,
}

impl GeneratorKind {
    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            GeneratorKind::Shapes => "shapes",
            GeneratorKind::Solid => "solid",
            GeneratorKind::Noise => "noise",
            GeneratorKind::Sphere => "sphere",
            GeneratorKind::Sdf => "sdf",
            GeneratorKind::Metaballs => "metaballs",
            GeneratorKind::Mesh => "mesh",
            GeneratorKind::Plume => "plume",
        }
    }
}

/// Everything a generator may use: the grid, the seed and the optional
/// parameters of the command line (each generator has its own defaults).
#[derive(Debug, Clone, PartialEq)]
pub struct Setup {
    /// Volume dimensions.
    pub dims: UVec3,
    /// Voxel spacing (the `.vol` "cell shape").
    pub spacing: Vec3,
    /// Seed of every random choice.
    pub seed: u64,
    /// `--n-of-shapes`.
    pub n_of_shapes: Option<u32>,
    /// `--object-size`, in voxels.
    pub object_size: Option<u32>,
    /// `--sample`.
    pub sample: Option<u8>,
    /// `--octaves` (noise).
    pub octaves: Option<u32>,
    /// `--band` (sdf), in voxels.
    pub band: Option<f32>,
    /// `--value-range LO,HI` (plume).
    pub value_range: Option<(f32, f32)>,
}

impl Setup {
    /// A setup with unit spacing and no optional parameters.
    pub fn new(dims: UVec3, seed: u64) -> Self {
        Setup {
            dims,
            spacing: Vec3::ONE,
            seed,
            n_of_shapes: None,
            object_size: None,
            sample: None,
            octaves: None,
            band: None,
            value_range: None,
        }
    }

    /// Spacing divided by the smallest spacing: the world position of voxel
    /// `v`, in units of the finest voxel, is `v · scale`. The geometric
    /// generators (sphere, sdf, metaballs, noise) work in these units, so
    /// their objects stay round in world space whatever the spacing.
    pub fn scale(&self) -> Vec3 {
        self.spacing / self.spacing.min_element()
    }

    /// The volume's extent `(dims − 1) · scale` in units of the finest voxel.
    pub fn extent(&self) -> Vec3 {
        (self.dims.as_vec3() - Vec3::ONE) * self.scale()
    }
}

/// A box of voxels `[lo, hi)` and where its values go in an output slice:
/// voxel `(x, y, z)` is at `(x − lo.x)·stride_x + (y − lo.y)·stride_y + (z − lo.z)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Region {
    /// Lowest voxel, inclusive.
    pub lo: UVec3,
    /// Highest voxel, exclusive.
    pub hi: UVec3,
    /// Output index step per x.
    pub stride_x: usize,
    /// Output index step per y.
    pub stride_y: usize,
}

impl Region {
    /// True when the box holds no voxel.
    pub fn is_empty(&self) -> bool {
        self.lo.cmpge(self.hi).any()
    }

    /// Output index of the first voxel of row `(x, y)`.
    #[inline]
    pub fn row_start(&self, x: u32, y: u32) -> usize {
        (x - self.lo.x) as usize * self.stride_x + (y - self.lo.y) as usize * self.stride_y
    }

    /// Voxels per row (along z).
    #[inline]
    pub fn row_len(&self) -> usize {
        (self.hi.z - self.lo.z) as usize
    }

    /// Calls `f(x, y, row)` for every row of the box, `row[i]` being voxel
    /// `(x, y, lo.z + i)`.
    pub fn for_each_row(&self, out: &mut [u8], mut f: impl FnMut(u32, u32, &mut [u8])) {
        if self.is_empty() {
            return;
        }
        let len = self.row_len();
        for x in self.lo.x..self.hi.x {
            for y in self.lo.y..self.hi.y {
                let start = self.row_start(x, y);
                f(x, y, &mut out[start..start + len]);
            }
        }
    }

    /// The voxels of the box that are also in `b`, or `None`.
    pub fn clip(&self, b: &IBox) -> Option<IBox> {
        if self.is_empty() {
            return None;
        }
        let lo = self.lo.max(b.lo);
        let hi = (self.hi - UVec3::ONE).min(b.hi);
        lo.cmple(hi).all().then_some(IBox { lo, hi })
    }
}

/// An integer box of voxels with inclusive bounds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct IBox {
    /// Lowest voxel.
    pub lo: UVec3,
    /// Highest voxel (inclusive).
    pub hi: UVec3,
}

impl IBox {
    /// The voxels `v` with `lo <= v <= hi` (real bounds) inside a grid of
    /// `dims`, or `None` when there are none.
    pub fn covering(lo: glam::DVec3, hi: glam::DVec3, dims: UVec3) -> Option<IBox> {
        let max = (dims - UVec3::ONE).as_dvec3();
        let l = lo.ceil().max(glam::DVec3::ZERO);
        let h = hi.floor().min(max);
        l.cmple(h).all().then(|| IBox {
            lo: l.as_uvec3(),
            hi: h.as_uvec3(),
        })
    }
}

/// A volume defined by a function: fills any region on demand.
pub trait Field: Send + Sync {
    /// Writes the value of every voxel of `region` into `out` (see
    /// [`Region`]). `out` is zeroed on entry, so voxels of value 0 may be
    /// skipped; entries outside the region must be left untouched. The values
    /// must not depend on the region: a voxel gets the same value in any box.
    fn fill(&self, region: &Region, out: &mut [u8]);
}

/// Builds the generator `kind`, drawing its random parameters from `setup.seed`.
pub fn build(kind: GeneratorKind, setup: &Setup) -> Result<Box<dyn Field>, String> {
    Ok(match kind {
        GeneratorKind::Shapes => Box::new(shapes::Shapes::new(setup)?),
        GeneratorKind::Solid => Box::new(solid::Solid::new(setup)),
        GeneratorKind::Noise => Box::new(noise::Noise::new(setup)?),
        GeneratorKind::Sphere => Box::new(sphere::Sphere::new(setup)),
        GeneratorKind::Sdf => Box::new(sdf::Sdf::new(setup)?),
        GeneratorKind::Metaballs => Box::new(metaballs::Metaballs::new(setup)?),
        // Not a voxel-by-voxel u8 field: `mesh::field::run` writes it.
        GeneratorKind::Mesh => {
            return Err(
                "--generator mesh writes f32 samples; it is run by mesh::field::run".into(),
            );
        }
        // f32 frames of a time series: `plume::run` writes them.
        GeneratorKind::Plume => {
            return Err("--generator plume writes f32 frames; it is run by plume::run".into());
        }
    })
}

/// The largest `--n-of-shapes` accepted (each object costs memory and setup time).
pub const MAX_OBJECTS: u32 = 10_000_000;

/// `--n-of-shapes` or `default`, checked against [`MAX_OBJECTS`].
pub(crate) fn object_count(setup: &Setup, default: u32) -> Result<u32, String> {
    let n = setup.n_of_shapes.unwrap_or(default);
    if n > MAX_OBJECTS {
        return Err(format!(
            "--n-of-shapes {n} is too many (at most {MAX_OBJECTS})"
        ));
    }
    Ok(n)
}

/// `--object-size` or `default`, at least 1.
pub(crate) fn object_size(setup: &Setup, default: f64) -> Result<f64, String> {
    match setup.object_size {
        Some(0) => Err("--object-size must be at least 1".into()),
        Some(s) => Ok(s as f64),
        None => Ok(default.max(1.0)),
    }
}

/// Quintic fade `6t⁵ − 15t⁴ + 10t³`, used for smooth interpolation.
#[inline(always)]
pub(crate) fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// A float in 0..=255 rounded to the nearest `u8`.
#[inline(always)]
pub(crate) fn to_u8(v: f32) -> u8 {
    v.clamp(0.0, 255.0).round() as u8
}

#[cfg(test)]
pub(crate) mod testing {
    //! Helpers for the generators' unit tests.
    use super::*;

    /// Fills the whole grid as one region, in linear order.
    pub fn render(field: &dyn Field, dims: UVec3) -> Vec<u8> {
        let mut out = vec![0u8; (dims.x * dims.y * dims.z) as usize];
        let region = Region {
            lo: UVec3::ZERO,
            hi: dims,
            stride_x: (dims.y * dims.z) as usize,
            stride_y: dims.z as usize,
        };
        field.fill(&region, &mut out);
        out
    }

    /// Fills the grid one voxel at a time and checks it matches [`render`].
    pub fn assert_region_independent(field: &dyn Field, dims: UVec3) {
        let whole = render(field, dims);
        let mut i = 0;
        for x in 0..dims.x {
            for y in 0..dims.y {
                for z in 0..dims.z {
                    let v = UVec3::new(x, y, z);
                    let region = Region {
                        lo: v,
                        hi: v + UVec3::ONE,
                        stride_x: 1,
                        stride_y: 1,
                    };
                    let mut one = [0u8];
                    field.fill(&region, &mut one);
                    assert_eq!(one[0], whole[i], "voxel {v}");
                    i += 1;
                }
            }
        }
    }
}
