//! One ray through the field `F = Σ K(|p − cᵢ|/Rᵢ)`: the first point where
//! `F` reaches the threshold, and its colour.
//!
//! The ray takes its tile's candidates in `t_lo` order, as they can
//! matter: a candidate is tested (ray against sphere) only once the sweep
//! has reached its `t_lo`. Each ball the ray meets gives an entry and an
//! exit event; between consecutive events the set of active balls is fixed,
//! so `F − T` is a polynomial in `t` there (degree 6 for Wyvill, 4 for
//! Murakami). The running sum is kept in the coordinate `x = (t − t₀)/S`
//! of the current interval start `t₀` (`S` the largest radius): it is
//! Taylor-shifted to each event and a ball's polynomial is added at its
//! entry and subtracted at its exit (the sum resets to 0 when no ball is
//! active). The first root in an interval is isolated with Bernstein bounds
//! ([`poly::first_root`]), to `1e-4·R_min`.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use glam::{DVec3, Vec3, Vec4};

use super::kernel::{Kernel, MAX_TERMS, Poly};
use super::poly;
use super::tiles::FrameBall;
use crate::geometry::Ray;
use crate::integrator::Phong;

/// A ray's entry into or exit from a ball, as one integer ordered like
/// `(t, exit before entry, slot)`: `t >= 0`, whose bits order as the
/// numbers do, in the high 64 bits; below them `!exit` and the slot (an
/// index into the ray's `met` list). Popped smallest first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Event(u128);

impl Event {
    #[inline]
    fn new(t: f64, slot: u32, exit: bool) -> Self {
        debug_assert!(t >= 0.0);
        // +0.0 for −0.0, so that the bits order as the numbers.
        let t = t + 0.0;
        Event(((t.to_bits() as u128) << 64) | ((!exit as u128) << 32) | slot as u128)
    }

    #[inline]
    fn t(self) -> f64 {
        f64::from_bits((self.0 >> 64) as u64)
    }

    #[inline]
    fn slot(self) -> u32 {
        self.0 as u32
    }

    #[inline]
    fn exit(self) -> bool {
        (self.0 >> 32) & 1 == 0
    }
}

/// A ball the ray meets: `b = (c − o)·d`, `h2` the squared distance of the
/// centre from the ray's line.
#[derive(Debug, Clone, Copy)]
struct Met {
    ball: u32,
    b: f64,
    h2: f64,
}

/// Per-thread buffers reused from ray to ray.
#[derive(Debug, Default)]
pub struct Scratch {
    heap: BinaryHeap<Reverse<Event>>,
    met: Vec<Met>,
}

/// What a frame's rays share.
#[derive(Debug, Clone, Copy)]
pub struct RayParams<'a> {
    /// The frame's balls.
    pub balls: &'a [FrameBall],
    /// The kernel.
    pub kernel: Kernel,
    /// The surface's field value `T` (> 0).
    pub threshold: f64,
    /// The polynomial coordinate's unit (the largest radius).
    pub scale: f64,
    /// Root tolerance in `x` units.
    pub tol: f64,
    /// Phong coefficients, `None`: flat colour.
    pub shading: Option<Phong>,
    /// Unit directions towards the lights; empty: a headlight.
    pub lights: &'a [Vec3],
}

/// A ray's result.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RayResult {
    /// The hit's `t`, `None` for a miss.
    pub t: Option<f64>,
    /// Balls the ray met (before stopping).
    pub met: u32,
}

/// The first `t >= 0` where the field of the `candidates` (indices into
/// `p.balls`, in `t_lo` order) crosses the threshold along `ray`.
pub fn first_hit(p: &RayParams<'_>, ray: &Ray, candidates: &[u32], s: &mut Scratch) -> RayResult {
    s.heap.clear();
    s.met.clear();
    let o = ray.origin.as_dvec3();
    let d = ray.dir.as_dvec3();
    let n = p.kernel.degree();
    let mut poly: Poly = [0.0; MAX_TERMS];
    let mut active = 0u32;
    let mut t_cur = 0.0f64;
    // +1: search for F − T rising through 0; −1 when the ray starts inside.
    let mut sign: Option<f64> = None;
    let mut next = 0usize;
    loop {
        // Take every candidate that may enter before the next event.
        while next < candidates.len() {
            let k = candidates[next];
            let fb = &p.balls[k as usize];
            if let Some(e) = s.heap.peek()
                && fb.t_lo > e.0.t()
            {
                break;
            }
            next += 1;
            let oc = fb.center - o;
            let b = oc.dot(d);
            let h2 = (oc - b * d).length_squared();
            if h2 >= fb.r2 {
                continue;
            }
            let half = (fb.r2 - h2).sqrt();
            let (t0, t1) = (b - half, b + half);
            if t1 <= t_cur {
                continue;
            }
            let slot = s.met.len() as u32;
            s.met.push(Met { ball: k, b, h2 });
            s.heap.push(Reverse(Event::new(t0.max(t_cur), slot, false)));
            s.heap.push(Reverse(Event::new(t1, slot, true)));
        }
        let Some(Reverse(ev)) = s.heap.pop() else {
            return RayResult {
                t: None,
                met: s.met.len() as u32,
            };
        };
        // The interval [t_cur, ev.t()] with the active set fixed.
        if active > 0 && ev.t() > t_cur {
            let len = (ev.t() - t_cur) / p.scale;
            let mut q = poly;
            q[0] -= p.threshold;
            let sg = *sign.get_or_insert(if q[0] > 0.0 { -1.0 } else { 1.0 });
            if sg < 0.0 {
                q.iter_mut().for_each(|c| *c = -*c);
            }
            if let Some(x) = poly::first_root(&q, n, len, p.tol) {
                return RayResult {
                    t: Some(t_cur + x * p.scale),
                    met: s.met.len() as u32,
                };
            }
        }
        if active > 0 {
            poly::shift(&mut poly, n, (ev.t() - t_cur) / p.scale);
        }
        t_cur = ev.t();
        let m = s.met[ev.slot() as usize];
        let fb = &p.balls[m.ball as usize];
        // s(x) = ((t_cur + S·x − b)² + h2)/R².
        let e = t_cur - m.b;
        let sc = p.scale;
        let q = [
            (e * e + m.h2) * fb.inv_r2,
            2.0 * sc * e * fb.inv_r2,
            sc * sc * fb.inv_r2,
        ];
        let kp = p.kernel.compose(q);
        if ev.exit() {
            active -= 1;
            if active == 0 {
                poly = [0.0; MAX_TERMS];
            } else {
                for (a, c) in poly.iter_mut().zip(kp) {
                    *a -= c;
                }
            }
        } else {
            active += 1;
            for (a, c) in poly.iter_mut().zip(kp) {
                *a += c;
            }
        }
    }
}

/// The colour at the hit `t` of `ray` found by [`first_hit`] with `s`: the
/// balls' colours blended by their kernel weights, Phong-shaded with the
/// gradient of the field as normal (two-sided), flat without shading.
/// Premultiplied, opaque.
pub fn shade(p: &RayParams<'_>, ray: &Ray, t: f64, s: &Scratch) -> Vec4 {
    let o = ray.origin.as_dvec3();
    let d = ray.dir.as_dvec3();
    let x = o + t * d;
    let mut grad = DVec3::ZERO;
    let mut color = Vec3::ZERO;
    let mut weight = 0.0f64;
    // Every ball active at the hit was met before it.
    for m in &s.met {
        let fb = &p.balls[m.ball as usize];
        let v = x - fb.center;
        let s = v.length_squared() * fb.inv_r2;
        if s >= 1.0 {
            continue;
        }
        let w = p.kernel.at_s(s);
        grad += (p.kernel.ds_at_s(s) * 2.0 * fb.inv_r2) * v;
        color += fb.color * w as f32;
        weight += w;
    }
    let c = if weight > 0.0 {
        color / weight as f32
    } else {
        Vec3::ONE
    };
    let rgb = match &p.shading {
        None => c,
        Some(ph) => {
            // The field falls outwards: the outward normal is −∇F.
            let len = grad.length();
            if len > 0.0 && len.is_finite() {
                let view = -ray.dir;
                let n = (-grad / len).as_vec3();
                let n = if n.dot(view) < 0.0 { -n } else { n };
                let headlight = [view];
                let lights = if p.lights.is_empty() {
                    &headlight[..]
                } else {
                    p.lights
                };
                let mut rgb = c * ph.ka;
                for &l in lights {
                    let (diffuse, spec) = ph.light(n, l, view);
                    rgb += c * diffuse + Vec3::splat(spec);
                }
                rgb
            } else {
                c * ph.ka
            }
        }
    };
    rgb.extend(1.0)
}

/// `∇F` at `x` from the `candidates` (for tests: the normal's direction).
pub fn gradient(p: &RayParams<'_>, x: DVec3, candidates: &[u32]) -> DVec3 {
    let mut grad = DVec3::ZERO;
    for &k in candidates {
        let fb = &p.balls[k as usize];
        let v = x - fb.center;
        let s = v.length_squared() * fb.inv_r2;
        grad += (p.kernel.ds_at_s(s) * 2.0 * fb.inv_r2) * v;
    }
    grad
}
