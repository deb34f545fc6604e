//! The geometry of a series, in `f64` and free of DICOM parsing: the slice
//! normal, the order of slices along it, duplicate positions, and the
//! spacing between slices.

/// Slices closer than this along the normal (mm) are at the same position.
pub(super) const SAME_POSITION_MM: f64 = 0.01;
/// Relative deviation of the slice spacing from its mean that is noted.
pub(super) const SPACING_TOLERANCE: f64 = 0.01;
/// Orientation cosines that differ by less than this are the same.
const ORIENTATION_TOLERANCE: f64 = 1e-3;

/// The unit slice normal `row × column` of an Image Orientation (Patient),
/// or `None` when the two directions are (nearly) parallel or not finite.
///
/// The cosines are decimal strings rounded to a few digits, so their cross
/// product is a little off unit length; normalising it keeps the
/// projections of positions on it true distances in mm.
pub(super) fn slice_normal(o: &[f64; 6]) -> Option<[f64; 3]> {
    let (r, c) = ([o[0], o[1], o[2]], [o[3], o[4], o[5]]);
    let n = [
        r[1] * c[2] - r[2] * c[1],
        r[2] * c[0] - r[0] * c[2],
        r[0] * c[1] - r[1] * c[0],
    ];
    let len = dot(n, n).sqrt();
    // Unit row and column directions are perpendicular, so `len` is about
    // 1; far less means the orientation does not define a plane.
    (len.is_finite() && len > 1e-3).then(|| n.map(|x| x / len))
}

/// Whether two orientations are the same (both absent, or every cosine
/// within the tolerance).
pub(super) fn same_orientation(a: Option<[f64; 6]>, b: Option<[f64; 6]>) -> bool {
    match (a, b) {
        (Some(a), Some(b)) => a
            .iter()
            .zip(b)
            .all(|(x, y)| (x - y).abs() <= ORIENTATION_TOLERANCE),
        (None, None) => true,
        _ => false,
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Indices of `positions` in ascending order of their projection on
/// `normal`, with the projections; equal projections keep input order.
pub(super) fn order_along(positions: &[[f64; 3]], normal: [f64; 3]) -> Vec<(usize, f64)> {
    let mut order: Vec<(usize, f64)> = positions
        .iter()
        .enumerate()
        .map(|(i, &p)| (i, dot(p, normal)))
        .collect();
    order.sort_by(|a, b| a.1.total_cmp(&b.1));
    order
}

/// Keeps the first of each run of sorted projections closer than `tol`;
/// returns the kept entries and how many were dropped.
pub(super) fn drop_duplicates(sorted: &[(usize, f64)], tol: f64) -> (Vec<(usize, f64)>, usize) {
    let mut kept: Vec<(usize, f64)> = Vec::with_capacity(sorted.len());
    for &(i, d) in sorted {
        match kept.last() {
            Some(&(_, last)) if d - last < tol => {}
            _ => kept.push((i, d)),
        }
    }
    let dropped = sorted.len() - kept.len();
    (kept, dropped)
}

/// The distances between consecutive slices of ascending positions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct SliceSpacing {
    /// The mean distance: first to last position over the number of gaps.
    pub(super) mean: f64,
    /// The smallest gap.
    pub(super) min: f64,
    /// The largest gap.
    pub(super) max: f64,
}

impl SliceSpacing {
    /// `None` for fewer than two positions.
    pub(super) fn of(sorted: &[f64]) -> Option<SliceSpacing> {
        let (&first, &last) = (sorted.first()?, sorted.last()?);
        if sorted.len() < 2 {
            return None;
        }
        let (mut min, mut max) = (f64::INFINITY, f64::NEG_INFINITY);
        for w in sorted.windows(2) {
            let d = w[1] - w[0];
            min = min.min(d);
            max = max.max(d);
        }
        Some(SliceSpacing {
            mean: (last - first) / (sorted.len() - 1) as f64,
            min,
            max,
        })
    }

    /// Whether some gap differs from the mean by more than `tol` (relative).
    pub(super) fn varies(&self, tol: f64) -> bool {
        (self.max - self.mean).abs() > tol * self.mean
            || (self.mean - self.min).abs() > tol * self.mean
    }
}

/// `v` rounded to 6 significant digits when that moves it by at most a
/// millionth of its value, else `v` unchanged.
///
/// A spacing computed from decimal positions carries their rounding: 3 mm
/// slices come out as 3.0000002. Rounding only what is that close to a
/// short decimal removes the noise and leaves real spacings (0.48828125)
/// all but unchanged.
pub(super) fn round_noise(v: f64) -> f64 {
    if !v.is_finite() || v == 0.0 {
        return v;
    }
    let scale = 10f64.powi(5 - v.abs().log10().floor() as i32);
    let rounded = (v * scale).round() / scale;
    if (rounded - v).abs() <= 1e-6 * v.abs() {
        rounded
    } else {
        v
    }
}
