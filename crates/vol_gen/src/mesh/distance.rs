//! The closest point of a triangle to a point (Ericson, *Real-Time Collision
//! Detection*, §5.1.5): which of the seven Voronoi regions of the triangle
//! (three vertices, three edges, the face) holds the point decides the
//! closest point, found with a few dot products and no square root.

use glam::DVec3;

/// The point of triangle `abc` nearest to `p`.
pub fn closest_point_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a; // vertex region A
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b; // vertex region B
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3)); // edge AB
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c; // vertex region C
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6)); // edge AC
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))); // edge BC
    }
    // Inside the face: barycentric coordinates (u, v, w) = (va, vb, vc) / sum.
    let denom = va + vb + vc;
    if denom == 0.0 {
        // A degenerate (zero-area) triangle that fell through: take the
        // nearest of its corners' edges' endpoints.
        return [a, b, c]
            .into_iter()
            .min_by(|x, y| x.distance_squared(p).total_cmp(&y.distance_squared(p)))
            .unwrap_or(a);
    }
    a + ab * (vb / denom) + ac * (vc / denom)
}

/// Squared distance from `p` to triangle `abc`.
pub fn distance_squared(p: DVec3, [a, b, c]: &[DVec3; 3]) -> f64 {
    closest_point_on_triangle(p, *a, *b, *c).distance_squared(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force: the nearest of many points sampled on the triangle.
    fn sampled(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
        let n = 200;
        let mut best = f64::INFINITY;
        for i in 0..=n {
            for j in 0..=(n - i) {
                let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                let q = a + (b - a) * u + (c - a) * v;
                best = best.min(q.distance(p));
            }
        }
        best
    }

    #[test]
    fn every_region_matches_brute_force() {
        let mut rng = fastrand::Rng::with_seed(5);
        let mut r = || DVec3::new(rng.f64(), rng.f64(), rng.f64()) * 4.0 - 2.0;
        for _ in 0..300 {
            let (a, b, c, p) = (r(), r(), r(), r());
            let exact = distance_squared(p, &[a, b, c]).sqrt();
            let brute = sampled(p, a, b, c);
            // The samples are a grid of step 1/200 of the edges.
            let step = (b - a).length().max((c - a).length()) / 200.0;
            assert!(exact <= brute + 1e-12, "{exact} > {brute}");
            assert!(brute - exact <= step, "{exact} vs {brute}");
        }
        let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::Y);
        assert_eq!(
            closest_point_on_triangle(DVec3::new(0.25, 0.25, 3.0), a, b, c),
            DVec3::new(0.25, 0.25, 0.0)
        );
        assert_eq!(
            closest_point_on_triangle(DVec3::new(-1.0, -1.0, 0.0), a, b, c),
            a
        );
        assert_eq!(
            closest_point_on_triangle(DVec3::new(2.0, 2.0, 0.0), a, b, c),
            DVec3::new(0.5, 0.5, 0.0)
        );
    }
}
