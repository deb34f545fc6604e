//! [`ShadowGrid`]: the balls binned into a uniform world-space grid, so a
//! shadow ray from a hit towards a light finds the balls it passes.
//!
//! Camera rays get their candidates from the screen tiles; shadow rays go
//! in any direction, so they walk a grid of cells about a radius wide by 3D
//! DDA (Amanatides–Woo). Each ball is binned into every cell its support
//! (a sphere) reaches into, so a cell's bin holds every ball that adds to
//! the field in the cell, and the field anywhere in the cell is the sum over its bin.
//! Each cell keeps a bound on that sum (each ball's kernel at its nearest
//! point of the cell); a cell whose bound is below `T` cannot hold the
//! surface and is passed over.
//!
//! In a cell that can, the ray looks for a root of `F − T` with the cell's
//! balls only, with the same solver as camera rays
//! ([`ray::first_hit_tile`]). The kernels are never negative, so the field
//! of some of the balls is at most the whole field: a root found with them
//! means the whole field reaches `T` too, while the ray started below it, so
//! the surface lies between the hit and the light. And where the whole field
//! crosses `T`, in some cell, that cell's balls give the whole field there,
//! so the crossing is found. A light is blocked exactly when the walk finds
//! one, and the walk stops at the first.

use glam::{DVec3, IVec3, Vec3};
use rayon::prelude::*;

use super::balls::Balls;
use super::kernel::Kernel;
use super::ray::{self, Cand, Chord, RayParams, Scratch, chord};
use super::tiles::FrameBall;
use crate::geometry::Ray;
use crate::render::bins::Bins;

/// At most about this many cells per ball (the cells grow when the balls'
/// box would need more): the grid's memory stays proportional to the
/// balls.
const CELLS_PER_BALL: f64 = 8.0;

/// Every ball of a frame (the shadow casters include balls the camera does
/// not see) in a uniform grid of cells, each ball in the cells its support
/// reaches into.
#[derive(Debug, Clone)]
pub struct ShadowGrid {
    /// The balls, indexed as the bins' items.
    pub balls: Vec<FrameBall>,
    cells: Cells,
    bins: Bins,
    /// Per cell, at least the field anywhere in it.
    bound: Vec<f64>,
}

/// Per-thread buffers for shadow rays.
#[derive(Debug, Default)]
pub struct ShadowScratch {
    scratch: Scratch,
    cands: Vec<Cand>,
}

/// A grid's geometry: `dims` cubic cells per axis, `size` wide, from
/// `origin`.
#[derive(Debug, Clone, Copy)]
struct Cells {
    origin: DVec3,
    size: f64,
    dims: IVec3,
}

impl Cells {
    fn count(&self) -> usize {
        (self.dims.x * self.dims.y * self.dims.z) as usize
    }

    /// Cell `c`'s index (x fastest).
    fn index(&self, c: IVec3) -> usize {
        ((c.z * self.dims.y + c.y) * self.dims.x + c.x) as usize
    }

    /// The cell of index `idx`.
    fn coords(&self, idx: usize) -> IVec3 {
        let (i, d) = (idx as i32, self.dims);
        IVec3::new(i % d.x, (i / d.x) % d.y, i / (d.x * d.y))
    }

    /// The cell holding `p`, clamped to the grid.
    fn containing(&self, p: DVec3) -> IVec3 {
        ((p - self.origin) / self.size)
            .floor()
            .as_ivec3()
            .clamp(IVec3::ZERO, self.dims - 1)
    }

    /// The squared distance from `p` to cell `c`'s box.
    fn dist2(&self, c: IVec3, p: DVec3) -> f64 {
        let lo = self.origin + c.as_dvec3() * self.size;
        (p.clamp(lo, lo + self.size) - p).length_squared()
    }
}

impl ShadowGrid {
    /// Bins `balls` and bounds the field of `kernel` per cell (colours are
    /// not needed: shadow rays only find roots). `None` when there are none.
    pub fn build(balls: &Balls, kernel: Kernel) -> Option<Self> {
        let all = balls.as_slice();
        if all.is_empty() {
            return None;
        }
        let (mut lo, mut hi, mut r_max) = (DVec3::MAX, DVec3::MIN, 0.0f64);
        for b in all {
            let (c, r) = (b.center.as_dvec3(), b.radius as f64);
            lo = lo.min(c - r);
            hi = hi.max(c + r);
            r_max = r_max.max(r);
        }
        let extent = (hi - lo).max(DVec3::splat(1e-9));
        // Cells a radius wide, or wider when that would make too many.
        let budget = CELLS_PER_BALL * all.len() as f64 + 64.0;
        let mut size = r_max.max((extent.x * extent.y * extent.z / budget).cbrt());
        // Axes thinner than a cell still count one: grow the cells until
        // the count is within the budget (balls strung along a line).
        let dims_for = |size: f64| (extent / size).ceil().max(DVec3::ONE);
        while dims_for(size).element_product() > budget {
            size *= 1.25;
        }
        let cells = Cells {
            origin: lo,
            size,
            dims: dims_for(size).as_ivec3(),
        };
        let frame_balls: Vec<FrameBall> = all
            .iter()
            .map(|b| {
                let r = b.radius as f64;
                FrameBall {
                    center: b.center.as_dvec3(),
                    r2: r * r,
                    inv_r2: 1.0 / (r * r),
                    t_lo: 0.0,
                    color: Vec3::ONE,
                }
            })
            .collect();
        let n = cells.count();
        let bins = Bins::build(n, frame_balls.len(), |k, put| {
            let fb = &frame_balls[k];
            let r = fb.r2.sqrt();
            let (a, b) = (
                cells.containing(fb.center - r),
                cells.containing(fb.center + r),
            );
            // The cells the ball's support reaches into (a little more
            // for rounding), not all those its bounding box touches.
            let reach = fb.r2 * (1.0 + 1e-6);
            for z in a.z..=b.z {
                for y in a.y..=b.y {
                    for x in a.x..=b.x {
                        let c = IVec3::new(x, y, z);
                        if cells.dist2(c, fb.center) <= reach {
                            put(cells.index(c));
                        }
                    }
                }
            }
        });
        let bound = (0..n)
            .into_par_iter()
            .map(|idx| {
                let c = cells.coords(idx);
                bins.get(idx)
                    .iter()
                    .map(|&k| {
                        let fb = &frame_balls[k as usize];
                        let s = cells.dist2(c, fb.center) * fb.inv_r2;
                        if s >= 1.0 { 0.0 } else { kernel.at_s(s) }
                    })
                    .sum::<f64>()
                    // Room for the rounding of the cell's box.
                    * (1.0 + 1e-9)
                    + 1e-12
            })
            .collect();
        Some(ShadowGrid {
            balls: frame_balls,
            bound,
            cells,
            bins,
        })
    }

    /// Whether the surface `F = T` of `p` (whose `balls` must be this
    /// grid's) crosses `ray` (unit direction) at some `t > 0`; the ray
    /// must start outside the surface (`F < T`).
    pub fn blocked(&self, p: &RayParams<'_>, ray: &Ray, s: &mut ShadowScratch) -> bool {
        let margin = 1e-6 * self.cells.size;
        self.walk(ray, |idx, t_a, t_b| {
            if self.bound[idx] < p.threshold() {
                return false;
            }
            // From where the ray enters the cell, with the balls that reach
            // its stretch of the ray in the cell: a crossing in the cell is
            // theirs, and a root of theirs anywhere blocks the ray (starting
            // inside their field, the solver finds where it leaves: the
            // whole field was at `T` or more there too).
            let entry = Ray {
                origin: ray.at(t_a as f32),
                dir: ray.dir,
            };
            let o = entry.origin.as_dvec3();
            let d = entry.dir.as_dvec3();
            let len = t_b - t_a + margin;
            s.cands.clear();
            for &k in self.bins.get(idx) {
                let fb = &self.balls[k as usize];
                match chord(fb.center, fb.r2, o, d) {
                    Some(Chord { t0, t1, .. }) if t1 > 0.0 && t0 < len => {
                        s.cands.push(Cand::new(fb, t0, k, o))
                    }
                    _ => {}
                }
            }
            if s.cands.is_empty() {
                return false;
            }
            s.cands
                .sort_unstable_by(|a, b| a.t_lo().total_cmp(&b.t_lo()));
            ray::first_hit_tile(p, &entry, &s.cands, o, &mut s.scratch)
                .t
                .is_some()
        })
    }

    /// Calls `visit` with the index of every cell `ray` crosses from its
    /// origin on, in order, and the stretch `[t_a, t_b]` of the ray in it,
    /// until it returns true (then true).
    fn walk(&self, ray: &Ray, mut visit: impl FnMut(usize, f64, f64) -> bool) -> bool {
        let Cells { origin, size, dims } = self.cells;
        let o = (ray.origin.as_dvec3() - origin) / size;
        let d = ray.dir.as_dvec3();
        // Enter the grid's box (in cell units) if the origin is outside it.
        let inv = d.recip();
        let t0 = (DVec3::ZERO - o) * inv;
        let t1 = (dims.as_dvec3() - o) * inv;
        let t_enter = t0.min(t1).max_element().max(0.0);
        let t_exit = t0.max(t1).min_element();
        if t_enter.is_nan() || t_exit.is_nan() || t_enter > t_exit {
            return false;
        }
        let start = o + d * t_enter;
        let mut c = start.floor().as_ivec3().clamp(IVec3::ZERO, dims - 1);
        let step = IVec3::new(
            if d.x >= 0.0 { 1 } else { -1 },
            if d.y >= 0.0 { 1 } else { -1 },
            if d.z >= 0.0 { 1 } else { -1 },
        );
        // Per axis the parameter of the next cell plane, computed from the
        // cell index each time (no accumulated drift).
        let next_t = |c: IVec3| {
            let plane = (c + step.max(IVec3::ZERO)).as_dvec3();
            let t = (plane - o) * inv;
            DVec3::select(d.abs().cmpgt(DVec3::ZERO), t, DVec3::INFINITY)
        };
        let mut t_prev = t_enter;
        loop {
            let t = next_t(c);
            let m = t.min_element();
            let t_next = m.min(t_exit);
            if visit(self.cells.index(c), t_prev * size, t_next * size) {
                return true;
            }
            if m > t_exit || !m.is_finite() {
                return false;
            }
            t_prev = m;
            let axis = if t.x == m {
                0
            } else if t.y == m {
                1
            } else {
                2
            };
            c[axis] += step[axis];
            if c[axis] < 0 || c[axis] >= dims[axis] {
                return false;
            }
        }
    }

    /// The balls binned in the cells `ray` crosses, each once, into `out`.
    #[cfg(test)]
    fn gather(&self, ray: &Ray, out: &mut Vec<u32>) {
        out.clear();
        self.walk(ray, |idx, _, _| {
            out.extend_from_slice(self.bins.get(idx));
            false
        });
        out.sort_unstable();
        out.dedup();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metaballs::balls::Ball;
    use crate::metaballs::ray::Scratch;

    /// `n` balls with centres in `[0, spread)³` and radii in `radii`.
    fn random_balls(
        rng: &mut fastrand::Rng,
        n: usize,
        spread: f32,
        radii: (f32, f32),
    ) -> Vec<Ball> {
        (0..n)
            .map(|_| Ball {
                center: Vec3::new(rng.f32(), rng.f32(), rng.f32()) * spread,
                radius: radii.0 + (radii.1 - radii.0) * rng.f32(),
                value: 0.0,
            })
            .collect()
    }

    /// The gathered balls include every ball the ray's half-line meets
    /// (brute force), for random balls and rays from inside and outside
    /// the grid.
    #[test]
    fn the_walk_gathers_every_ball_the_ray_meets() {
        let mut rng = fastrand::Rng::with_seed(3);
        let list = random_balls(&mut rng, 300, 4.0, (0.1, 0.4));
        let balls = Balls::new(list.clone(), false).unwrap();
        let grid = ShadowGrid::build(&balls, Kernel::Wyvill).unwrap();
        let mut found = Vec::new();
        for _ in 0..500 {
            let origin = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 6.0 - 1.0;
            let dir = (Vec3::new(rng.f32(), rng.f32(), rng.f32()) - 0.5).normalize();
            let ray = Ray { origin, dir };
            grid.gather(&ray, &mut found);
            for (k, b) in list.iter().enumerate() {
                let oc = b.center - origin;
                let t = oc.dot(dir);
                let h2 = (oc - t * dir).length_squared();
                let meets = h2 < b.radius * b.radius && t + (b.radius * b.radius - h2).sqrt() > 0.0;
                if meets {
                    assert!(found.binary_search(&(k as u32)).is_ok(), "ball {k} missed");
                }
            }
        }
        // Along an axis too (zero direction components).
        let ray = Ray {
            origin: Vec3::new(-1.0, 2.0, 2.0),
            dir: Vec3::X,
        };
        grid.gather(&ray, &mut found);
        assert!(!found.is_empty());
    }

    /// Two separate balls (their supports do not overlap): points of the
    /// lower ball's surface are blocked from a light above exactly when the
    /// half-line towards the light meets the upper ball's surface sphere
    /// (radius from the closed form), away from the shadow's edge.
    #[test]
    fn a_balls_shadow_falls_where_the_spheres_say() {
        let kernel = Kernel::Wyvill;
        let threshold = 0.5f64;
        let (lower, upper) = (Vec3::ZERO, Vec3::new(0.3, 2.5, 0.1));
        let balls = Balls::new(
            vec![
                Ball {
                    center: lower,
                    radius: 1.0,
                    value: 0.0,
                },
                Ball {
                    center: upper,
                    radius: 0.6,
                    value: 0.0,
                },
            ],
            false,
        )
        .unwrap();
        let grid = ShadowGrid::build(&balls, kernel).unwrap();
        let params = RayParams::new(&grid.balls, kernel, threshold, 1.0, 1e-5);
        // The surface radius of a lone ball: K(s) = T, s = (r/R)².
        let surface = |radius: f64| {
            let (mut a, mut b) = (0.0f64, 1.0f64);
            for _ in 0..60 {
                let m = 0.5 * (a + b);
                if kernel.at_s(m) > threshold {
                    a = m
                } else {
                    b = m
                }
            }
            radius * (0.5 * (a + b)).sqrt()
        };
        let (r_low, r_up) = (surface(1.0), surface(0.6));
        let light = Vec3::new(0.1, 1.0, -0.05).normalize();
        let mut s = ShadowScratch::default();
        let mut rng = fastrand::Rng::with_seed(11);
        let (mut shadowed, mut lit) = (0, 0);
        for _ in 0..4000 {
            let n = (Vec3::new(rng.f32(), rng.f32(), rng.f32()) - 0.5).normalize();
            if n.dot(light) <= 0.05 {
                continue;
            }
            let p = lower + n * r_low as f32;
            // The half-line's closest approach to the upper centre.
            let oc = upper - p;
            let t = oc.dot(light);
            let miss = (oc - t * light).length() as f64 - r_up;
            if t <= 0.0 || miss.abs() < 0.02 {
                continue;
            }
            let ray = Ray {
                origin: p + n * 1e-3,
                dir: light,
            };
            let blocked = grid.blocked(&params, &ray, &mut s);
            assert_eq!(blocked, miss < 0.0, "point {p}: miss distance {miss}");
            if blocked { shadowed += 1 } else { lit += 1 }
        }
        assert!(shadowed > 20 && lit > 200, "{shadowed} shadowed, {lit} lit");
    }

    /// Balls strung along a very long line get a grid within the budget
    /// (not one cell a radius wide per step of the line), and shadows
    /// still work there.
    #[test]
    fn a_long_line_of_balls_keeps_the_grid_small() {
        let list: Vec<Ball> = (0..4)
            .map(|i| Ball {
                center: Vec3::new(i as f32 * 1e8, 0.0, 0.0),
                radius: 1.0,
                value: 0.0,
            })
            .chain([Ball {
                center: Vec3::new(0.0, 2.0, 0.0),
                radius: 1.0,
                value: 0.0,
            }])
            .collect();
        let balls = Balls::new(list, false).unwrap();
        let grid = ShadowGrid::build(&balls, Kernel::Wyvill).unwrap();
        assert!(grid.cells.count() as f64 <= CELLS_PER_BALL * 5.0 + 64.0);
        let params = RayParams::new(&grid.balls, Kernel::Wyvill, 0.5, 1.0, 1e-5);
        let mut s = ShadowScratch::default();
        let up = |x: f32| Ray {
            origin: Vec3::new(x, 0.7, 0.0),
            dir: Vec3::Y,
        };
        assert!(grid.blocked(&params, &up(0.0), &mut s));
        assert!(!grid.blocked(&params, &up(1e8), &mut s));
    }

    /// The walk's answer, cell by cell with each cell's balls, is the answer
    /// of one solve along the ray with every ball the ray meets, from
    /// random points outside the surface of overlapping balls.
    #[test]
    fn cell_by_cell_agrees_with_all_the_balls_at_once() {
        let kernel = Kernel::Wyvill;
        let mut rng = fastrand::Rng::with_seed(5);
        let list = random_balls(&mut rng, 200, 3.0, (0.3, 0.7));
        let balls = Balls::new(list, false).unwrap();
        let grid = ShadowGrid::build(&balls, kernel).unwrap();
        let params = RayParams::new(&grid.balls, kernel, 0.5, 0.7, 1e-5);
        let field = |x: DVec3| {
            grid.balls
                .iter()
                .map(|b| {
                    let s = (x - b.center).length_squared() * b.inv_r2;
                    if s < 1.0 { kernel.at_s(s) } else { 0.0 }
                })
                .sum::<f64>()
        };
        let (mut s, mut scratch) = (ShadowScratch::default(), Scratch::default());
        let (mut blocked, mut tried) = (0, 0);
        for _ in 0..3000 {
            let origin = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 3.6 - 0.3;
            if field(origin.as_dvec3()) > 0.45 {
                continue;
            }
            let dir = (Vec3::new(rng.f32(), rng.f32(), rng.f32()) - 0.5).normalize();
            let ray = Ray { origin, dir };
            let (o, d) = (origin.as_dvec3(), dir.as_dvec3());
            let mut all: Vec<Cand> = grid
                .balls
                .iter()
                .enumerate()
                .filter_map(|(k, fb)| {
                    let c = chord(fb.center, fb.r2, o, d)?;
                    (c.t1 > 0.0).then(|| Cand::new(fb, c.t0, k as u32, o))
                })
                .collect();
            all.sort_unstable_by(|a, b| a.t_lo().total_cmp(&b.t_lo()));
            let want = ray::first_hit_tile(&params, &ray, &all, o, &mut scratch)
                .t
                .is_some();
            assert_eq!(
                grid.blocked(&params, &ray, &mut s),
                want,
                "from {origin} towards {dir}"
            );
            tried += 1;
            blocked += want as u32;
        }
        assert!(
            blocked > 100 && tried - blocked > 100,
            "{blocked} of {tried}"
        );
    }
}
