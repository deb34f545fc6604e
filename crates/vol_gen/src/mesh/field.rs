//! The signed distance field of a mesh on the output grid, and the
//! `vol_gen --generator mesh` job that writes it.
//!
//! **Placement.** The mesh's bounding box is scaled uniformly (one spacing
//! for all three axes, so shapes keep their proportions) and centred in the
//! grid, leaving `--margin` voxels between the box and the grid's faces on
//! the tightest axis ([`Placement::fit`]).
//!
//! **Units.** Distances are in the mesh's own units, and the file's spacing
//! is the grid spacing in those units: world coordinates of the file are
//! mesh coordinates (shifted so that voxel (0, 0, 0) is at the world origin,
//! as the formats' readers put it), so the SDF is metrically the mesh's.
//! The shift is printed: voxel (0, 0, 0) is at mesh point
//! [`Placement::origin`].
//!
//! **Values.** Each voxel holds the exact distance to the nearest triangle
//! ([`super::bvh`]), negative inside ([`super::sign`]); f32 samples, so the
//! output must be NRRD or NIfTI (`.vol` holds 8 bits only).

use std::path::Path;
use std::time::Instant;

use glam::{DVec3, UVec3, Vec3};
use raycaster::format::save::{OutputFormat, SaveOptions, output_format, save};
use raycaster::storage::Storage;
use raycaster::volume::{AnyVolume, AxisOrder, Grid};
use rayon::prelude::*;

use super::Mesh;
use super::bvh::Bvh;
use super::distance::closest_point_on_triangle;
use super::sign::{Crossings, Vote};
use crate::cli::Config;
use crate::error::{Error, Result};
use crate::progress::Progress;
use crate::{Summary, signal};

/// Default `--margin`, in voxels.
pub const DEFAULT_MARGIN: u32 = 3;

/// Where the mesh sits in the grid: voxel `v` is at mesh point
/// `origin + v · spacing`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// Mesh point of voxel (0, 0, 0).
    pub origin: DVec3,
    /// Distance between neighbouring voxels, in mesh units (all axes).
    pub spacing: f64,
}

impl Placement {
    /// Fits the box `[lo, hi]` into a grid of `dims` voxels, centred, with
    /// `margin` voxels to spare on the tightest axis.
    pub fn fit(lo: DVec3, hi: DVec3, dims: UVec3, margin: u32) -> Result<Placement, String> {
        let extent = hi - lo;
        let mut spacing: f64 = 0.0;
        for axis in 0..3 {
            if extent[axis] <= 0.0 {
                continue; // a flat mesh: any spacing fits this axis
            }
            let room = f64::from(dims[axis]) - 1.0 - 2.0 * f64::from(margin);
            if room <= 0.0 {
                return Err(format!(
                    "--dims {},{},{} leaves no room for the mesh inside a margin of {margin} voxels",
                    dims.x, dims.y, dims.z
                ));
            }
            spacing = spacing.max(extent[axis] / room);
        }
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(format!("the mesh's extent {extent} is zero or too large"));
        }
        let centre = (lo + hi) / 2.0;
        let origin = centre - (dims.as_dvec3() - DVec3::ONE) / 2.0 * spacing;
        Ok(Placement { origin, spacing })
    }

    /// Grid coordinates (voxel units) of mesh point `p`.
    pub fn to_grid(&self, p: DVec3) -> DVec3 {
        (p - self.origin) / self.spacing
    }
}

/// Writes the signed distance at every voxel of a `dims` grid, in mesh
/// units, into `out` (x fastest: `index = (z·Y + y)·X + x`; its length must
/// be the voxel count). `progress` is told of each finished z-slice (its
/// voxel count); `stop` is asked before each slice, and the return value is
/// false when it said stop (`out` is then incomplete).
pub fn signed_distances(
    mesh: &Mesh,
    dims: UVec3,
    placement: &Placement,
    out: &mut [f32],
    progress: &(dyn Fn(u64) + Sync),
    stop: &(dyn Fn() -> bool + Sync),
) -> bool {
    // Everything below works in grid coordinates: rows at integer positions.
    let grid_mesh = mesh.map_vertices(|p| placement.to_grid(p));
    let triangles = grid_mesh.triangle_corners();
    let crossings = Crossings::new(&triangles, dims);
    let bvh = Bvh::new(triangles);
    let slice = dims.x as usize * dims.y as usize;
    assert_eq!(out.len(), slice * dims.z as usize, "one value per voxel");
    let spacing = placement.spacing;
    out.par_chunks_mut(slice)
        .enumerate()
        .for_each(|(z, values)| {
            if stop() {
                return;
            }
            let mut hint = None;
            for y in 0..dims.y {
                for x in 0..dims.x {
                    let v = UVec3::new(x, y, z as u32);
                    let p = v.as_dvec3();
                    // The previous voxel's nearest triangle is at most one
                    // voxel farther: a tight first bound for the search.
                    let nearest = bvh.nearest(p, hint);
                    hint = Some(nearest.triangle);
                    let d = nearest.distance_squared.sqrt();
                    let inside = match crossings.vote(v) {
                        Vote::Inside => true,
                        Vote::Outside => false,
                        Vote::Tie => {
                            let [a, b, c] = *bvh.triangle(nearest.triangle);
                            let q = closest_point_on_triangle(p, a, b, c);
                            (p - q).dot((b - a).cross(c - a)) < 0.0
                        }
                    };
                    let signed = if inside { -d } else { d };
                    values[(y * dims.x + x) as usize] = (signed * spacing) as f32;
                }
            }
            progress(slice as u64);
        });
    !stop()
}

/// The file formats that hold f32 samples with a spacing.
fn check_float_output(path: &Path) -> Result<()> {
    let format = output_format(path, &SaveOptions::default())?;
    match format {
        OutputFormat::Nrrd(_) | OutputFormat::Nifti { .. } => Ok(()),
        OutputFormat::Vol(_) | OutputFormat::Raw => Err(Error::Usage(format!(
            "{}: --generator mesh writes a signed distance field of f32 samples, which needs \
             a float format with a spacing: name the output .nrrd, .nii or .nii.gz \
             (.vol holds 8-bit samples only)",
            path.display()
        ))),
    }
}

/// Runs `vol_gen --generator mesh`: reads the mesh, fits it into the grid,
/// computes the SDF with a progress bar and writes it (atomically), in the
/// format the output file's extension names.
pub fn run(config: &Config) -> Result<Summary> {
    let Some(mesh_path) = &config.mesh else {
        return Err(Error::Usage(
            "--generator mesh needs --mesh FILE (.obj, .ply or .stl)".into(),
        ));
    };
    check_float_output(&config.output)?;
    let dims = config.header.dims;
    let voxels = u64::from(dims.x) * u64::from(dims.y) * u64::from(dims.z);
    let bytes = voxels
        .checked_mul(4)
        .filter(|&b| usize::try_from(b).is_ok())
        .ok_or_else(|| Error::Usage("--dims: the volume is too large".into()))?;
    crate::check_output(&config.output, config.force, bytes)?;
    signal::install();
    let start = Instant::now();
    let mesh = Mesh::load(mesh_path).map_err(|e| Error::Failed(e.to_string()))?;
    let (lo, hi) = mesh.bounds();
    let placement = Placement::fit(lo, hi, dims, config.margin).map_err(Error::Usage)?;
    if !config.quiet {
        let o = placement.origin;
        eprintln!(
            "vol_gen: {}: {} triangles; {} mesh units per voxel; voxel (0,0,0) at mesh point ({:.6}, {:.6}, {:.6})",
            mesh_path.display(),
            mesh.triangles().len(),
            placement.spacing,
            o.x,
            o.y,
            o.z
        );
    }
    // An allocation failure would abort the process; say it in one line.
    let mut values: Vec<f32> = Vec::new();
    values.try_reserve_exact(voxels as usize).map_err(|_| {
        Error::Failed(format!(
            "--dims {},{},{}: not enough memory for the field ({})",
            dims.x,
            dims.y,
            dims.z,
            raycaster::units::bytes(bytes)
        ))
    })?;
    values.resize(voxels as usize, 0.0);
    let progress = Progress::voxels(voxels, !config.quiet);
    let complete = signed_distances(
        &mesh,
        dims,
        &placement,
        &mut values,
        &|n| progress.advance(n),
        &signal::interrupted,
    );
    progress.finish();
    if !complete {
        return Err(Error::Interrupted);
    }
    let grid = Grid::new(dims, Vec3::splat(placement.spacing as f32));
    let volume = AnyVolume::linear(grid, Storage::from_vec(values), AxisOrder::XFast)?;
    save(&config.output, &volume, &SaveOptions::default())?;
    let seconds = start.elapsed().as_secs_f64();
    let len = std::fs::metadata(&config.output).map_or(bytes, |m| m.len());
    if !config.quiet {
        eprintln!(
            "vol_gen: wrote {} ({}x{}x{} signed distances, f32) in {seconds:.2} s",
            config.output.display(),
            dims.x,
            dims.y,
            dims.z
        );
    }
    Ok(Summary {
        path: config.output.clone(),
        bytes: len,
        seconds,
    })
}

#[cfg(test)]
mod tests {
    use super::super::testing::{cube, icosphere, winding_number};
    use super::*;

    fn sdf(mesh: &Mesh, dims: UVec3, margin: u32) -> (Vec<f32>, Placement) {
        let (lo, hi) = mesh.bounds();
        let placement = Placement::fit(lo, hi, dims, margin).unwrap();
        let mut values = vec![0.0; (dims.x * dims.y * dims.z) as usize];
        assert!(signed_distances(
            mesh,
            dims,
            &placement,
            &mut values,
            &|_| {},
            &|| false
        ));
        (values, placement)
    }

    /// Mesh point of every voxel, in the order of [`signed_distances`].
    fn points(dims: UVec3, placement: &Placement) -> Vec<DVec3> {
        let mut out = Vec::new();
        for z in 0..dims.z {
            for y in 0..dims.y {
                for x in 0..dims.x {
                    out.push(placement.origin + UVec3::new(x, y, z).as_dvec3() * placement.spacing);
                }
            }
        }
        out
    }

    fn box_sdf(p: DVec3, lo: DVec3, hi: DVec3) -> f64 {
        let q = (p - (lo + hi) / 2.0).abs() - (hi - lo) / 2.0;
        q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
    }

    #[test]
    fn placement_is_uniform_centred_with_margin() {
        let p = Placement::fit(
            DVec3::ZERO,
            DVec3::new(2.0, 1.0, 1.0),
            UVec3::new(27, 27, 11),
            3,
        )
        .unwrap();
        // x: 2 / 20 = 0.1, y: 1 / 20, z: 1 / 4 = 0.25 is the tightest.
        assert!((p.spacing - 0.25).abs() < 1e-12);
        let centre = p.origin + DVec3::new(13.0, 13.0, 5.0) * p.spacing;
        assert!((centre - DVec3::new(1.0, 0.5, 0.5)).length() < 1e-12);
        assert!((p.to_grid(DVec3::new(0.0, 0.0, 1.0)).z - 7.0).abs() < 1e-9);
        assert!(Placement::fit(DVec3::ZERO, DVec3::ONE, UVec3::new(7, 20, 20), 3).is_err());
    }

    #[test]
    fn cube_matches_the_analytic_sdf() {
        let (lo, hi) = (DVec3::new(-1.0, -0.5, 0.0), DVec3::new(1.0, 0.7, 0.9));
        let mesh = cube(lo, hi);
        let dims = UVec3::new(30, 22, 19);
        let (values, placement) = sdf(&mesh, dims, 4);
        for (v, p) in values.iter().zip(points(dims, &placement)) {
            let want = box_sdf(p, lo, hi);
            assert!((f64::from(*v) - want).abs() < 1e-5, "{p}: {v} vs {want}");
        }
    }

    #[test]
    fn icosphere_matches_the_sphere_within_its_facets() {
        let (centre, r) = (DVec3::new(0.3, -2.0, 5.0), 1.5);
        let mesh = icosphere(centre, r, 3);
        // The mesh lies between the sphere and the ball through its facets'
        // centres; the gap (sagitta) bounds the difference of the SDFs.
        let gap = mesh
            .triangle_corners()
            .iter()
            .map(|t| r - ((t[0] + t[1] + t[2]) / 3.0 - centre).length())
            .fold(0.0, f64::max);
        let dims = UVec3::splat(33);
        let (values, placement) = sdf(&mesh, dims, 3);
        let mut signs_checked = 0;
        for (v, p) in values.iter().zip(points(dims, &placement)) {
            let want = (p - centre).length() - r;
            let v = f64::from(*v);
            assert!((v - want).abs() <= gap + 1e-6, "{p}: {v} vs {want}");
            if want.abs() > gap + 1e-6 {
                assert_eq!(v < 0.0, want < 0.0, "{p}");
                signs_checked += 1;
            }
        }
        assert!(signs_checked > 30_000);
    }

    #[test]
    fn negative_exactly_inside() {
        // Random meshes points: a sphere and a cube, placed off the grid's
        // symmetry, against the winding number (brute force).
        let mut rng = fastrand::Rng::with_seed(3);
        for mesh in [
            icosphere(DVec3::new(0.1, 0.2, 0.3), 1.0, 2),
            cube(DVec3::new(-0.3, 0.1, 0.0), DVec3::new(0.77, 0.5, 0.61)),
        ] {
            let dims = UVec3::new(21, 17, 19);
            let (values, placement) = sdf(&mesh, dims, 2);
            let pts = points(dims, &placement);
            for _ in 0..2000 {
                let i = rng.usize(..values.len());
                let w = winding_number(&mesh, pts[i]);
                if values[i].abs() < 1e-6 {
                    continue; // on the surface: either sign
                }
                assert_eq!(values[i] < 0.0, w > 0.5, "{} w {w} d {}", pts[i], values[i]);
            }
        }
    }

    #[test]
    fn the_bunny_is_negative_exactly_inside() {
        // The committed scan: 3674 triangles of uneven size, not symmetric.
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/bunny.ply");
        let mesh = Mesh::load(&path).unwrap();
        let dims = UVec3::new(37, 36, 29);
        let (values, placement) = sdf(&mesh, dims, 2);
        let pts = points(dims, &placement);
        let mut rng = fastrand::Rng::with_seed(4);
        let mut inside = 0;
        for _ in 0..600 {
            let i = rng.usize(..values.len());
            let w = winding_number(&mesh, pts[i]);
            assert_eq!(values[i] < 0.0, w > 0.5, "{} w {w} d {}", pts[i], values[i]);
            inside += usize::from(w > 0.5);
        }
        assert!(inside > 50, "{inside}");
    }

    #[test]
    fn the_bunny_without_its_base_keeps_its_inside() {
        // Cut away every triangle below y = 0.6 (the scanned bunny's base,
        // about 3 voxels high here): a hole across the whole bottom, as in
        // the original Stanford scan. Rays along y through the hole tie;
        // those along x and z still see a closed outline and decide.
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/bunny.ply");
        let closed = Mesh::load(&path).unwrap();
        let cut_y = 0.6;
        let kept: Vec<[i64; 3]> = closed
            .triangles()
            .iter()
            .filter(|t| t.iter().any(|&i| closed.vertices()[i as usize].y > cut_y))
            .map(|t| t.map(i64::from))
            .collect();
        assert!(kept.len() < closed.triangles().len());
        let open = Mesh::from_polygons(closed.vertices().to_vec(), kept).unwrap();
        let dims = UVec3::new(37, 36, 29);
        let (lo, hi) = closed.bounds();
        let placement = Placement::fit(lo, hi, dims, 2).unwrap();
        let mut values = vec![0.0; (dims.x * dims.y * dims.z) as usize];
        assert!(signed_distances(
            &open,
            dims,
            &placement,
            &mut values,
            &|_| {},
            &|| false
        ));
        let pts = points(dims, &placement);
        let mut checked = 0;
        for (v, p) in values.iter().zip(&pts) {
            if p.y < cut_y + 2.0 * placement.spacing {
                continue;
            }
            let w = winding_number(&closed, *p);
            assert_eq!(*v < 0.0, w > 0.5, "{p} w {w} d {v}");
            checked += 1;
        }
        assert!(checked > 30_000, "{checked}");
    }

    #[test]
    fn a_hole_does_not_flip_the_sign_away_from_it() {
        let (lo, hi) = (DVec3::new(-1.0, -1.0, -1.0), DVec3::new(1.0, 1.0, 1.0));
        let closed = cube(lo, hi);
        // Take away one of the two triangles of the x = hi face and replace
        // the face by a fine grid of triangles with one small one missing:
        // a hole of about 0.1 x 0.1 units.
        let mut vertices = closed.vertices().to_vec();
        let mut polygons: Vec<Vec<i64>> = closed
            .triangles()
            .iter()
            .filter(|t| !t.iter().all(|&i| vertices[i as usize].x == hi.x))
            .map(|t| t.iter().map(|&i| i64::from(i)).collect())
            .collect();
        let n = 20;
        let base = vertices.len() as i64;
        for j in 0..=n {
            for k in 0..=n {
                let s = |i: i64| -1.0 + 2.0 * i as f64 / n as f64;
                vertices.push(DVec3::new(hi.x, s(j), s(k)));
            }
        }
        let id = |j: i64, k: i64| base + j * (n + 1) + k;
        let hole = (10, 10);
        for j in 0..n {
            for k in 0..n {
                polygons.push(vec![id(j, k), id(j + 1, k), id(j + 1, k + 1)]);
                if (j, k) != hole {
                    polygons.push(vec![id(j, k), id(j + 1, k + 1), id(j, k + 1)]);
                }
            }
        }
        let mesh = Mesh::from_polygons(vertices, polygons).unwrap();
        let dims = UVec3::splat(31);
        let (values, placement) = sdf(&mesh, dims, 3);
        let hole_centre = DVec3::new(hi.x, 0.05, 0.05);
        for (v, p) in values.iter().zip(points(dims, &placement)) {
            let want = box_sdf(p, lo, hi);
            if want.abs() < 1e-6 || (p - hole_centre).length() < 0.2 {
                continue;
            }
            assert_eq!(*v < 0.0, want < 0.0, "{p}: {v} vs {want}");
        }
    }
}
