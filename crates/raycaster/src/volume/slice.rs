//! Axis-aligned slices of a volume, for slice views (axial, coronal,
//! sagittal) beside the 3D image.
//!
//! A slice is resampled on the volume's own in-plane grid: one pixel per
//! voxel along the two in-plane axes, so a pixel is `spacing[u] ×
//! spacing[v]` world units (not square when the spacing is not), and a
//! viewer shows it with the aspect of its physical extent. Along the
//! normal, the slice lies at any world position: its values are the linear
//! interpolation of the two voxel planes around it, which is the trilinear
//! interpolation of SPEC §2 at the pixel's world position (on a voxel plane,
//! the voxels themselves). Only those one or two planes are read, so a
//! slice of a memory-mapped file touches the pages that hold its voxels and
//! no others (which, for a plane across the file's fastest axis, can still
//! be most pages: a linear z-fast file keeps an axial slice's voxels
//! `Z` samples apart).

use glam::{UVec3, Vec3};
use rayon::prelude::*;

use super::{AnyVolume, Volume, VolumeVisitor};
use crate::sample::Sample;

/// Which plane a slice shows, named by its normal along the volume's axes
/// (the medical names assume the usual x = left–right, y = posterior–
/// anterior, z = inferior–superior of NIfTI and DICOM).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SliceAxis {
    /// z constant: x across, y up.
    Axial,
    /// y constant: x across, z up.
    Coronal,
    /// x constant: y across, z up.
    Sagittal,
}

impl SliceAxis {
    /// The three, in the order viewers lay them out.
    pub const ALL: [SliceAxis; 3] = [SliceAxis::Axial, SliceAxis::Coronal, SliceAxis::Sagittal];

    /// The axis (0 = x, 1 = y, 2 = z) the slice is perpendicular to.
    pub fn normal(self) -> usize {
        match self {
            SliceAxis::Axial => 2,
            SliceAxis::Coronal => 1,
            SliceAxis::Sagittal => 0,
        }
    }

    /// The axes of the image's columns (`u`) and rows (`v`).
    pub fn in_plane(self) -> (usize, usize) {
        match self {
            SliceAxis::Axial => (0, 1),
            SliceAxis::Coronal => (0, 2),
            SliceAxis::Sagittal => (1, 2),
        }
    }

    /// "Axial", "Coronal", "Sagittal".
    pub fn label(self) -> &'static str {
        match self {
            SliceAxis::Axial => "Axial",
            SliceAxis::Coronal => "Coronal",
            SliceAxis::Sagittal => "Sagittal",
        }
    }
}

/// The values of one slice.
#[derive(Debug, Clone, PartialEq)]
pub struct SliceImage {
    /// The plane.
    pub axis: SliceAxis,
    /// Pixels along the `u` axis (the volume's dimension along it).
    pub width: u32,
    /// Pixels along the `v` axis.
    pub height: u32,
    /// Values, `values[v · width + u]`: row `v` is voxel row `v` (the first
    /// row is the lowest coordinate; a viewer that wants `v` up flips it).
    pub values: Vec<f32>,
    /// World size of a pixel along `u` and `v` (the volume's spacing).
    pub pixel_size: [f32; 2],
    /// The world coordinate along the normal that the slice lies at
    /// (the requested one, clamped into the volume's bounding box).
    pub position: f32,
}

impl SliceImage {
    /// The value of pixel `(u, v)`, `None` outside the image.
    pub fn get(&self, u: u32, v: u32) -> Option<f32> {
        (u < self.width && v < self.height)
            .then(|| self.values[v as usize * self.width as usize + u as usize])
    }
}

/// The slice of `volume` perpendicular to `axis` at world coordinate
/// `position` along it (clamped into the bounding box), resampled on the
/// volume's in-plane voxel grid. Rows are computed on the current rayon
/// pool.
pub fn slice_image(volume: &AnyVolume, axis: SliceAxis, position: f32) -> SliceImage {
    struct Slice(SliceAxis, f32);
    impl VolumeVisitor for Slice {
        type Output = SliceImage;
        fn visit<V: Volume>(self, v: &V) -> SliceImage {
            slice_of(v, self.0, self.1)
        }
    }
    volume.visit(Slice(axis, position))
}

fn slice_of<V: Volume>(volume: &V, axis: SliceAxis, position: f32) -> SliceImage {
    let grid = *volume.grid();
    let n = axis.normal();
    let (u_axis, v_axis) = axis.in_plane();
    let dims = grid.dims.to_array();
    let last = (dims[n] - 1) as f32;
    let t = ((position - grid.origin[n]) / grid.spacing[n]).clamp(0.0, last);
    let t = if t.is_nan() { 0.0 } else { t };
    // The plane below `t` and the fraction towards the one above; on a
    // voxel plane (f = 0) only that plane is read.
    let lower = (t.floor() as u32).min(dims[n].saturating_sub(2));
    let f = t - lower as f32;
    let (width, height) = (dims[u_axis], dims[v_axis]);
    let mut values = vec![0.0f32; width as usize * height as usize];
    values
        .par_chunks_mut(width as usize)
        .enumerate()
        .for_each(|(row, out)| {
            let mut at = [0u32; 3];
            at[v_axis] = row as u32;
            for (col, o) in out.iter_mut().enumerate() {
                at[u_axis] = col as u32;
                at[n] = lower;
                let a = volume.voxel(UVec3::from_array(at)).to_f32();
                *o = if f > 0.0 {
                    at[n] = lower + 1;
                    let b = volume.voxel(UVec3::from_array(at)).to_f32();
                    a + (b - a) * f
                } else {
                    a
                };
            }
        });
    SliceImage {
        axis,
        width,
        height,
        values,
        pixel_size: [grid.spacing[u_axis], grid.spacing[v_axis]],
        position: grid.origin[n] + t * grid.spacing[n],
    }
}

/// The trilinearly interpolated value at world position `p`, `None`
/// outside the volume's bounding box.
pub fn value_at(volume: &AnyVolume, p: Vec3) -> Option<f32> {
    struct At(Vec3);
    impl VolumeVisitor for At {
        type Output = f32;
        fn visit<V: Volume>(self, v: &V) -> f32 {
            v.sample(v.grid().world_to_voxel(self.0))
        }
    }
    let b = volume.grid().bounds();
    // A little slack, so a point on a face rounded in f32 still counts.
    let eps = volume.grid().spacing * 1e-4;
    let inside = p.cmpge(b.min - eps).all() && p.cmple(b.max + eps).all();
    inside.then(|| volume.visit(At(p)))
}

/// The values at quantiles `qs` (each in 0..1) of about `max_samples`
/// voxels taken on a regular lattice through the volume (a window/level
/// "auto" for data without standard windows, such as MR). Reads only the
/// sampled voxels.
pub fn sampled_quantiles(volume: &AnyVolume, qs: &[f32], max_samples: u64) -> Vec<f32> {
    struct Sampled(u64);
    impl VolumeVisitor for Sampled {
        type Output = Vec<f32>;
        fn visit<V: Volume>(self, v: &V) -> Vec<f32> {
            let d = v.grid().dims;
            // The same stride along each axis, chosen so the lattice holds
            // at most about `max_samples` voxels.
            let ratio = (v.grid().voxel_count() as f64 / self.0.max(1) as f64).cbrt();
            let stride = (ratio.ceil() as u32).max(1);
            let mut out = Vec::new();
            for x in (0..d.x).step_by(stride as usize) {
                for y in (0..d.y).step_by(stride as usize) {
                    for z in (0..d.z).step_by(stride as usize) {
                        out.push(v.voxel(UVec3::new(x, y, z)).to_f32());
                    }
                }
            }
            out
        }
    }
    let mut values = volume.visit(Sampled(max_samples));
    values.retain(|v| v.is_finite());
    values.sort_unstable_by(f32::total_cmp);
    qs.iter()
        .map(|q| {
            if values.is_empty() {
                return 0.0;
            }
            let i = (q.clamp(0.0, 1.0) * (values.len() - 1) as f32).round() as usize;
            values[i]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::Grid;

    fn ramp(grid: Grid) -> AnyVolume {
        AnyVolume::from_fn(grid, |v| (v.x + 10 * v.y + 100 * v.z) as u16)
    }

    #[test]
    fn a_slice_on_a_voxel_plane_is_that_plane() {
        let grid = Grid::new(UVec3::new(4, 5, 6), Vec3::new(1.0, 2.0, 0.5));
        let vol = ramp(grid);
        let s = slice_image(&vol, SliceAxis::Axial, 1.5);
        assert_eq!((s.width, s.height), (4, 5));
        assert_eq!(s.pixel_size, [1.0, 2.0]);
        assert_eq!(s.position, 1.5);
        for v in 0..5 {
            for u in 0..4 {
                assert_eq!(s.get(u, v), Some(vol.value(UVec3::new(u, v, 3))));
            }
        }
        assert_eq!(s.get(4, 0), None);
    }

    #[test]
    fn between_planes_is_linear_and_outside_is_clamped() {
        let grid = Grid::new(UVec3::new(4, 5, 6), Vec3::new(1.0, 2.0, 0.5));
        let vol = ramp(grid);
        let s = slice_image(&vol, SliceAxis::Sagittal, 1.25);
        assert_eq!((s.width, s.height), (5, 6));
        assert_eq!(s.get(2, 3), Some(1.25 + 20.0 + 300.0));
        let s = slice_image(&vol, SliceAxis::Coronal, 99.0);
        assert_eq!(s.position, 8.0);
        assert_eq!(s.get(1, 2), Some(1.0 + 40.0 + 200.0));
        let s = slice_image(&vol, SliceAxis::Coronal, f32::NAN);
        assert_eq!(s.position, 0.0);
    }

    #[test]
    fn quantiles_of_a_ramp() {
        let grid = Grid::new(UVec3::new(101, 1, 1), Vec3::ONE);
        let vol = AnyVolume::from_fn(grid, |v| v.x as u8);
        assert_eq!(
            sampled_quantiles(&vol, &[0.0, 0.01, 0.99, 1.0], 1000),
            vec![0.0, 1.0, 99.0, 100.0]
        );
        assert_eq!(value_at(&vol, Vec3::new(2.5, 0.0, 0.0)), Some(2.5));
        assert_eq!(value_at(&vol, Vec3::new(-1.0, 0.0, 0.0)), None);
    }
}
