//! Sampling tests shared by both layouts.

use glam::{UVec3, Vec3};

use super::*;

/// An affine field: trilinear interpolation must reproduce it exactly and its
/// gradient is the coefficient vector divided by the spacing.
fn affine(v: UVec3) -> f32 {
    2.0 * v.x as f32 + 3.0 * v.y as f32 - 1.5 * v.z as f32 + 100.0
}

/// A volume owned by a test, viewed as a [`GridVolume`].
struct Owned<S: Sample, A: Addressing> {
    grid: Grid,
    data: Vec<S>,
    addr: A,
}

impl<S: Sample, A: Addressing> Owned<S, A> {
    fn view(&self) -> GridVolume<'_, S, A> {
        GridVolume::new(&self.grid, &self.data, &self.addr)
    }
}

fn linear<S: Sample>(grid: Grid, f: impl Fn(UVec3) -> S) -> Owned<S, Linear> {
    let v = AnyVolume::from_fn(grid, f);
    Owned {
        grid,
        data: v.samples::<S>().unwrap().to_vec(),
        addr: Linear::new(grid.dims, AxisOrder::ZFast).unwrap(),
    }
}

fn bricked<S: Sample>(grid: Grid, side: u32, f: impl Fn(UVec3) -> S) -> Owned<S, Bricked> {
    let v = AnyVolume::bricked_from_fn(grid, side, f).unwrap();
    Owned {
        grid,
        data: v.samples::<S>().unwrap().to_vec(),
        addr: Bricked::new(grid.dims, side).unwrap(),
    }
}

fn volumes(dims: UVec3, spacing: Vec3, side: u32) -> (Owned<f32, Linear>, Owned<f32, Bricked>) {
    let grid = Grid::new(dims, spacing);
    (linear(grid, affine), bricked(grid, side, affine))
}

#[test]
fn trilinear_reproduces_affine_fields_in_both_layouts() {
    let mut rng = fastrand::Rng::with_seed(1);
    for (dims, side) in [
        (UVec3::new(9, 7, 12), 4),
        (UVec3::new(5, 1, 6), 2),
        (UVec3::new(17, 16, 3), 16),
    ] {
        let (lin, bri) = volumes(dims, Vec3::new(1.0, 0.5, 2.0), side);
        let max = (dims - UVec3::ONE).as_vec3();
        for _ in 0..500 {
            let p = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * max;
            let want = 2.0 * p.x + 3.0 * p.y - 1.5 * p.z + 100.0;
            assert!((lin.view().sample(p) - want).abs() < 1e-3, "{p}");
            assert_eq!(
                lin.view().sample(p),
                bri.view().sample(p),
                "layouts differ at {p}"
            );
        }
        // Grid points and the far corner read the voxels themselves.
        assert_eq!(lin.view().sample(max), affine(dims - UVec3::ONE));
        assert_eq!(bri.view().sample(max), affine(dims - UVec3::ONE));
        // Out-of-grid positions clamp.
        assert_eq!(lin.view().sample(Vec3::splat(-5.0)), affine(UVec3::ZERO));
    }
}

/// SPEC §8's gradient, written out independently: per voxel the central
/// differences `(v[i+1] − v[i−1]) / (2·spacing)` with the indices clamped to
/// the grid, trilinearly interpolated, in f64.
fn spec_gradient<V: Volume>(v: &V, p: Vec3) -> Vec3 {
    let g = v.grid();
    let last = g.dims - UVec3::ONE;
    let at = |c: [u32; 3]| v.voxel(UVec3::from_array(c)).to_f32() as f64;
    let voxel_gradient = |c: [u32; 3]| {
        let mut out = [0.0f64; 3];
        for (a, o) in out.iter_mut().enumerate() {
            let (mut lo, mut hi) = (c, c);
            lo[a] = c[a].saturating_sub(1);
            hi[a] = (c[a] + 1).min(last[a]);
            *o = (at(hi) - at(lo)) / (2.0 * g.spacing[a] as f64);
        }
        out
    };
    let mut sum = [0.0f64; 3];
    let q = p.clamp(Vec3::ZERO, last.as_vec3());
    let i0 = q
        .floor()
        .as_uvec3()
        .min((g.dims.max(UVec3::splat(2)) - 2).min(last));
    let f = q - i0.as_vec3();
    for dx in 0..2u32 {
        for dy in 0..2u32 {
            for dz in 0..2u32 {
                let w = [(dx, f.x), (dy, f.y), (dz, f.z)]
                    .iter()
                    .map(|&(d, f)| if d == 1 { f as f64 } else { 1.0 - f as f64 })
                    .product::<f64>();
                let c = (i0 + UVec3::new(dx, dy, dz)).min(last).to_array();
                let vg = voxel_gradient(c);
                for a in 0..3 {
                    sum[a] += w * vg[a];
                }
            }
        }
    }
    Vec3::new(sum[0] as f32, sum[1] as f32, sum[2] as f32)
}

#[test]
fn gradient_is_specs_central_difference_everywhere_and_exact_inside() {
    let mut rng = fastrand::Rng::with_seed(2);
    let spacing = Vec3::new(1.0, 0.5, 2.0);
    let (lin, bri) = volumes(UVec3::new(20, 18, 22), spacing, 6);
    let exact = Vec3::new(2.0, 3.0, -1.5) / spacing;
    let max = Vec3::new(19.0, 17.0, 21.0);
    for _ in 0..500 {
        let p = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * max;
        let want = spec_gradient(&lin.view(), p);
        for g in [lin.view().gradient(p), bri.view().gradient(p)] {
            assert!((g - want).length() < 1e-3, "{p}: {g} vs {want}");
        }
        // An affine field's central differences are exact away from the
        // faces (all eight corners of the cell inside the stencil).
        if p.cmpge(Vec3::ONE).all() && p.cmple(max - Vec3::ONE).all() {
            assert!((want - exact).length() < 1e-3, "{p}: {want} vs {exact}");
        }
    }
    // At a face the difference is index-clamped, not one-sided: half the
    // slope on the face voxel (SPEC §8).
    let face = lin.view().gradient(Vec3::new(0.0, 5.0, 5.0));
    assert!((face.x - exact.x / 2.0).abs() < 1e-3, "{face}");
    // A non-affine field, faces included; flat axes (size 1) give 0.
    for dims in [
        UVec3::new(12, 11, 13),
        UVec3::new(1, 7, 5),
        UVec3::new(6, 1, 2),
    ] {
        let grid = Grid::new(dims, spacing);
        let f = |v: UVec3| ((v.x * 37 + v.y * 11 + v.z * v.z * 5) % 251) as u8;
        let lin = linear(grid, f);
        let bri = bricked(grid, 5, f);
        let hi = (dims - UVec3::ONE).as_vec3();
        for _ in 0..500 {
            let p = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * hi;
            let want = spec_gradient(&lin.view(), p);
            assert!(
                (lin.view().gradient(p) - want).length() < 1e-3,
                "{dims} {p}"
            );
            assert!(
                (bri.view().gradient(p) - want).length() < 1e-3,
                "{dims} {p}"
            );
        }
    }
}

#[test]
fn value_ranges_agree_between_layouts() {
    let mut rng = fastrand::Rng::with_seed(3);
    let grid = Grid::new(UVec3::new(23, 9, 31), Vec3::ONE);
    let f = |v: UVec3| ((v.x * 131 + v.y * 71 + v.z * 17) % 253) as u8;
    let lin = linear(grid, f);
    for side in [2, 3, 7, 16] {
        let bri = bricked(grid, side, f);
        for _ in 0..200 {
            let lo = UVec3::new(rng.u32(0..23), rng.u32(0..9), rng.u32(0..31));
            let hi = lo + UVec3::new(rng.u32(0..10), rng.u32(0..10), rng.u32(0..10));
            let brute = (lo.x..=hi.x.min(22))
                .flat_map(|x| {
                    (lo.y..=hi.y.min(8)).flat_map(move |y| {
                        (lo.z..=hi.z.min(30)).map(move |z| f(UVec3::new(x, y, z)))
                    })
                })
                .fold((255u8, 0u8), |(a, b), v| (a.min(v), b.max(v)));
            assert_eq!(lin.view().value_range(lo, hi), brute);
            assert_eq!(
                bri.view().value_range(lo, hi),
                brute,
                "side {side} box {lo}..{hi}"
            );
        }
    }
}

#[test]
fn fast_macrocell_ranges_equal_the_generic_ones() {
    for (dims, cell) in [
        (UVec3::new(23, 9, 31), 4),
        (UVec3::new(17, 17, 17), 8),
        (UVec3::new(16, 1, 9), 3),
        (UVec3::new(1, 1, 1), 8),
        (UVec3::new(40, 33, 2), 8),
    ] {
        let grid = Grid::new(dims, Vec3::ONE);
        let f = |v: UVec3| ((v.x * 131 + v.y * 71 + v.z * 17) % 253) as u8;
        let lin = linear(grid, f);
        let bri = bricked(grid, 5, f);
        let n = |d: u32| if d <= 1 { 1 } else { (d - 1).div_ceil(cell) };
        let count = UVec3::new(n(dims.x), n(dims.y), n(dims.z));
        assert_eq!(
            lin.view().cell_value_ranges(cell, count),
            bri.view().cell_value_ranges(cell, count),
            "{dims} cell {cell}"
        );
    }
}

#[test]
fn unchecked_conversions_are_fed_only_representable_values() {
    // The float-to-int truncations skip their checks after clamping; these
    // inputs would be undefined behaviour without the clamps.
    for v in [
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        -1e30,
        1e30,
        -0.0,
        3.7,
    ] {
        let c = cell_coord(v, 5);
        assert!(c <= 5, "{v} -> {c}");
    }
    assert_eq!(cell_coord(f32::NAN, 5), 0);
    assert_eq!(cell_coord(1e30, 5), 5);
    assert_eq!(cell_coord(3.7, 5), 3);
    let (lin, bri) = volumes(UVec3::new(6, 5, 4), Vec3::ONE, 3);
    for p in [
        Vec3::NAN,
        Vec3::INFINITY,
        Vec3::NEG_INFINITY,
        Vec3::new(f32::NAN, 2.0, -9.0),
    ] {
        assert!(lin.view().sample(p).is_finite(), "{p}");
        assert!(bri.view().sample(p).is_finite(), "{p}");
        assert!(lin.view().gradient(p).is_finite(), "{p}");
    }
    let tf =
        crate::transfer::TransferFunction::preset("ramp", crate::sample::SampleType::U8).unwrap();
    let lut = crate::transfer::TfLut::new(&tf, 0.5);
    for v in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        assert!(lut.lookup(v).is_finite(), "{v}");
        let _ = lut.any_visible(v, v);
    }
}

/// The same field stored x fastest.
fn x_fast<S: Sample>(grid: Grid, f: impl Fn(UVec3) -> S) -> Owned<S, Linear> {
    let d = grid.dims;
    let mut v = Vec::new();
    for z in 0..d.z {
        for y in 0..d.y {
            for x in 0..d.x {
                v.push(f(UVec3::new(x, y, z)));
            }
        }
    }
    Owned {
        grid,
        data: v,
        addr: Linear::new(grid.dims, AxisOrder::XFast).unwrap(),
    }
}

#[test]
fn x_fast_order_samples_like_z_fast() {
    let mut rng = fastrand::Rng::with_seed(4);
    for dims in [
        UVec3::new(23, 9, 31),
        UVec3::new(5, 1, 6),
        UVec3::new(1, 7, 1),
        UVec3::new(17, 16, 3),
    ] {
        let grid = Grid::new(dims, Vec3::new(1.0, 0.5, 2.0));
        let f = |v: UVec3| ((v.x * 131 + v.y * 71 + v.z * v.z * 17) % 253) as i16 - 100;
        let z = linear(grid, f);
        let x = x_fast(grid, f);
        assert_eq!(x.addr.layout(), Layout::LinearXFast);
        let max = grid.max_coord();
        for _ in 0..300 {
            let p = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * max;
            assert_eq!(x.view().sample(p), z.view().sample(p), "{dims} at {p}");
            assert_eq!(x.view().gradient(p), z.view().gradient(p), "{dims} at {p}");
            let v = (p.as_uvec3()).min(dims - UVec3::ONE);
            assert_eq!(x.view().voxel(v), z.view().voxel(v));
            let hi = v + UVec3::new(rng.u32(0..6), rng.u32(0..6), rng.u32(0..6));
            assert_eq!(
                x.view().value_range(v, hi),
                z.view().value_range(v, hi),
                "{dims} {v}..{hi}"
            );
        }
        for cell in [2, 4, 8] {
            let n = |d: u32| if d <= 1 { 1 } else { (d - 1).div_ceil(cell) };
            let count = UVec3::new(n(dims.x), n(dims.y), n(dims.z));
            assert_eq!(
                x.view().cell_value_ranges(cell, count),
                z.view().cell_value_ranges(cell, count),
                "{dims} cell {cell}"
            );
        }
    }
}

/// A [`GradientCache`] gives [`Volume::gradient`]'s bits for positions
/// that come back to a few cells in any order (more cells than it keeps,
/// so that slots are taken over), on a field whose gradient changes from
/// cell to cell.
#[test]
fn the_gradient_cache_gives_the_volumes_gradients() {
    let grid = Grid::new(UVec3::new(9, 8, 7), Vec3::new(1.0, 0.5, 2.0));
    let vol = linear(grid, |v| {
        let p = v.as_vec3();
        (p.x * 0.7).sin() * 40.0 + p.y * p.z - (p.z * 1.3).cos() * 9.0
    });
    let vol = vol.view();
    let mut rng = fastrand::Rng::with_seed(17);
    let mut cache = GradientCache::default();
    // A handful of cells, one more than the cache keeps, revisited.
    let cells: Vec<Vec3> = (0..GRADIENT_CELLS + 1)
        .map(|_| Vec3::new(rng.f32() * 7.0, rng.f32() * 6.0, rng.f32() * 5.0).floor())
        .collect();
    for _ in 0..2000 {
        let p = if rng.u32(0..8) == 0 {
            Vec3::new(rng.f32() * 8.0, rng.f32() * 7.0, rng.f32() * 6.0)
        } else {
            cells[rng.usize(0..cells.len())] + Vec3::new(rng.f32(), rng.f32(), rng.f32())
        };
        let want = vol.gradient(p);
        assert_eq!(cache.gradient(&vol, p).to_array(), want.to_array(), "{p}");
    }
}
