//! Compactly supported kernels: Wyvill's and Murakami's. Both are
//! polynomials in `s = a²` (`a` = distance / radius), so along a ray, where
//! `s` is a quadratic in `t`, a ball's contribution is a polynomial in `t`.

/// A kernel `K(a)` with `K(0) = 1`, `K(a) = 0` for `a >= 1`, decreasing
/// in between.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Kernel {
    /// Wyvill: `1 − 22/9·a² + 17/9·a⁴ − 4/9·a⁶` (degree 6 in `t`).
    #[default]
    #[cfg_attr(feature = "clap", value(help = "1 - 22/9 a^2 + 17/9 a^4 - 4/9 a^6"))]
    Wyvill,
    /// Murakami: `(1 − a²)²` (degree 4 in `t`).
    #[cfg_attr(feature = "clap", value(help = "(1 - a^2)^2"))]
    Murakami,
}

/// The most coefficients a kernel's polynomial along a ray has (degree 6).
pub const MAX_TERMS: usize = 7;

/// A polynomial `Σ c[k]·x^k` of degree at most 6.
pub type Poly = [f64; MAX_TERMS];

impl Kernel {
    /// The name used on command lines.
    pub fn name(self) -> &'static str {
        match self {
            Kernel::Wyvill => "wyvill",
            Kernel::Murakami => "murakami",
        }
    }

    /// Coefficients of `K` as a polynomial in `s = a²`: `c0 + c1·s + c2·s² + c3·s³`.
    #[inline]
    pub const fn coefficients(self) -> [f64; 4] {
        match self {
            Kernel::Wyvill => [1.0, -22.0 / 9.0, 17.0 / 9.0, -4.0 / 9.0],
            Kernel::Murakami => [1.0, -2.0, 1.0, 0.0],
        }
    }

    /// Degree of `K` along a ray (in `t`): twice its degree in `s`.
    #[inline]
    pub const fn degree(self) -> usize {
        match self {
            Kernel::Wyvill => 6,
            Kernel::Murakami => 4,
        }
    }

    /// `K` at `s = a²` (0 for `s >= 1`).
    #[inline]
    pub fn at_s(self, s: f64) -> f64 {
        if s >= 1.0 {
            return 0.0;
        }
        let c = self.coefficients();
        c[0] + s * (c[1] + s * (c[2] + s * c[3]))
    }

    /// `dK/ds` at `s = a²` (0 for `s >= 1`).
    #[inline]
    pub fn ds_at_s(self, s: f64) -> f64 {
        if s >= 1.0 {
            return 0.0;
        }
        let c = self.coefficients();
        c[1] + s * (2.0 * c[2] + s * 3.0 * c[3])
    }

    /// `K(a)`.
    pub fn at(self, a: f64) -> f64 {
        self.at_s(a * a)
    }

    /// The `a` in `[0, 1]` where `K(a) = level` (`level` in `(0, 1)`): the
    /// surface radius of a lone ball, as a fraction of its radius. `None`
    /// outside `(0, 1)`.
    pub fn level_radius(self, level: f64) -> Option<f64> {
        self.level_s(level).map(f64::sqrt)
    }

    /// The `s = a²` in `[0, 1]` where `K = level` (`level` in `(0, 1)`),
    /// by bisection to the last bit ([`Kernel::level_radius`] is its square
    /// root). `None` outside `(0, 1)`.
    pub fn level_s(self, level: f64) -> Option<f64> {
        if !(level > 0.0 && level < 1.0) {
            return None;
        }
        // K decreases on [0, 1]: bisection on s.
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        for _ in 0..80 {
            let mid = 0.5 * (lo + hi);
            if self.at_s(mid) > level {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        Some(0.5 * (lo + hi))
    }

    /// `K(s(x))` as a polynomial in `x` for the quadratic
    /// `s(x) = q[0] + q[1]·x + q[2]·x²` (valid where `s(x) < 1`).
    #[inline]
    pub fn compose(self, q: [f64; 3]) -> Poly {
        let c = self.coefficients();
        let [g, b, a] = q;
        // s² and s³ by multiplying out.
        let s2 = [g * g, 2.0 * g * b, b * b + 2.0 * a * g, 2.0 * a * b, a * a];
        let mut p = [0.0; MAX_TERMS];
        p[0] = c[0] + c[1] * g + c[2] * s2[0];
        p[1] = c[1] * b + c[2] * s2[1];
        p[2] = c[1] * a + c[2] * s2[2];
        p[3] = c[2] * s2[3];
        p[4] = c[2] * s2[4];
        if c[3] != 0.0 {
            // s³ = s²·s.
            let k = c[3];
            p[0] += k * s2[0] * g;
            p[1] += k * (s2[1] * g + s2[0] * b);
            p[2] += k * (s2[2] * g + s2[1] * b + s2[0] * a);
            p[3] += k * (s2[3] * g + s2[2] * b + s2[1] * a);
            p[4] += k * (s2[4] * g + s2[3] * b + s2[2] * a);
            p[5] = k * (s2[4] * b + s2[3] * a);
            p[6] = k * s2[4] * a;
        }
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernels_have_compact_support_and_their_closed_forms() {
        for k in [Kernel::Wyvill, Kernel::Murakami] {
            assert_eq!(k.at(0.0), 1.0);
            assert!(k.at(1.0).abs() < 1e-15, "{k:?}");
            assert_eq!(k.at(1.5), 0.0);
            assert_eq!(k.ds_at_s(1.2), 0.0);
            // Decreasing on [0, 1], and the derivative vanishes at a = 1 (C1).
            let mut prev = 1.0;
            for i in 1..=100 {
                let v = k.at(i as f64 / 100.0);
                assert!(v < prev);
                prev = v;
            }
            assert!(k.ds_at_s(1.0 - 1e-12).abs() < 1e-9);
        }
        let a: f64 = 0.37;
        let wy = 1.0 - 22.0 / 9.0 * a.powi(2) + 17.0 / 9.0 * a.powi(4) - 4.0 / 9.0 * a.powi(6);
        assert!((Kernel::Wyvill.at(a) - wy).abs() < 1e-15);
        assert!((Kernel::Murakami.at(a) - (1.0 - a * a).powi(2)).abs() < 1e-15);
        // dK/ds by a central difference.
        for k in [Kernel::Wyvill, Kernel::Murakami] {
            let s = 0.3;
            let fd = (k.at_s(s + 1e-6) - k.at_s(s - 1e-6)) / 2e-6;
            assert!((k.ds_at_s(s) - fd).abs() < 1e-8);
        }
    }

    #[test]
    fn level_radius_solves_the_kernel() {
        for k in [Kernel::Wyvill, Kernel::Murakami] {
            for level in [0.1, 0.5, 0.9] {
                let a = k.level_radius(level).unwrap();
                assert!((k.at(a) - level).abs() < 1e-12);
            }
            assert!(k.level_radius(1.0).is_none() && k.level_radius(0.0).is_none());
        }
        // Murakami in closed form: a = sqrt(1 − sqrt(T)).
        let a = Kernel::Murakami.level_radius(0.5).unwrap();
        assert!((a - (1.0 - 0.5f64.sqrt()).sqrt()).abs() < 1e-12);
    }

    #[test]
    fn composition_expands_the_polynomial_along_a_ray() {
        let q = [0.3, -0.8, 0.55];
        for k in [Kernel::Wyvill, Kernel::Murakami] {
            let p = k.compose(q);
            assert!(p[k.degree() + 1..].iter().all(|&c| c == 0.0));
            for i in 0..20 {
                let x = -0.5 + i as f64 * 0.1;
                let s = q[0] + q[1] * x + q[2] * x * x;
                let c = k.coefficients();
                let direct = c[0] + c[1] * s + c[2] * s * s + c[3] * s * s * s;
                let horner = p.iter().rev().fold(0.0, |acc, &c| acc * x + c);
                assert!((direct - horner).abs() < 1e-12, "{k:?} x={x}");
            }
        }
    }
}
