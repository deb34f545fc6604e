//! Metaballs (SPEC §8, issue 14): hit points against closed forms and an
//! independent f64 dense march, normals, candidate lists, renderers.

use glam::{DVec3, Vec3};
use raycaster::camera::{Camera, Projection};
use raycaster::metaballs::internals::{RayParams, Scratch, TileLists, first_hit, gradient};
use raycaster::metaballs::{
    Ball, Balls, Extraction, Kernel, MetaballOptions, MetaballRenderer, ROOT_TOLERANCE, TILE,
};
use raycaster::prelude::*;

/// The frame's candidate lists, as the renderer builds them.
fn setup(balls: &Balls, camera: &Camera) -> TileLists {
    let f = camera.frame().unwrap();
    TileLists::build(balls, &f, camera.width, camera.height, TILE, |_| Vec3::ONE).unwrap()
}

/// The ray parameters the renderer uses (unshaded).
fn params<'a>(
    lists: &'a TileLists,
    balls: &Balls,
    kernel: Kernel,
    threshold: f64,
) -> RayParams<'a> {
    let (lo, hi) = balls
        .as_slice()
        .iter()
        .fold((f64::MAX, 0.0f64), |(l, h), b| {
            (l.min(b.radius as f64), h.max(b.radius as f64))
        });
    RayParams::new(
        &lists.balls,
        kernel,
        threshold,
        hi,
        ROOT_TOLERANCE * lo / hi,
    )
}

/// Each pixel's ray, its tile's candidates, and the hit (`None`: miss).
fn hits(
    camera: &Camera,
    lists: &TileLists,
    p: &RayParams<'_>,
) -> Vec<(u32, u32, raycaster::geometry::Ray, Option<f64>)> {
    let f = camera.frame().unwrap();
    let mut s = Scratch::default();
    let mut out = Vec::new();
    for j in 0..camera.height {
        for i in 0..camera.width {
            let ray = f.ray(i, j);
            let cands = lists.candidates(i / lists.tile, j / lists.tile);
            out.push((i, j, ray, first_hit(p, &ray, cands, &mut s).t));
        }
    }
    out
}

/// The field of `balls` at `x`, in f64 directly from the kernel's formula.
fn field(balls: &[Ball], kernel: Kernel, x: DVec3) -> f64 {
    balls
        .iter()
        .map(|b| {
            let a = (x - b.center.as_dvec3()).length() / b.radius as f64;
            if a >= 1.0 {
                0.0
            } else {
                match kernel {
                    Kernel::Wyvill => {
                        1.0 - 22.0 / 9.0 * a.powi(2) + 17.0 / 9.0 * a.powi(4)
                            - 4.0 / 9.0 * a.powi(6)
                    }
                    Kernel::Murakami => (1.0 - a * a).powi(2),
                }
            }
        })
        .sum()
}

/// The reference: march `F − T` along the ray in steps of `step` from 0 to
/// `t_max`, bisect the first sign change to 1e-12.
fn reference_hit(
    balls: &[Ball],
    kernel: Kernel,
    threshold: f64,
    o: DVec3,
    d: DVec3,
    step: f64,
    t_max: f64,
) -> Option<f64> {
    let g = |t: f64| field(balls, kernel, o + t * d) - threshold;
    assert!(g(0.0) < 0.0);
    let mut t0 = 0.0;
    while t0 < t_max {
        let t1 = t0 + step;
        if g(t1) >= 0.0 {
            let (mut a, mut b) = (t0, t1);
            while b - a > 1e-12 {
                let m = 0.5 * (a + b);
                if g(m) >= 0.0 { b = m } else { a = m }
            }
            return Some(b);
        }
        t0 = t1;
    }
    None
}

#[test]
fn one_ball_is_the_analytic_sphere_with_radial_normals() {
    for kernel in [Kernel::Wyvill, Kernel::Murakami] {
        for (threshold, proj) in [
            (0.5, Projection::Perspective),
            (0.2, Projection::Orthographic),
        ] {
            let c = Vec3::new(0.3, -0.2, 0.1);
            let r = 2.0f32;
            let balls = Balls::new(
                vec![Ball {
                    center: c,
                    radius: r,
                    value: 0.0,
                }],
                false,
            )
            .unwrap();
            let mut cam = Camera::look_at(Vec3::new(1.0, 2.0, 8.0), Vec3::ZERO, 64, 48);
            cam.projection = proj;
            let lists = setup(&balls, &cam);
            let p = params(&lists, &balls, kernel, threshold);
            let rho = kernel.level_radius(threshold).unwrap() * r as f64;
            let mut hit_count = 0;
            for (i, j, ray, t) in hits(&cam, &lists, &p) {
                let o = ray.origin.as_dvec3();
                let d = ray.dir.as_dvec3();
                let oc = c.as_dvec3() - o;
                let b = oc.dot(d);
                let h2 = (oc - b * d).length_squared();
                let analytic = (h2 < rho * rho).then(|| b - (rho * rho - h2).sqrt());
                match (t, analytic) {
                    (Some(t), Some(a)) => {
                        assert!(
                            (t - a).abs() < 1e-3 * r as f64,
                            "{kernel:?} {i},{j}: {t} vs {a}"
                        );
                        // The normal (−∇F) is radial.
                        let x = o + t * d;
                        let cands = lists.candidates(i / TILE, j / TILE);
                        let n = -gradient(&p, x, cands).normalize();
                        let radial = (x - c.as_dvec3()).normalize();
                        assert!(
                            n.dot(radial) > 1.0 - 1e-6,
                            "{kernel:?} {i},{j}: {n} vs {radial}"
                        );
                        hit_count += 1;
                    }
                    (None, None) => {}
                    // Grazing rays: within the tolerance of the silhouette.
                    (got, want) => {
                        let grazing = (h2.sqrt() - rho).abs() < 1e-3 * r as f64;
                        assert!(
                            grazing,
                            "{kernel:?} {i},{j}: {got:?} vs {want:?}, h {}",
                            h2.sqrt()
                        );
                    }
                }
            }
            assert!(hit_count > 100, "{kernel:?}: {hit_count}");
        }
    }
}

#[test]
fn two_overlapping_balls_match_a_dense_f64_march() {
    for kernel in [Kernel::Wyvill, Kernel::Murakami] {
        let balls = vec![
            Ball {
                center: Vec3::new(-0.55, 0.0, 0.0),
                radius: 1.0,
                value: 0.0,
            },
            Ball {
                center: Vec3::new(0.55, 0.1, -0.2),
                radius: 0.8,
                value: 0.0,
            },
        ];
        let set = Balls::new(balls.clone(), false).unwrap();
        let threshold = 0.45;
        for pos in [Vec3::new(0.2, 0.5, 4.0), Vec3::new(3.0, 1.5, 0.5)] {
            let mut cam = Camera::look_at(pos, Vec3::ZERO, 40, 32);
            cam.fov_y_deg = 50.0;
            let lists = setup(&set, &cam);
            let p = params(&lists, &set, kernel, threshold);
            let r_min = 0.8;
            let mut n_hits = 0;
            for (i, j, ray, t) in hits(&cam, &lists, &p) {
                let (o, d) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
                let want = reference_hit(&balls, kernel, threshold, o, d, 2e-3, 10.0);
                match (t, want) {
                    (Some(t), Some(w)) => {
                        assert!(
                            (t - w).abs() < 1e-3 * r_min,
                            "{kernel:?} {i},{j}: {t} vs {w}"
                        );
                        n_hits += 1;
                    }
                    (None, None) => {}
                    (None, Some(w)) => {
                        panic!("{kernel:?} {i},{j}: missed the reference hit at {w}")
                    }
                    (Some(t), None) => {
                        // Only a grazing hit the march stepped over.
                        let g = field(&balls, kernel, o + t * d) - threshold;
                        assert!(
                            g.abs() < 1e-6,
                            "{kernel:?} {i},{j}: hit at {t} where F − T = {g}"
                        );
                    }
                }
            }
            assert!(n_hits > 80, "{kernel:?}: {n_hits}");
        }
    }
}

#[test]
fn the_neck_of_two_balls_is_the_root_of_the_1d_field() {
    // Two equal balls at x = ±h: in the plane x = 0 the surface is the
    // circle of radius y* with 2·K(√(h² + y*²)/R) = T.
    let (h, r, threshold) = (0.6f64, 1.0f64, 0.6f64);
    let kernel = Kernel::Wyvill;
    let balls = Balls::new(
        vec![
            Ball {
                center: Vec3::new(-h as f32, 0.0, 0.0),
                radius: r as f32,
                value: 0.0,
            },
            Ball {
                center: Vec3::new(h as f32, 0.0, 0.0),
                radius: r as f32,
                value: 0.0,
            },
        ],
        false,
    )
    .unwrap();
    let (mut lo, mut hi) = (0.0f64, (r * r - h * h).sqrt());
    for _ in 0..200 {
        let y = 0.5 * (lo + hi);
        if 2.0 * kernel.at((h * h + y * y).sqrt() / r) > threshold {
            lo = y
        } else {
            hi = y
        }
    }
    let neck = 0.5 * (lo + hi);
    assert!(neck > 0.1);
    // A camera on the +y axis looking down at the origin: the centre ray
    // meets the neck at distance 5 − y*.
    let mut cam = Camera::look_at(Vec3::new(0.0, 5.0, 0.0), Vec3::ZERO, 33, 33);
    cam.up = Vec3::Z;
    let lists = setup(&balls, &cam);
    let p = params(&lists, &balls, kernel, threshold);
    let f = cam.frame().unwrap();
    let ray = f.ray(16, 16);
    let t = first_hit(
        &p,
        &ray,
        lists.candidates(16 / TILE, 16 / TILE),
        &mut Scratch::default(),
    )
    .t
    .unwrap();
    assert!((t - (5.0 - neck)).abs() < 1e-3 * r, "{t} vs {}", 5.0 - neck);
}

fn lattice(n: u32, radius: f32, values: bool) -> Balls {
    let mut v = Vec::new();
    for x in 0..n {
        for y in 0..n {
            for z in 0..n {
                let p = Vec3::new(x as f32, y as f32, z as f32) / (n - 1) as f32;
                v.push(Ball {
                    center: p,
                    radius,
                    value: (x * 40 + y * 7 + z * 3) as f32,
                });
            }
        }
    }
    Balls::new(v, values).unwrap()
}

#[test]
fn every_renderer_and_thread_count_gives_the_same_image() {
    let balls = lattice(5, 0.2, true);
    let tf = TransferFunction::preset("ramp", SampleType::U8).unwrap();
    let cam = Camera::look_at(Vec3::new(1.6, 1.2, 2.4), Vec3::splat(0.5), 90, 70);
    let mut options = MetaballOptions {
        lights: vec![Vec3::new(1.0, 1.0, 1.0), Vec3::new(-1.0, 0.2, 0.5)],
        ..MetaballOptions::default()
    };
    let reference = MetaballRenderer::new(RendererKind::Serial, 1)
        .unwrap()
        .render(&balls, &cam, Some(&tf), &options)
        .unwrap()
        .0;
    assert!(reference.stats.covered > 1000, "{:?}", reference.stats);
    for kind in RendererKind::ALL {
        for threads in [1, 2, 3] {
            let (frame, _) = MetaballRenderer::new(kind, threads)
                .unwrap()
                .render(&balls, &cam, Some(&tf), &options)
                .unwrap();
            assert_eq!(frame.rgb, reference.rgb, "{kind:?} with {threads} threads");
            assert_eq!(frame.stats.covered, reference.stats.covered);
            assert_eq!(frame.stats.samples, reference.stats.samples);
        }
    }
    // Flat colour: the shaded image differs, the covered pixels do not.
    options.shading = false;
    let flat = MetaballRenderer::new(RendererKind::Tiles, 2)
        .unwrap()
        .render(&balls, &cam, Some(&tf), &options)
        .unwrap()
        .0;
    assert_ne!(flat.rgb, reference.rgb);
    assert_eq!(flat.stats.covered, reference.stats.covered);
}

#[test]
fn colours_blend_the_balls_values_and_white_without_values() {
    let balls = Balls::new(
        vec![
            Ball {
                center: Vec3::new(-1.0, 0.0, 0.0),
                radius: 1.0,
                value: 0.0,
            },
            Ball {
                center: Vec3::new(1.0, 0.0, 0.0),
                radius: 1.0,
                value: 255.0,
            },
        ],
        true,
    )
    .unwrap();
    // A TF from black at 0 to red at 255.
    let tf = TransferFunction::new(
        Interpolation::Linear,
        vec![
            TfPoint {
                value: 0.0,
                color: [0.0, 0.0, 0.0],
                opacity: 1.0,
            },
            TfPoint {
                value: 255.0,
                color: [1.0, 0.0, 0.0],
                opacity: 1.0,
            },
        ],
    )
    .unwrap();
    let cam = Camera::look_at(Vec3::new(0.0, 0.0, 6.0), Vec3::ZERO, 64, 32);
    // Ball centres at pixel columns 38.4 and 25.6, surfaces ±3 pixels.
    let options = MetaballOptions {
        shading: false,
        background: Vec3::splat(0.5),
        ..MetaballOptions::default()
    };
    let mut r = MetaballRenderer::new(RendererKind::Serial, 1).unwrap();
    let (frame, _) = r.render(&balls, &cam, Some(&tf), &options).unwrap();
    assert_eq!(frame.pixel(2, 16), [128, 128, 128]);
    let left = frame.pixel(25, 16);
    let right = frame.pixel(38, 16);
    assert_eq!(left, [0, 0, 0], "left ball is black");
    assert_eq!(right, [255, 0, 0], "right ball is red");
    // Without values (or without a TF): white.
    let (frame, _) = r.render(&balls, &cam, None, &options).unwrap();
    assert_eq!(frame.pixel(25, 16), [255, 255, 255]);
}

#[test]
fn a_volume_becomes_balls_and_renders() {
    let grid = Grid::new(glam::UVec3::splat(20), Vec3::ONE);
    let vol = AnyVolume::from_fn(grid, |v| {
        if (v.as_vec3() - Vec3::splat(9.5)).length() < 6.0 {
            180u8
        } else {
            10
        }
    });
    let mut want = 0;
    for x in (0..20).step_by(2) {
        for y in (0..20).step_by(2) {
            for z in (0..20).step_by(2) {
                want += ((Vec3::new(x as f32, y as f32, z as f32) - Vec3::splat(9.5)).length()
                    < 6.0) as usize;
            }
        }
    }
    let ex = Extraction {
        threshold: 100.0,
        stride: 2,
        radius: None,
        max_balls: None,
    };
    let balls = Balls::from_volume(&vol, &ex).unwrap();
    assert_eq!(balls.len(), want);
    let cam = Camera::framing(&grid.bounds(), 48, 48, 45.0);
    let (frame, _) = MetaballRenderer::new(RendererKind::Tiles, 2)
        .unwrap()
        .render(&balls, &cam, None, &MetaballOptions::default())
        .unwrap();
    assert!(frame.pixel(24, 24)[0] > 50);
    assert_eq!(frame.pixel(0, 0), [0, 0, 0]);
    // The cap.
    let ex = Extraction {
        max_balls: Some(want - 1),
        ..ex
    };
    assert!(matches!(
        Balls::from_volume(&vol, &ex),
        Err(raycaster::Error::TooManyBalls { .. })
    ));
}

#[test]
fn volume_renderers_reject_the_metaballs_mode() {
    let grid = Grid::new(glam::UVec3::splat(8), Vec3::ONE);
    let scene = Scene::new(AnyVolume::from_fn(grid, |_| 1u8));
    let cam = Camera::framing(&grid.bounds(), 16, 16, 45.0);
    let tf = TransferFunction::preset("ramp", SampleType::U8).unwrap();
    let options = RenderOptions {
        mode: RenderMode::Metaballs,
        ..RenderOptions::default()
    };
    for kind in RendererKind::ALL {
        let e = kind
            .renderer(1)
            .unwrap()
            .render(&scene, &cam, &tf, &options)
            .unwrap_err();
        assert!(e.to_string().contains("MetaballRenderer"), "{e}");
    }
}

/// A small ball above a large one (their supports apart), lit from above:
/// with shadows the top of the large ball under the small one darkens,
/// a point of it well outside the shadow does not, no pixel brightens,
/// and every renderer gives the same image.
#[test]
fn a_ball_above_another_casts_its_shadow_on_it() {
    let balls = Balls::new(
        vec![
            Ball {
                center: Vec3::ZERO,
                radius: 1.0,
                value: 0.0,
            },
            Ball {
                center: Vec3::new(0.0, 1.8, 0.0),
                radius: 0.5,
                value: 0.0,
            },
        ],
        false,
    )
    .unwrap();
    let cam = Camera::look_at(Vec3::new(0.0, 2.2, 3.5), Vec3::new(0.0, 0.4, 0.0), 160, 160);
    let mut options = MetaballOptions {
        lights: vec![Vec3::Y],
        ..MetaballOptions::default()
    };
    let render = |kind, threads, options: &MetaballOptions| {
        MetaballRenderer::new(kind, threads)
            .unwrap()
            .render(&balls, &cam, None, options)
            .unwrap()
            .0
    };
    let lit = render(RendererKind::Serial, 1, &options);
    options.shadows = true;
    let shadowed = render(RendererKind::Serial, 1, &options);
    for kind in RendererKind::ALL {
        for threads in [1, 2] {
            assert_eq!(
                render(kind, threads, &options).rgb,
                shadowed.rgb,
                "{kind:?} {threads}"
            );
        }
    }
    // The lower ball's surface radius: Wyvill's kernel at T = 0.5.
    let r_low = Kernel::Wyvill.level_radius(0.5).unwrap() as f32;
    let frame = cam.frame().unwrap();
    let pixel = |p: Vec3| {
        let (x, y) = frame.project(p).unwrap();
        let k = 3 * (y as usize * 160 + x as usize);
        (lit.rgb[k..k + 3].to_vec(), shadowed.rgb[k..k + 3].to_vec())
    };
    // Right under the small ball, and 50° away from the top towards the camera.
    let (a, b) = pixel(Vec3::new(0.0, r_low, 0.0));
    assert!(b.iter().zip(&a).all(|(s, l)| s < l), "top: {a:?} -> {b:?}");
    let side = Vec3::new(0.0, 50f32.to_radians().cos(), 50f32.to_radians().sin()) * r_low;
    let (a, b) = pixel(side);
    assert_eq!(a, b, "outside the shadow");
    assert!(lit.rgb.iter().zip(&shadowed.rgb).all(|(l, s)| s <= l));
}
