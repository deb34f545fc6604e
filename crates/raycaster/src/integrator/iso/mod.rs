//! Isosurfaces: the first crossing of the iso value by the trilinear
//! interpolant along the ray, found exactly, cell by cell.
//!
//! The search walks two levels. Macrocells (the frame's [`SkipGrid`] for the
//! iso value) whose value range excludes the iso value are jumped over,
//! through the largest empty box the grid knows; inside a macrocell whose
//! range holds it, a 3D DDA (Amanatides–Woo) visits the interpolation cells
//! the ray crosses, and in each cell whose corners straddle the iso value
//! [`CellCubic`] finds the first crossing of the cubic the interpolant is
//! along the ray. A crossing between two sample positions is never missed:
//! the walk does not sample at all.
//!
//! Robustness: the DDA's plane parameters are computed from each plane's
//! coordinate, never accumulated, so they cannot drift out of the
//! macrocell; every cell and macrocell is entered at a point found from the
//! ray itself (the first point past its entry); and the side of the iso
//! value the ray is on is carried from cell to cell, so a crossing that
//! falls in a sliver the walk stepped across (a ray grazing an edge, a
//! rounding at a face) is still reported, at the sliver's end. A direction
//! component of ±0 never steps along its axis.
//!
//! The same walk answers shadow rays, from the hit towards each light.

mod crossing;
mod packet;

pub use crossing::CellCubic;
use glam::{IVec3, UVec3, Vec3, Vec3A, Vec4};

use super::shading::powi_lanes;
use super::{BLOCK, Fragment, FrameContext, Integrator, Occupancy, RayBlock, Span, integrate_each};
use crate::accel::{CellClass, CellMasks, IsoCells, SkipGrid};
use crate::geometry::{Aabb, max_to, min_to};
use crate::simd::{self, Isa, Kernel, lanes_of, mask_of};
use crate::volume::{Corners, GradientCache, Grid, Volume};

/// How an isosurface's normal is found at a hit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum IsoNormals {
    /// The trilinear interpolation of the corners' central differences
    /// (smooth across cells; what volume rendering shades with).
    #[default]
    #[cfg_attr(
        feature = "clap",
        value(help = "Interpolated central differences of the corners (smooth)")
    )]
    Gradient,
    /// The exact derivative of the cell's trilinear interpolant (faceted:
    /// it jumps at cell faces).
    #[cfg_attr(
        feature = "clap",
        value(help = "Exact derivative of the cell's trilinear interpolant (faceted)")
    )]
    Analytic,
}

/// Where a ray first crosses the iso value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IsoHit {
    /// Ray parameter (world units).
    pub t: f32,
    /// Voxel-space position (16 bytes: written whole by the search and
    /// read whole by the shading, where a narrowly stored `Vec3` read as
    /// one vector stalls).
    pub pos: Vec3A,
    /// The interpolation cell the crossing lies in.
    pub cell: UVec3,
    /// World direction of the ray (unit), for shading.
    pub world_dir: Vec3,
}

/// The search state of an iso ray.
#[derive(Debug, Clone, Copy, Default)]
pub struct IsoState {
    /// The side of the iso value (`value ≥ iso`) where the walk so far
    /// ended, once known.
    side: Option<bool>,
    /// The first crossing, once found.
    pub hit: Option<IsoHit>,
}

/// What the hits of one tile share ([`IsoState::resolve_in`]): the TF's
/// colour at the iso value, the corner differences of the cell the last
/// hit lay in (a cell spans several pixels, so the next hit is often in it
/// again), and the shadow rays' direction towards each of the first lights
/// (the same for every shadow ray of the frame: only their origins differ).
#[derive(Debug, Clone, Copy, Default)]
pub struct ShadingCache {
    colour: Option<Vec3>,
    gradients: GradientCache,
    /// The same for the surface reflection rays meet.
    reflected: GradientCache,
    shadow_rays: [Option<VoxelRay>; CACHED_LIGHTS],
}

impl ShadingCache {
    /// The TF's colour at the frame's iso value, looked up once per tile.
    #[inline(always)]
    fn colour<V: Volume>(&mut self, ctx: &FrameContext<'_, V>) -> Vec3 {
        *self
            .colour
            .get_or_insert_with(|| ctx.tf.evaluate(ctx.iso_value).truncate())
    }
}

/// How many lights' shadow-ray directions a [`ShadingCache`] keeps.
const CACHED_LIGHTS: usize = 4;

impl Integrator for IsoState {
    type Scratch = ShadingCache;

    const SPLITS_RAYS: bool = false;

    const OCCUPANCY: Occupancy = Occupancy::IsoValue;

    /// Searches the part of the ray from sample `start` to sample `end`
    /// (the box's exit for the last piece) for the first crossing. Returns
    /// the number of cells visited.
    #[inline(always)]
    fn integrate<V: Volume>(&mut self, span: Span<'_, V>) -> u64 {
        // A ray that clipping left without samples shows nothing, in every
        // renderer (the object renderer never hands it a span).
        if self.hit.is_some() || span.seg.is_empty() {
            return 0;
        }
        let (ctx, seg) = (span.ctx, span.seg);
        // The first piece starts where the search starts (the clipped
        // box's entry, or the frame's proxy depth); frames with iso never
        // jitter, so sample `first`'s parameter is at or after the box
        // entry. A piece before the search's start is skipped.
        let t0 = if span.start <= seg.first {
            seg.t_in
        } else {
            seg.t(span.start).max(seg.t_in)
        };
        let t1 = if span.end >= seg.count {
            seg.t_out
        } else {
            seg.t(span.end)
        };
        let ray = VoxelRay::with_inverse(seg.origin, seg.dir, seg.inv_dir);
        let mut search = Search::new(ctx.volume, ctx.iso_value, self.side);
        search.walk(ctx.ess.then_some(ctx.skip), &ray, t0, t1);
        self.side = search.side;
        if let Some((t, cell)) = search.hit {
            self.hit = Some(IsoHit {
                t,
                pos: ray.at(t).into(),
                cell,
                world_dir: seg.world_dir,
            });
        }
        search.steps
    }

    const PACKETS: bool = true;

    /// Walks the rays together (`packet`) when the frame has the
    /// two-level structure to walk: the same hits as one by one. A block
    /// with one ray to search goes the same way, so that a ray's count of
    /// cells visited does not depend on how a renderer cut the image.
    fn integrate_packet<V: Volume>(
        ctx: &FrameContext<'_, V>,
        rays: &mut [Self; BLOCK],
        block: &RayBlock,
    ) -> u64 {
        let Some(fine) = packet_cells(ctx) else {
            return integrate_each(ctx, rays, block);
        };
        // A whole span: from the box's (or the proxy's) entry to the exit;
        // nothing at all for a ray clipping left empty.
        let mut empty = [0u32; BLOCK];
        for (l, e) in empty.iter_mut().enumerate() {
            *e = block.is_empty(l) as u32;
        }
        let empty = mask_of(&empty);
        let rays_in = packet::PacketRays {
            o: &block.origin,
            d: &block.dir,
            inv: &block.inv_dir,
            t0: &block.t_in,
            t1: &block.t_out,
        };
        let found = search_lanes(ctx, fine, rays_in, block.searched & !empty);
        let mut steps = 0;
        for l in lanes_of(block.searched) {
            let f = &found[l];
            // `VoxelRay::at`'s arithmetic.
            let at = |t: f32| {
                let (o, d) = (&block.origin, &block.dir);
                Vec3A::new(
                    o[0][l] + d[0][l] * t,
                    o[1][l] + d[1][l] * t,
                    o[2][l] + d[2][l] * t,
                )
            };
            rays[l] = IsoState {
                side: f.side,
                hit: f.hit.map(|(t, cell)| IsoHit {
                    t,
                    pos: at(t),
                    cell,
                    world_dir: Vec3::new(
                        block.world_dir[0][l],
                        block.world_dir[1][l],
                        block.world_dir[2][l],
                    ),
                }),
            };
            steps += f.steps;
        }
        steps
    }

    fn is_done(&self) -> bool {
        self.hit.is_some()
    }

    /// The TF colour at the iso value, lit by the frame's lights (Phong,
    /// shadow rays when asked) when shading is on; opaque.
    /// The shaded colour at the hit and its depth (the ray parameter).
    fn fragment<V: Volume>(&self, ctx: &FrameContext<'_, V>) -> Fragment {
        match self.hit {
            Some(hit) => Fragment {
                rgba: self.resolve(ctx),
                value: hit.t,
                count: 1,
            },
            None => Fragment {
                value: f32::INFINITY,
                ..Fragment::default()
            },
        }
    }

    fn resolve<V: Volume>(&self, ctx: &FrameContext<'_, V>) -> Vec4 {
        self.resolve_in(ctx, &mut ShadingCache::default())
    }

    fn resolve_in<V: Volume>(&self, ctx: &FrameContext<'_, V>, cache: &mut ShadingCache) -> Vec4 {
        let Some(hit) = self.hit else {
            return Vec4::ZERO;
        };
        let n = if ctx.shading.is_some() || ctx.reflection > 0.0 {
            normal(ctx, &hit, &mut cache.gradients)
        } else {
            None
        };
        shade(ctx, &hit, n, None, cache)
    }

    /// The block's normals and lights' Phong terms are computed lane-wise
    /// (`LaneNormals`, `lit_lanes`), and with shadows its shadow rays
    /// towards each light are walked together (`shadow_masks`): they share
    /// a direction and start close to each other on the surface. The same
    /// colours, to the bit, as one by one.
    fn resolve_packet<V: Volume>(
        rays: &[Self; BLOCK],
        lanes: u32,
        ctx: &FrameContext<'_, V>,
        cache: &mut ShadingCache,
        out: &mut [Vec4; BLOCK],
    ) {
        simd::dispatch(ResolvePacket {
            rays,
            lanes,
            ctx,
            cache,
            out,
        });
    }
}

/// [`IsoState::resolve_packet`] as a [`Kernel`]: its lane-wise loops over
/// the block's hits (normals, Phong) compiled 16 wide where the CPU has
/// AVX-512, else 8 wide with AVX2 ([`Kernel::WIDE`]).
struct ResolvePacket<'a, 'c, V: Volume> {
    rays: &'a [IsoState; BLOCK],
    lanes: u32,
    ctx: &'a FrameContext<'c, V>,
    cache: &'a mut ShadingCache,
    out: &'a mut [Vec4; BLOCK],
}

impl<V: Volume> Kernel for ResolvePacket<'_, '_, V> {
    type Output = ();
    const WIDE: bool = true;

    #[inline(always)]
    fn run<I: Isa>(self, _isa: I) {
        let ResolvePacket {
            rays,
            lanes,
            ctx,
            cache,
            out,
        } = self;
        let casts = ctx.shading.is_some() && ctx.shadows && !ctx.lights.is_empty();
        let fine = packet_cells(ctx).filter(|_| casts);
        // The lanes with a hit to shade.
        let mut hits = 0u32;
        for l in lanes_of(lanes) {
            hits |= (rays[l].hit.is_some() as u32) << l;
            out[l] = Vec4::ZERO;
        }
        // Unshaded and without reflection: the TF's colour at the iso
        // value (what `shade` gives without a normal).
        if ctx.shading.is_none() && ctx.reflection <= 0.0 {
            let c = cache.colour(ctx);
            for l in lanes_of(hits) {
                out[l] = c.extend(1.0);
            }
            return;
        }
        // Lane-wise normals and lights where nothing is one ray's own (a
        // mirror bounce, shadow rays beyond the cached lights').
        let lane_wise = ctx.shading.is_some()
            && ctx.reflection <= 0.0
            && ctx.lights.len() <= CACHED_LIGHTS
            && (!casts || fine.is_some());
        if !lane_wise {
            if let Some(fine) = fine {
                let mut normals = [None; BLOCK];
                for l in lanes_of(hits) {
                    if let Some(hit) = &rays[l].hit {
                        normals[l] = normal(ctx, hit, &mut cache.gradients);
                    }
                }
                let masks = shadow_masks(ctx, fine, rays, hits, &normals);
                for l in lanes_of(hits) {
                    if let Some(hit) = &rays[l].hit {
                        out[l] = shade(ctx, hit, normals[l], Some((&masks, l)), cache);
                    }
                }
            } else {
                for l in lanes_of(hits) {
                    out[l] = rays[l].resolve_in(ctx, cache);
                }
            }
            return;
        }
        // The gradients one by one (the cache of corner differences), the
        // rest for all lanes at once.
        let mut g = [Vec3::ZERO; BLOCK];
        let mut view = [Vec3::ZERO; BLOCK];
        for l in lanes_of(hits) {
            if let Some(hit) = &rays[l].hit {
                g[l] = gradient_at(ctx, hit, &mut cache.gradients);
                view[l] = -hit.world_dir;
            }
        }
        let normals = LaneNormals::new(&g, &view);
        let masks = match fine {
            Some(fine) => {
                let mut each = [None; BLOCK];
                for l in lanes_of(hits) {
                    each[l] = (normals.valid[l] != 0).then(|| normals.normal(l));
                }
                shadow_masks(ctx, fine, rays, hits, &each)
            }
            None => ShadowMasks::default(),
        };
        let c = cache.colour(ctx);
        let rgb = lit_lanes(ctx, c, &normals, &view, casts.then_some(&masks));
        for l in lanes_of(hits) {
            out[l] = rgb[l].extend(1.0);
        }
    }
}

/// Which of a packet's hits each of the first lights is hidden from:
/// bit `lane` of entry `k` set when light `k`'s shadow ray from the hit in
/// lane `lane` meets the surface.
type ShadowMasks = [u32; CACHED_LIGHTS];

/// The opaque colour of the surface at `hit` (unit world normal `n`, `None`
/// where there is none): the TF colour at the iso value, lit ([`lit`]) and
/// mixed with the mirror image when the frame reflects. `known`: the
/// packet's shadow masks found ahead and the hit's lane in them.
#[inline(always)]
fn shade<V: Volume>(
    ctx: &FrameContext<'_, V>,
    hit: &IsoHit,
    n: Option<Vec3>,
    known: Option<(&ShadowMasks, usize)>,
    cache: &mut ShadingCache,
) -> Vec4 {
    let c = cache.colour(ctx);
    let mut rgb = lit(ctx, c, hit, n, known, &mut cache.shadow_rays);
    if ctx.reflection > 0.0
        && let Some(n) = n
    {
        let k = ctx.reflection;
        rgb = rgb * (1.0 - k) + mirror(ctx, c, hit, n, cache) * k;
    }
    rgb.extend(1.0)
}

/// The shadow rays of a packet's hits (the lanes `hits` of `rays`, with
/// their view-facing normals `normals`) towards each of the first
/// [`CACHED_LIGHTS`] lights, walked as packets through the fine occupancy
/// level `fine`: the rays [`in_shadow`] would cast, with the same answers.
fn shadow_masks<V: Volume>(
    ctx: &FrameContext<'_, V>,
    fine: &IsoCells,
    rays: &[IsoState; BLOCK],
    hits: u32,
    normals: &[Option<Vec3>; BLOCK],
) -> ShadowMasks {
    let grid = ctx.volume.grid();
    let mut masks = ShadowMasks::default();
    for (k, (&l, mask)) in ctx.lights.iter().zip(&mut masks).enumerate() {
        let towards_light = VoxelRay::new(Vec3::ZERO, l / grid.spacing);
        // A lane per hit, in place.
        let mut lanes = packet::PacketLanes::EMPTY;
        let mut casting = 0u32;
        for lane in lanes_of(hits) {
            let (Some(hit), Some(n)) = (&rays[lane].hit, normals[lane]) else {
                continue;
            };
            if n.dot(l) <= 0.0 {
                continue;
            }
            let ray = VoxelRay {
                origin: off_surface(grid, hit.pos.into(), n).into(),
                ..towards_light
            };
            let t1 = shadow_reach(ctx, &ray, k);
            // As `secondary_hit`: nothing to search on an empty interval.
            if t1.is_nan() || t1 <= 0.0 {
                continue;
            }
            lanes.set(lane, &packet::PacketRay { ray, t0: 0.0, t1 });
            casting |= 1 << lane;
        }
        if casting == 0 {
            continue;
        }
        let found = search_lanes(ctx, fine, lanes.rays(), casting);
        for lane in lanes_of(casting) {
            if found[lane].hit.is_some() {
                *mask |= 1 << lane;
            }
        }
    }
    masks
}

/// The fine occupancy level the packet walks need: the frame's, with
/// skipping on (without it rays go one by one).
#[inline]
fn packet_cells<'a, V: Volume>(ctx: &FrameContext<'a, V>) -> Option<&'a IsoCells> {
    ctx.skip.iso_cells().filter(|_| ctx.ess)
}

/// The first crossings of the iso value along the lanes `mask` of a
/// packet's `lanes` in the frame's volume, lane `l`'s in entry `l`.
#[inline]
fn search_lanes<V: Volume>(
    ctx: &FrameContext<'_, V>,
    fine: &IsoCells,
    lanes: packet::PacketRays<'_>,
    mask: u32,
) -> [packet::PacketHit; packet::PACKET] {
    let mut found = [packet::PacketHit::default(); packet::PACKET];
    packet::search_packet(
        ctx.volume,
        ctx.skip,
        fine,
        ctx.iso_value,
        lanes,
        mask,
        &mut found,
    );
    found
}

/// The unit world normal at `hit`, facing where its ray came from (the
/// surface is two-sided); `None` where the gradient vanishes.
#[inline(always)]
fn normal<V: Volume>(
    ctx: &FrameContext<'_, V>,
    hit: &IsoHit,
    gradients: &mut GradientCache,
) -> Option<Vec3> {
    let g = gradient_at(ctx, hit, gradients);
    let len = g.length();
    if len > 0.0 && len.is_finite() {
        let view = -hit.world_dir;
        let n = g / len;
        Some(if n.dot(view) < 0.0 { -n } else { n })
    } else {
        None
    }
}

/// The normals of a packet's hits, lane by lane: [`normal`]'s arithmetic
/// in the same order, for all lanes at once.
struct LaneNormals {
    n: [[f32; packet::PACKET]; 3],
    /// Non-zero where the lane has a normal.
    valid: [u32; packet::PACKET],
}

impl LaneNormals {
    /// From the gradients `g` and the directions `view` towards the eye.
    #[inline(always)]
    fn new(g: &[Vec3; packet::PACKET], view: &[Vec3; packet::PACKET]) -> Self {
        let mut n = [[0.0f32; packet::PACKET]; 3];
        let mut valid = [0u32; packet::PACKET];
        for l in 0..packet::PACKET {
            let len = ((g[l].x * g[l].x) + (g[l].y * g[l].y) + (g[l].z * g[l].z)).sqrt();
            valid[l] = (len > 0.0 && len.is_finite()) as u32;
            let (x, y, z) = (g[l].x / len, g[l].y / len, g[l].z / len);
            let back = (x * view[l].x) + (y * view[l].y) + (z * view[l].z) < 0.0;
            n[0][l] = if back { -x } else { x };
            n[1][l] = if back { -y } else { y };
            n[2][l] = if back { -z } else { z };
        }
        LaneNormals { n, valid }
    }

    #[inline(always)]
    fn normal(&self, l: usize) -> Vec3 {
        Vec3::new(self.n[0][l], self.n[1][l], self.n[2][l])
    }
}

/// [`lit`] for a packet's hits with normals `lanes` (seen from `view`), for
/// all lanes at once with its arithmetic in the same order; `masks`: the
/// packet's shadow masks when the frame casts shadows. The frame shades,
/// and has at most [`CACHED_LIGHTS`] lights.
#[inline(always)]
fn lit_lanes<V: Volume>(
    ctx: &FrameContext<'_, V>,
    c: Vec3,
    lanes: &LaneNormals,
    view: &[Vec3; packet::PACKET],
    masks: Option<&ShadowMasks>,
) -> [Vec3; packet::PACKET] {
    const P: usize = packet::PACKET;
    let Some(ph) = &ctx.shading else {
        return [c; P];
    };
    let ambient = c * ph.ka;
    let mut r = [[ambient.x; P], [ambient.y; P], [ambient.z; P]];
    let n = &lanes.n;
    let count = ctx.lights.len().max(1);
    for k in 0..count {
        // The light's direction per lane (a headlight: the view's).
        let l: [[f32; P]; 3] = match ctx.lights.get(k) {
            Some(d) => [[d.x; P], [d.y; P], [d.z; P]],
            None => [view.map(|v| v.x), view.map(|v| v.y), view.map(|v| v.z)],
        };
        let shadowed = masks.map_or(0, |m| m[k]);
        // `Phong::light`, its power taken for all lanes at once.
        let mut ndotl = [0.0f32; P];
        let mut rdotv = [0.0f32; P];
        for i in 0..P {
            ndotl[i] = (n[0][i] * l[0][i]) + (n[1][i] * l[1][i]) + (n[2][i] * l[2][i]);
            let twice = 2.0 * ndotl[i];
            let rx = n[0][i] * twice - l[0][i];
            let ry = n[1][i] * twice - l[1][i];
            let rz = n[2][i] * twice - l[2][i];
            rdotv[i] = ((rx * view[i].x) + (ry * view[i].y) + (rz * view[i].z)).max(0.0);
        }
        let spec = if ph.ks > 0.0 {
            powi_lanes(rdotv, ph.shininess).map(|p| ph.ks * p)
        } else {
            [0.0; P]
        };
        for i in 0..P {
            let on = lanes.valid[i] != 0 && ndotl[i] > 0.0 && shadowed >> i & 1 == 0;
            let diffuse = ph.kd * ndotl[i];
            if on {
                r[0][i] += c.x * diffuse + spec[i];
                r[1][i] += c.y * diffuse + spec[i];
                r[2][i] += c.z * diffuse + spec[i];
            }
        }
    }
    std::array::from_fn(|i| Vec3::new(r[0][i], r[1][i], r[2][i]))
}

/// The gradient at `hit` that [`normal`] normalises.
#[inline(always)]
fn gradient_at<V: Volume>(
    ctx: &FrameContext<'_, V>,
    hit: &IsoHit,
    gradients: &mut GradientCache,
) -> Vec3 {
    match ctx.iso_normals {
        IsoNormals::Gradient => gradients.gradient(ctx.volume, hit.pos.into()),
        IsoNormals::Analytic => {
            let corners = ctx.volume.corners(hit.cell);
            trilinear_derivative(&corners, Vec3::from(hit.pos) - hit.cell.as_vec3())
                / ctx.volume.grid().spacing
        }
    }
}

/// The colour `c` of the surface at `hit` with normal `n`: lit by the
/// frame's lights (Phong, shadow rays when asked) when shading is on, only
/// ambient where there is no normal.
#[inline(always)]
fn lit<V: Volume>(
    ctx: &FrameContext<'_, V>,
    c: Vec3,
    hit: &IsoHit,
    n: Option<Vec3>,
    known: Option<(&ShadowMasks, usize)>,
    shadow_rays: &mut [Option<VoxelRay>; CACHED_LIGHTS],
) -> Vec3 {
    let Some(ph) = &ctx.shading else {
        return c;
    };
    let Some(n) = n else {
        return c * ph.ka;
    };
    let view = -hit.world_dir;
    let headlight = [view];
    let lights = if ctx.lights.is_empty() {
        &headlight[..]
    } else {
        ctx.lights
    };
    // A headlight casts no shadow the eye can see: its shadow ray would
    // retrace the ray that found the hit, which met nothing before it. (Its
    // direction differs from pixel to pixel, so the per-tile cache of
    // shadow rays cannot hold it either.)
    let casts = ctx.shadows && !ctx.lights.is_empty();
    let mut rgb = c * ph.ka;
    for (k, &l) in lights.iter().enumerate() {
        let ndotl = n.dot(l);
        let mut shadowed = || match known {
            Some((masks, lane)) if k < CACHED_LIGHTS => masks[k] >> lane & 1 != 0,
            _ => in_shadow(ctx, hit.pos.into(), n, (l, k), shadow_rays),
        };
        if ndotl <= 0.0 || (casts && shadowed()) {
            continue;
        }
        let (diffuse, spec) = ph.light(n, l, view);
        rgb += c * diffuse + Vec3::splat(spec);
    }
    rgb
}

/// What the ray of `hit` sees reflected about the normal `n` there: the
/// surface where the reflected ray first crosses the iso value, lit as
/// [`lit`] lights a primary hit, or the background where it leaves the
/// volume. One bounce: the surface it meets is not reflective. (Out of
/// line: frames without reflection should not carry its code.)
#[inline(never)]
fn mirror<V: Volume>(
    ctx: &FrameContext<'_, V>,
    c: Vec3,
    hit: &IsoHit,
    n: Vec3,
    cache: &mut ShadingCache,
) -> Vec3 {
    let d = hit.world_dir;
    let r = (d - n * (2.0 * d.dot(n))).normalize_or_zero();
    if r == Vec3::ZERO {
        return ctx.background;
    }
    let grid = ctx.volume.grid();
    let ray = VoxelRay::new(off_surface(grid, hit.pos.into(), n), r / grid.spacing);
    let t1 = Aabb::new(Vec3::ZERO, grid.max_coord()).exit(ray.origin, ray.inv_dir);
    match secondary_hit(ctx, &ray, t1) {
        Some((t, cell)) => {
            let seen = IsoHit {
                t,
                pos: ray.at(t).into(),
                cell,
                world_dir: r,
            };
            let n = normal(ctx, &seen, &mut cache.reflected);
            lit(ctx, c, &seen, n, None, &mut cache.shadow_rays)
        }
        None => ctx.background,
    }
}

/// The derivative of the trilinear interpolant of `c` at fractions `f`
/// (value units per voxel).
fn trilinear_derivative(c: &Corners, f: Vec3) -> Vec3 {
    let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
    let bi = |a: f32, b: f32, c: f32, d: f32, s: f32, t: f32| lerp(lerp(a, b, t), lerp(c, d, t), s);
    // Along each axis: the difference of the two faces across it, each
    // interpolated bilinearly in the other two fractions.
    Vec3::new(
        bi(c[4], c[5], c[6], c[7], f.y, f.z) - bi(c[0], c[1], c[2], c[3], f.y, f.z),
        bi(c[2], c[3], c[6], c[7], f.x, f.z) - bi(c[0], c[1], c[4], c[5], f.x, f.z),
        bi(c[1], c[3], c[5], c[7], f.x, f.y) - bi(c[0], c[2], c[4], c[6], f.x, f.y),
    )
}

/// Whether the surface point `p` (voxel space) with normal `n` (world,
/// facing the light) is hidden from a directional light towards `l`
/// (world, unit; light number `light` of the frame) by the isosurface.
/// `rays` keeps the first lights' shadow rays (all but their origins).
fn in_shadow<V: Volume>(
    ctx: &FrameContext<'_, V>,
    p: Vec3,
    n: Vec3,
    (l, light): (Vec3, usize),
    rays: &mut [Option<VoxelRay>; CACHED_LIGHTS],
) -> bool {
    let grid = ctx.volume.grid();
    let origin = off_surface(grid, p, n);
    let towards_light = || VoxelRay::new(Vec3::ZERO, l / grid.spacing);
    let ray = VoxelRay {
        origin: origin.into(),
        ..match rays.get_mut(light) {
            Some(cached) => *cached.get_or_insert_with(towards_light),
            None => towards_light(),
        }
    };
    secondary_hit(ctx, &ray, shadow_reach(ctx, &ray, light)).is_some()
}

/// How far a shadow ray `ray` towards light number `light` is searched:
/// to where it leaves the volume, or sooner past the last cell towards the
/// light that can hold the surface there (the light's proxy).
#[inline]
fn shadow_reach<V: Volume>(ctx: &FrameContext<'_, V>, ray: &VoxelRay, light: usize) -> f32 {
    let grid = ctx.volume.grid();
    let bounds = Aabb::new(Vec3::ZERO, grid.max_coord());
    let t1 = bounds.exit(ray.origin, ray.inv_dir);
    match ctx.light_proxies.get(light) {
        Some(Some(proxy)) => t1.min(proxy.reach(grid.voxel_to_world(ray.origin.into()))),
        _ => t1,
    }
}

/// Where a ray leaving the surface point `p` (voxel space) with world
/// normal `n` starts (shadow and reflection rays): [`SHADOW_OFFSET`] voxels
/// off the surface along the normal, since a ray that started on the
/// surface could find the surface itself (shadow acne).
#[inline]
fn off_surface(grid: &Grid, p: Vec3, n: Vec3) -> Vec3 {
    let normal_vox = (n / grid.spacing).normalize_or_zero();
    p + normal_vox * SHADOW_OFFSET
}

/// The first crossing along a ray leaving the surface, on `[0, t1]`
/// (`None` for an empty interval).
#[inline]
fn secondary_hit<V: Volume>(
    ctx: &FrameContext<'_, V>,
    ray: &VoxelRay,
    t1: f32,
) -> Option<(f32, UVec3)> {
    if t1.is_nan() || t1 <= 0.0 {
        return None;
    }
    let mut search = Search::new(ctx.volume, ctx.iso_value, None);
    search.walk(ctx.ess.then_some(ctx.skip), ray, 0.0, t1);
    search.hit
}

/// How far (voxels) a shadow or reflection ray starts from the surface,
/// along the normal.
const SHADOW_OFFSET: f32 = 0.05;

/// A ray in voxel space, `origin + dir·t`, with what its walk needs.
///
/// Its vectors are 16-byte [`Vec3A`]s: the walk reads them as whole
/// vectors, and a 16-byte load of a [`Vec3`] that was stored as 8 + 4
/// bytes cannot take its value from the stores in flight (a
/// store-forwarding stall at the start of every DDA run).
#[derive(Debug, Clone, Copy)]
pub(crate) struct VoxelRay {
    pub origin: Vec3A,
    pub dir: Vec3A,
    pub inv_dir: Vec3A,
    /// The DDA's step per axis: ±1, or 0 for a direction component of ±0.
    step: IVec3,
    /// A parameter step of 10⁻⁴ voxel: how far past a face the walk looks
    /// to decide which cell comes next.
    nudge: f32,
    /// The tolerance of a crossing's parameter (10⁻⁵ voxel).
    tol: f32,
}

impl VoxelRay {
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Self::with_inverse(origin, dir, dir.recip())
    }

    /// As [`VoxelRay::new`] with `1/dir` known (a [`RaySegment`]'s).
    ///
    /// [`RaySegment`]: super::RaySegment
    pub fn with_inverse(origin: Vec3, dir: Vec3, inv_dir: Vec3) -> Self {
        let axis_step = |d: f32| (d > 0.0) as i32 - (d < 0.0) as i32;
        VoxelRay {
            origin: origin.into(),
            dir: dir.into(),
            inv_dir: inv_dir.into(),
            step: IVec3::new(axis_step(dir.x), axis_step(dir.y), axis_step(dir.z)),
            nudge: 1e-4 / dir.abs().max_element().max(1e-30),
            tol: 1e-5 / dir.length().max(1e-30),
        }
    }

    #[inline(always)]
    pub fn at(&self, t: f32) -> Vec3 {
        (self.origin + self.dir * t).into()
    }
}

/// A 3D DDA's state (Amanatides–Woo): where the ray crosses the next cell
/// plane per axis, each computed from the plane's coordinate, never
/// accumulated, so it cannot drift.
struct Dda {
    /// The step per axis (±1, 0 for a direction component of ±0).
    step: IVec3,
    /// The parameter of the next plane per axis.
    next: Vec3,
}

impl Dda {
    #[inline(always)]
    fn new(ray: &VoxelRay, cell: IVec3) -> Self {
        let mut dda = Dda {
            step: ray.step,
            next: Vec3::ZERO,
        };
        for a in 0..3 {
            dda.next[a] = dda.plane(ray, cell, a);
        }
        dda
    }

    /// The parameter where the ray leaves `cell` across its plane on axis
    /// `a` (infinite when it does not move along `a`).
    #[inline(always)]
    fn plane(&self, ray: &VoxelRay, cell: IVec3, a: usize) -> f32 {
        match self.step[a] {
            0 => f32::INFINITY,
            s => {
                let plane = (cell[a] + (s > 0) as i32) as f32;
                (plane - ray.origin[a]) * ray.inv_dir[a]
            }
        }
    }

    /// Steps `cell` across the nearest plane; returns its axis.
    #[inline(always)]
    fn advance(&mut self, cell: &mut IVec3, ray: &VoxelRay) -> usize {
        let n = self.next;
        let a = if n.x <= n.y && n.x <= n.z {
            0
        } else if n.y <= n.z {
            1
        } else {
            2
        };
        cell[a] += self.step[a];
        self.next[a] = self.plane(ray, *cell, a);
        a
    }
}

/// One walk along a ray for the first crossing.
pub(crate) struct Search<'v, V: Volume> {
    volume: &'v V,
    iso: f32,
    /// The highest interpolation cell per axis.
    last: IVec3,
    /// The side of the iso value where the walk so far ended.
    pub side: Option<bool>,
    /// The crossing: ray parameter and cell.
    pub hit: Option<(f32, UVec3)>,
    /// Cells visited (the DDA's steps).
    pub steps: u64,
}

impl<'v, V: Volume> Search<'v, V> {
    pub fn new(volume: &'v V, iso: f32, side: Option<bool>) -> Self {
        let dims = volume.grid().dims;
        Search {
            volume,
            iso,
            last: (dims.max(UVec3::splat(2)) - UVec3::splat(2)).as_ivec3(),
            side,
            hit: None,
            steps: 0,
        }
    }

    /// Walks `[t0, t1]` of `ray` until the first crossing: over the
    /// macrocells of `skip` (all of the interval as one occupied stretch
    /// when `None`), cell by cell inside the occupied ones.
    pub fn walk(&mut self, skip: Option<&SkipGrid>, ray: &VoxelRay, t0: f32, t1: f32) {
        let Some(skip) = skip else {
            self.cells(ray, t0, t1, None);
            return;
        };
        let fine = skip.iso_cells();
        let ahead = skip.ahead(ray.inv_dir.into());
        let nudge = ray.nudge;
        let mut t = t0;
        while t < t1 && self.hit.is_none() {
            // Classify the first point past `t`, not `t` itself, which may
            // lie on the face of the box just left.
            let probe = ray.at(t + nudge.min(0.5 * (t1 - t)));
            let (bounds, occupied) = match skip.classify_ahead(probe, ahead) {
                CellClass::Empty(b) => (b, None),
                CellClass::Occupied {
                    bounds,
                    index,
                    coords,
                } => (bounds, Some((index, coords))),
            };
            let exit = min_to(bounds.exit(ray.origin, ray.inv_dir), t1);
            let mut next = max_to(exit, t + nudge);
            if let Some((index, coords)) = occupied {
                match fine.and_then(|f| Some((f, f.masks(index)?))) {
                    Some((fine, m)) if !m.none_straddle() => {
                        let left = self.straddling_run(ray, fine, (index, m, coords), t, t1);
                        next = max_to(left, t + nudge);
                    }
                    masks => {
                        let masks = masks.map(|(_, m)| (m, (bounds.min + 0.5).as_uvec3()));
                        self.cells(ray, t, min_to(next, t1), masks);
                    }
                }
            }
            // Across an empty box the side stays: its values are all on one
            // side, and they meet the cells around it continuously.
            t = next;
        }
    }

    /// The DDA over the interpolation cells between `ta` and `tb`; with
    /// `masks`, those of one macrocell (its fine bit sets and its lowest
    /// cell), opening only the cells that straddle the iso value.
    fn cells(&mut self, ray: &VoxelRay, ta: f32, tb: f32, masks: Option<(CellMasks<'_>, UVec3)>) {
        if ta.is_nan() || tb.is_nan() || ta >= tb {
            return;
        }
        let (mut first, mut last) = (IVec3::ZERO, self.last);
        if let Some((m, origin)) = &masks {
            // Stay inside the macrocell: its cells are origin .. origin + m.
            first = origin.as_ivec3();
            last = last.min(first + IVec3::splat(m.side() as i32 - 1));
        }
        let nudge = ray.nudge;
        let start = ray.at(ta + nudge.min(0.5 * (tb - ta)));
        let mut cell = start.floor().as_ivec3().clamp(first, last);
        if let Some((m, origin)) = &masks
            && m.none_straddle()
        {
            // One side throughout (cells that share corners cannot lie on
            // opposite sides without one of them straddling).
            self.steps += 1;
            let side = m.above(cell.as_uvec3() - *origin);
            if self.side == Some(!side) {
                self.hit = Some((ta, cell.as_uvec3()));
            } else {
                self.side = Some(side);
            }
            return;
        }
        let mut dda = Dda::new(ray, cell);
        let tol = ray.tol;
        let mut tc = ta;
        loop {
            let te = max_to(min_to(dda.next.min_element(), tb), tc);
            self.steps += 1;
            let c = cell.as_uvec3();
            let found = match &masks {
                Some((m, origin)) => {
                    let local = c - *origin;
                    if m.straddles(local) {
                        let corners = self.volume.corners(c);
                        self.crossing(ray, c, &corners, tc, te, tol)
                    } else {
                        self.one_side(m.above(local), tc, c)
                    }
                }
                None => self.cell(ray, c, tc, te, tol),
            };
            if found || te >= tb {
                return;
            }
            let a = dda.advance(&mut cell, ray);
            if cell[a] < first[a] || cell[a] > last[a] {
                return;
            }
            tc = te;
        }
    }

    /// The DDA over the interpolation cells from `ta` (at most to `tb`),
    /// starting in occupied macrocell `index` (at `macrocell` in the grid)
    /// with masks `m`, and going on into each next macrocell the ray enters as
    /// long as that one has straddling cells: a surface spans many
    /// macrocells, and stepping into the next one costs a lookup, not a new
    /// classification and DDA set-up. Opens only the straddling cells.
    /// Returns where it stopped: `tb`, the hit, or the face into a
    /// macrocell it does not go on into (empty, or without straddling
    /// cells), which the caller classifies.
    fn straddling_run(
        &mut self,
        ray: &VoxelRay,
        fine: &IsoCells,
        (mut index, mut m, macrocell): (usize, CellMasks<'_>, UVec3),
        ta: f32,
        tb: f32,
    ) -> f32 {
        if ta.is_nan() || tb.is_nan() || ta >= tb {
            return tb;
        }
        let side = fine.side() as i32;
        let count = fine.count().as_ivec3();
        let stride = [(count.y * count.z) as isize, count.z as isize, 1];
        let start = ray.at(ta + ray.nudge.min(0.5 * (tb - ta)));
        // (The macrocell's coordinates come from the caller: dividing its
        // lowest cell by the side would cost three integer divisions a run.)
        let mut macrocell = macrocell.as_ivec3();
        let lo = macrocell * side;
        let mut cell = start
            .floor()
            .as_ivec3()
            .clamp(lo, self.last.min(lo + IVec3::splat(side - 1)));
        let mut dda = Dda::new(ray, cell);
        let tol = ray.tol;
        // The cell's bit in its macrocell's masks, kept up to date as the
        // DDA steps (one step along axis `a` moves it by `bit_stride[a]`).
        let bit_stride = [side * side, side, 1];
        let mut bit = m.index((cell - lo).as_uvec3()) as i32;
        let mut tc = ta;
        loop {
            let te = max_to(min_to(dda.next.min_element(), tb), tc);
            self.steps += 1;
            let found = if m.straddles_at(bit as u32) {
                let c = cell.as_uvec3();
                let corners = self.volume.corners(c);
                self.crossing(ray, c, &corners, tc, te, tol)
            } else {
                self.one_side(m.above_at(bit as u32), tc, cell.as_uvec3())
            };
            if found || te >= tb {
                return te;
            }
            let a = dda.advance(&mut cell, ray);
            if cell[a] < 0 || cell[a] > self.last[a] {
                return te;
            }
            let s = dda.step[a];
            let into = cell[a] - macrocell[a] * side;
            if into < 0 || into >= side {
                // Into the next macrocell along axis `a`, on its far side.
                macrocell[a] += s;
                if macrocell[a] < 0 || macrocell[a] >= count[a] {
                    return te;
                }
                index = index.wrapping_add_signed(s as isize * stride[a]);
                match fine.masks(index) {
                    Some(next) if !next.none_straddle() => m = next,
                    _ => return te,
                }
                bit -= s * (side - 1) * bit_stride[a];
            } else {
                bit += s * bit_stride[a];
            }
            tc = te;
        }
    }

    /// A cell wholly on one side (`above`: at or above the iso value),
    /// entered at `tc`: a hit there when the ray arrives from the other
    /// side. True when found.
    #[inline(always)]
    fn one_side(&mut self, above: bool, tc: f32, cell: UVec3) -> bool {
        if self.side == Some(!above) {
            self.hit = Some((tc, cell));
            return true;
        }
        self.side = Some(above);
        false
    }

    /// Looks for the crossing inside `cell` on `[tc, te]`, deciding from its
    /// corners whether it can hold one; true when found.
    #[inline]
    fn cell(&mut self, ray: &VoxelRay, cell: UVec3, tc: f32, te: f32, tol: f32) -> bool {
        let corners = self.volume.corners(cell);
        let (lo, hi) = corners
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            });
        if lo >= self.iso || hi < self.iso {
            // The whole cell lies on one side (the interpolant is a convex
            // combination of the corners).
            return self.one_side(lo >= self.iso, tc, cell);
        }
        self.crossing(ray, cell, &corners, tc, te, tol)
    }

    /// Solves for the first crossing inside `cell`, whose `corners`
    /// straddle the iso value, on `[tc, te]`; true when found.
    #[inline(always)]
    fn crossing(
        &mut self,
        ray: &VoxelRay,
        cell: UVec3,
        corners: &Corners,
        tc: f32,
        te: f32,
        tol: f32,
    ) -> bool {
        let p0 = ray.at(tc) - cell.as_vec3();
        let cubic = CellCubic::new(corners, p0, ray.dir.into(), self.iso);
        let start_side = cubic.eval(0.0) >= 0.0;
        if self.side == Some(!start_side) {
            self.hit = Some((tc, cell));
            return true;
        }
        let len = te - tc;
        if let Some(dt) = cubic.first_crossing(len, tol) {
            self.hit = Some((tc + dt, cell));
            return true;
        }
        self.side = Some(cubic.eval(len) >= 0.0);
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::interpolate;

    #[test]
    fn the_analytic_derivative_is_the_interpolants() {
        let mut rng = fastrand::Rng::with_seed(4);
        for _ in 0..500 {
            let c: Corners = std::array::from_fn(|_| rng.f32() * 10.0 - 5.0);
            let f = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 0.98 + 0.01;
            let d = trilinear_derivative(&c, f);
            let h = 1e-3;
            for a in 0..3 {
                let mut e = Vec3::ZERO;
                e[a] = h;
                let fd = (interpolate(&c, f + e) - interpolate(&c, f - e)) / (2.0 * h);
                assert!((fd - d[a]).abs() < 2e-2, "axis {a}: {fd} vs {}", d[a]);
            }
        }
    }
}
