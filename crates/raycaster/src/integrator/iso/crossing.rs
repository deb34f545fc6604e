//! The first crossing of an iso value by the trilinear interpolant along a
//! ray inside one cell.
//!
//! Along a ray, the trilinear interpolant of a cell is a cubic in the ray
//! parameter (each of the three fractions is linear in it). The crossing is
//! found by root isolation rather than a closed formula: the cubic's extrema
//! (roots of its derivative, a quadratic) cut the interval into pieces on
//! which it is monotonic, and the first piece whose ends lie on different
//! sides of the iso value holds the first crossing, which Newton's method,
//! kept inside a shrinking bracket, then pins down. This finds two
//! crossings in one cell (which a linear estimate from the cell's entry and
//! exit values misses) and stays stable near double roots, where Cardano's
//! formula loses its digits.

use glam::Vec3;

use crate::volume::Corners;

/// `g(t) = f(t) − iso` along a ray inside one cell, `t` measured from the
/// point where the ray enters the cell: `a·t³ + b·t² + c·t + d`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellCubic {
    a: f32,
    b: f32,
    c: f32,
    d: f32,
}

impl CellCubic {
    /// `g = 0`: a placeholder.
    pub const ZERO: CellCubic = CellCubic {
        a: 0.0,
        b: 0.0,
        c: 0.0,
        d: 0.0,
    };

    /// The cubic of cell `corners` for the ray that is at fractions `p0`
    /// inside the cell at `t = 0` and moves by `dir` (cell units per unit of
    /// `t`), minus `iso`.
    #[inline(always)]
    pub fn new(corners: &Corners, p0: Vec3, dir: Vec3, iso: f32) -> Self {
        // Each fraction is u(t) = p0 + dir·t, and 1 − u(t) = (1 − p0) − dir·t.
        // Interpolating along x, then y, then z with these linear weights
        // multiplies polynomials: linear after x, quadratic after y, cubic
        // after z.
        let lin = |v0: f32, v1: f32, u0: f32, du: f32| {
            // v0·((1 − u0) − du·t) + v1·(u0 + du·t)
            (v0 + (v1 - v0) * u0, (v1 - v0) * du)
        };
        let x: [(f32, f32); 4] =
            std::array::from_fn(|jk| lin(corners[jk], corners[4 + jk], p0.x, dir.x));
        // (a0 + a1·t)·(w0 + w1·t) + (b0 + b1·t)·(s0 + s1·t) with
        // w = 1 − u and s = u along y.
        let (wy0, wy1, sy0, sy1) = (1.0 - p0.y, -dir.y, p0.y, dir.y);
        let y: [(f32, f32, f32); 2] = std::array::from_fn(|k| {
            let (a0, a1) = x[k];
            let (b0, b1) = x[2 + k];
            (
                a0 * wy0 + b0 * sy0,
                a0 * wy1 + a1 * wy0 + b0 * sy1 + b1 * sy0,
                a1 * wy1 + b1 * sy1,
            )
        });
        let (wz0, wz1, sz0, sz1) = (1.0 - p0.z, -dir.z, p0.z, dir.z);
        let ((a0, a1, a2), (b0, b1, b2)) = (y[0], y[1]);
        CellCubic {
            a: a2 * wz1 + b2 * sz1,
            b: a1 * wz1 + a2 * wz0 + b1 * sz1 + b2 * sz0,
            c: a0 * wz1 + a1 * wz0 + b0 * sz1 + b1 * sz0,
            d: a0 * wz0 + b0 * sz0 - iso,
        }
    }

    /// `g(t)`.
    #[inline(always)]
    pub fn eval(&self, t: f32) -> f32 {
        ((self.a * t + self.b) * t + self.c) * t + self.d
    }

    /// The roots of `g'(t) = 3a·t² + 2b·t + c` strictly inside `(0, len)`,
    /// in increasing order (`NaN` for a missing one).
    #[inline]
    fn extrema(&self, len: f32) -> [f32; 2] {
        let (qa, qb, qc) = (3.0 * self.a, 2.0 * self.b, self.c);
        let mut r = [f32::NAN; 2];
        let scale = qa.abs().max(qb.abs()).max(qc.abs());
        if scale == 0.0 {
            return r;
        }
        if qa.abs() <= 1e-7 * scale {
            // Effectively a quadratic g: one extremum.
            if qb != 0.0 {
                r[0] = -qc / qb;
            }
        } else {
            let disc = qb * qb - 4.0 * qa * qc;
            if disc < 0.0 {
                return r;
            }
            // The stable pair: q = −(b + sign(b)·√disc)/2, roots q/a and c/q.
            let s = disc.sqrt();
            let q = -0.5 * (qb + if qb >= 0.0 { s } else { -s });
            let (r0, r1) = (q / qa, if q != 0.0 { qc / q } else { f32::NAN });
            r = if r0 <= r1 { [r0, r1] } else { [r1, r0] };
        }
        for x in &mut r {
            if !(*x > 0.0 && *x < len) {
                *x = f32::NAN;
            }
        }
        if r[0].is_nan() {
            r = [r[1], f32::NAN];
        }
        r
    }

    /// The first `t` in `[0, len]` where `g` changes side (`g ≥ 0` against
    /// `g < 0`) relative to `g(0)`, to within `tol` in `t`; `None` when it
    /// stays on one side. `g(0)` itself decides the side it starts on.
    #[inline]
    pub fn first_crossing(&self, len: f32, tol: f32) -> Option<f32> {
        if self.stays_on(self.eval(0.0) >= 0.0, len) {
            return None;
        }
        self.first_crossing_unproven(len, tol)
    }

    /// [`CellCubic::first_crossing`] for a caller that has already tried
    /// `CellCubic::stays_on` on `[0, len]` with the side of `g(0)` and
    /// failed (the packets, for every lane): the same answer, without the
    /// proof tried twice.
    #[inline]
    pub fn first_crossing_unproven(&self, len: f32, tol: f32) -> Option<f32> {
        let g0 = self.eval(0.0);
        let side = g0 >= 0.0;
        // A cubic proven monotonic on the interval has no extremum inside
        // it: the search is the bracket [0, len], without the square root
        // and divisions of the extrema (most cells a ray hits in).
        let [e0, e1] = if self.monotonic(len) {
            [f32::NAN; 2]
        } else {
            self.extrema(len)
        };
        let (mut lo, mut g_lo) = (0.0f32, g0);
        for hi in [e0, e1, len] {
            if hi.is_nan() {
                continue;
            }
            let g_hi = self.eval(hi);
            if (g_hi >= 0.0) != side {
                return Some(self.refine((lo, g_lo), (hi, g_hi), side, tol));
            }
            (lo, g_lo) = (hi, g_hi);
        }
        None
    }

    /// [`CellCubic::first_crossing_unproven`] of the lanes in `open` of
    /// `cubics` at once: per lane the crossing's `t` in `[0, len]`, `NaN`
    /// where there is none (or for a lane not in `open`). Each lane goes
    /// through the scalar function's operations in its order, so it gets
    /// the same bits; its branches become selections, and the refinement
    /// runs until the last open lane is done, so the lanes' different
    /// paths cost no mispredicted branches.
    #[inline(always)]
    pub fn first_crossings_unproven<const N: usize>(
        cubics: &[CellCubic; N],
        len: &[f32; N],
        tol: &[f32; N],
        open: u32,
    ) -> [f32; N] {
        let mut out = [f32::NAN; N];
        // The bracket of each lane's first crossing: the first piece
        // between extrema whose ends lie on different sides.
        let mut side = [false; N];
        let mut lo = [0.0f32; N];
        let mut g_lo = [0.0f32; N];
        let mut hi = [0.0f32; N];
        let mut g_hi = [0.0f32; N];
        let mut bracketed = [false; N];
        for l in 0..N {
            let c = &cubics[l];
            let g0 = c.eval(0.0);
            side[l] = g0 >= 0.0;
            let [e0, e1] = if c.monotonic(len[l]) {
                [f32::NAN; 2]
            } else {
                c.extrema_selected(len[l])
            };
            let (mut lo_l, mut g_lo_l, mut found) = (0.0f32, g0, false);
            for h in [e0, e1, len[l]] {
                let g_h = c.eval(h);
                let take = !found && !h.is_nan();
                let crosses = take && ((g_h >= 0.0) != side[l]);
                if crosses {
                    (hi[l], g_hi[l]) = (h, g_h);
                }
                if take && !crosses {
                    (lo_l, g_lo_l) = (h, g_h);
                }
                found |= crosses;
            }
            (lo[l], g_lo[l], bracketed[l]) = (lo_l, g_lo_l, found && (open >> l) & 1 != 0);
        }
        // `refine`, lane-wise.
        let mut t = [0.0f32; N];
        let mut active = 0u32;
        for l in 0..N {
            let chord = lo[l] + (hi[l] - lo[l]) * (g_lo[l] / (g_lo[l] - g_hi[l]));
            t[l] = if chord > lo[l] && chord < hi[l] {
                chord
            } else {
                0.5 * (lo[l] + hi[l])
            };
            active |= (bracketed[l] as u32) << l;
        }
        let mut rounds = 0;
        while active != 0 && rounds < 48 {
            rounds += 1;
            let mut done = [0u32; N];
            for l in 0..N {
                let c = &cubics[l];
                let g = c.eval(t[l]);
                let on = (g >= 0.0) == side[l];
                let (lo_n, hi_n) = if on { (t[l], hi[l]) } else { (lo[l], t[l]) };
                let is_active = (active >> l) & 1 != 0;
                if is_active {
                    (lo[l], hi[l]) = (lo_n, hi_n);
                }
                let d = c.slope(t[l]);
                let newton = t[l] - g / d;
                let narrow = hi_n - lo_n <= tol[l];
                let still = (newton - t[l]).abs() <= 0.5 * tol[l];
                // `f32::clamp` without its assertion (an inactive lane's
                // bracket may be anything).
                let mut clamped = newton;
                if clamped < lo_n {
                    clamped = lo_n;
                }
                if clamped > hi_n {
                    clamped = hi_n;
                }
                let result = if narrow { 0.5 * (lo_n + hi_n) } else { clamped };
                let next = if newton > lo_n && newton < hi_n {
                    newton
                } else {
                    0.5 * (lo_n + hi_n)
                };
                let finished = narrow || still;
                if is_active && finished {
                    out[l] = result;
                }
                if is_active && !finished {
                    t[l] = next;
                }
                done[l] = (is_active && finished) as u32;
            }
            for (l, &d) in done.iter().enumerate() {
                active &= !(d << l);
            }
        }
        // Lanes the 48 rounds did not settle end where they are, as the
        // scalar loop does.
        for l in 0..N {
            if (active >> l) & 1 != 0 {
                out[l] = t[l];
            }
        }
        out
    }

    /// [`CellCubic::extrema`] with its branches as selections, for
    /// [`CellCubic::first_crossings_unproven`]: the same values.
    #[inline(always)]
    fn extrema_selected(&self, len: f32) -> [f32; 2] {
        let (qa, qb, qc) = (3.0 * self.a, 2.0 * self.b, self.c);
        let scale = qa.abs().max(qb.abs()).max(qc.abs());
        // Effectively a quadratic g: one extremum.
        let linear = qa.abs() <= 1e-7 * scale;
        let lin_root = if qb != 0.0 { -qc / qb } else { f32::NAN };
        let disc = qb * qb - 4.0 * qa * qc;
        let s = disc.sqrt();
        let q = -0.5 * (qb + if qb >= 0.0 { s } else { -s });
        let (r0, r1) = (q / qa, if q != 0.0 { qc / q } else { f32::NAN });
        let pair = if r0 <= r1 { [r0, r1] } else { [r1, r0] };
        let mut r = if scale == 0.0 {
            [f32::NAN; 2]
        } else if linear {
            [lin_root, f32::NAN]
        } else if disc < 0.0 {
            [f32::NAN; 2]
        } else {
            pair
        };
        for x in &mut r {
            if !(*x > 0.0 && *x < len) {
                *x = f32::NAN;
            }
        }
        if r[0].is_nan() {
            r = [r[1], f32::NAN];
        }
        r
    }

    /// A cheap proof that `g` keeps the side `side` on all of `[0, len]`,
    /// which most cells a ray crosses without a crossing pass (they only
    /// clip a corner of the surface's cell): the cubic's Bernstein
    /// coefficients on the interval bound it (convex hull property), so when
    /// all of them lie on `side` by more than `g`'s rounding error, no
    /// evaluation of `g` there can land on the other side. False means "not
    /// proven", and the extrema decide, as before.
    #[inline(always)]
    pub(super) fn stays_on(&self, side: bool, len: f32) -> bool {
        // Power coefficients on u = t/len ∈ [0, 1]: d + p1·u + p2·u² + p3·u³.
        let p1 = self.c * len;
        let p2 = self.b * len * len;
        let p3 = self.a * len * len * len;
        let d = self.d;
        let b1 = d + p1 * (1.0 / 3.0);
        let b2 = d + (2.0 * p1 + p2) * (1.0 / 3.0);
        let b3 = d + p1 + p2 + p3;
        // Each coefficient and each evaluation of g errs by a few ulps of
        // the terms' sum; 1e-5 of it is far beyond both.
        let margin = 1e-5 * (d.abs() + p1.abs() + p2.abs() + p3.abs());
        // Each coefficient compared on its own rather than their minimum
        // or maximum: `f32::min`/`max`'s NaN handling triples the
        // instructions of this test, which packets run for every lane of
        // every straddling cell. (A NaN proves nothing: the extrema decide.)
        // Below the side, the coefficients negated (exactly) instead of a
        // branch on it, which is either side at random.
        let s = if side { 1.0 } else { -1.0 };
        (s * d > margin) & (s * b1 > margin) & (s * b2 > margin) & (s * b3 > margin)
    }

    /// A cheap proof that `g'` keeps one sign on `[0, len]`, so that `g` is
    /// monotonic there: the Bernstein coefficients of the quadratic `g'`
    /// on the interval all on one side of 0 by more than their rounding
    /// error (as in [`CellCubic::stays_on`]).
    #[inline(always)]
    fn monotonic(&self, len: f32) -> bool {
        // g'(u·len) = c + 2b·len·u + 3a·len²·u², u ∈ [0, 1].
        let q1 = self.b * len;
        let q2 = 3.0 * self.a * len * len;
        let (b0, b1, b2) = (self.c, self.c + q1, self.c + 2.0 * q1 + q2);
        let margin = 1e-5 * (self.c.abs() + 2.0 * q1.abs() + q2.abs());
        // As in `stays_on`, without `f32::min`/`max`.
        ((b0 > margin) & (b1 > margin) & (b2 > margin))
            | ((b0 < -margin) & (b1 < -margin) & (b2 < -margin))
    }

    /// `g'(t)`.
    #[inline(always)]
    fn slope(&self, t: f32) -> f32 {
        (3.0 * self.a * t + 2.0 * self.b) * t + self.c
    }

    /// The crossing in `[lo, hi]`, where `g` is monotonic, `g(lo)` on
    /// `side` and `g(hi)` not (the values at the ends given): Newton's
    /// method kept inside the shrinking bracket (a bisection step whenever
    /// Newton would leave it), until a step or the bracket is shorter than
    /// `tol`.
    #[inline]
    fn refine(
        &self,
        (mut lo, g_lo): (f32, f32),
        (mut hi, g_hi): (f32, f32),
        side: bool,
        tol: f32,
    ) -> f32 {
        // Start where the chord between the bracket's ends crosses zero: a
        // distance field is nearly linear across a cell, so this is most of
        // the way there and Newton needs a step or two, not a bisection's
        // worth.
        let chord = lo + (hi - lo) * (g_lo / (g_lo - g_hi));
        let mut t = if chord > lo && chord < hi {
            chord
        } else {
            0.5 * (lo + hi)
        };
        for _ in 0..48 {
            let g = self.eval(t);
            if (g >= 0.0) == side {
                lo = t;
            } else {
                hi = t;
            }
            if hi - lo <= tol {
                return 0.5 * (lo + hi);
            }
            let d = self.slope(t);
            let newton = t - g / d;
            // A step this short means `t` is at the root (then Newton may
            // land just outside the bracket, on `t`'s side, by rounding:
            // bisecting would throw the answer away).
            if (newton - t).abs() <= 0.5 * tol {
                return newton.clamp(lo, hi);
            }
            t = if newton > lo && newton < hi {
                newton
            } else {
                0.5 * (lo + hi)
            };
        }
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::interpolate;

    fn random_corners(rng: &mut fastrand::Rng) -> Corners {
        std::array::from_fn(|_| rng.f32() * 2.0 - 1.0)
    }

    #[test]
    fn the_cubic_is_the_trilinear_interpolant_along_the_ray() {
        let mut rng = fastrand::Rng::with_seed(5);
        for _ in 0..1000 {
            let c = random_corners(&mut rng);
            let p0 = Vec3::new(rng.f32(), rng.f32(), rng.f32());
            let dir = Vec3::new(rng.f32() - 0.5, rng.f32() - 0.5, rng.f32() - 0.5);
            let g = CellCubic::new(&c, p0, dir, 0.25);
            for i in 0..=10 {
                let t = i as f32 * 0.1;
                let want = interpolate(&c, p0 + dir * t) - 0.25;
                assert!((g.eval(t) - want).abs() < 1e-5, "{} vs {want}", g.eval(t));
            }
        }
    }

    #[test]
    fn a_cubic_proven_monotonic_has_no_extremum_inside() {
        let mut rng = fastrand::Rng::with_seed(7);
        let (mut proven, mut not) = (0, 0);
        for _ in 0..5000 {
            let c = random_corners(&mut rng);
            let p0 = Vec3::new(rng.f32(), rng.f32(), rng.f32());
            let dir = Vec3::new(rng.f32() - 0.5, rng.f32() - 0.5, rng.f32() - 0.5);
            let g = CellCubic::new(&c, p0, dir, 0.0);
            let len = 0.2 + rng.f32();
            if g.monotonic(len) {
                proven += 1;
                assert_eq!(g.extrema(len)[0].to_bits(), f32::NAN.to_bits());
                let sign = g.slope(0.0) > 0.0;
                for i in 0..=1000 {
                    assert_eq!(g.slope(len * i as f32 / 1000.0) > 0.0, sign);
                }
            } else {
                not += 1;
            }
        }
        // Both kinds occur, so the test tests something.
        assert!(proven > 100 && not > 100, "{proven} proven, {not} not");
    }

    /// The lane-wise search gives every open lane the scalar search's bits
    /// (and `NaN` where it finds nothing or the lane is closed), on cubics
    /// of every kind: random corners, near-double roots, quadratics and
    /// constants along the ray, intervals of any length.
    #[test]
    fn lanes_find_the_scalar_crossings_to_the_bit() {
        let mut rng = fastrand::Rng::with_seed(8);
        let (mut found, mut none) = (0, 0);
        for round in 0..4000 {
            let cubics: [CellCubic; 8] = std::array::from_fn(|_| {
                let mut c = random_corners(&mut rng);
                match rng.u32(0..5) {
                    // Flat along x and y: a linear or constant g.
                    0 => {
                        for k in 4..8 {
                            c[k] = c[k - 4];
                        }
                    }
                    // Corners near the iso value: roots close together.
                    1 => c.iter_mut().for_each(|v| *v *= 1e-3),
                    _ => {}
                }
                let p0 = Vec3::new(rng.f32(), rng.f32(), rng.f32());
                let dir = Vec3::new(rng.f32() - 0.5, rng.f32() - 0.5, rng.f32() - 0.5);
                CellCubic::new(&c, p0, dir, 0.0)
            });
            let len: [f32; 8] = std::array::from_fn(|_| rng.f32() * 1.5);
            let tol: [f32; 8] = std::array::from_fn(|_| [1e-5, 1e-3, 1e-6][rng.usize(0..3)]);
            let open = if round % 2 == 0 {
                0xff
            } else {
                rng.u32(0..256)
            };
            let got = CellCubic::first_crossings_unproven(&cubics, &len, &tol, open);
            for l in 0..8 {
                let want = if (open >> l) & 1 != 0 {
                    cubics[l].first_crossing_unproven(len[l], tol[l])
                } else {
                    None
                };
                match want {
                    Some(t) => {
                        found += 1;
                        assert_eq!(got[l].to_bits(), t.to_bits(), "lane {l} of round {round}");
                    }
                    None => {
                        none += 1;
                        assert!(got[l].is_nan(), "lane {l} of round {round}: {}", got[l]);
                    }
                }
            }
        }
        assert!(found > 2000 && none > 2000, "{found} found, {none} none");
    }

    #[test]
    fn finds_the_first_of_several_crossings_and_misses_none() {
        let mut rng = fastrand::Rng::with_seed(6);
        let mut doubles = 0;
        for _ in 0..5000 {
            let c = random_corners(&mut rng);
            let p0 = Vec3::new(rng.f32(), rng.f32(), 0.0);
            let dir = Vec3::new(rng.f32() - 0.5, rng.f32() - 0.5, 1.0) * 0.9;
            let g = CellCubic::new(&c, p0, dir, 0.0);
            // Brute force: the first sign change on a fine grid of t.
            let n = 20000;
            let side = g.eval(0.0) >= 0.0;
            let brute = (1..=n)
                .map(|i| i as f32 / n as f32)
                .find(|&t| (g.eval(t) >= 0.0) != side);
            let got = g.first_crossing(1.0, 1e-6);
            match (brute, got) {
                (None, None) => {}
                (Some(b), Some(t)) => {
                    // The brute force may step over a pair of crossings
                    // closer together than its grid: then ours comes first.
                    assert!(
                        (b - t).abs() <= 2.0 / n as f32 || t < b,
                        "found {t}, brute force {b}"
                    );
                    doubles += ((g.eval(1.0) >= 0.0) == side) as usize;
                }
                // Bisection ends on a real change of side, which the brute
                // force's grid may step over when two crossings are close.
                (None, Some(_)) => {}
                (Some(b), None) => panic!("missed the crossing at {b} for {c:?}"),
            }
        }
        assert!(doubles > 0, "no ray crossed twice: the test tests nothing");
    }
}
