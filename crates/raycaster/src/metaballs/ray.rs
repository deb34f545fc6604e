//! One ray through the field `F = Σ K(|p − cᵢ|/Rᵢ)`: the first point where
//! `F` reaches the threshold, and its colour.
//!
//! The ray takes its tile's candidates in `t_lo` order, as they can
//! matter: a candidate is taken only once the sweep has reached its `t_lo`,
//! which [`tighten_tile`] raises, per tile, from the frame's bound to the
//! earliest entry of any of the tile's rays. The test of a candidate
//! against the ray's line runs a few candidates at a time, just ahead of
//! the sweep, in vector lanes (from [`CandColumns`]: no branch per
//! candidate); only those the line meets are then taken one by one.
//! Each ball the ray meets gives an entry and an exit event, queued in a
//! binary heap (the exit when the ball is entered: it takes the entry's
//! place at the heap's top, one sift); between
//! consecutive events the set of active balls is fixed, so `F − T` is a
//! polynomial in `t` there (degree 6 for Wyvill, 4 for Murakami).
//!
//! The running sum of the active balls' polynomials is kept in a
//! coordinate `x = (t − t_org)/S` (`S` the largest radius) whose origin
//! stays put while the sweep is less than `MAX_LAG` past it at an entry:
//! a ball's polynomial is added at its entry and the same coefficients are
//! subtracted at its exit while the origin has not moved (the sum resets
//! to 0 when no ball is active). An interval is first tested against the
//! sum of the active balls' peaks (a ball's kernel is largest where the ray
//! passes closest to its centre): below the threshold it holds no root and
//! costs no polynomial work. While every active ball's kernel still rises
//! along the ray (the interval ends before each one's point closest to the
//! ray), so does `F`: outside the surface, the interval holds a root only
//! if `F` reaches `T` at its end, one evaluation. With one ball active, `F`
//! is its kernel alone, which reaches `T` on a sphere: the root in closed
//! form ([`lone_root`]; the fronts of sparse balls). Otherwise a copy of the
//! sum is Taylor-shifted to the interval's start and its first root
//! isolated with Bernstein bounds ([`poly::first_root`]), to `1e-4·R_min`.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use glam::{DVec3, Vec3, Vec4};

use super::kernel::{Kernel, MAX_TERMS, Poly};
use super::poly;
use super::tiles::FrameBall;
use crate::camera::{CameraFrame, PixelRect, Projection};
use crate::geometry::Ray;
use crate::integrator::Phong;

/// A ray's entry into or exit from a ball, as one integer ordered like
/// `(t, exit before entry, ball)`: `t >= 0`, whose bits order as the
/// numbers do, in the high 64 bits; below them `!exit`, the ball's index
/// and the slot (an index into the ray's `met` list, below 2³¹). Popped
/// smallest first. Ties in `t` go by the ball's index, not by when the
/// ray met the ball, so the order of events does not depend on the order
/// in which a tile's candidates are taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Event(u128);

impl Event {
    #[inline]
    fn new(t: f64, ball: u32, slot: u32, exit: bool) -> Self {
        debug_assert!(t >= 0.0 && slot < 1 << 31);
        // +0.0 for −0.0, so that the bits order as the numbers.
        let t = t + 0.0;
        Event(
            ((t.to_bits() as u128) << 64)
                | ((!exit as u128) << 63)
                | ((ball as u128) << 31)
                | slot as u128,
        )
    }

    #[inline]
    fn t(self) -> f64 {
        f64::from_bits((self.0 >> 64) as u64)
    }

    #[inline]
    fn slot(self) -> u32 {
        self.0 as u32 & ((1 << 31) - 1)
    }

    #[inline]
    fn ball(self) -> u32 {
        (self.0 >> 31) as u32
    }

    #[inline]
    fn exit(self) -> bool {
        (self.0 >> 63) & 1 == 0
    }
}

/// A ball the ray meets: `b = (c − o)·d`, `h2` the squared distance of the
/// centre from the ray's line, `t1` where the ray leaves it; from its
/// entry on, `peak` the kernel's largest value along the ray (at `t = b`).
///
/// `kp` is the ball's polynomial as added at its entry, in the coordinates
/// of origin `epoch`: while the origin has not moved, the exit subtracts
/// it instead of composing the kernel again.
#[derive(Debug, Clone, Copy)]
struct Met {
    ball: u32,
    epoch: u32,
    b: f64,
    h2: f64,
    inv_r2: f64,
    t1: f64,
    peak: f64,
    kp: Poly,
}

/// Per-thread buffers reused from ray to ray.
#[derive(Debug, Default)]
pub struct Scratch {
    heap: BinaryHeap<Reverse<Event>>,
    met: Vec<Met>,
    /// After a hit: the balls active there (entered, not yet left), for
    /// [`shade`], in the heap's order: that follows from the tile's
    /// candidate list, the same for every renderer, so there is no need to
    /// sort them (which showed in profiles of dense lattices).
    active: Vec<u32>,
    /// The candidates for [`first_hit`] called without a tile's.
    cands: Vec<Cand>,
    /// The last hit's `t`: the next ray's root search starts there when
    /// that is in the root's bracket (neighbouring pixels hit close to
    /// each other). Where the search starts changes the iterations, not
    /// the root; a tile's rays run in a fixed order on one `Scratch`, so
    /// the images stay the same for every renderer.
    last_hit: Option<f64>,
}

/// Candidates tested against a ray's line at a time.
const CHUNK: usize = 4;

/// One chunk of candidates tested against a ray's line: for each, `b`
/// (where the ray passes closest to the centre), `h2` (the squared
/// distance of the centre from the line) and `half` (half the chord,
/// `√(R² − h2)`, NaN for a ball the line misses), as [`first_hit`]'s sweep
/// computes them one by one: the same operations in the same order, lane
/// by lane (the square roots in one vector instruction, off the sweep's
/// chain of dependent steps).
#[derive(Debug, Clone, Copy, Default)]
struct Chunk {
    b: [f64; CHUNK],
    h2: [f64; CHUNK],
    half: [f64; CHUNK],
}

impl Chunk {
    /// Tests the candidates `base..base + n` (`n <= CHUNK`) of `from`
    /// against the line through the ray's origin (`origin − shift` for
    /// candidates made for `origin`) along the unit `d`: the bits of those
    /// the line may meet (`h2 < R²`, or NaN).
    #[inline(always)]
    fn test(
        &mut self,
        from: &(impl ChunkSource + ?Sized),
        base: usize,
        n: usize,
        shift: DVec3,
        from_origin: bool,
        d: DVec3,
    ) -> u32 {
        debug_assert!(n <= CHUNK);
        let [mut ox, mut oy, mut oz, mut oc2, r2] = from.columns(base, n);
        if !from_origin {
            for l in 0..CHUNK {
                ox[l] += shift.x;
                oy[l] += shift.y;
                oz[l] += shift.z;
                oc2[l] = ox[l] * ox[l] + oy[l] * oy[l] + oz[l] * oz[l];
            }
        }
        let mut mask = 0u32;
        for l in 0..CHUNK {
            let b = ox[l] * d.x + oy[l] * d.y + oz[l] * d.z;
            let h2 = oc2[l] - b * b;
            self.b[l] = b;
            self.h2[l] = h2;
            self.half[l] = (r2[l] - h2).sqrt();
            // Kept unless the sweep's own test `h2 >= R²` rejects it (a NaN
            // is kept), in one vector compare.
            #[allow(clippy::neg_cmp_op_on_partial_ord)]
            let meets = !(h2 >= r2[l]);
            mask |= (meets as u32) << l;
        }
        mask & ((1u32 << n) - 1)
    }
}

/// Where [`Chunk::test`] reads a chunk of candidates: `centre − origin`
/// per axis, its squared length and `R²`, one array each (lanes past the
/// `n` asked for may hold anything).
trait ChunkSource {
    fn columns(&self, base: usize, n: usize) -> [[f64; CHUNK]; 5];
}

impl ChunkSource for [Cand] {
    #[inline(always)]
    fn columns(&self, base: usize, n: usize) -> [[f64; CHUNK]; 5] {
        let mut out = [[0.0f64; CHUNK]; 5];
        for (l, c) in self[base..base + n].iter().enumerate() {
            for (col, v) in out.iter_mut().zip(c.test_values()) {
                col[l] = v;
            }
        }
        out
    }
}

/// A tile's candidates' centres (relative to the origin they were made
/// for), squared distances and `R²` in columns, padded by a [`CHUNK`]: what
/// [`Chunk::test`] reads, as vector loads.
#[derive(Debug, Clone, Default)]
pub struct CandColumns {
    cols: [Vec<f64>; 5],
}

impl CandColumns {
    /// The columns of `cands`.
    pub fn fill(&mut self, cands: &[Cand]) {
        for (k, col) in self.cols.iter_mut().enumerate() {
            col.clear();
            col.extend(cands.iter().map(|c| c.test_values()[k]));
            // A chunk may start at any candidate.
            col.resize(cands.len() + CHUNK, 0.0);
        }
    }
}

impl ChunkSource for CandColumns {
    #[inline(always)]
    fn columns(&self, base: usize, _n: usize) -> [[f64; CHUNK]; 5] {
        self.cols.each_ref().map(|col| {
            let mut a = [0.0f64; CHUNK];
            a.copy_from_slice(&col[base..base + CHUNK]);
            a
        })
    }
}

impl Scratch {
    /// After a hit: the balls active there, for [`shade`].
    pub fn active(&self) -> &[u32] {
        &self.active
    }
}

/// A candidate as a tile's rays test it: what the test reads, copied once
/// per tile into one array in list order (no indirection per ray).
///
/// The centre is kept relative to an origin, the eye for a perspective
/// tile (where every ray starts), with its squared length: a ray from that
/// origin tests the ball with a dot product, and computes the chord only
/// for a ball it meets.
#[derive(Debug, Clone, Copy)]
pub struct Cand {
    /// `centre − origin`.
    oc: DVec3,
    /// `|oc|²`.
    oc2: f64,
    r2: f64,
    inv_r2: f64,
    t_lo: f64,
    ball: u32,
}

impl Cand {
    /// A candidate: ball `ball`, which is `fb`, and no ray enters it
    /// before `t_lo`, for rays from `origin` (from elsewhere costs a
    /// little more: see [`first_hit_tile`]).
    pub fn new(fb: &FrameBall, t_lo: f64, ball: u32, origin: DVec3) -> Self {
        let oc = fb.center - origin;
        Cand {
            oc,
            oc2: oc.length_squared(),
            r2: fb.r2,
            inv_r2: fb.inv_r2,
            t_lo,
            ball,
        }
    }

    /// No ray enters the ball before this.
    pub fn t_lo(&self) -> f64 {
        self.t_lo
    }

    /// What [`Chunk::test`] reads: `oc` per axis, `|oc|²`, `R²`.
    #[inline(always)]
    fn test_values(&self) -> [f64; 5] {
        [self.oc.x, self.oc.y, self.oc.z, self.oc2, self.r2]
    }
}

/// A tile's `candidates` (indices into `balls`, in `t_lo` order) as
/// [`Cand`]s for rays from `origin`, into `out`.
pub fn tile_cands(balls: &[FrameBall], candidates: &[u32], origin: DVec3, out: &mut Vec<Cand>) {
    out.clear();
    out.extend(candidates.iter().map(|&k| {
        let fb = &balls[k as usize];
        Cand::new(fb, fb.t_lo, k, origin)
    }));
}

/// Rounding allowance of [`tighten_tile`], relative to the distance of a
/// ball: the rays' directions are rounded to `f32` (about 1e-7), and a
/// chord's entry, near a grazing ray, moves by up to the square root of
/// the rounding of `h²` (about 3e-8 of the distance).
const TIGHTEN_MARGIN: f64 = 1e-6;

/// Tightens a tile's candidates (from [`tile_cands`] for rays from
/// `origin`) for the rays of its pixels `rect` under `frame`: a ball no ray of the tile meets is
/// dropped, and each other's `t_lo` (the frame's bound, the eye's distance
/// less the radius: right only for a ray through the centre) is raised to
/// the earliest entry of any ray of the tile; then the list is sorted
/// again by `t_lo` (ties by index). With balls far wider on screen than a
/// tile, most of a tile's rays pass far from most centres, and a ray tests
/// a candidate only once its sweep reaches `t_lo`: fewer tests, and fewer
/// balls met long before the ray enters them. The events come out in the
/// same order as without it (ties go by index), so the hits are the same.
///
/// The tile's rays lie in the pyramid spanned by its corner pixels' rays;
/// a centre `c` at distance `h` outside one of its side planes is at least
/// `h` from every ray in it, and a ray at distance `h` from `c` enters the
/// ball (radius `R`, `D = |c − eye|`) at `√(D² − h²) − √(R² − h²)`, which
/// grows with `h`. Perspective only (orthographic lists are left as they
/// are), and balls holding the eye keep their bound. Only the candidates
/// within `depth` of the list's first are tightened.
pub fn tighten_tile(
    frame: &CameraFrame,
    rect: &PixelRect,
    cands: &mut Vec<Cand>,
    origin: DVec3,
    depth: f64,
) {
    if frame.projection() != Projection::Perspective || rect.x1 <= rect.x0 || rect.y1 <= rect.y0 {
        return;
    }
    let eye = frame.position().as_dvec3();
    let corners = [
        (rect.x0, rect.y0),
        (rect.x1 - 1, rect.y0),
        (rect.x1 - 1, rect.y1 - 1),
        (rect.x0, rect.y1 - 1),
    ]
    .map(|(i, j)| frame.ray(i, j).dir.as_dvec3());
    // The pyramid's side planes through the eye, unit normals inwards.
    let mut planes = [DVec3::ZERO; 4];
    for (k, plane) in planes.iter_mut().enumerate() {
        let n = corners[k].cross(corners[(k + 1) % 4]);
        let len = n.length();
        // A tile one pixel wide or tall has no pyramid.
        if len.is_nan() || len <= 1e-12 {
            return;
        }
        let n = n / len;
        let inside = corners[(k + 2) % 4] + corners[(k + 3) % 4];
        *plane = if n.dot(inside) < 0.0 { -n } else { n };
    }
    // Only the candidates up to `cut` (by the frame's bound) are tightened
    // and sorted again, their bounds capped at `cut`: the rest keep theirs
    // (all above `cut`) and their place after them, so the list stays in
    // order. A tile's rays mostly stop long before the end of its list, and
    // the sort is most of the cost.
    let cut = cands.first().map_or(0.0, |c| c.t_lo) + depth;
    let prefix = cands.partition_point(|c| c.t_lo <= cut);
    // The candidates kept, as integer keys ordered like (t_lo, ball),
    // with their place in `cands` in the low bits.
    let mut keys = Vec::with_capacity(prefix);
    for (i, c) in cands[..prefix].iter_mut().enumerate() {
        let oc = c.oc + (origin - eye);
        let d2 = oc.length_squared();
        if d2 > c.r2 {
            let dist = d2.sqrt();
            let h = planes.iter().fold(0.0f64, |h, n| h.max(-n.dot(oc))) - TIGHTEN_MARGIN * dist;
            if h > 0.0 {
                let h2 = h * h;
                if h2 >= c.r2 {
                    continue;
                }
                let r = c.r2.sqrt();
                let entry = (d2 - h2).sqrt() - (c.r2 - h2).sqrt() - TIGHTEN_MARGIN * (dist + r);
                c.t_lo = c.t_lo.max(entry).min(cut);
            }
        }
        keys.push(((order_bits(c.t_lo) as u128) << 64) | ((c.ball as u128) << 32) | i as u128);
    }
    keys.sort_unstable();
    let mut out = Vec::with_capacity(keys.len() + cands.len() - prefix);
    out.extend(keys.iter().map(|&k| cands[k as u32 as usize]));
    out.extend_from_slice(&cands[prefix..]);
    *cands = out;
}

/// The bits of `x` as an integer ordered like [`f64::total_cmp`].
#[inline]
fn order_bits(x: f64) -> u64 {
    let b = x.to_bits();
    if b >> 63 == 1 { !b } else { b | 1 << 63 }
}

/// Where a ray's line `o + t·d` (unit `d`) passes through a ball.
#[derive(Debug, Clone, Copy)]
pub struct Chord {
    /// Entry and exit.
    pub t0: f64,
    pub t1: f64,
}

/// The chord of the ball (`center`, radius² `r2`) on the line `o + t·d`,
/// `None` when the line misses it.
#[inline(always)]
pub fn chord(center: DVec3, r2: f64, o: DVec3, d: DVec3) -> Option<Chord> {
    let oc = center - o;
    let b = oc.dot(d);
    let h2 = (oc - b * d).length_squared();
    if h2 >= r2 {
        return None;
    }
    let half = (r2 - h2).sqrt();
    Some(Chord {
        t0: b - half,
        t1: b + half,
    })
}

/// What a frame's rays share. The kernel and threshold are set once, by
/// [`RayParams::new`], with what follows from them.
#[derive(Debug, Clone, Copy)]
pub struct RayParams<'a> {
    /// The frame's balls.
    pub balls: &'a [FrameBall],
    kernel: Kernel,
    /// The surface's field value `T` (> 0).
    threshold: f64,
    /// Where a lone ball's kernel equals `T`, as `s = a²`
    /// ([`Kernel::level_s`]); NaN when it never does (`T >= 1`).
    level_s: f64,
    /// The polynomial coordinate's unit (the largest radius).
    pub scale: f64,
    /// Root tolerance in `x` units.
    pub tol: f64,
    /// Phong coefficients, `None`: flat colour.
    pub shading: Option<Phong>,
    /// Unit directions towards the lights; empty: a headlight.
    pub lights: &'a [Vec3],
}

impl<'a> RayParams<'a> {
    /// The parameters for the surface `F = threshold` of `balls` under
    /// `kernel`, unshaded (set `shading` and `lights` to shade).
    pub fn new(
        balls: &'a [FrameBall],
        kernel: Kernel,
        threshold: f64,
        scale: f64,
        tol: f64,
    ) -> Self {
        RayParams {
            balls,
            kernel,
            threshold,
            level_s: kernel.level_s(threshold).unwrap_or(f64::NAN),
            scale,
            tol,
            shading: None,
            lights: &[],
        }
    }

    /// The same parameters for another set of balls.
    pub fn with_balls(self, balls: &'a [FrameBall]) -> Self {
        RayParams { balls, ..self }
    }

    /// The surface's field value `T`.
    pub fn threshold(&self) -> f64 {
        self.threshold
    }
}

/// A ray's result.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RayResult {
    /// The hit's `t`, `None` for a miss.
    pub t: Option<f64>,
    /// Balls the ray met (before stopping).
    pub met: u32,
}

/// How far (in units of `scale`) the running polynomial's origin may lag
/// behind an entry before it is moved (Taylor-shifted) to the sweep: with
/// the chords of the balls active since, the origin is never more than
/// `MAX_LAG + 2` behind the sweep, which bounds the size of the
/// coefficients, so their rounding.
const MAX_LAG: f64 = 1.0;

/// Slack on the peak bound for the rounding of its running sum.
const PEAK_SLACK: f64 = 1e-9;

/// The largest value of a ball's kernel along a ray: at the point closest
/// to its centre, `h2` the squared distance of the centre from the ray's
/// line, `inv_r2` the ball's `1/R²` (the kernel decreases with distance).
#[inline]
fn peak_of(kernel: Kernel, h2: f64, inv_r2: f64) -> f64 {
    kernel.at_s(h2 * inv_r2)
}

/// The first `t >= 0` where the field of the `candidates` (indices into
/// `p.balls`, in `t_lo` order) crosses the threshold along `ray`.
pub fn first_hit(p: &RayParams<'_>, ray: &Ray, candidates: &[u32], s: &mut Scratch) -> RayResult {
    let mut cands = std::mem::take(&mut s.cands);
    let origin = ray.origin.as_dvec3();
    tile_cands(p.balls, candidates, origin, &mut cands);
    let r = first_hit_tile(p, ray, &cands, origin, s);
    s.cands = cands;
    r
}

/// [`first_hit`] for a tile's candidates made by [`tile_cands`] (or
/// [`Cand::new`]) for rays from `origin`: fastest for a ray from there.
pub fn first_hit_tile(
    p: &RayParams<'_>,
    ray: &Ray,
    candidates: &[Cand],
    origin: DVec3,
    s: &mut Scratch,
) -> RayResult {
    first_hit_from(p, ray, candidates, candidates, origin, s)
}

/// [`first_hit_tile`] with the candidates' [`CandColumns`] as well (made
/// from the same list): faster.
#[inline(always)]
pub fn first_hit_columns(
    p: &RayParams<'_>,
    ray: &Ray,
    candidates: &[Cand],
    columns: &CandColumns,
    origin: DVec3,
    s: &mut Scratch,
) -> RayResult {
    first_hit_from(p, ray, candidates, columns, origin, s)
}

/// [`first_hit_tile`] with the candidates' line tests read from `columns`:
/// the one dispatch on the kernel.
#[inline(always)]
fn first_hit_from(
    p: &RayParams<'_>,
    ray: &Ray,
    candidates: &[Cand],
    columns: &(impl ChunkSource + ?Sized),
    origin: DVec3,
    s: &mut Scratch,
) -> RayResult {
    match p.kernel {
        Kernel::Wyvill => first_hit_n::<6, true>(p, ray, candidates, columns, origin, s),
        Kernel::Murakami => first_hit_n::<4, true>(p, ray, candidates, columns, origin, s),
    }
}

/// [`first_hit`] for a kernel of degree `N` along the ray.
///
/// The running sum `poly`, its origin `t_org` and the peak bound are as in
/// the module docs. `SHORTCUTS = false` turns off what only saves work
/// (the peak bound, the rising test, a lone ball's closed form): the
/// tests compare the hits with and without them.
#[inline(always)]
fn first_hit_n<const N: usize, const SHORTCUTS: bool>(
    p: &RayParams<'_>,
    ray: &Ray,
    candidates: &[Cand],
    columns: &(impl ChunkSource + ?Sized),
    origin: DVec3,
    s: &mut Scratch,
) -> RayResult {
    s.heap.clear();
    s.met.clear();
    s.active.clear();
    let o = ray.origin.as_dvec3();
    // A unit direction to rounding in f64 (the `f32` one is unit to about
    // 1e-7), so that a ball's squared distance from the line is `|oc|² −
    // b²`; `t` along it is the ray's own `t` times `inv_len`.
    let d = ray.dir.as_dvec3();
    let inv_len = 1.0 / d.length();
    let d = d * inv_len;
    // The candidates' centres are relative to `origin`: a ray from
    // elsewhere (orthographic, a test) moves them (exactly 0 when it
    // starts there).
    let shift = origin - o;
    let from_origin = shift == DVec3::ZERO;
    let kernel = p.kernel;
    let sc = p.scale;
    let inv_sc = 1.0 / sc;
    let mut poly: Poly = [0.0; MAX_TERMS];
    let mut t_org = 0.0f64;
    // Counts the moves of the origin (an entry's polynomial is valid at its
    // exit while this has not changed).
    let mut epoch = 0u32;
    // The sum of the active balls' peaks: F <= peak along the interval.
    let mut peak = 0.0f64;
    let mut active = 0u32;
    let mut t_cur = 0.0f64;
    // +1: search for F − T rising through 0; −1 when the ray starts inside;
    // 0 until the first interval tested.
    let mut sign = 0.0f64;
    // The smallest `b` of the balls entered since nothing was last active:
    // before it every active ball's kernel rises along the ray, so `F` does.
    let mut rising_to = f64::INFINITY;
    // The candidates are tested against the ray's line a chunk at a time
    // (`CHUNK` lanes of `f64`, no branch per candidate; a chunk of 8 did
    // fewer tests at 8000 balls but more work in all at 1000): `pending` holds
    // the bits of the chunk's candidates from `base` on that the line
    // meets and the sweep has not taken yet, `tested` is where the next
    // chunk starts. Testing ahead of the sweep changes nothing but the
    // work: a candidate the line misses is dropped wherever it is met, and
    // the sweep still takes the others one by one in list order.
    let mut chunk = Chunk::default();
    let (mut base, mut pending, mut tested) = (0usize, 0u32, 0usize);
    loop {
        // Take every candidate that may enter before the next event.
        loop {
            if pending == 0 {
                if tested >= candidates.len() {
                    break;
                }
                base = tested;
                tested = (base + CHUNK).min(candidates.len());
                pending = chunk.test(columns, base, tested - base, shift, from_origin, d);
                continue;
            }
            let lane = pending.trailing_zeros() as usize;
            let fb = &candidates[base + lane];
            if let Some(e) = s.heap.peek()
                && fb.t_lo > e.0.t()
            {
                break;
            }
            pending &= pending - 1;
            let (b, h2, half) = (chunk.b[lane], chunk.h2[lane], chunk.half[lane]);
            let (t0, t1) = (b - half, b + half);
            if t1 <= t_cur {
                continue;
            }
            let slot = s.met.len() as u32;
            s.met.push(Met {
                ball: fb.ball,
                b,
                h2,
                inv_r2: fb.inv_r2,
                t1,
                peak: 0.0,
                epoch: u32::MAX,
                kp: [0.0; MAX_TERMS],
            });
            // The exit is queued when the ball is entered.
            s.heap
                .push(Reverse(Event::new(t0.max(t_cur), fb.ball, slot, false)));
        }
        // The next event stays in the heap until it is done with: an entry
        // gives its place to the ball's exit (one sift instead of a pop and
        // a push).
        let Some(&Reverse(ev)) = s.heap.peek() else {
            return RayResult {
                t: None,
                met: s.met.len() as u32,
            };
        };
        let t_ev = ev.t();
        // The interval [t_cur, t_ev] with the active set fixed.
        if active > 0
            && t_ev > t_cur
            && (!SHORTCUTS || sign < 0.0 || peak + PEAK_SLACK >= p.threshold)
            // Outside the surface with `F` rising on the interval: a root
            // only if `F` reaches `T` by its end (one evaluation, where the
            // shift and bound below take several times as long).
            && !(SHORTCUTS
                && sign > 0.0
                && t_ev <= rising_to
                && poly::eval_n::<N>(&poly, (t_ev - t_org) * inv_sc) < p.threshold)
        {
            // A lone ball's surface is the sphere where its kernel is `T`:
            // the root in closed form, where the search below would take
            // a shift, a bound and iterations (sparse balls' fronts).
            // The lone ball is the one whose exit is queued: found when
            // needed, as one more value carried through the sweep (the
            // active slots XORed) cost more than the search saved at 1000
            // balls. (Written as a match: the same as a closure passed to
            // `and_then`, which made the whole sweep compile to more
            // instructions.)
            let lone = (SHORTCUTS && active == 1)
                .then(|| s.heap.iter().find(|e| e.0.exit()))
                .flatten();
            let lone_root = match lone {
                Some(e) => lone_root(
                    &s.met[e.0.slot() as usize],
                    p.level_s,
                    t_cur,
                    t_ev,
                    &mut sign,
                ),
                None => None,
            };
            let root = match lone_root {
                Some(root) => root,
                None => {
                    // F − T in the interval's own coordinate x = (t − t_cur)/S.
                    let mut q = poly;
                    poly::shift_n::<N>(&mut q, (t_cur - t_org) * inv_sc);
                    let len = (t_ev - t_cur) * inv_sc;
                    q[0] -= p.threshold;
                    if sign == 0.0 {
                        sign = if q[0] > 0.0 { -1.0 } else { 1.0 };
                    }
                    if sign < 0.0 {
                        q.iter_mut().for_each(|c| *c = -*c);
                    }
                    let guess = s.last_hit.map_or(f64::NAN, |t| (t - t_cur) * inv_sc);
                    poly::first_root_n::<N>(&q, len, p.tol, guess).map(|x| t_cur + x * sc)
                }
            };
            if let Some(t) = root {
                // The active balls are those whose exit is queued.
                s.active
                    .extend(s.heap.iter().filter(|e| e.0.exit()).map(|e| e.0.ball()));
                s.last_hit = Some(t);
                return RayResult {
                    t: Some(t * inv_len),
                    met: s.met.len() as u32,
                };
            }
        }
        t_cur = t_ev;
        let slot = ev.slot();
        if ev.exit() {
            s.heap.pop();
            active -= 1;
            if active == 0 {
                poly = [0.0; MAX_TERMS];
                peak = 0.0;
                rising_to = f64::INFINITY;
                continue;
            }
            let m = &s.met[slot as usize];
            peak -= m.peak;
            let kp = if m.epoch == epoch {
                m.kp
            } else {
                compose_at(kernel, m, t_org, sc)
            };
            for (a, c) in poly.iter_mut().zip(kp).take(N + 1) {
                *a -= c;
            }
        } else {
            // A new origin at the sweep when the last one is far behind (so
            // the coefficients stay small) or nothing is active.
            if active == 0 {
                t_org = t_cur;
                epoch += 1;
            } else if (t_cur - t_org) * inv_sc > MAX_LAG {
                poly::shift_n::<N>(&mut poly, (t_cur - t_org) * inv_sc);
                t_org = t_cur;
                epoch += 1;
            }
            active += 1;
            let m = &mut s.met[slot as usize];
            m.peak = peak_of(kernel, m.h2, m.inv_r2);
            peak += m.peak;
            rising_to = rising_to.min(m.b);
            let kp = compose_at(kernel, m, t_org, sc);
            for (a, c) in poly.iter_mut().zip(kp).take(N + 1) {
                *a += c;
            }
            m.kp = kp;
            m.epoch = epoch;
            let exit = Reverse(Event::new(m.t1, m.ball, slot, true));
            if let Some(mut top) = s.heap.peek_mut() {
                *top = exit;
            }
        }
    }
}

/// The first root of `F − T` in `[t_cur, t_ev]` where `m` is the only
/// active ball, so `F` its kernel: `F >= T` exactly on the chord of the
/// sphere `s = level_s` (`s` the ball's `a²`), `b ∓ √(level_s·R² − h²)`.
/// `Some(None)` when the interval holds no root; `None` when the ray starts
/// inside that sphere (`sign` still 0: the first interval tested), which
/// the polynomial search handles. Sets `sign` to +1 (searching for `F`
/// rising through `T`) when it was 0. Out of line: inlined, it left the
/// sweep's other paths slower.
#[inline(never)]
fn lone_root(m: &Met, level_s: f64, t_cur: f64, t_ev: f64, sign: &mut f64) -> Option<Option<f64>> {
    if *sign < 0.0 {
        return None;
    }
    // NaN (no sphere: the kernel never reaches `T`) compares false.
    let d2 = level_s / m.inv_r2 - m.h2;
    let (t_in, t_out) = if d2 > 0.0 {
        let half = d2.sqrt();
        (m.b - half, m.b + half)
    } else {
        (f64::INFINITY, f64::NEG_INFINITY)
    };
    if *sign == 0.0 {
        if t_in < t_cur && t_cur < t_out {
            return None;
        }
        *sign = 1.0;
    }
    // Outside the surface at `t_cur`: the root is the sphere's entry if
    // the interval reaches it (`t_cur` past the entry by rounding: there).
    Some((t_cur < t_out && t_in <= t_ev).then(|| t_in.max(t_cur)))
}

/// A met ball's kernel as a polynomial in `x = (t − t_org)/S`:
/// `K(s(x))` with `s(x) = ((t_org + S·x − b)² + h2)/R²`.
#[inline(always)]
fn compose_at(kernel: Kernel, m: &Met, t_org: f64, sc: f64) -> Poly {
    let e = t_org - m.b;
    kernel.compose([
        (e * e + m.h2) * m.inv_r2,
        2.0 * sc * e * m.inv_r2,
        sc * sc * m.inv_r2,
    ])
}

/// The colour at the hit `t` of `ray` found by [`first_hit`], `active` the
/// balls active there ([`Scratch::active`]): the balls' colours blended by
/// their kernel weights, Phong-shaded with the gradient of the field as
/// normal (two-sided), flat without shading.
/// Premultiplied, opaque. `blocked(x, n, l)` says whether the light towards
/// `l` is hidden from the hit `x` (outward normal `n`, facing `l`).
#[inline(always)]
pub fn shade(
    p: &RayParams<'_>,
    ray: &Ray,
    t: f64,
    active: &[u32],
    mut blocked: impl FnMut(DVec3, Vec3, Vec3) -> bool,
) -> Vec4 {
    let o = ray.origin.as_dvec3();
    let d = ray.dir.as_dvec3();
    let x = o + t * d;
    let mut grad = DVec3::ZERO;
    let mut color = Vec3::ZERO;
    let mut weight = 0.0f64;
    // The balls active at the hit (the others add nothing there).
    for &k in active {
        let fb = &p.balls[k as usize];
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
                let outward = (-grad / len).as_vec3();
                let n = if outward.dot(view) < 0.0 {
                    -outward
                } else {
                    outward
                };
                let headlight = [view];
                let lights = if p.lights.is_empty() {
                    &headlight[..]
                } else {
                    p.lights
                };
                let mut rgb = c * ph.ka;
                for &l in lights {
                    if n.dot(l) > 0.0 && outward.dot(l) > 0.0 && blocked(x, outward, l) {
                        continue;
                    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Camera;
    use crate::metaballs::balls::{Ball, Balls};
    use crate::metaballs::tiles::TileLists;

    /// The field of `balls` at `x`, directly from the kernel.
    fn field(balls: &[FrameBall], kernel: Kernel, x: DVec3) -> f64 {
        balls
            .iter()
            .map(|b| kernel.at_s((x - b.center).length_squared() * b.inv_r2))
            .sum()
    }

    /// The parameters these tests trace with: radii 0.3 to 0.9 (the
    /// scale the largest), unshaded.
    fn test_params(balls: &[FrameBall], kernel: Kernel, threshold: f64) -> RayParams<'_> {
        RayParams::new(balls, kernel, threshold, 0.9, 1e-4 * 0.3 / 0.9)
    }

    fn random_balls(rng: &mut fastrand::Rng, n: usize, spread: f32) -> Balls {
        let balls = (0..n)
            .map(|_| Ball {
                center: Vec3::new(
                    rng.f32() * spread - spread / 2.0,
                    rng.f32() * spread - spread / 2.0,
                    rng.f32() * spread - spread / 2.0,
                ),
                radius: 0.3 + rng.f32() * 0.6,
                value: 0.0,
            })
            .collect();
        Balls::new(balls, false).unwrap()
    }

    /// [`lone_root`] against the lone ball's field sampled densely: a root
    /// it gives is in the interval, on the surface, with the field below
    /// `T` before it; "no root" means the field stays below `T`; "not
    /// mine" only for a ray that starts inside. Thresholds at and above 1
    /// (no surface), rays through and past the ball, intervals short and
    /// long, before and after the search's sign is known.
    #[test]
    fn a_lone_balls_root_is_where_its_field_first_reaches_the_threshold() {
        let mut rng = fastrand::Rng::with_seed(12);
        let (mut roots, mut none, mut inside) = (0, 0, 0);
        for kernel in [Kernel::Wyvill, Kernel::Murakami] {
            for threshold in [0.2, 0.5, 0.9, 1.0, 1.5] {
                let level_s = kernel.level_s(threshold).unwrap_or(f64::NAN);
                for case in 0..3000 {
                    let r = 0.3 + rng.f64();
                    let b = rng.f64() * 4.0 - 1.0;
                    let m = Met {
                        ball: 0,
                        epoch: 0,
                        b,
                        h2: (rng.f64() * 1.1 * r).powi(2),
                        inv_r2: 1.0 / (r * r),
                        t1: b + r,
                        peak: 0.0,
                        kp: [0.0; MAX_TERMS],
                    };
                    let field = |t: f64| kernel.at_s(((t - m.b).powi(2) + m.h2) * m.inv_r2);
                    let t_cur = b + (rng.f64() * 2.4 - 1.2) * r;
                    let t_ev = t_cur + rng.f64() * 1.5 * r;
                    // Half the cases with the sign known: outside at `t_cur`.
                    let known = case % 2 == 0 && field(t_cur) < threshold;
                    let mut sign = if known { 1.0 } else { 0.0 };
                    let below_until = |end: f64| {
                        (0..400).all(|k| {
                            let t = t_cur + (end - t_cur) * k as f64 / 400.0;
                            field(t) < threshold + 1e-9
                        })
                    };
                    match lone_root(&m, level_s, t_cur, t_ev, &mut sign) {
                        None => {
                            assert!(!known && field(t_cur) > threshold - 1e-9, "{case}");
                            assert_eq!(sign, 0.0);
                            inside += 1;
                        }
                        Some(Some(t)) => {
                            assert!(
                                t >= t_cur && t <= t_ev,
                                "{case}: {t} not in {t_cur}..{t_ev}"
                            );
                            assert!(
                                (field(t) - threshold).abs() < 1e-9,
                                "{case}: F = {}",
                                field(t)
                            );
                            assert!(below_until(t), "{case}");
                            assert_eq!(sign, 1.0);
                            roots += 1;
                        }
                        Some(None) => {
                            assert!(below_until(t_ev), "{case}");
                            assert_eq!(sign, 1.0);
                            none += 1;
                        }
                    }
                }
            }
        }
        assert!(
            roots > 1000 && none > 1000 && inside > 500,
            "{roots} {none} {inside}"
        );
    }

    #[test]
    fn chunks_of_candidates_test_as_one_by_one_from_either_layout() {
        // `Chunk::test` against the sweep's own arithmetic, candidate by
        // candidate: the same `b`, `h2` and half chord to the bit and the same verdict,
        // from the list and from its columns, for rays from the candidates'
        // origin and from elsewhere, in whole and partial chunks.
        let mut rng = fastrand::Rng::with_seed(12);
        let balls = random_balls(&mut rng, 23, 3.0);
        let eye = DVec3::new(0.5, 1.0, 6.0);
        let f = Camera::look_at(eye.as_vec3(), Vec3::ZERO, 8, 8)
            .frame()
            .unwrap();
        let lists = TileLists::build(&balls, &f, 8, 8, 8, |_| Vec3::ONE).unwrap();
        let all: Vec<u32> = (0..lists.balls.len() as u32).collect();
        let mut cands = Vec::new();
        tile_cands(&lists.balls, &all, eye, &mut cands);
        let mut columns = CandColumns::default();
        columns.fill(&cands);
        let (mut met, mut missed) = (0, 0);
        for trial in 0..400 {
            let o = if trial % 2 == 0 {
                eye
            } else {
                DVec3::new(rng.f64() * 4.0 - 2.0, rng.f64() * 4.0 - 2.0, 5.0)
            };
            let target = DVec3::new(rng.f64() * 2.0 - 1.0, rng.f64() * 2.0 - 1.0, rng.f64());
            let d = (target - o).normalize();
            let shift = eye - o;
            let from_origin = shift == DVec3::ZERO;
            let mut base = 0;
            while base < cands.len() {
                let n = (cands.len() - base).min(CHUNK).min(1 + trial % CHUNK);
                let (mut a, mut b) = (Chunk::default(), Chunk::default());
                let from_list = a.test(&cands[..], base, n, shift, from_origin, d);
                let from_columns = b.test(&columns, base, n, shift, from_origin, d);
                assert_eq!(from_list, from_columns);
                for (l, c) in cands[base..base + n].iter().enumerate() {
                    let oc = c.oc + shift;
                    let oc2 = if from_origin {
                        c.oc2
                    } else {
                        oc.length_squared()
                    };
                    let bb = oc.dot(d);
                    let h2 = oc2 - bb * bb;
                    let meets = h2 < c.r2;
                    assert_eq!(from_list >> l & 1 == 1, meets, "trial {trial} lane {l}");
                    assert_eq!(a.b[l].to_bits(), bb.to_bits());
                    assert_eq!(a.h2[l].to_bits(), h2.to_bits());
                    assert_eq!(b.b[l].to_bits(), bb.to_bits());
                    assert_eq!(b.h2[l].to_bits(), h2.to_bits());
                    if meets {
                        let half = (c.r2 - h2).sqrt();
                        assert_eq!(a.half[l].to_bits(), half.to_bits());
                        assert_eq!(b.half[l].to_bits(), half.to_bits());
                    }
                    met += meets as u32;
                    missed += !meets as u32;
                }
                assert_eq!(from_list >> n, 0, "no bit past the chunk's candidates");
                base += n;
            }
        }
        assert!(met > 500 && missed > 500, "{met} met, {missed} missed");
    }

    #[test]
    fn the_peak_bound_is_above_the_field_sampled_densely_along_random_rays() {
        let mut rng = fastrand::Rng::with_seed(21);
        for kernel in [Kernel::Wyvill, Kernel::Murakami] {
            let balls = random_balls(&mut rng, 40, 3.0);
            let lists = TileLists::build(
                &balls,
                &Camera::look_at(Vec3::new(0.0, 0.0, 6.0), Vec3::ZERO, 8, 8)
                    .frame()
                    .unwrap(),
                8,
                8,
                8,
                |_| Vec3::ONE,
            )
            .unwrap();
            let fbs = &lists.balls;
            let mut checked = 0;
            for _ in 0..300 {
                let o = DVec3::new(rng.f64() * 8.0 - 4.0, rng.f64() * 8.0 - 4.0, 6.0);
                let target = DVec3::new(
                    rng.f64() * 2.0 - 1.0,
                    rng.f64() * 2.0 - 1.0,
                    rng.f64() * 2.0 - 1.0,
                );
                let d = (target - o).normalize();
                // Each ball's chord and peak along this ray.
                let chords: Vec<(f64, f64, f64)> = fbs
                    .iter()
                    .filter_map(|fb| {
                        let oc = fb.center - o;
                        let b = oc.dot(d);
                        let h2 = (oc - b * d).length_squared();
                        (h2 < fb.r2).then(|| {
                            let half = (fb.r2 - h2).sqrt();
                            (b - half, b + half, peak_of(kernel, h2, fb.inv_r2))
                        })
                    })
                    .collect();
                for i in 0..4000 {
                    let t = i as f64 * 12.0 / 4000.0;
                    let bound: f64 = chords
                        .iter()
                        .filter(|c| c.0 <= t && t <= c.1)
                        .map(|c| c.2)
                        .sum();
                    let f = field(fbs, kernel, o + t * d);
                    assert!(
                        f <= bound + 1e-12,
                        "{kernel:?}: F {f} > bound {bound} at t {t}"
                    );
                    checked += (f > 0.0) as u32;
                }
            }
            assert!(checked > 10_000, "{checked}");
        }
    }

    #[test]
    fn tightened_tile_lists_keep_every_ball_met_and_change_no_hit() {
        let mut rng = fastrand::Rng::with_seed(31);
        for (n, pos) in [
            (80, Vec3::new(0.5, 1.0, 6.0)),
            (300, Vec3::new(-4.0, 2.0, 3.0)),
            // The eye inside the balls' box: some balls hold it.
            (60, Vec3::new(0.2, 0.1, 0.3)),
        ] {
            let balls = random_balls(&mut rng, n, 3.0);
            let cam = Camera::look_at(pos, Vec3::ZERO, 45, 38);
            let f = cam.frame().unwrap();
            let lists = TileLists::build(&balls, &f, 45, 38, 16, |_| Vec3::ONE).unwrap();
            let p = test_params(&lists.balls, Kernel::Wyvill, 0.5);
            // One scratch per list: a ray's root search starts at the last
            // hit of its own sequence.
            let (mut sa, mut sb, mut hits) = (Scratch::default(), Scratch::default(), 0);
            let (mut plain, mut tight) = (Vec::new(), Vec::new());
            let mut dropped = 0;
            let eye = f.position().as_dvec3();
            for ty in 0..lists.rows {
                for tx in 0..lists.cols {
                    let rect = lists.rect(tx, ty);
                    tile_cands(&lists.balls, lists.candidates(tx, ty), eye, &mut plain);
                    tight.clone_from(&plain);
                    // Not all of the list: 2 radii past its first.
                    tighten_tile(&f, &rect, &mut tight, eye, 1.8);
                    dropped += plain.len() - tight.len();
                    assert!(
                        tight
                            .windows(2)
                            .all(|w| (w[0].t_lo, w[0].ball) <= (w[1].t_lo, w[1].ball))
                    );
                    for j in rect.y0..rect.y1 {
                        for i in rect.x0..rect.x1 {
                            let ray = f.ray(i, j);
                            let (o, d) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
                            for c in &plain {
                                let center = lists.balls[c.ball as usize].center;
                                let Some(ch) = chord(center, c.r2, o, d) else {
                                    continue;
                                };
                                if ch.t1 <= 0.0 {
                                    continue;
                                }
                                let kept = tight.iter().find(|k| k.ball == c.ball);
                                let kept = kept
                                    .unwrap_or_else(|| panic!("{i},{j}: ball {} dropped", c.ball));
                                assert!(
                                    ch.t0 >= kept.t_lo || ch.t0 < 0.0,
                                    "{i},{j}: {} < {}",
                                    ch.t0,
                                    kept.t_lo
                                );
                            }
                            let a = first_hit_tile(&p, &ray, &plain, eye, &mut sa);
                            let b = first_hit_tile(&p, &ray, &tight, eye, &mut sb);
                            assert_eq!(a.t.map(f64::to_bits), b.t.map(f64::to_bits), "{i},{j}");
                            hits += a.t.is_some() as u32;
                        }
                    }
                }
            }
            assert!(
                hits > 100 && dropped > 0,
                "{n}: {hits} hits, {dropped} dropped"
            );
        }
    }

    #[test]
    fn candidates_kept_relative_to_another_origin_find_the_same_hits() {
        // Orthographic tiles (and any caller) test rays from points other
        // than the origin their candidates were made for: the centres are
        // moved per ray, which may round differently from the eye's case
        // but must find the same surface.
        let mut rng = fastrand::Rng::with_seed(44);
        let balls = random_balls(&mut rng, 60, 3.0);
        let eye = Vec3::new(0.5, 1.0, 6.0);
        let f = Camera::look_at(eye, Vec3::ZERO, 8, 8).frame().unwrap();
        let lists = TileLists::build(&balls, &f, 8, 8, 8, |_| Vec3::ONE).unwrap();
        let p = test_params(&lists.balls, Kernel::Wyvill, 0.5);
        let all: Vec<u32> = (0..lists.balls.len() as u32).collect();
        let (mut own, mut other) = (Vec::new(), Vec::new());
        let (mut sa, mut sb, mut hits) = (Scratch::default(), Scratch::default(), 0);
        for _ in 0..2000 {
            let o = DVec3::new(
                rng.f64() * 8.0 - 4.0,
                rng.f64() * 8.0 - 4.0,
                5.0 + rng.f64(),
            );
            let target = DVec3::new(rng.f64() * 2.0 - 1.0, rng.f64() * 2.0 - 1.0, rng.f64());
            let ray = Ray {
                origin: o.as_vec3(),
                dir: (target - o).normalize().as_vec3(),
            };
            let o = ray.origin.as_dvec3();
            // Every ball, entry bound 0 (valid for any ray, and the lists
            // stay in `t_lo` order).
            for (list, origin) in [(&mut own, o), (&mut other, eye.as_dvec3())] {
                tile_cands(&lists.balls, &all, origin, list);
                list.iter_mut().for_each(|c| c.t_lo = 0.0);
            }
            let a = first_hit_tile(&p, &ray, &own, o, &mut sa);
            let b = first_hit_tile(&p, &ray, &other, eye.as_dvec3(), &mut sb);
            match (a.t, b.t) {
                (Some(a), Some(b)) => {
                    assert!((a - b).abs() < 1e-6, "from {o}: {a} vs {b}");
                    hits += 1;
                }
                (None, None) => {}
                (a, b) => {
                    // Only a ray grazing the surface, where two roots lie
                    // within the tolerance of each other.
                    let t = a.or(b).unwrap();
                    let x = o + t * ray.dir.as_dvec3();
                    let g = field(&lists.balls, Kernel::Wyvill, x) - 0.5;
                    assert!(g.abs() < 1e-6, "from {o}: {a:?} vs {b:?}, F - T = {g}");
                }
            }
        }
        assert!(hits > 200, "{hits}");
    }

    #[test]
    fn the_shortcuts_change_no_hit() {
        let mut rng = fastrand::Rng::with_seed(8);
        for kernel in [Kernel::Wyvill, Kernel::Murakami] {
            for (n, spread, threshold) in [(30, 3.0, 0.5), (200, 2.5, 0.3), (60, 4.0, 0.9)] {
                let balls = random_balls(&mut rng, n, spread);
                let cam = Camera::look_at(Vec3::new(0.5, 1.0, 6.0), Vec3::ZERO, 48, 40);
                let f = cam.frame().unwrap();
                let lists = TileLists::build(&balls, &f, 48, 40, 16, |_| Vec3::ONE).unwrap();
                let p = test_params(&lists.balls, kernel, threshold);
                let (mut s, mut hits) = (Scratch::default(), 0);
                let mut tile = Vec::new();
                for j in 0..40 {
                    for i in 0..48 {
                        let ray = f.ray(i, j);
                        let o = ray.origin.as_dvec3();
                        tile_cands(&lists.balls, lists.candidates(i / 16, j / 16), o, &mut tile);
                        let cands = &tile;
                        let with = match kernel {
                            Kernel::Wyvill => {
                                first_hit_n::<6, true>(&p, &ray, cands, &cands[..], o, &mut s)
                            }
                            Kernel::Murakami => {
                                first_hit_n::<4, true>(&p, &ray, cands, &cands[..], o, &mut s)
                            }
                        };
                        let without = match kernel {
                            Kernel::Wyvill => {
                                first_hit_n::<6, false>(&p, &ray, cands, &cands[..], o, &mut s)
                            }
                            Kernel::Murakami => {
                                first_hit_n::<4, false>(&p, &ray, cands, &cands[..], o, &mut s)
                            }
                        };
                        match (with.t, without.t) {
                            (Some(a), Some(b)) => {
                                assert!((a - b).abs() < 1e-4, "{kernel:?} {i},{j}: {a} vs {b}");
                                hits += 1;
                            }
                            (None, None) => {}
                            // Only a grazing pair of roots, within the
                            // tolerance of each other, may be seen by one
                            // and not the other.
                            (Some(a), None) | (None, Some(a)) => {
                                let x = ray.origin.as_dvec3() + a * ray.dir.as_dvec3();
                                let g = field(&lists.balls, kernel, x) - threshold;
                                assert!(g.abs() < 1e-6, "{kernel:?} {i},{j}: {a} F - T = {g}");
                            }
                        }
                    }
                }
                assert!(hits > 50, "{kernel:?} {n}: {hits}");
            }
        }
    }
}
