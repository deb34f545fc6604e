//! Packets of neighbouring primary rays walked together, slice by slice
//! (the seed thesis's coherent grid traversal, §3.3.3, cut down to the
//! 16 rays of a 4×4 pixel block).
//!
//! Neighbouring pixels' rays pass through nearly the same cells. Instead of
//! a DDA per ray, the packet visits the grid in slices of cells across the
//! rays' major axis; in each slice it takes the rectangle of cells any of
//! its rays passes through, looks each cell up once in the two-level
//! occupancy structure, and loads the corners of each straddling cell once
//! for all rays. Each ray then solves only in the straddling cells it
//! actually crosses, with the walk's own arithmetic: the cell's entry and
//! exit are its planes' parameters, computed from their coordinates as the
//! DDA computes them, and the crossing is [`CellCubic`]'s. A ray's first
//! crossing is the earliest one in the first slice that has any (the
//! slices are ordered along every ray of the packet).
//!
//! What a ray finds depends on that ray alone, never on its packet: it
//! tests exactly the straddling cells it crosses, in the slices of its own
//! window ([`WINDOW`] slices from its start), and a ray not done by then
//! goes on alone with the scalar [`Search`] from the end of its window. So
//! every renderer, however it cuts the image into tiles, gives the same
//! image. The side of the iso value a ray is on is fixed until its hit: it
//! is taken where the ray starts, and a straddling cell the ray enters on
//! the other side (a crossing in a sliver between cells) is a hit at the
//! cell's entry, as in the scalar walk.

use glam::{IVec3, UVec3, Vec3};

use super::{CellCubic, Search, VoxelRay};
use crate::accel::{IsoCells, SkipGrid};
use crate::geometry::{max_to, min_to};
use crate::integrator::BLOCK;
use crate::simd::{self, Isa, Kernel, lanes_of};
use crate::volume::Volume;

/// Rays per packet: a block of 4×4 pixels ([`BLOCK`]).
pub(crate) const PACKET: usize = BLOCK;

// Lane masks are `u32`s, and `reduce` halves the lanes.
const _: () = assert!(PACKET <= 32 && PACKET.is_power_of_two());

/// How many slices a ray is walked in its packet before it goes on alone.
/// Primary rays start at their proxy depth, a cell or so before the
/// surface: most hit within a few slices, and the rays that graze the
/// silhouette and miss are better served by the scalar walk's empty-space
/// skipping than by a packet stepping slice after slice. With 16-ray
/// packets on AVX-512 the bunny's turntable ran 3-6 % faster with 32
/// slices than with 12 (20 and 64 were about as fast as 32, 8 slower).
const WINDOW: i32 = 32;

/// How far (cells) past the rays' extent in a slice the rectangle of cells
/// reaches: far beyond the rounding of a position, so that a ray grazing
/// a cell's edge still finds the cell in the rectangle.
const RECT_MARGIN: f32 = 1e-3;

/// One ray of a packet: the whole part of it to search.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PacketRay {
    pub ray: VoxelRay,
    pub t0: f32,
    pub t1: f32,
}

/// The rays of a packet, lane by lane (a structure of arrays): each lane's
/// ray in voxel space and the part of it to search, `t0..t1` (nothing
/// where either is NaN or `t0 >= t1`). Borrowed, so that the packet walk
/// reads a [`RayBlock`]'s lanes where they are.
///
/// [`RayBlock`]: crate::integrator::RayBlock
#[derive(Debug, Clone, Copy)]
pub(crate) struct PacketRays<'a> {
    pub o: &'a [[f32; PACKET]; 3],
    pub d: &'a [[f32; PACKET]; 3],
    pub inv: &'a [[f32; PACKET]; 3],
    pub t0: &'a [f32; PACKET],
    pub t1: &'a [f32; PACKET],
}

impl PacketRays<'_> {
    /// Lane `l`'s ray.
    #[inline(always)]
    fn ray(&self, l: usize) -> VoxelRay {
        let at = |v: &[[f32; PACKET]; 3]| Vec3::new(v[0][l], v[1][l], v[2][l]);
        VoxelRay::with_inverse(at(self.o), at(self.d), at(self.inv))
    }
}

/// [`PacketRays`] that own their lanes (shadow rays).
#[derive(Debug, Clone, Copy)]
pub(crate) struct PacketLanes {
    o: [[f32; PACKET]; 3],
    d: [[f32; PACKET]; 3],
    inv: [[f32; PACKET]; 3],
    t0: [f32; PACKET],
    t1: [f32; PACKET],
}

impl PacketLanes {
    /// Every lane along +x from the origin, with nothing to search.
    pub const EMPTY: PacketLanes = PacketLanes {
        o: [[0.0; PACKET]; 3],
        d: [[1.0; PACKET], [0.0; PACKET], [0.0; PACKET]],
        inv: [
            [1.0; PACKET],
            [f32::INFINITY; PACKET],
            [f32::INFINITY; PACKET],
        ],
        t0: [f32::NAN; PACKET],
        t1: [f32::NAN; PACKET],
    };

    /// Puts `r` in lane `l`.
    #[inline(always)]
    pub fn set(&mut self, l: usize, r: &PacketRay) {
        for a in 0..3 {
            self.o[a][l] = r.ray.origin[a];
            self.d[a][l] = r.ray.dir[a];
            self.inv[a][l] = r.ray.inv_dir[a];
        }
        self.t0[l] = r.t0;
        self.t1[l] = r.t1;
    }

    /// The rays `rays` in lanes `0..rays.len()`, and the mask of those
    /// lanes.
    #[cfg(test)]
    fn of(rays: &[PacketRay]) -> (Self, u32) {
        let mut lanes = Self::EMPTY;
        for (l, r) in rays.iter().enumerate() {
            lanes.set(l, r);
        }
        (lanes, ((1u64 << rays.len()) - 1) as u32)
    }

    /// The lanes as [`PacketRays`].
    #[inline(always)]
    pub fn rays(&self) -> PacketRays<'_> {
        PacketRays {
            o: &self.o,
            d: &self.d,
            inv: &self.inv,
            t0: &self.t0,
            t1: &self.t1,
        }
    }
}

/// What the search of one ray found: as [`Search`] reports it.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct PacketHit {
    pub hit: Option<(f32, UVec3)>,
    pub side: Option<bool>,
    pub steps: u64,
}

/// Searches the rays of the lanes `lanes` of `rays` for their first
/// crossings of `iso` through the occupancy structure `skip` (with its fine
/// level `fine`), lane `l`'s into `out[l]`.
pub(crate) fn search_packet<V: Volume>(
    volume: &V,
    skip: &SkipGrid,
    fine: &IsoCells,
    iso: f32,
    rays: PacketRays<'_>,
    lanes: u32,
    out: &mut [PacketHit; PACKET],
) {
    simd::dispatch(Packet {
        volume,
        skip,
        fine,
        iso,
        rays,
        lanes,
        out,
    });
}

/// [`search_packet`] as a [`Kernel`]: its lane-wise loops over the 16
/// lanes compiled 16 wide where the CPU has AVX-512, else 8 wide with AVX2
/// ([`Kernel::WIDE`]).
struct Packet<'a, V: Volume> {
    volume: &'a V,
    skip: &'a SkipGrid,
    fine: &'a IsoCells,
    iso: f32,
    rays: PacketRays<'a>,
    lanes: u32,
    out: &'a mut [PacketHit; PACKET],
}

impl<V: Volume> Kernel for Packet<'_, V> {
    type Output = ();
    const WIDE: bool = true;

    #[inline(always)]
    fn run<I: Isa>(self, isa: I) {
        let Packet {
            volume,
            skip,
            fine,
            iso,
            rays,
            lanes,
            out,
        } = self;
        // Rays are grouped by major axis and direction along it; a ray with
        // a zero direction component goes alone (its slab test would need
        // the scalar walk's care for ±0).
        let mut keys = [0u32; PACKET];
        for (l, key) in keys.iter_mut().enumerate() {
            *key = axis_key(rays.d[0][l], rays.d[1][l], rays.d[2][l]);
        }
        let mut left = lanes;
        while left != 0 {
            let first = left.trailing_zeros() as usize;
            let key = keys[first];
            if key == 0 {
                let ray = rays.ray(first);
                out[first] = alone(
                    volume,
                    skip,
                    iso,
                    &ray,
                    rays.t0[first],
                    rays.t1[first],
                    None,
                );
                left &= !(1 << first);
                continue;
            }
            let same = keys.map(|k| (k == key) as u32);
            let group = left & lane_mask(isa, &same);
            left &= !group;
            let axis = ((key - 1) / 2) as usize;
            let step = if (key - 1) % 2 == 1 { 1 } else { -1 };
            walk_group(isa, volume, skip, fine, iso, rays, group, (axis, step), out);
        }
    }
}

/// A lane's packet group as a number: 0 for a ray along `(x, y, z)` that
/// goes alone (a component zero or not finite), else `1 + 2·axis + s`
/// from its major axis and `s = 1` along it, 0 against it
/// ([`axis_of`]'s answer).
#[inline(always)]
fn axis_key(x: f32, y: f32, z: f32) -> u32 {
    let (ax, ay, az) = (x.abs(), y.abs(), z.abs());
    let k = if ax >= ay && ax >= az {
        0
    } else if ay >= az {
        1
    } else {
        2
    };
    let along = if k == 0 {
        x
    } else if k == 1 {
        y
    } else {
        z
    };
    let finite = x.is_finite() && y.is_finite() && z.is_finite();
    if x == 0.0 || y == 0.0 || z == 0.0 || !finite {
        0
    } else {
        1 + 2 * k as u32 + (along > 0.0) as u32
    }
}

/// The major axis of a ray along `d` and its step along it, `None` when a
/// direction component is zero.
#[cfg(test)]
fn axis_of(d: Vec3) -> Option<(usize, i32)> {
    if d.x == 0.0 || d.y == 0.0 || d.z == 0.0 || !d.is_finite() {
        return None;
    }
    let a = d.abs();
    let k = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    Some((k, if d[k] > 0.0 { 1 } else { -1 }))
}

/// The scalar walk of one ray over `t0..t1` (its side at `t0` known or
/// not).
fn alone<V: Volume>(
    volume: &V,
    skip: &SkipGrid,
    iso: f32,
    ray: &VoxelRay,
    t0: f32,
    t1: f32,
    side: Option<bool>,
) -> PacketHit {
    let mut search = Search::new(volume, iso, side);
    search.walk(Some(skip), ray, t0, t1);
    PacketHit {
        hit: search.hit,
        side: search.side,
        steps: search.steps,
    }
}

/// The lanes of one packet group, structure of arrays: the packet's rays
/// copied out of their [`PacketRays`] (borrowed there, the walk's loops
/// reloaded them and ran more instructions than the copy costs), with the
/// group's own part of each to search.
struct Lanes {
    o: [[f32; PACKET]; 3],
    d: [[f32; PACKET]; 3],
    inv: [[f32; PACKET]; 3],
    /// Per axis, 0 or 1: the offset of a cell's near plane from its lower
    /// corner along the lane (1 when the lane runs backwards), and of its
    /// far plane.
    near: [[f32; PACKET]; 3],
    far: [[f32; PACKET]; 3],
    t0: [f32; PACKET],
    t1: [f32; PACKET],
}

impl Lanes {
    /// Where lane `l` enters and leaves the cell with lower corner `c`
    /// (clipped to the lane's part to search; entry after exit when it
    /// misses the cell): the cell's planes' parameters, computed as the
    /// DDA computes them.
    #[inline(always)]
    fn span_in(&self, l: usize, c: Vec3) -> (f32, f32) {
        let mut tn = self.t0[l];
        let mut tf = self.t1[l];
        for a in 0..3 {
            let near = (c[a] + self.near[a][l] - self.o[a][l]) * self.inv[a][l];
            let far = (c[a] + self.far[a][l] - self.o[a][l]) * self.inv[a][l];
            // (No NaN here: no direction component is 0.)
            tn = if near > tn { near } else { tn };
            tf = if far < tf { far } else { tf };
        }
        (tn, tf)
    }
}

/// Walks the rays `group` (a bit set over `rays`), which share major axis
/// and direction `(k, step)`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn walk_group<V: Volume, I: Isa>(
    isa: I,
    volume: &V,
    skip: &SkipGrid,
    fine: &IsoCells,
    iso: f32,
    rays: PacketRays<'_>,
    group: u32,
    (k, step): (usize, i32),
    out: &mut [PacketHit; PACKET],
) {
    let dims = volume.grid().dims;
    let last = (dims.max(UVec3::splat(2)) - UVec3::splat(2)).as_ivec3();
    let (u, v) = ((k + 1) % 3, (k + 2) % 3);
    let last_a = last.to_array();
    // Lanes outside the group cross nothing: an empty interval.
    let mut lanes = Lanes {
        o: *rays.o,
        d: *rays.d,
        inv: *rays.inv,
        near: [[0.0; PACKET]; 3],
        far: [[0.0; PACKET]; 3],
        t0: [0.0; PACKET],
        t1: [0.0; PACKET],
    };
    for l in 0..PACKET {
        let in_group = (group >> l) & 1 != 0;
        lanes.t0[l] = if in_group { rays.t0[l] } else { f32::INFINITY };
        lanes.t1[l] = if in_group {
            rays.t1[l]
        } else {
            f32::NEG_INFINITY
        };
        for a in 0..3 {
            let back = (rays.d[a][l] < 0.0) as u32 as f32;
            lanes.near[a][l] = back;
            lanes.far[a][l] = 1.0 - back;
        }
    }
    // Per lane: its side of the iso value (also as bits), the slice it
    // starts in (its window is the `WINDOW` slices from there along
    // `step`), whether it is still searching, and the tolerance of its
    // crossings.
    let mut side = [false; PACKET];
    let mut side_bits = 0u32;
    let mut start = [0i32; PACKET];
    let mut tol = [0.0f32; PACKET];
    // Cells visited per lane (the DDA's steps, as the scalar walk counts
    // them): in the slices, and alone after its window. 32-bit lanes in the
    // per-cell loop, so that it is compiled as wide as its `f32`s.
    let mut steps = [0u32; PACKET];
    let mut steps_alone = [0u64; PACKET];
    let mut active = 0u32;
    for l in lanes_of(group) {
        let (t0, t1) = (rays.t0[l], rays.t1[l]);
        out[l] = PacketHit::default();
        if t0.is_nan() || t1.is_nan() || t0 >= t1 {
            continue;
        }
        let ray = rays.ray(l);
        tol[l] = ray.tol;
        // The cell the walk starts in, and the side of the iso value there:
        // the cell's, as the walk takes it, when the cell lies on one side;
        // else the cubic's value at the start, as the walk computes it.
        let probe = ray.at(t0 + ray.nudge.min(0.5 * (t1 - t0)));
        let cell = probe.floor().as_ivec3().clamp(IVec3::ZERO, last);
        side[l] = match fine.cell_state(cell.as_uvec3()) {
            Some(st) if !st.straddles => st.above,
            _ => {
                let corners = volume.corners(cell.as_uvec3());
                let p0 = ray.at(t0) - cell.as_vec3();
                CellCubic::new(&corners, p0, ray.dir.into(), iso).eval(0.0) >= 0.0
            }
        };
        side_bits |= (side[l] as u32) << l;
        out[l].side = Some(side[l]);
        steps[l] = 1;
        start[l] = cell.to_array()[k];
        active |= 1 << l;
    }
    if active == 0 {
        return;
    }
    // Slices from the earliest start along the step to the latest window's
    // end. Per slice the lanes' work is done for all lanes at once, in
    // arrays the compiler keeps in vector registers, and kept as bit masks
    // over the lanes: only the rare per-lane events (a crossing to solve, a
    // lane done) loop over lanes.
    let started = active;
    let mut s = lanes_of(active).map(|l| start[l] * step).min().unwrap_or(0) * step;
    while active != 0 {
        if s < 0 || s > last_a[k] {
            // Past the grid: the lanes still searching end without a hit.
            break;
        }
        // The lanes whose window holds slice `s` (`windowed`), the part of
        // each in it, those that have a part (`in_slice`), and their extent
        // across it (lanes without a part add nothing).
        let (near, far) = if step > 0 {
            (s as f32, (s + 1) as f32)
        } else {
            ((s + 1) as f32, s as f32)
        };
        let mut ta = [0.0f32; PACKET];
        let mut tb = [0.0f32; PACKET];
        let mut into = [0i32; PACKET];
        let mut live = [0u32; PACKET];
        let mut inside = [0u32; PACKET];
        let mut lo_u = [f32::INFINITY; PACKET];
        let mut hi_u = [f32::NEG_INFINITY; PACKET];
        let mut lo_v = [f32::INFINITY; PACKET];
        let mut hi_v = [f32::NEG_INFINITY; PACKET];
        for l in 0..PACKET {
            into[l] = (s - start[l]) * step;
            let a = max_to((near - lanes.o[k][l]) * lanes.inv[k][l], lanes.t0[l]);
            let b = min_to((far - lanes.o[k][l]) * lanes.inv[k][l], lanes.t1[l]);
            ta[l] = a;
            tb[l] = b;
            let is_live = (active >> l) & 1 != 0 && into[l] >= 0;
            live[l] = is_live as u32;
            let is_inside = is_live && a <= b;
            inside[l] = is_inside as u32;
            let (ua, ub) = (
                lanes.o[u][l] + lanes.d[u][l] * a,
                lanes.o[u][l] + lanes.d[u][l] * b,
            );
            let (va, vb) = (
                lanes.o[v][l] + lanes.d[v][l] * a,
                lanes.o[v][l] + lanes.d[v][l] * b,
            );
            if is_inside {
                lo_u[l] = min_to(ua, ub);
                hi_u[l] = max_to(ua, ub);
                lo_v[l] = min_to(va, vb);
                hi_v[l] = max_to(va, vb);
            }
        }
        let windowed = lane_mask(isa, &live);
        let in_slice = lane_mask(isa, &inside);
        // The earliest crossing per lane in this slice, the entry of the
        // cell it lies in (ties go to the cell entered first), and that
        // cell.
        let mut best_t = [f32::INFINITY; PACKET];
        let mut best_tc = [f32::INFINITY; PACKET];
        let mut best_cell = [UVec3::ZERO; PACKET];
        if in_slice != 0 {
            let (lo_u, hi_u) = (reduce(lo_u, min_to), reduce(hi_u, max_to));
            let (lo_v, hi_v) = (reduce(lo_v, min_to), reduce(hi_v, max_to));
            let cu0 = ((lo_u - RECT_MARGIN).floor() as i32).max(0);
            let cu1 = ((hi_u + RECT_MARGIN).floor() as i32).min(last_a[u]);
            let cv0 = ((lo_v - RECT_MARGIN).floor() as i32).max(0);
            let cv1 = ((hi_v + RECT_MARGIN).floor() as i32).min(last_a[v]);
            // The cell's coordinates by axis in an array: a `glam` vector
            // indexed by a run-time axis is a `match` on it (for shadow
            // rays the axes change from packet to packet).
            let mut at = [0i32; 3];
            at[k] = s;
            for cu in cu0..=cu1 {
                at[u] = cu;
                for cv in cv0..=cv1 {
                    at[v] = cv;
                    let cell = IVec3::from_array(at);
                    let Some(st) = fine.cell_state(cell.as_uvec3()) else {
                        continue;
                    };
                    if !st.straddles {
                        // A cell wholly on one side: a hit at its entry for
                        // a lane arriving from the other side (a crossing
                        // on the face between cells, or in a sliver the
                        // lane grazed), as in the walk.
                        let against = in_slice & if st.above { !side_bits } else { side_bits };
                        for l in lanes_of(against) {
                            let (tc, te) = lanes.span_in(l, cell.as_vec3());
                            if tc <= te && tc < best_t[l] {
                                best_t[l] = tc;
                                best_tc[l] = tc;
                                best_cell[l] = cell.as_uvec3();
                            }
                        }
                        continue;
                    }
                    let corners = volume.corners(cell.as_uvec3());
                    // The cell's entry and exit along each lane: its planes'
                    // parameters, as the DDA computes them; each lane's
                    // cubic in the cell, and whether it is proven to stay on
                    // the lane's side throughout (most cells a ray passes
                    // clip the surface's cell without a crossing).
                    let c = cell.as_vec3();
                    let mut tc = [0.0f32; PACKET];
                    let mut te = [0.0f32; PACKET];
                    let mut crosses = [0u32; PACKET];
                    let mut open = [0u32; PACKET];
                    let mut cubic = [CellCubic::ZERO; PACKET];
                    for l in 0..PACKET {
                        let (tn, tf) = lanes.span_in(l, c);
                        tc[l] = tn;
                        te[l] = if tn > tf { tn } else { tf };
                        let cross = (in_slice >> l) & 1 != 0 && tn <= tf && tn < best_t[l];
                        crosses[l] = cross as u32;
                        steps[l] += cross as u32;
                        let origin = Vec3::new(lanes.o[0][l], lanes.o[1][l], lanes.o[2][l]);
                        let dir = Vec3::new(lanes.d[0][l], lanes.d[1][l], lanes.d[2][l]);
                        let p0 = origin + dir * tc[l] - c;
                        cubic[l] = CellCubic::new(&corners, p0, dir, iso);
                        open[l] = (cross && !cubic[l].stays_on(side[l], te[l] - tc[l])) as u32;
                    }
                    let open = lane_mask(isa, &open);
                    if open == 0 {
                        continue;
                    }
                    // A lane whose cubic is across at the cell's entry hits
                    // there; the others' crossings are searched together
                    // (`stays_on` failed just above for each open lane).
                    let mut across = [0u32; PACKET];
                    let mut len = [0.0f32; PACKET];
                    for l in 0..PACKET {
                        across[l] = ((cubic[l].eval(0.0) >= 0.0) != side[l]) as u32;
                        len[l] = te[l] - tc[l];
                    }
                    let across = lane_mask(isa, &across);
                    let dt =
                        CellCubic::first_crossings_unproven(&cubic, &len, &tol, open & !across);
                    for l in lanes_of(open) {
                        let tc = tc[l];
                        let hit = if (across >> l) & 1 != 0 {
                            Some(tc)
                        } else {
                            (!dt[l].is_nan()).then(|| tc + dt[l])
                        };
                        if let Some(t) = hit
                            && (t, tc) < (best_t[l], best_tc[l])
                        {
                            best_t[l] = t;
                            best_tc[l] = tc;
                            best_cell[l] = cell.as_uvec3();
                        }
                    }
                }
            }
        }
        // Each windowed lane: a hit; or it left the part to search (no
        // crossing); or its window ends here and it goes on alone.
        let mut found = [0u32; PACKET];
        let mut left = [0u32; PACKET];
        let mut expires = [0u32; PACKET];
        for l in 0..PACKET {
            found[l] = (best_t[l] < f32::INFINITY) as u32;
            left[l] = (tb[l] >= lanes.t1[l] || ta[l] > tb[l]) as u32;
            expires[l] = (into[l] + 1 >= WINDOW) as u32;
        }
        let found = windowed & lane_mask(isa, &found);
        let left = windowed & !found & lane_mask(isa, &left);
        let expires = windowed & !found & !left & lane_mask(isa, &expires);
        for l in lanes_of(found) {
            out[l].hit = Some((best_t[l], best_cell[l]));
        }
        for l in lanes_of(expires) {
            let ray = rays.ray(l);
            out[l] = alone(volume, skip, iso, &ray, tb[l], rays.t1[l], Some(side[l]));
            steps_alone[l] = out[l].steps;
        }
        active &= !(found | left | expires);
        s += step;
    }
    for l in lanes_of(started) {
        out[l].steps = steps[l] as u64 + steps_alone[l];
    }
}

/// The least (`f = min_to`) or greatest (`max_to`) of the lanes, as a tree.
#[inline(always)]
fn reduce(mut x: [f32; PACKET], f: fn(f32, f32) -> f32) -> f32 {
    let mut n = PACKET;
    while n > 1 {
        n /= 2;
        for i in 0..n {
            x[i] = f(x[i], x[i + n]);
        }
    }
    x[0]
}

/// Bit `l` set when `v[l] != 0`, [`simd::LANES`] lanes at a time.
#[inline(always)]
fn lane_mask<I: Isa>(isa: I, v: &[u32; PACKET]) -> u32 {
    let mut m = 0;
    for (c, chunk) in v.chunks_exact(simd::LANES).enumerate() {
        let chunk: &[u32; simd::LANES] = chunk.try_into().expect("chunks_exact");
        m |= isa.nonzero_mask(chunk) << (c * simd::LANES);
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::MacrocellGrid;
    use crate::geometry::{Aabb, Ray};
    use crate::volume::{AnyVolume, Grid, VolumeVisitor};

    /// A sphere's distance field with ripples (a surface that bends inside
    /// cells, so that rays cross it twice in some) over a floor that lies
    /// exactly on a plane of cell faces (where a crossing falls between
    /// cells), and its two-level structure for iso value 6; long along z,
    /// so that some rays walk past a packet's window of slices.
    fn rippled_sphere() -> (AnyVolume, SkipGrid) {
        let grid = Grid::new(UVec3::new(23, 19, 72), Vec3::ONE);
        let centre = Vec3::new(11.0, 10.0, 12.5);
        let volume = AnyVolume::from_fn(grid, |v| {
            let d = v.as_vec3() - centre;
            let sphere = d.length() + 1.5 * (0.9 * d.x).sin() * (0.7 * d.y).cos();
            sphere.min(v.y as f32 - 3.0 + ISO)
        });
        let cells = MacrocellGrid::build_any(&volume, 4, None);
        let skip = SkipGrid::for_iso(&volume, &cells, ISO);
        (volume, skip)
    }

    const ISO: f32 = 6.0;

    /// A ray from `origin` towards `target` clipped to `grid`'s box, `None`
    /// when it misses.
    fn packet_ray(grid: &Grid, origin: Vec3, target: Vec3) -> Option<PacketRay> {
        let dir = target - origin;
        let (t0, t1) = Aabb::new(Vec3::ZERO, grid.max_coord()).intersect(&Ray { origin, dir })?;
        Some(PacketRay {
            ray: VoxelRay::new(origin, dir),
            t0,
            t1,
        })
    }

    /// Packets of random rays: coherent ones (an eye outside or inside the
    /// volume looking at a small patch, as neighbouring pixels do), mixed
    /// ones with different major axes, and rays with a zero direction
    /// component.
    fn random_packets(grid: &Grid, rng: &mut fastrand::Rng, n: usize) -> Vec<Vec<PacketRay>> {
        let size = grid.max_coord();
        let point = |rng: &mut fastrand::Rng, lo: f32, hi: f32| {
            Vec3::new(rng.f32(), rng.f32(), rng.f32()) * (hi - lo) * size + lo * size
        };
        let mut packets = Vec::new();
        while packets.len() < n {
            let kind = rng.u32(0..4);
            let eye = if kind == 3 {
                point(rng, 0.1, 0.9)
            } else {
                point(rng, -0.8, 1.8)
            };
            let patch = point(rng, 0.2, 0.8);
            let spread = [0.05, 0.3, 8.0, 0.3][kind as usize];
            let rays: Vec<PacketRay> = (0..rng.usize(1..=PACKET))
                .filter_map(|_| {
                    let mut target =
                        patch + (Vec3::new(rng.f32(), rng.f32(), rng.f32()) - 0.5) * spread;
                    let mut origin = eye;
                    if rng.u32(0..8) == 0 {
                        // Along a plane of cells: one direction component 0.
                        let a = rng.usize(0..3);
                        origin[a] = origin[a].round();
                        target[a] = origin[a];
                    }
                    packet_ray(grid, origin, target)
                })
                .collect();
            if !rays.is_empty() {
                packets.push(rays);
            }
        }
        packets
    }

    struct Check<'a> {
        skip: &'a SkipGrid,
    }

    impl VolumeVisitor for Check<'_> {
        type Output = ();
        fn visit<V: Volume>(self, volume: &V) {
            let skip = self.skip;
            let fine = skip.iso_cells().unwrap();
            let mut rng = fastrand::Rng::with_seed(12);
            let (mut hits, mut handed_on, mut rounded, mut rays_seen) = (0, 0, 0, 0);
            for rays in random_packets(volume.grid(), &mut rng, 3000) {
                let mut out = [PacketHit::default(); PACKET];
                let (lanes, mask) = PacketLanes::of(&rays);
                search_packet(volume, skip, fine, ISO, lanes.rays(), mask, &mut out);
                for (l, r) in rays.iter().enumerate() {
                    // The scalar walk's hit, to the bit, in the same cell;
                    // except, rarely, by the rounding of the cell's entry:
                    // where the scalar walk starts a macrocell a hair
                    // outside it (the start clamped into the macrocell),
                    // it enters the next cell at an earlier plane than
                    // the packet, whose entry is the cell's own.
                    let mut search = Search::new(volume, ISO, None);
                    search.walk(Some(skip), &r.ray, r.t0, r.t1);
                    rays_seen += 1;
                    if out[l].hit != search.hit {
                        let (Some((a, ca)), Some((b, cb))) = (out[l].hit, search.hit) else {
                            panic!("ray {r:?}: {:?} vs {:?}", out[l].hit, search.hit);
                        };
                        assert!(
                            ca == cb && (a - b).abs() <= r.ray.tol,
                            "ray {r:?}: {a} vs {b}"
                        );
                        rounded += 1;
                    }
                    hits += search.hit.is_some() as u32;
                    // Rays whose search spans more slices than a window go
                    // on alone.
                    if let Some((k, _)) = axis_of(r.ray.dir.into()) {
                        let end = search.hit.map_or(r.t1, |(t, _)| t);
                        let slices = r.ray.at(end)[k].floor() - r.ray.at(r.t0)[k].floor();
                        handed_on += (slices.abs() >= WINDOW as f32) as u32;
                    }
                    // The same alone as in its packet.
                    let mut alone = [PacketHit::default(); PACKET];
                    let (lane, mask) = PacketLanes::of(std::slice::from_ref(r));
                    search_packet(volume, skip, fine, ISO, lane.rays(), mask, &mut alone);
                    assert_eq!(alone[0].hit, out[l].hit);
                    assert_eq!(alone[0].steps, out[l].steps);
                }
            }
            // The rays hit often, and some walk past their packet's window.
            assert!(hits > 3000, "{hits}");
            assert!(handed_on > 0);
            assert!(rounded * 1000 <= rays_seen, "{rounded} of {rays_seen}");
        }
    }

    /// Every ray of a packet finds the crossing the scalar walk finds (to
    /// the bit but for a rare rounding of a cell's entry, see `Check`),
    /// and exactly the same as when it is searched alone: what a ray finds
    /// does not depend on the rays it is searched with, so every renderer
    /// (which cut the image into different blocks) gives the same image.
    #[test]
    fn packets_find_the_scalar_walks_crossings_whatever_their_company() {
        let (volume, skip) = rippled_sphere();
        volume.visit(Check { skip: &skip });
    }

    /// A lane's group key says what `axis_of` says of its direction,
    /// zero, infinite and NaN components included.
    #[test]
    fn group_keys_are_the_axes_of_the_directions() {
        let mut rng = fastrand::Rng::with_seed(21);
        let special = [0.0, -0.0, f32::INFINITY, f32::NAN, 1e-30, -2.5];
        for _ in 0..100_000 {
            let c = |rng: &mut fastrand::Rng| {
                if rng.u32(0..6) == 0 {
                    special[rng.usize(0..special.len())]
                } else {
                    rng.f32() * 2.0 - 1.0
                }
            };
            let d = Vec3::new(c(&mut rng), c(&mut rng), c(&mut rng));
            let want = axis_of(d).map_or(0, |(k, s)| 1 + 2 * k as u32 + (s > 0) as u32);
            assert_eq!(axis_key(d.x, d.y, d.z), want, "{d}");
        }
    }
}
