//! A bounding volume hierarchy over triangles for nearest-triangle queries.
//!
//! Built top-down: each node's triangles are split at the median of their
//! centroids along the longest axis of the centroids' box, down to leaves of
//! at most [`LEAF_SIZE`] triangles. A median split is not the best tree for
//! ray tracing (SAH is), but for distance queries on scanned meshes of
//! evenly sized triangles it is nearly as good, cannot degenerate, and builds
//! in `O(n log n)`. Nodes are stored depth-first in one array with the
//! triangles reordered to match, so a leaf is a contiguous range.
//!
//! A query visits the nearer child first and skips every node whose box is
//! farther than the best distance found so far; starting from a good upper
//! bound (the neighbouring voxel's answer, see [`Bvh::nearest`]) prunes most
//! of the tree at once.

use glam::DVec3;

use super::distance::distance_squared;

/// Most triangles in a leaf.
pub const LEAF_SIZE: usize = 4;

#[derive(Debug, Clone, Copy)]
struct Node {
    lo: DVec3,
    hi: DVec3,
    /// Leaf: first triangle; inner node: index of the second child (the
    /// first child follows the node).
    start: u32,
    /// Leaf: number of triangles; inner node: 0.
    count: u32,
}

/// The hierarchy, owning its triangles (in leaf order).
#[derive(Debug, Clone)]
pub struct Bvh {
    nodes: Vec<Node>,
    triangles: Vec<[DVec3; 3]>,
    /// Original index of each reordered triangle.
    ids: Vec<u32>,
}

/// The answer of a nearest-triangle query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nearest {
    /// Squared distance to the nearest triangle.
    pub distance_squared: f64,
    /// That triangle's index in the hierarchy's order ([`Bvh::triangle`]).
    pub triangle: u32,
}

fn bounds(t: &[DVec3; 3]) -> (DVec3, DVec3) {
    (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]))
}

/// Squared distance from `p` to the box `[lo, hi]` (0 inside).
fn box_distance_squared(p: DVec3, lo: DVec3, hi: DVec3) -> f64 {
    let d = (lo - p).max(p - hi).max(DVec3::ZERO);
    d.length_squared()
}

impl Bvh {
    /// Builds the hierarchy over `triangles` (at least one).
    pub fn new(triangles: Vec<[DVec3; 3]>) -> Bvh {
        let mut order: Vec<u32> = (0..triangles.len() as u32).collect();
        let centroids: Vec<DVec3> = triangles
            .iter()
            .map(|t| (t[0] + t[1] + t[2]) / 3.0)
            .collect();
        let mut nodes = Vec::with_capacity(2 * triangles.len() / LEAF_SIZE + 1);
        build(&mut nodes, &triangles, &centroids, &mut order, 0);
        let reordered = order.iter().map(|&i| triangles[i as usize]).collect();
        Bvh {
            nodes,
            triangles: reordered,
            ids: order,
        }
    }

    /// Triangle `i` in the hierarchy's order.
    pub fn triangle(&self, i: u32) -> &[DVec3; 3] {
        &self.triangles[i as usize]
    }

    /// The index in the input of triangle `i` of the hierarchy's order.
    pub fn original_index(&self, i: u32) -> u32 {
        self.ids[i as usize]
    }

    /// The triangle nearest to `p`. `hint` (a triangle index in the
    /// hierarchy's order, usually the answer at a neighbouring point) is
    /// measured first: its distance bounds the search from the start.
    pub fn nearest(&self, p: DVec3, hint: Option<u32>) -> Nearest {
        let mut best = Nearest {
            distance_squared: f64::INFINITY,
            triangle: 0,
        };
        if let Some(h) = hint.filter(|&h| (h as usize) < self.triangles.len()) {
            best = Nearest {
                distance_squared: distance_squared(p, &self.triangles[h as usize]),
                triangle: h,
            };
        }
        // Entries are (node, squared distance to its box), so a node's box
        // is measured once, when its parent is opened. The median split
        // halves the triangles at each level, so the depth is below 32 and
        // the stack, holding at most one entry per level plus one, fits in
        // a fixed array (no allocation per query).
        let mut stack = [(0u32, 0.0f64); 64];
        let mut len = 1;
        while len > 0 {
            len -= 1;
            let (i, box_d) = stack[len];
            if box_d >= best.distance_squared {
                continue;
            }
            let node = &self.nodes[i as usize];
            if node.count > 0 {
                let start = node.start as usize;
                for (k, t) in self.triangles[start..start + node.count as usize]
                    .iter()
                    .enumerate()
                {
                    let d = distance_squared(p, t);
                    if d < best.distance_squared {
                        best = Nearest {
                            distance_squared: d,
                            triangle: (start + k) as u32,
                        };
                    }
                }
                continue;
            }
            let (a, b) = (i + 1, node.start);
            let da = {
                let n = &self.nodes[a as usize];
                box_distance_squared(p, n.lo, n.hi)
            };
            let db = {
                let n = &self.nodes[b as usize];
                box_distance_squared(p, n.lo, n.hi)
            };
            // Pushed last is visited first: the nearer child. Children
            // already beyond the best distance are not pushed.
            let (near, far) = if da <= db {
                ((a, da), (b, db))
            } else {
                ((b, db), (a, da))
            };
            if far.1 < best.distance_squared {
                stack[len] = far;
                len += 1;
            }
            if near.1 < best.distance_squared {
                stack[len] = near;
                len += 1;
            }
        }
        best
    }
}

/// Appends the subtree over `order[..]` (indices into `triangles`, which
/// start at `offset` in the final order) to `nodes`; returns its root index.
fn build(
    nodes: &mut Vec<Node>,
    triangles: &[[DVec3; 3]],
    centroids: &[DVec3],
    order: &mut [u32],
    offset: usize,
) -> u32 {
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    let (mut clo, mut chi) = (lo, hi);
    for &t in order.iter() {
        let (l, h) = bounds(&triangles[t as usize]);
        lo = lo.min(l);
        hi = hi.max(h);
        clo = clo.min(centroids[t as usize]);
        chi = chi.max(centroids[t as usize]);
    }
    let index = nodes.len() as u32;
    nodes.push(Node {
        lo,
        hi,
        start: offset as u32,
        count: order.len() as u32,
    });
    if order.len() <= LEAF_SIZE {
        return index;
    }
    let extent = chi - clo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |&a, &b| {
        centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
    });
    let (left, right) = order.split_at_mut(mid);
    build(nodes, triangles, centroids, left, offset);
    let second = build(nodes, triangles, centroids, right, offset + mid);
    nodes[index as usize].start = second;
    nodes[index as usize].count = 0;
    index
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_matches_brute_force() {
        let mut rng = fastrand::Rng::with_seed(9);
        let mut r = || DVec3::new(rng.f64(), rng.f64(), rng.f64());
        let triangles: Vec<[DVec3; 3]> = (0..500)
            .map(|_| {
                let c = r() * 10.0;
                [c + r(), c + r(), c + r()]
            })
            .collect();
        let bvh = Bvh::new(triangles.clone());
        let mut hint = None;
        for _ in 0..500 {
            let p = r() * 14.0 - DVec3::splat(2.0);
            let brute = triangles
                .iter()
                .map(|t| distance_squared(p, t))
                .fold(f64::INFINITY, f64::min);
            let got = bvh.nearest(p, hint);
            assert_eq!(got.distance_squared, brute);
            let original = bvh.original_index(got.triangle) as usize;
            assert_eq!(distance_squared(p, &triangles[original]), brute);
            assert_eq!(bvh.triangle(got.triangle), &triangles[original]);
            hint = Some(got.triangle);
        }
    }
}
