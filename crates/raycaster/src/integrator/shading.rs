//! Phong shading: with a headlight (volume rendering) or with directional
//! lights (isosurfaces).

use glam::Vec3;

/// Phong coefficients. The light sits at the eye (a headlight), so the light
/// and view directions coincide.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Phong {
    /// Ambient weight.
    pub ka: f32,
    /// Diffuse weight.
    pub kd: f32,
    /// Specular weight.
    pub ks: f32,
    /// Specular exponent (an integer, so the power is a few multiplications).
    pub shininess: i32,
    /// Shading is applied only where the gradient magnitude (value units per
    /// world unit) exceeds this; elsewhere the colour is used as it is.
    pub gradient_threshold: f32,
}

impl Default for Phong {
    fn default() -> Self {
        Phong {
            ka: 0.3,
            kd: 0.7,
            ks: 0.25,
            shininess: 20,
            gradient_threshold: 1e-3,
        }
    }
}

impl Phong {
    /// Defaults with the gradient threshold at 1% of the data's value range
    /// per world unit.
    pub fn for_value_range(range: f32) -> Self {
        Phong {
            gradient_threshold: (range * 0.01).max(1e-6),
            ..Phong::default()
        }
    }

    /// Diffuse factor and specular term for gradient `g` seen along `view_dir`
    /// (the ray direction), or `None` when the gradient is too weak to define
    /// a surface. Lighting is two-sided: a surface is lit from whichever side
    /// the camera sees it.
    #[inline]
    pub fn terms(&self, g: Vec3, view_dir: Vec3) -> Option<(f32, f32)> {
        let len2 = g.length_squared();
        if len2 <= self.gradient_threshold * self.gradient_threshold {
            return None;
        }
        // N = -g/|g|, L = V = -view_dir; two-sided: |N·L|.
        let ndotl = (g.dot(view_dir) / len2.sqrt()).abs();
        // R = 2(N·L)N − L, so R·V = 2(N·L)² − 1 for a headlight.
        let rdotv = (2.0 * ndotl * ndotl - 1.0).max(0.0);
        let spec = if self.ks > 0.0 {
            self.ks * powi(rdotv, self.shininess)
        } else {
            0.0
        };
        Some((self.ka + self.kd * ndotl, spec))
    }

    /// Diffuse factor and specular term of one directional light towards
    /// `l` (unit) for unit normal `n` (facing the viewer) seen from the
    /// direction `view` (unit, towards the eye): `kd·(N·L)` and
    /// `ks·max(0, R·V)ⁿ` with `R = 2(N·L)N − L`; zero when the light is
    /// behind the surface. With `l = view` this is [`Phong::terms`]'s
    /// headlight.
    #[inline]
    pub fn light(&self, n: Vec3, l: Vec3, view: Vec3) -> (f32, f32) {
        let ndotl = n.dot(l);
        if ndotl <= 0.0 {
            return (0.0, 0.0);
        }
        let r = n * (2.0 * ndotl) - l;
        let rdotv = r.dot(view).max(0.0);
        let spec = if self.ks > 0.0 {
            self.ks * powi(rdotv, self.shininess)
        } else {
            0.0
        };
        (self.kd * ndotl, spec)
    }
}

/// `x` to the integer power `n`, by the square-and-multiply that
/// `f32::powi` runs out of line for an exponent known only at run time
/// (compiler-rt's `__powisf2`; the same products in the same order, so the
/// same result), written here so it inlines into the sample loops: the
/// call was 2 % of a shaded frame.
#[inline(always)]
pub(crate) fn powi(mut x: f32, n: i32) -> f32 {
    let recip = n < 0;
    let mut b = n.unsigned_abs();
    let mut r = 1.0f32;
    loop {
        if b & 1 != 0 {
            r *= x;
        }
        b /= 2;
        if b == 0 {
            break;
        }
        x *= x;
    }
    if recip { 1.0 / r } else { r }
}

/// [`powi`] of every lane of `x`, the lanes' products in [`powi`]'s order
/// (so the same bits), with the exponent's loop once for all lanes.
#[inline(always)]
pub(crate) fn powi_lanes<const N: usize>(mut x: [f32; N], n: i32) -> [f32; N] {
    let mut b = n.unsigned_abs();
    let mut r = [1.0f32; N];
    loop {
        if b & 1 != 0 {
            for (r, x) in r.iter_mut().zip(&x) {
                *r *= x;
            }
        }
        b /= 2;
        if b == 0 {
            break;
        }
        for x in &mut x {
            *x *= *x;
        }
    }
    if n < 0 { r.map(|r| 1.0 / r) } else { r }
}

#[cfg(test)]
mod tests {
    use super::{powi, powi_lanes};

    #[test]
    fn powi_lanes_is_powi_lane_by_lane() {
        let mut rng = fastrand::Rng::with_seed(8);
        for _ in 0..2_000 {
            let x: [f32; 8] = std::array::from_fn(|_| rng.f32() * 2.0);
            let n = rng.i32(-40..=200);
            let lanes = powi_lanes(x, n);
            for (l, &v) in lanes.iter().enumerate() {
                assert_eq!(v.to_bits(), powi(x[l], n).to_bits(), "{}^{n}", x[l]);
            }
        }
    }

    #[test]
    fn powi_is_f32_powi() {
        let mut rng = fastrand::Rng::with_seed(7);
        for _ in 0..10_000 {
            let x = rng.f32() * 2.0;
            let n = rng.i32(-40..=200);
            let (a, b) = (powi(x, n), x.powi(n));
            assert!(
                a == b || (a - b).abs() <= 1e-6 * b.abs() || (a.is_infinite() && b.is_infinite()),
                "{x}^{n}: {a} against {b}"
            );
        }
        assert_eq!(powi(0.5, 0), 1.0);
        assert_eq!(powi(3.0, 1), 3.0);
        assert_eq!(powi(2.0, 10), 1024.0);
        assert_eq!(powi(2.0, -2), 0.25);
    }
}
