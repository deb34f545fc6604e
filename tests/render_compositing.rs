//! Compositing with analytic answers: the opacity of a
//! homogeneous medium and of a slab of known thickness, where ERT stops, MIP
//! of known maxima, `avg` and the `ramp` preset across sample types, and step
//! TFs over wide value spans.

mod common;

use common::scenes::{down_camera, opts, render, tf_points, u8_volume, white_linear_tf};
use glam::{UVec3, Vec3};
use raycaster::prelude::*;

// ------------------------------------------------------- opacity of media

/// Samples `t_in + k·s <= t_in + len` (k = 0, 1, …) on a chord of length `len`.
fn samples_on_chord(len: f64, s: f64) -> u32 {
    let mut n = 0;
    while n as f64 * s <= len + 1e-9 {
        n += 1;
    }
    n
}

/// A homogeneous volume (every voxel 100) with a white TF of constant opacity
/// `a`: the centre ray crosses L = 20 world units, takes n = floor(L/s) + 1
/// samples, each of opacity α = 1 − (1 − a)^s, so A = 1 − (1 − α)^n =
/// 1 − (1 − a)^(s·n), which exceeds the continuous 1 − (1 − a)^L by at most
/// (1 − a)^L·(1 − (1 − a)^s).
#[test]
fn homogeneous_medium_has_the_spec_opacity() {
    // Box [0, 32]² × [0, 20]; the camera at z = 100 gives t_in = 80, t_out = 100,
    // both exact in f32, so steps dividing 20 put the last sample on t_out.
    let scene = Scene::new(u8_volume([33, 33, 21], Vec3::ONE, |_| 100));
    let len = 20.0f64;
    let mut worst_cont = 0.0f64;
    for projection in [Projection::Perspective, Projection::Orthographic] {
        let cam = down_camera(16.0, 16.0, 100.0, projection);
        for a in [0.02f32, 0.05, 0.2, 0.5] {
            let tf = white_linear_tf(a);
            for s in [0.25f32, 0.3, 0.5, 0.7, 1.0, 1.3, 2.5, 3.0, 7.0] {
                let o = opts(RenderMode::Dvr, s);
                let px = render(&scene, &cam, &tf, &o).pixel(16, 16);
                let (a64, s64) = (a as f64, s as f64);
                let n = samples_on_chord(len, s64);
                let alpha = 1.0 - (1.0 - a64).powf(s64);
                let expect = 1.0 - (1.0 - alpha).powi(n as i32);
                assert!(
                    ((1.0 - (1.0 - a64).powf(s64 * n as f64)) - expect).abs() < 1e-12,
                    "algebra"
                );
                for ch in px {
                    assert!(
                        (ch as f64 - 255.0 * expect).abs() <= 1.0,
                        "{projection:?} a {a} s {s}: n = {n}, expected A = {expect:.5} \
                         ({:.1}/255), pixel {px:?}",
                        255.0 * expect
                    );
                }
                // Approaches the continuous answer within the discretisation bound.
                let cont = 1.0 - (1.0 - a64).powf(len);
                let bound = (1.0 - a64).powf(len) * (1.0 - (1.0 - a64).powf(s64));
                let got = px[0] as f64 / 255.0;
                assert!(
                    got - cont >= -1.0 / 255.0 && got - cont <= bound + 1.0 / 255.0,
                    "a {a} s {s}: A = {got:.4}, continuous {cont:.4}, bound {bound:.4}"
                );
                if s <= 0.3 {
                    worst_cont = worst_cont.max((got - cont).abs());
                }
            }
        }
    }
    // At small steps the discrete answer is within ~1.5% of the continuous one.
    assert!(worst_cont < 0.015, "{worst_cont}");
}

/// ERT stops at the first sample where A >= threshold: with a homogeneous
/// medium that is A_k* = 1 − (1 − α)^k* for the first such k*.
#[test]
fn ert_stops_at_the_first_sample_over_the_threshold() {
    let scene = Scene::new(u8_volume([33, 33, 21], Vec3::ONE, |_| 100));
    let cam = down_camera(16.0, 16.0, 100.0, Projection::Perspective);
    let mut checked = 0;
    for a in [0.3f32, 0.5, 0.8] {
        let tf = white_linear_tf(a);
        for s in [0.3f32, 0.5, 1.0] {
            for thr in [0.5f32, 0.9, 0.99] {
                let alpha = 1.0 - (1.0 - a as f64).powf(s as f64);
                let n = samples_on_chord(20.0, s as f64);
                let acc = |k: u32| 1.0 - (1.0 - alpha).powi(k as i32);
                let k_stop = (1..=n).find(|&k| acc(k) >= thr as f64).unwrap_or(n);
                if (1..=n).any(|k| (acc(k) - thr as f64).abs() < 1e-4) {
                    continue; // some A_k too close to the threshold to call in f32
                }
                let o = RenderOptions {
                    ert: true,
                    ert_threshold: thr,
                    ..opts(RenderMode::Dvr, s)
                };
                let frame = render(&scene, &cam, &tf, &o);
                let px = frame.pixel(16, 16);
                let expect = 255.0 * acc(k_stop);
                assert!(
                    (px[0] as f64 - expect).abs() <= 1.0,
                    "a {a} s {s} thr {thr}: stop after {k_stop} samples, A = {expect:.1}/255, got {px:?}"
                );
                checked += 1;
            }
        }
    }
    assert!(checked > 20);
}

/// A slab of value 200 for voxel z in [10, 20] (0 elsewhere) under a step TF
/// visible from 50: the interpolated value is >= 50 exactly for
/// z ∈ [9.25, 20.75], so the samples counted are those z_k = 30 − k·s in that
/// interval (boundaries included) and A = 1 − (1 − α)^count.
#[test]
fn slab_of_known_thickness() {
    let scene = Scene::new(u8_volume([17, 17, 31], Vec3::ONE, |v| {
        if (10..=20).contains(&v.z) { 200 } else { 0 }
    }));
    let a = 0.1f32;
    let tf = tf_points(
        Interpolation::Step,
        &[(50.0, [1.0; 3], a), (250.0, [0.0; 3], 0.0)],
    );
    for ess in [false, true] {
        for s in [0.25f32, 0.3, 0.5, 0.75, 1.0, 1.5] {
            let cam = down_camera(8.0, 8.0, 100.0, Projection::Perspective);
            let o = RenderOptions {
                ess,
                ..opts(RenderMode::Dvr, s)
            };
            let px = render(&scene, &cam, &tf, &o).pixel(16, 16);
            let count = (0..)
                .map(|k| 30.0 - k as f64 * s as f64)
                .take_while(|&z| z >= 0.0)
                .filter(|&z| (9.25..=20.75).contains(&z))
                .count();
            let alpha = 1.0 - (1.0 - a as f64).powf(s as f64);
            let expect = 1.0 - (1.0 - alpha).powi(count as i32);
            assert!(
                (px[0] as f64 - 255.0 * expect).abs() <= 1.0,
                "s {s} ess {ess}: {count} samples in the slab, A = {expect:.4}, got {px:?}"
            );
            // 11.5 world units of medium.
            let cont = 1.0 - (1.0 - a as f64).powf(11.5);
            assert!(
                (px[0] as f64 / 255.0 - cont).abs() < 0.06,
                "s {s}: {px:?} vs {cont}"
            );
        }
    }
}

// ----------------------------------------------------------------------- MIP

/// MIP shows TF(max) composited once, C = a·c and A = a, with no step
/// correction, whatever the step.
#[test]
fn mip_is_the_tf_of_the_maximum_composited_once() {
    // A single bright voxel: the centre ray of an orthographic camera passes
    // through it and a sample lands on it (z_k = 20 − k/2 hits 10).
    let scene = Scene::new(u8_volume([21, 21, 21], Vec3::ONE, |v| {
        if v == UVec3::splat(10) { 200 } else { 0 }
    }));
    let colour = [1.0, 0.5, 0.25];
    let tf = tf_points(
        Interpolation::Linear,
        &[(0.0, colour, 0.0), (255.0, colour, 1.0)],
    );
    let cam = down_camera(10.0, 10.0, 100.0, Projection::Orthographic);
    for ess in [false, true] {
        for s in [0.5f32, 0.25, 1.0] {
            let o = RenderOptions {
                ess,
                ..opts(RenderMode::Mip, s)
            };
            let px = render(&scene, &cam, &tf, &o).pixel(16, 16);
            let a = 200.0 / 255.0;
            let want = colour.map(|c| (255.0 * a * c as f64).round() as u8);
            assert_eq!(px, want, "ess {ess} step {s}");
        }
    }

    // An affine field v = 2x + 3y + z is reproduced exactly by trilinear
    // interpolation; along a vertical ray its maximum is on the top face
    // z = 49, where the first sample lies: m = 2x + 3y + 49.
    let scene = Scene::new(u8_volume([40, 30, 50], Vec3::ONE, |v| {
        (2 * v.x + 3 * v.y + v.z) as u8
    }));
    let shapes = TransferFunction::preset("shapes", SampleType::U8).unwrap();
    let c255 = |c: [f64; 3], a: f64| c.map(|x| (a * x).round() as u8);
    for (x, y, want) in [
        // m = 96: the shapes TF gives (10, 60, 180)/255 with a = 0.3 — not
        // the step-corrected 1 − 0.7^s.
        (12.25f32, 7.5f32, c255([10.0, 60.0, 180.0], 0.3)),
        // m = 94: (255, 30, 60)/255, a = 0.02.
        (15.0, 5.0, c255([255.0, 30.0, 60.0], 0.02)),
        // m = 100 exactly: still blue (the bound is 100 < v for green).
        (13.5, 8.0, c255([10.0, 60.0, 180.0], 0.3)),
        // m = 101: (90, 210, 20)/255, a = 0.6.
        (14.0, 8.0, c255([90.0, 210.0, 20.0], 0.6)),
        // m = 122: transparent.
        (20.75, 10.5, [0, 0, 0]),
    ] {
        for projection in [Projection::Perspective, Projection::Orthographic] {
            for ess in [false, true] {
                let cam = down_camera(x, y, 120.0, projection);
                let o = RenderOptions {
                    ess,
                    ..opts(RenderMode::Mip, 0.7)
                };
                let px = render(&scene, &cam, &shapes, &o).pixel(16, 16);
                assert_eq!(px, want, "({x}, {y}) {projection:?} ess {ess}");
            }
        }
    }
}

// -------------------------------------------------------------- sample types

/// `avg` divides the mean by the sample type's maximum, and the `ramp`
/// preset spans the type's range.
#[test]
fn avg_and_ramp_follow_the_sample_type() {
    let dims = [9u32, 9, 9];
    let grid = Grid::new(UVec3::from_array(dims), Vec3::ONE);
    let cam = down_camera(4.0, 4.0, 50.0, Projection::Perspective);
    let avg = opts(RenderMode::Avg, 0.5);
    let grey = |scene: &Scene, t: SampleType| {
        let tf = TransferFunction::preset("ramp", t).unwrap();
        render(scene, &cam, &tf, &avg).pixel(16, 16)
    };
    let s = Scene::new(AnyVolume::from_fn(grid, |_| 30000u16));
    let g = (255.0 * 30000.0 / 65535.0f64).round() as u8;
    assert_eq!(grey(&s, SampleType::U16), [g; 3], "u16");
    let s = Scene::new(AnyVolume::from_fn(grid, |_| 1000i16));
    let g = (255.0 * 1000.0 / 32767.0f64).round() as u8;
    assert_eq!(grey(&s, SampleType::I16), [g; 3], "i16");
    let s = Scene::new(AnyVolume::from_fn(grid, |_| 0.25f32));
    assert_eq!(grey(&s, SampleType::F32), [64; 3], "f32");
    // MIP with the u16 ramp: a = c = 30000/65535.
    let s = Scene::new(AnyVolume::from_fn(grid, |_| 30000u16));
    let tf = TransferFunction::preset("ramp", SampleType::U16).unwrap();
    let px = render(&s, &cam, &tf, &opts(RenderMode::Mip, 0.5)).pixel(16, 16);
    let g = (255.0 * 30000.0 / 65535.0f64).round() as u8;
    assert_eq!(px, [g; 3]);
}

/// LIBRARY BUG (a step TF gives the RGBA of the last point whose value is
/// <= v): DVR looks the TF up in a table (`TfLut`) with `scale` entries per
/// value unit, a power of two chosen to keep ~4096 entries. When the TF's
/// points span more than 4096 value units (u16 data, or i16 CT data with a
/// wide TF), the scale drops below 1 (1/16 for a span near 65535), and a step
/// point that is not on a table boundary (here 1010, boundaries every 16
/// units from 1000) takes effect only at the next boundary (1016): values in
/// [1010, 1016) get the previous point's colour. The table's own doc claims
/// step TFs are exact; that holds only for spans <= 4096.
///
/// Homogeneous u16 volume of value 1012, TF step 1000 → red, 1010 → green,
/// 60000 → transparent: the image must be green (MIP, which evaluates the
/// TF exactly, is green; DVR is red).
#[test]
fn step_tf_is_exact_for_wide_value_spans() {
    let grid = Grid::new(UVec3::splat(9), Vec3::ONE);
    let scene = Scene::new(AnyVolume::from_fn(grid, |_| 1012u16));
    let tf = tf_points(
        Interpolation::Step,
        &[
            (1000.0, [1.0, 0.0, 0.0], 1.0),
            (1010.0, [0.0, 1.0, 0.0], 1.0),
            (60000.0, [0.0, 0.0, 0.0], 0.0),
        ],
    );
    let cam = down_camera(4.0, 4.0, 50.0, Projection::Perspective);
    let mip = render(&scene, &cam, &tf, &opts(RenderMode::Mip, 0.5)).pixel(16, 16);
    assert_eq!(mip, [0, 255, 0], "MIP evaluates the TF exactly");
    let dvr = render(&scene, &cam, &tf, &opts(RenderMode::Dvr, 0.5)).pixel(16, 16);
    assert_eq!(
        dvr,
        [0, 255, 0],
        "DVR shows the colour of TF(1012) = the point at 1010"
    );
}
