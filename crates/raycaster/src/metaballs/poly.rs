//! Polynomials of degree ≤ 6 on an interval: evaluation, the Taylor shift
//! that moves a ray's running sum from one interval to the next, and the
//! first root on `[0, len]`, isolated with Bernstein coefficients.
//!
//! Root isolation: on `[0, len]` the polynomial's Bernstein coefficients
//! bound it (convex hull property). When all of them are negative the
//! interval has no root; otherwise it is halved (de Casteljau) and the left
//! half searched first, down to a width of `tol`. A piece whose
//! coefficients change sign once holds exactly one root, which Newton's
//! method finds without leaving the piece. A leaf of width `tol`
//! holds a root when its ends differ in sign; the root is then
//! interpolated linearly between them (error < `tol`). So the first sign
//! change is never missed nor overshot; two roots closer together than
//! `tol` (a ray grazing the surface, a double root) can go unnoticed,
//! which moves nothing by more than `tol`.

use super::kernel::{MAX_TERMS, Poly};

/// `p(x)` for a polynomial of degree `n` (<= 6).
#[inline]
pub fn eval(p: &Poly, n: usize, x: f64) -> f64 {
    match n {
        6 => eval_n::<6>(p, x),
        4 => eval_n::<4>(p, x),
        _ => {
            let mut acc = p[n];
            for k in (0..n).rev() {
                acc = acc * x + p[k];
            }
            acc
        }
    }
}

/// [`eval`] for a degree known at compile time (unrolled).
#[inline(always)]
pub fn eval_n<const N: usize>(p: &Poly, x: f64) -> f64 {
    let mut acc = p[N];
    let mut k = N;
    while k > 0 {
        k -= 1;
        acc = acc * x + p[k];
    }
    acc
}

/// Replaces `p(x)` by `p(x + d)` (Taylor shift, `n(n+1)/2` multiply-adds).
#[inline]
pub fn shift(p: &mut Poly, n: usize, d: f64) {
    match n {
        6 => shift_n::<6>(p, d),
        4 => shift_n::<4>(p, d),
        _ => {
            if d == 0.0 {
                return;
            }
            for i in 0..n {
                for k in (i..n).rev() {
                    p[k] += d * p[k + 1];
                }
            }
        }
    }
}

/// [`shift`] for a degree known at compile time (unrolled).
#[inline(always)]
pub fn shift_n<const N: usize>(p: &mut Poly, d: f64) {
    if d == 0.0 {
        return;
    }
    for i in 0..N {
        let mut k = N;
        while k > i {
            k -= 1;
            p[k] += d * p[k + 1];
        }
    }
}

/// Binomial coefficients `C(i, k)` for `i, k <= 6`.
const BINOM: [[f64; MAX_TERMS]; MAX_TERMS] = {
    let mut t = [[0.0; MAX_TERMS]; MAX_TERMS];
    let mut i = 0;
    while i < MAX_TERMS {
        t[i][0] = 1.0;
        let mut k = 1;
        while k <= i {
            t[i][k] = t[i - 1][k - 1] + if k < i { t[i - 1][k] } else { 0.0 };
            k += 1;
        }
        i += 1;
    }
    t
};

/// `1 / C(i, k)` (0 where `k > i`).
const INV_BINOM: [[f64; MAX_TERMS]; MAX_TERMS] = {
    let mut t = [[0.0; MAX_TERMS]; MAX_TERMS];
    let mut i = 0;
    while i < MAX_TERMS {
        let mut k = 0;
        while k <= i {
            t[i][k] = 1.0 / BINOM[i][k];
            k += 1;
        }
        i += 1;
    }
    t
};

/// Bernstein coefficients of `p` (degree `n`) on `[0, len]`.
#[inline]
pub fn bernstein(p: &Poly, n: usize, len: f64) -> Poly {
    match n {
        6 => bernstein_n::<6>(p, len),
        4 => bernstein_n::<4>(p, len),
        _ => {
            let mut scaled = [0.0; MAX_TERMS];
            let mut l = 1.0;
            for k in 0..=n {
                scaled[k] = p[k] * l / BINOM[n][k];
                l *= len;
            }
            let mut b = [0.0; MAX_TERMS];
            for i in 0..=n {
                let mut acc = 0.0;
                for k in 0..=i {
                    acc += BINOM[i][k] * scaled[k];
                }
                b[i] = acc;
            }
            b
        }
    }
}

/// [`bernstein`] for a degree known at compile time (unrolled): the
/// coefficients scaled by `len^k / C(N, k)`, then their binomial transform
/// `b_i = Σ_k C(i, k)·s_k` as `N` passes of running sums.
#[inline(always)]
pub fn bernstein_n<const N: usize>(p: &Poly, len: f64) -> Poly {
    let mut b = [0.0; MAX_TERMS];
    let mut l = 1.0;
    for k in 0..=N {
        b[k] = p[k] * l * INV_BINOM[N][k];
        l *= len;
    }
    for r in 0..N {
        let mut i = N;
        while i > r {
            b[i] += b[i - 1];
            i -= 1;
        }
    }
    b
}

/// The first `x` in `[0, len]` where `p` (degree `n`) reaches 0 from below,
/// within `tol`; `Some(0)` when `p(0) >= 0`. See the module docs for what
/// may be missed (two roots closer than `tol`).
pub fn first_root(p: &Poly, n: usize, len: f64, tol: f64) -> Option<f64> {
    match n {
        6 => first_root_n::<6>(p, len, tol, f64::NAN),
        5 => first_root_n::<5>(p, len, tol, f64::NAN),
        4 => first_root_n::<4>(p, len, tol, f64::NAN),
        3 => first_root_n::<3>(p, len, tol, f64::NAN),
        2 => first_root_n::<2>(p, len, tol, f64::NAN),
        1 => first_root_n::<1>(p, len, tol, f64::NAN),
        _ => first_root_n::<0>(p, len, tol, f64::NAN),
    }
}

/// The cheap test of [`first_root_n`]: `false` when `p` (degree `N`) is
/// negative on all of `[0, len]` by the bound
/// `p <= p0 + Σ max(p_k, 0)·len^k`.
#[inline(always)]
pub fn may_reach_zero_n<const N: usize>(p: &Poly, len: f64) -> bool {
    let mut upper = 0.0;
    let mut k = N;
    while k > 0 {
        upper = (upper + p[k].max(0.0)) * len;
        k -= 1;
    }
    !(p[0] < 0.0 && p[0] + upper < 0.0)
}

/// [`first_root`] for a degree known at compile time. `guess` is where
/// the root probably is (a neighbouring ray's hit; NaN or outside
/// `[0, len]`: none): the refinement starts there when it lies in the
/// root's bracket. It changes the iterations, not which root is found.
#[inline]
pub fn first_root_n<const N: usize>(p: &Poly, len: f64, tol: f64, guess: f64) -> Option<f64> {
    // A cheap bound first: on [0, len], p <= p0 + Σ max(p_k, 0)·len^k. On
    // the short intervals between the events of many balls it is usually
    // enough to rule a root out.
    if !may_reach_zero_n::<N>(p, len) {
        return None;
    }
    first_root_bernstein_n::<N>(p, len, tol, guess)
}

/// [`first_root_n`] without the cheap bound: Bernstein isolation.
#[inline(never)]
fn first_root_bernstein_n<const N: usize>(p: &Poly, len: f64, tol: f64, guess: f64) -> Option<f64> {
    let b = bernstein_n::<N>(p, len);
    search::<N>(p, &b, 0.0, len, tol.max(len * 1e-12), guess)
}

/// Sign changes in the Bernstein coefficients (zeros skipped): an upper
/// bound on the roots in the interval, exact when 0 or 1 (Descartes' rule
/// for the Bernstein basis).
#[inline]
fn sign_changes<const N: usize>(b: &Poly) -> u32 {
    let mut changes = 0;
    let mut prev = 0.0f64;
    for &c in &b[..=N] {
        if c != 0.0 {
            if prev != 0.0 && (c > 0.0) != (prev > 0.0) {
                changes += 1;
            }
            prev = c;
        }
    }
    changes
}

/// The first root of `p` on `[a, a + w]`, whose Bernstein coefficients are
/// `b`, with `p(a) < 0` unless it is the first call.
fn search<const N: usize>(p: &Poly, b: &Poly, a: f64, w: f64, tol: f64, guess: f64) -> Option<f64> {
    if b[0] >= 0.0 {
        return Some(a);
    }
    match sign_changes::<N>(b) {
        // p(a) < 0 and no sign change: p <= 0 on the interval.
        0 => return None,
        // Exactly one root, p(a) < 0 < p(a + w): refine it.
        // (The Bernstein end coefficients are p's values at the ends.)
        1 if b[N] > 0.0 => return Some(refine::<N>(p, a, a + w, [b[0], b[N]], tol, guess)),
        _ => {}
    }
    if w <= tol {
        // A sign change between the leaf's ends: interpolate.
        return (b[N] >= 0.0).then(|| a + w * (b[0] / (b[0] - b[N])));
    }
    let (left, right) = split::<N>(b);
    let h = 0.5 * w;
    search::<N>(p, &left, a, h, tol, guess).or_else(|| search::<N>(p, &right, a + h, h, tol, guess))
}

/// The one root of `p` in `[lo, hi]` (`p(lo) < 0 < p(hi)`, their values
/// `f_ends`) to within `tol`: Newton's method kept inside the bracket
/// (a step that would leave it halves the bracket instead), starting from
/// `guess` when it lies in the bracket, else from the secant point. It
/// stops when a step moves less than `tol / 4` (past that, Newton's error
/// is far below the step near a simple root, and no larger than it near a
/// double one) or the bracket is narrower than `tol`.
fn refine<const N: usize>(
    p: &Poly,
    mut lo: f64,
    mut hi: f64,
    f_ends: [f64; 2],
    tol: f64,
    guess: f64,
) -> f64 {
    let mut x = if guess > lo && guess < hi {
        guess
    } else {
        let [f_lo, f_hi] = f_ends;
        let secant = lo + (hi - lo) * (f_lo / (f_lo - f_hi));
        if secant > lo && secant < hi {
            secant
        } else {
            0.5 * (lo + hi)
        }
    };
    for _ in 0..100 {
        let (fx, dfx) = eval_with_derivative_n::<N>(p, x);
        if fx == 0.0 {
            return x;
        }
        if fx > 0.0 {
            hi = x;
        } else {
            lo = x;
        }
        let step = fx / dfx;
        let next = x - step;
        if next > lo && next < hi {
            if step.abs() <= 0.25 * tol {
                return next;
            }
            x = next;
        } else {
            x = 0.5 * (lo + hi);
        }
        if hi - lo <= tol {
            break;
        }
    }
    // The root is in [lo, hi], narrower than tol (or p is flat to rounding
    // there).
    0.5 * (lo + hi)
}

/// `p(x)` and `p'(x)` for a degree known at compile time (Horner, both
/// chains at once).
#[inline(always)]
pub fn eval_with_derivative_n<const N: usize>(p: &Poly, x: f64) -> (f64, f64) {
    let mut f = p[N];
    let mut df = 0.0;
    let mut k = N;
    while k > 0 {
        k -= 1;
        df = df * x + f;
        f = f * x + p[k];
    }
    (f, df)
}

/// de Casteljau at the midpoint: the Bernstein coefficients of both halves.
#[inline]
fn split<const N: usize>(b: &Poly) -> (Poly, Poly) {
    let mut work = *b;
    let mut left = [0.0; MAX_TERMS];
    let mut right = [0.0; MAX_TERMS];
    left[0] = work[0];
    right[N] = work[N];
    for r in 1..=N {
        for k in 0..=N - r {
            work[k] = 0.5 * (work[k] + work[k + 1]);
        }
        left[r] = work[0];
        right[N - r] = work[N - r];
    }
    (left, right)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn from_roots(roots: &[f64], scale: f64) -> Poly {
        let mut p = [0.0; MAX_TERMS];
        p[0] = scale;
        for &r in roots {
            // multiply by (x − r)
            for k in (0..MAX_TERMS).rev() {
                let lower = if k > 0 { p[k - 1] } else { 0.0 };
                p[k] = lower - r * p[k];
            }
        }
        p
    }

    #[test]
    fn shift_and_bernstein_agree_with_evaluation() {
        let p = [0.3, -1.2, 0.7, 2.0, -0.4, 0.1, -0.05];
        let mut q = p;
        shift(&mut q, 6, 0.75);
        for i in 0..10 {
            let x = i as f64 * 0.2 - 1.0;
            assert!((eval(&q, 6, x) - eval(&p, 6, x + 0.75)).abs() < 1e-12);
        }
        // Bernstein end coefficients are the end values, and they bound p.
        let b = bernstein(&p, 6, 1.5);
        assert!((b[0] - eval(&p, 6, 0.0)).abs() < 1e-12);
        assert!((b[6] - eval(&p, 6, 1.5)).abs() < 1e-12);
        let (lo, hi) = b
            .iter()
            .fold((f64::MAX, f64::MIN), |(l, h), &c| (l.min(c), h.max(c)));
        for i in 0..=100 {
            let v = eval(&p, 6, 1.5 * i as f64 / 100.0);
            assert!(v >= lo - 1e-12 && v <= hi + 1e-12);
        }
        // The halves of a split evaluate to p on each half.
        let (l, r) = split::<6>(&b);
        let power_of = |bc: &Poly, x: f64| {
            // Bernstein evaluation on [0, 1].
            (0..=6)
                .map(|i| BINOM[6][i] * x.powi(i as i32) * (1.0 - x).powi(6 - i as i32) * bc[i])
                .sum::<f64>()
        };
        assert!((power_of(&l, 0.5) - eval(&p, 6, 0.375)).abs() < 1e-12);
        assert!((power_of(&r, 0.5) - eval(&p, 6, 1.125)).abs() < 1e-12);
    }

    #[test]
    fn first_root_finds_the_leftmost_sign_change() {
        // Roots 0.3, 0.31 (close pair), 0.9; negative at 0.
        let p = from_roots(&[0.3, 0.31, 0.9, 2.0, 3.0, -1.0], 1.0);
        assert!(eval(&p, 6, 0.0) < 0.0);
        let r = first_root(&p, 6, 1.0, 1e-6).unwrap();
        assert!((r - 0.3).abs() < 1e-6, "{r}");
        // No root on [0, 0.29].
        assert!(first_root(&p, 6, 0.29, 1e-6).is_none());
        // Degree 4.
        let q = from_roots(&[0.55, 1.7, -0.5, 4.0], 1.0);
        assert!(eval(&q, 4, 0.0) < 0.0);
        assert!((first_root(&q, 4, 1.0, 1e-7).unwrap() - 0.55).abs() < 1e-7);
        // Already non-negative at 0.
        assert_eq!(
            first_root(&[1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 6, 1.0, 1e-6),
            Some(0.0)
        );
        // Negative everywhere.
        assert!(first_root(&[-1.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.0], 6, 1.0, 1e-6).is_none());
    }

    #[test]
    fn a_guess_moves_the_first_root_by_less_than_the_tolerance() {
        // Random polynomials with a root in [0, 1]: guesses anywhere (in
        // the bracket, past a later root, outside the interval) find the
        // root the search without a guess finds, to the tolerance.
        let mut rng = fastrand::Rng::with_seed(12);
        let mut tested = 0;
        for _ in 0..2000 {
            let mut p = [0.0; MAX_TERMS];
            for c in p.iter_mut() {
                *c = rng.f64() * 4.0 - 2.0;
            }
            p[0] = -rng.f64() - 0.01;
            let tol = 1e-6;
            let Some(plain) = first_root_n::<6>(&p, 1.0, tol, f64::NAN) else {
                continue;
            };
            tested += 1;
            for guess in [plain, plain + 0.01, plain - 0.003, 0.999, 0.0, -1.0, 2.0] {
                let got = first_root_n::<6>(&p, 1.0, tol, guess).unwrap();
                assert!(
                    (got - plain).abs() <= tol,
                    "{guess}: {got} vs {plain}: {p:?}"
                );
            }
        }
        assert!(tested > 300, "{tested}");
    }

    #[test]
    fn first_root_matches_a_dense_scan_on_random_polynomials() {
        let mut rng = fastrand::Rng::with_seed(11);
        for _ in 0..2000 {
            let mut p = [0.0; MAX_TERMS];
            for c in p.iter_mut() {
                *c = rng.f64() * 4.0 - 2.0;
            }
            p[0] = -rng.f64() - 0.01;
            let tol = 1e-7;
            let got = first_root(&p, 6, 1.0, tol);
            // Dense scan: the first sample at or above zero.
            let m = 20_000;
            let scan = (1..=m)
                .map(|i| i as f64 / m as f64)
                .find(|&x| eval(&p, 6, x) >= 0.0);
            match (got, scan) {
                (Some(g), Some(s)) => {
                    assert!(g <= s + tol && g > s - 1.0 / m as f64 - tol, "{g} {s}")
                }
                (None, Some(s)) => panic!("missed a root near {s}: {p:?}"),
                (Some(g), None) => {
                    // Only a root pair between scan samples may be found alone.
                    assert!(eval(&p, 6, g).abs() < 1e-5, "{g} {p:?}");
                }
                (None, None) => {}
            }
        }
    }
}
