//! [`ProxyDepth`]: per pixel, a lower bound on where the ray first meets a
//! cell that can hold the isosurface.
//!
//! An exact iso ray spends most of its walk reaching the surface: jumping
//! over empty macrocells, stepping through cells wholly on one side of the
//! iso value. A crossing can only lie in a cell whose corners straddle the
//! iso value, and those cells are few (a shell a cell or two thick around
//! the surface). So before the rays are cast the straddling cells' boxes
//! are drawn into a per-pixel buffer, like the proxy geometry GPU ray
//! casters rasterise to find where rays start: over the bounding rectangle
//! of a box's projected corners, at a depth no ray can enter it before (the
//! eye's distance to the box). A ray then begins its walk at its pixel's
//! depth, and a pixel no box covers cannot hit at all. Both are
//! conservative, so the hits are the walk's own; a ray starts at most
//! about a box early, and only rays passing within a pixel of the
//! surface's silhouette are walked in vain. A box is a run of straddling
//! cells along z ([`IsoCells::straddling_runs`]): half as many boxes to
//! draw as cells, for a rectangle and a depth that are nearly the cells'
//! own (seen along the run, its first cell hides the others; seen across
//! it, its cells lie side by side at about one depth).
//!
//! The boxes are grown by `MARGIN` voxels, far more than the rounding of
//! a ray's position, so a ray that grazes a straddling cell, which the walk
//! might still open, is never culled and never starts past it. The boxes
//! are binned into bands of rows and the bands filled in parallel; the
//! result does not depend on the order (a minimum per pixel). Both passes
//! (the boxes' rectangles, the fill) run on threads started for them
//! (`on_threads`), rather than on a rayon pool that is asleep after the
//! frame's rendering; the threads take the work in pieces in turn (a few
//! pieces of the boxes per thread, one band of rows at a time), because
//! the boxes crowd into the bands the surface covers and equal shares of
//! the bands left one thread with twice the other's fill.
//!
//! DVR draws the same way the macrocells its TF makes visible
//! ([`CellRuns::plain`]): a sample before the nearest of them along its
//! ray lies in an empty macrocell and adds nothing, so a ray's first kept
//! sample moves to its pixel's depth (the samples stay where they are), and
//! a ray that meets none keeps no sample. The object renderer already
//! passes over empty bricks, so it gains little; the serial and tiled
//! renderers no longer walk the empty space in front of the data.
//! Macrocells are several pixels across, so a rectangle and a nearest point
//! per box would start many rays early and walk many past the data's
//! silhouette in vain: under perspective DVR draws each box pixel by pixel
//! instead, where the pixel's own ray enters it ([`Coverage::Rays`]). For
//! an eye outside the macrocells it draws only those on the surface of the
//! occupied region, each run's box narrowed to where its visible voxels lie
//! ([`CellRuns::visible`]), so a ray starts near its first visible
//! sample rather than at the macrocell's face.
//!
//! [`LightProxy`] draws the same cells as seen along a directional light, so
//! that shadow rays, which are parallel, learn where they have passed the
//! last cell towards the light.

use glam::{UVec3, Vec3};
use parking_lot::Mutex;

use super::bins::Bins;
use crate::accel::{IsoCells, SkipGrid};
use crate::camera::{AffineProjection, Camera, CameraFrame, PixelRect, Projection};
use crate::geometry::clip_slab;
use crate::integrator::{BLOCK as RAY_BLOCK, PACKET_H, PACKET_W};
use crate::simd::{self, Isa, Kernel};
use crate::volume::Grid;

/// At most this many cells are drawn ([`ProxyDepth::pays`]).
const MAX_BOXES: u64 = 1 << 23;

/// At most this many cells per pixel of the screen rectangle are drawn.
const BOXES_PER_PIXEL: u64 = 4;

/// How far (voxels) each straddling cell's box is grown on every side.
const MARGIN: f32 = 0.01;

/// The buffer's resolution with [`Coverage::Blocks`]: one depth per
/// square of this many pixels a side. Coarser means fewer blocks per box
/// to draw (a straddling cell spans only a few pixels), at the price of
/// rays within a block of the silhouette walked in vain.
const BLOCK: u32 = 1 << BLOCK_SHIFT;

/// `BLOCK = 1 << BLOCK_SHIFT`: the buffer's indices are shifted pixels.
const BLOCK_SHIFT: u32 = 1;

/// How a box is drawn into the depth buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Coverage {
    /// Over the blocks of 2×2 pixels its projected rectangle touches, at
    /// the eye's distance to the box: two numbers a box, for boxes a few
    /// pixels across (the exact iso mode's cells).
    Blocks,
    /// Pixel by pixel, where the pixel's own ray enters the box (a slab
    /// test), and not at all where that ray misses it: for boxes many
    /// pixels across (DVR's macrocells), whose rectangles and nearest
    /// points would start many rays early or in vain. Perspective frames
    /// only (others are drawn as `Blocks`).
    Rays,
}

/// Block rows per band: the unit of the boxes' binning (each thread fills
/// a contiguous group of bands).
const BAND: u32 = 4;

/// Per pixel of a screen rectangle, a ray parameter (world units, `>= 0`)
/// before which the pixel's ray meets no straddling cell, `f32::INFINITY`
/// when it meets none.
#[derive(Debug, Clone)]
pub struct ProxyDepth {
    rect: PixelRect,
    /// A block's side is `1 << shift` pixels (1 or [`BLOCK`]).
    shift: u32,
    /// Blocks per row.
    width: u32,
    /// Per block of pixels of `rect`, row-major: the minimum over the
    /// block's pixels.
    depth: Vec<f32>,
    /// How many boxes (runs of cells) were drawn.
    boxes: usize,
}

impl ProxyDepth {
    /// Whether drawing `cells` for the pixels of `rect` is worth it: not
    /// when the surface has many more straddling cells than the rectangle
    /// has pixels (a fine surface in a small preview, or a huge volume),
    /// where listing and drawing them would cost more than the walks they
    /// shorten, and the list alone could take much memory.
    /// `cells` is how many cells there are to draw.
    pub fn pays(cells: usize, rect: &PixelRect) -> bool {
        let n = cells as u64;
        n <= MAX_BOXES && n <= BOXES_PER_PIXEL * rect.area()
    }

    /// Draws the boxes of `runs` (on a grid `grid`) as seen by `frame`,
    /// over the pixels of `rect`, as `coverage` says.
    pub fn build(
        frame: &CameraFrame,
        rect: PixelRect,
        grid: &Grid,
        runs: CellRuns<'_>,
        coverage: Coverage,
    ) -> Self {
        let per_ray = coverage == Coverage::Rays && frame.projection() == Projection::Perspective;
        let shift = if per_ray { 0 } else { BLOCK_SHIFT };
        let block = 1 << shift;
        // The buffer's blocks over `rect`.
        let (w, h) = (
            (rect.x1 - rect.x0).div_ceil(block),
            (rect.y1 - rect.y0).div_ceil(block),
        );
        let mut depth = vec![f32::INFINITY; (w * h) as usize];
        if depth.is_empty() {
            return ProxyDepth {
                rect,
                shift,
                width: w,
                depth,
                boxes: 0,
            };
        }
        // Pieces of the work (a few per thread, taken in turn: a thread
        // that starts late takes fewer).
        let parts = rayon::current_num_threads().max(1);
        let n = runs.runs.len();
        let chunk = n.div_ceil(4 * parts).max(1);
        let pieces: Vec<CellRuns<'_>> = (0..n)
            .step_by(chunk)
            .map(|a| runs.slice(a..(a + chunk).min(n)))
            .collect();
        let boxes: Vec<Drawn> = on_threads(parts, pieces, |piece| match frame.projection() {
            Projection::Perspective => simd::dispatch(BoxRects {
                frame,
                rect,
                grid,
                runs: piece,
                shift,
            }),
            Projection::Orthographic => (0..piece.runs.len())
                .filter_map(|k| box_of(frame, &rect, grid, piece.voxel_box(k)))
                .collect::<Vec<_>>(),
        })
        .concat();
        // The boxes by band of block rows.
        let bands = Bins::build(h.div_ceil(BAND) as usize, boxes.len(), |k, put| {
            let r = boxes[k].blocks;
            for b in r.y0 / BAND..=(r.y1 - 1) / BAND {
                put(b as usize);
            }
        });
        // Where each column's rays cross the image plane, for every band
        // ([`FillRays`]).
        let across: Vec<f32> = if per_ray {
            (rect.x0..rect.x1)
                .map(|i| frame.image_plane(i, 0).0)
                .collect()
        } else {
            Vec::new()
        };
        let fill_band = |b: usize, out: &mut [f32]| {
            let y0 = b as u32 * BAND;
            let y1 = (y0 + BAND).min(h);
            if per_ray {
                fill_rays(frame, &rect, &across, (y0, y1), &boxes, bands.get(b), out);
                return;
            }
            for &k in bands.get(b) {
                let Drawn { blocks: r, t, .. } = boxes[k as usize];
                for j in r.y0.max(y0)..r.y1.min(y1) {
                    let o = ((j - y0) * w + r.x0) as usize;
                    for d in &mut out[o..o + (r.x1 - r.x0) as usize] {
                        *d = if t < *d { t } else { *d };
                    }
                }
            }
        };
        // Band by band, taken in turn by the threads: the boxes crowd into
        // the bands the surface covers, so equal shares of the bands are
        // unequal shares of the work.
        let band_len = (BAND * w) as usize;
        let pieces: Vec<(usize, &mut [f32])> = depth.chunks_mut(band_len).enumerate().collect();
        on_threads(parts, pieces, |(b, band)| fill_band(b, band));
        ProxyDepth {
            rect,
            shift,
            width: w,
            depth,
            boxes: n,
        }
    }

    /// Where pixel `(i, j)`'s ray may first meet a straddling cell (at or
    /// before it does); `f32::INFINITY` when it meets none (or the pixel
    /// lies outside the rectangle drawn).
    #[inline(always)]
    pub fn at(&self, i: u32, j: u32) -> f32 {
        if !self.rect.contains(i, j) {
            return f32::INFINITY;
        }
        let (x, y) = (
            (i - self.rect.x0) >> self.shift,
            (j - self.rect.y0) >> self.shift,
        );
        self.depth[(y * self.width + x) as usize]
    }

    /// [`at`] for the pixels of the block of rays at `(i0, j0)`: lane `l`
    /// is pixel `(i0 + l % PACKET_W, j0 + l / PACKET_W)`. A block inside
    /// the rectangle drawn (almost every one) reads the buffer without
    /// [`at`]'s test per pixel.
    ///
    /// [`at`]: ProxyDepth::at
    #[inline(always)]
    pub fn block_at(&self, i0: u32, j0: u32) -> [f32; RAY_BLOCK] {
        let r = &self.rect;
        let inside = i0 >= r.x0 && j0 >= r.y0 && i0 + PACKET_W <= r.x1 && j0 + PACKET_H <= r.y1;
        // Loops rather than `std::array::from_fn`, whose closures the
        // compiler left out of line here.
        let mut out = [0.0f32; RAY_BLOCK];
        if !inside {
            for (l, t) in out.iter_mut().enumerate() {
                *t = self.at(i0 + l as u32 % PACKET_W, j0 + l as u32 / PACKET_W);
            }
            return out;
        }
        let (x0, y0) = (i0 - r.x0, j0 - r.y0);
        for (l, t) in out.iter_mut().enumerate() {
            let (x, y) = (
                (x0 + l as u32 % PACKET_W) >> self.shift,
                (y0 + l as u32 / PACKET_W) >> self.shift,
            );
            *t = self.depth[(y * self.width + x) as usize];
        }
        out
    }

    /// Whether no pixel ray of `r` meets a straddling cell: [`at`] is
    /// `f32::INFINITY` for every pixel of `r`, read a block of the buffer
    /// at a time.
    ///
    /// [`at`]: ProxyDepth::at
    pub fn culls(&self, r: &PixelRect) -> bool {
        let r = r.intersect(&self.rect);
        if r.is_empty() {
            return true;
        }
        let (x0, x1) = (
            (r.x0 - self.rect.x0) >> self.shift,
            (r.x1 - 1 - self.rect.x0) >> self.shift,
        );
        let (y0, y1) = (
            (r.y0 - self.rect.y0) >> self.shift,
            (r.y1 - 1 - self.rect.y0) >> self.shift,
        );
        (y0..=y1).all(|y| {
            let row = (y * self.width) as usize;
            self.depth[row + x0 as usize..=row + x1 as usize]
                .iter()
                .all(|&t| t == f32::INFINITY)
        })
    }

    /// How many boxes (runs of straddling cells) were drawn.
    pub fn boxes(&self) -> usize {
        self.boxes
    }
}

/// Cells to draw as boxes, in runs along z: each run's first cell (in
/// units of `side` voxels) and how many cells it holds.
#[derive(Debug, Clone, Copy)]
pub struct CellRuns<'a> {
    /// Each run's first cell and length.
    pub runs: &'a [(UVec3, u32)],
    /// A cell's side, voxels.
    pub side: f32,
    /// Empty, or per run how far (voxels) its box is narrowed: from its
    /// lower corner up and from its upper corner down, per axis.
    pub shrink: &'a [[u8; 6]],
}

impl<'a> CellRuns<'a> {
    /// The interpolation cells that straddle an iso value (exact iso mode).
    pub fn straddling(cells: &'a IsoCells) -> Self {
        CellRuns {
            runs: cells.straddling_runs(),
            side: 1.0,
            shrink: &[],
        }
    }

    /// The macrocells a transfer function makes visible (DVR): with
    /// `surface`, only those on the surface of the occupied region, which
    /// give rays from outside the grid the same nearest occupied cell
    /// ([`SkipGrid::proxy_runs`]).
    pub fn plain(skip: &'a SkipGrid, surface: bool) -> Self {
        CellRuns {
            runs: skip.proxy_runs(surface),
            side: skip.cell_side(),
            shrink: &[],
        }
    }

    /// [`CellRuns::plain`] narrowed to where a ray can first meet a visible sample
    /// ([`SkipGrid::visible_runs`]).
    pub fn visible(
        skip: &'a SkipGrid,
        surface: bool,
        visible: impl Fn(UVec3) -> Option<[UVec3; 2]> + Sync,
    ) -> Self {
        let (runs, shrink) = skip.visible_runs(surface, visible);
        CellRuns {
            runs,
            side: skip.cell_side(),
            shrink,
        }
    }

    /// Runs `range` of these.
    fn slice(&self, range: std::ops::Range<usize>) -> Self {
        CellRuns {
            runs: &self.runs[range.clone()],
            side: self.side,
            shrink: if self.shrink.is_empty() {
                &[]
            } else {
                &self.shrink[range]
            },
        }
    }

    /// Run `k`'s box, voxels (not grown).
    #[inline(always)]
    fn voxel_box(&self, k: usize) -> (Vec3, Vec3) {
        let (c, len) = self.runs[k];
        let c = c.as_vec3();
        let lo = c * self.side;
        let hi = (c + Vec3::new(1.0, 1.0, len as f32)) * self.side;
        match self.shrink.get(k) {
            Some(s) => (
                lo + Vec3::new(s[0] as f32, s[1] as f32, s[2] as f32),
                hi - Vec3::new(s[3] as f32, s[4] as f32, s[5] as f32),
            ),
            None => (lo, hi),
        }
    }
}

/// A box as drawn: the blocks its pixels' rectangle touches, a lower bound
/// on where any ray enters it, and the box (world, grown by [`MARGIN`]).
#[derive(Debug, Clone, Copy)]
struct Drawn {
    blocks: PixelRect,
    t: f32,
    lo: Vec3,
    hi: Vec3,
}

/// The box of a run ([`CellRuns::voxel_box`]: `(lo, hi)`, voxels), grown
/// by [`MARGIN`], as `frame` sees it in `rect`, in blocks of [`BLOCK`]
/// pixels; `None` when it does not show.
fn box_of(
    frame: &CameraFrame,
    rect: &PixelRect,
    grid: &Grid,
    (lo, hi): (Vec3, Vec3),
) -> Option<Drawn> {
    let grow = Vec3::splat(MARGIN);
    let lo = grid.voxel_to_world(lo - grow);
    let hi = grid.voxel_to_world(hi + grow);
    let r = frame.box_rect(lo, hi)?.intersect(rect);
    if r.is_empty() {
        return None;
    }
    Some(Drawn {
        blocks: blocks_of(&r, rect, BLOCK_SHIFT),
        t: nearest_t(frame, lo, hi),
        lo,
        hi,
    })
}

/// [`Coverage::Rays`]' fill of the pixel rows `y0..y1` of `rect` (`out`,
/// row-major) with the boxes `boxes[k]` for `k` in `band`: per pixel, the
/// least parameter at which its perspective ray enters one of the boxes
/// it meets, by a slab test against each box whose rectangle holds the
/// pixel. The rays' directions are worked out from the image plane as
/// [`CameraFrame::perspective_dirs`] does, rounded a little differently
/// (the inverse of a unit component as the length over the component):
/// the boxes' [`MARGIN`] covers that, as it covers the rounding of the two
/// paths' positions, so a ray meets a box here where it does there.
fn fill_rays(
    frame: &CameraFrame,
    rect: &PixelRect,
    across: &[f32],
    rows: (u32, u32),
    boxes: &[Drawn],
    band: &[u32],
    out: &mut [f32],
) {
    simd::dispatch(FillRays {
        frame,
        rect,
        across,
        rows,
        boxes,
        band,
        out,
    })
}

/// [`fill_rays`] as a [`Kernel`], so that its lane-wise loops are 8 wide
/// where the CPU has AVX2.
struct FillRays<'a> {
    frame: &'a CameraFrame,
    rect: &'a PixelRect,
    /// Per column of `rect`, where its rays cross the image plane
    /// ([`CameraFrame::image_plane`]'s `x`).
    across: &'a [f32],
    rows: (u32, u32),
    boxes: &'a [Drawn],
    band: &'a [u32],
    out: &'a mut [f32],
}

impl Kernel for FillRays<'_> {
    type Output = ();

    #[inline(always)]
    fn run<I: Isa>(self, _isa: I) {
        let FillRays {
            frame,
            rect,
            across,
            rows: (y0, y1),
            boxes,
            band,
            out,
        } = self;
        use crate::simd::LANES;
        let w = (rect.x1 - rect.x0) as usize;
        let rows = (y1 - y0) as usize;
        // The band in rows of `stride` values: a box's span of a row is
        // tested a whole vector at a time from its first pixel, the lanes past
        // its end masked, so a span of a few pixels (most of them) costs a
        // vector step or two and no scalar remainder loop; the padding keeps
        // every step inside the row.
        let stride = w.next_multiple_of(LANES) + LANES;
        // The band's rays' inverse directions, per axis. An axis a ray does not
        // move along gets ±f32::MAX instead of ±∞, so that a box face through
        // the eye gives 0 rather than NaN (0·∞), and the slab stays right: all
        // of the ray's parameters when the eye is between the planes, none
        // otherwise (with the eye on a plane, either: a box is grown by
        // `MARGIN`, so such a ray passes that far outside its cells). Lanes
        // past the row's end repeat its last pixel (their results are masked).
        let mut inv = [(); 3].map(|_| vec![0.0f32; rows * stride]);
        // The directions are `forward + x·right + y·up` normalised, with `x`
        // per column and `y` per row ([`CameraFrame::image_plane`]): a
        // square root and three divisions a pixel, where normalising and
        // then inverting took seven, in a plain loop the compiler
        // vectorises (the bands' set-up had been a third of the fill).
        let (forward, right, up) = (frame.forward, frame.right, frame.up);
        for row in 0..rows {
            let y = frame.image_plane(0, rect.y0 + y0 + row as u32).1;
            let base = forward + y * up;
            let [ix, iy, iz] = &mut inv;
            let (ix, iy, iz) = (
                &mut ix[row * stride..][..stride],
                &mut iy[row * stride..][..stride],
                &mut iz[row * stride..][..stride],
            );
            for (x, &sx) in across.iter().enumerate() {
                let (dx, dy, dz) = (
                    base.x + sx * right.x,
                    base.y + sx * right.y,
                    base.z + sx * right.z,
                );
                let len = ((dx * dx) + (dy * dy) + (dz * dz)).sqrt();
                ix[x] = (len / dx).clamp(-f32::MAX, f32::MAX);
                iy[x] = (len / dy).clamp(-f32::MAX, f32::MAX);
                iz[x] = (len / dz).clamp(-f32::MAX, f32::MAX);
            }
            for inv in [ix, iy, iz] {
                let last = inv[w - 1];
                inv[w..].fill(last);
            }
        }
        let mut depth = vec![f32::INFINITY; rows * stride];
        let eye = frame.position();
        for &k in band {
            let b = boxes[k as usize];
            let (lo, hi) = ((b.lo - eye).to_array(), (b.hi - eye).to_array());
            let r = b.blocks;
            for j in r.y0.max(y0)..r.y1.min(y1) {
                let at = (j - y0) as usize * stride;
                let mut x = r.x0 as usize;
                while x < r.x1 as usize {
                    // Lanes `0..n` are the span's pixels `x..x + n`.
                    let n = (r.x1 as usize - x).min(LANES) as u32;
                    // (The padded row holds a whole vector from any pixel.)
                    let chunk = at + x..at + x + LANES;
                    let lanes = |v: &[f32]| -> [f32; LANES] {
                        v[chunk.clone()].try_into().expect("LANES values")
                    };
                    let (ix, iy, iz) = (lanes(&inv[0]), lanes(&inv[1]), lanes(&inv[2]));
                    let d = &mut depth[chunk];
                    // The slab test, from the box's lower bound, lane-wise
                    // without a branch (vectorised): NaN-free (see above). A
                    // lane past the span starts with an empty interval.
                    let mut t0 = [b.t; LANES];
                    let mut t1: [f32; LANES] = std::array::from_fn(|l| {
                        if (l as u32) < n {
                            f32::INFINITY
                        } else {
                            f32::NEG_INFINITY
                        }
                    });
                    for (a, inv) in [ix, iy, iz].into_iter().enumerate() {
                        for l in 0..LANES {
                            (t0[l], t1[l]) = clip_slab(lo[a], hi[a], inv[l], (t0[l], t1[l]));
                        }
                    }
                    // `f32::min` (neither is NaN): the compiler makes `if t <
                    // d { d = t }` a masked store of the lanes that change,
                    // which is slow.
                    for l in 0..LANES {
                        let t = if t0[l] <= t1[l] { t0[l] } else { f32::INFINITY };
                        d[l] = d[l].min(t);
                    }
                    x += LANES;
                }
            }
        }
        // Moved a few units in the last place earlier than found: the
        // directions' rounding differs from the renderer's by about that
        // much, and a depth stays a bound on the grown box's own entry
        // along the renderer's ray.
        for (row, out) in out.chunks_mut(w).enumerate().take(rows) {
            for (out, &d) in out.iter_mut().zip(&depth[row * stride..row * stride + w]) {
                *out = d * (1.0 - 8.0 * f32::EPSILON);
            }
        }
    }
}

/// The boxes of the runs of straddling cells `runs` seen by a perspective
/// `frame` ([`ProxyDepth::build`]'s first pass): [`box_of`] of each, those
/// that show. Its arithmetic (the grown box, [`CameraFrame::box_rect`],
/// [`nearest_t`]) is done for [`RUN_LANES`] boxes at once, in the same
/// order lane by lane, so the results are the same to the bit; a
/// [`Kernel`] so that it is compiled 16 wide where the CPU has AVX-512.
struct BoxRects<'a> {
    frame: &'a CameraFrame,
    rect: PixelRect,
    grid: &'a Grid,
    runs: CellRuns<'a>,
    /// Blocks of `1 << shift` pixels a side.
    shift: u32,
}

/// Boxes per lane-wise step of [`BoxRects`].
const RUN_LANES: usize = 16;

impl Kernel for BoxRects<'_> {
    type Output = Vec<Drawn>;
    const WIDE: bool = true;

    #[inline(always)]
    fn run<I: Isa>(self, _isa: I) -> Self::Output {
        const N: usize = RUN_LANES;
        let BoxRects {
            frame,
            rect,
            grid,
            runs,
            shift,
        } = self;
        let (origin, spacing) = (grid.origin, grid.spacing);
        let eye = frame.position();
        let n = runs.runs.len();
        let mut out = Vec::with_capacity(n);
        for first in (0..n).step_by(N) {
            let chunk_len = N.min(n - first);
            // Lanes past the chunk's end repeat its first run.
            let mut lo = [[0.0f32; N]; 3];
            let mut hi = [[0.0f32; N]; 3];
            for l in 0..N {
                let (vlo, vhi) = runs.voxel_box(first + if l < chunk_len { l } else { 0 });
                for a in 0..3 {
                    lo[a][l] = origin[a] + (vlo[a] - MARGIN) * spacing[a];
                    hi[a][l] = origin[a] + (vhi[a] + MARGIN) * spacing[a];
                }
            }
            let r = frame.box_rects(&lo, &hi);
            // `nearest_t`: the eye's distance to the box.
            let mut t = [0.0f32; N];
            for (l, t) in t.iter_mut().enumerate() {
                let d: [f32; 3] = std::array::from_fn(|a| {
                    let q = if eye[a] > lo[a][l] { eye[a] } else { lo[a][l] };
                    let q = if q < hi[a][l] { q } else { hi[a][l] };
                    q - eye[a]
                });
                *t = ((d[0] * d[0]) + (d[1] * d[1]) + (d[2] * d[2]))
                    .sqrt()
                    .max(0.0);
            }
            for l in 0..chunk_len {
                let r = PixelRect {
                    x0: r[0][l],
                    y0: r[1][l],
                    x1: r[2][l],
                    y1: r[3][l],
                }
                .intersect(&rect);
                if r.is_empty() {
                    continue;
                }
                out.push(Drawn {
                    blocks: blocks_of(&r, &rect, shift),
                    t: t[l],
                    lo: Vec3::new(lo[0][l], lo[1][l], lo[2][l]),
                    hi: Vec3::new(hi[0][l], hi[1][l], hi[2][l]),
                });
            }
        }
        out
    }
}

/// Runs `f` on each of `pieces` on the calling thread and up to
/// `threads − 1` scoped threads (fewer when there are fewer pieces, or one
/// cannot be started), which take the pieces in turn, and returns the
/// results in the pieces' order.
///
/// The proxy's two passes are short (a millisecond or two a frame), and a
/// rayon pool asked for them from outside, after idling through the
/// frame's rendering, often left one worker to do all of it while the
/// others had not woken (measured per thread in the object renderer's
/// frames): threads started for the pass work from the start.
fn on_threads<P: Send, T: Send>(
    threads: usize,
    pieces: Vec<P>,
    f: impl Fn(P) -> T + Sync,
) -> Vec<T> {
    let helpers = pieces.len().min(threads).saturating_sub(1);
    let queue = Mutex::new(pieces.into_iter().enumerate());
    // Each thread takes pieces until none is left (the lock held only to
    // take one) and returns what it made, by piece.
    let work = || {
        let mut made = Vec::new();
        loop {
            let next = queue.lock().next();
            let Some((i, p)) = next else {
                return made;
            };
            made.push((i, f(p)));
        }
    };
    let mut made: Vec<(usize, T)> = std::thread::scope(|s| {
        // A thread that cannot be started leaves its piece to the others.
        let started: Vec<_> = (0..helpers)
            .filter_map(|_| {
                std::thread::Builder::new()
                    .name("raycaster-proxy".into())
                    .spawn_scoped(s, work)
                    .ok()
            })
            .collect();
        let mut made = work();
        for h in started {
            match h.join() {
                Ok(m) => made.extend(m),
                Err(panic) => std::panic::resume_unwind(panic),
            }
        }
        made
    });
    made.sort_unstable_by_key(|&(i, _)| i);
    made.into_iter().map(|(_, t)| t).collect()
}

/// The straddling cells seen from a directional light: how far a shadow
/// ray can go towards the light before it has passed every cell that can
/// hold the surface.
///
/// Shadow rays are parallel, so each is a single point in an orthographic
/// view along the light, and a [`ProxyDepth`] drawn in that view holds,
/// per block of that point's neighbourhood, the depth of the straddling
/// cell nearest the light. A shadow ray from a point at depth `d` meets no
/// straddling cell once it has climbed past that depth, so its walk ends
/// there instead of at the volume's edge, and a walk that never enters one
/// cannot find a crossing. Conservative as the camera's proxy is (grown
/// boxes, one pixel of margin around each box's rectangle), so shadows are
/// unchanged.
#[derive(Debug, Clone)]
pub struct LightProxy {
    depth: ProxyDepth,
    /// The light view's projection (every shadow ray projects its origin,
    /// first thing: no divisions). It rounds a little differently from the
    /// boxes' rectangles, which their margin of a pixel absorbs.
    to_view: AffineProjection,
}

/// The light's view: pixels of about this many of the grid's smallest
/// spacings a side (a block of [`BLOCK`] pixels is then about a cell, the
/// size of what is drawn).
const LIGHT_PIXEL: f32 = 0.5;

/// At most this many pixels a side in a light's view.
const LIGHT_MAX_SIDE: u32 = 2048;

impl LightProxy {
    /// The straddling cells of `cells` (a grid `grid`) seen from the
    /// directional light towards `light` (world, unit); `None` when drawing
    /// them would not pay ([`ProxyDepth::pays`]) or the view is degenerate.
    pub fn build(light: Vec3, grid: &Grid, cells: &IsoCells) -> Option<Self> {
        let bounds = grid.bounds();
        let centre = bounds.center();
        let radius = 0.5 * (bounds.max - bounds.min).length();
        if !(radius > 0.0 && radius.is_finite()) {
            return None;
        }
        // An eye outside the bounding sphere, and an image a little larger
        // than the sphere's disc.
        let distance = 2.0 * radius + 1.0;
        let half = 1.02 * radius;
        let pixel = LIGHT_PIXEL * grid.spacing.min_element();
        let side = ((2.0 * half / pixel).ceil() as u32).clamp(2 * BLOCK, LIGHT_MAX_SIDE);
        let mut camera = Camera::look_at(centre + light * distance, centre, side, side);
        camera.projection = Projection::Orthographic;
        camera.fov_y_deg = 2.0 * (half / distance).atan().to_degrees();
        if light.y.abs() > 0.9 {
            camera.up = Vec3::X;
        }
        let frame = camera.frame()?;
        let rect = frame.full_rect();
        if !ProxyDepth::pays(cells.straddling_count(), &rect) {
            return None;
        }
        let to_view = frame.affine_projection()?;
        let depth = ProxyDepth::build(
            &frame,
            rect,
            grid,
            CellRuns::straddling(cells),
            Coverage::Blocks,
        );
        Some(LightProxy { depth, to_view })
    }

    /// How far (world units) a shadow ray from world point `p` towards the
    /// light can meet a straddling cell: none lies beyond this. Infinite
    /// when `p` is outside the light's view (nothing is known there), zero
    /// or less when the ray meets none.
    #[inline]
    pub fn reach(&self, p: Vec3) -> f32 {
        let [x, y, depth] = self.to_view.apply(p);
        let rect = self.depth.rect;
        // Behind the view's image plane, or outside the image.
        if !(depth >= 0.0 && x >= 0.0 && y >= 0.0 && x < rect.x1 as f32 && y < rect.y1 as f32) {
            return f32::INFINITY;
        }
        let nearest = self.depth.at(x as u32, y as u32);
        if nearest == f32::INFINITY {
            return f32::NEG_INFINITY;
        }
        // The ray climbs towards the light, against the view's depth.
        depth - nearest + 1e-4 * (depth.abs() + nearest.abs())
    }
}

/// The buffer's blocks (of `1 << shift` pixels a side over `rect`) that
/// the pixels `r` of `rect` touch.
#[inline(always)]
fn blocks_of(r: &PixelRect, rect: &PixelRect, shift: u32) -> PixelRect {
    let block = 1 << shift;
    PixelRect {
        x0: (r.x0 - rect.x0) >> shift,
        y0: (r.y0 - rect.y0) >> shift,
        x1: (r.x1 - rect.x0).div_ceil(block),
        y1: (r.y1 - rect.y0).div_ceil(block),
    }
}

/// A lower bound on the ray parameter at which any of `frame`'s rays meets
/// the box `[lo, hi]`: under perspective the distance from the eye to the
/// box (rays have unit directions), orthographic the box's nearest depth
/// from the image plane the rays start on; never below 0.
fn nearest_t(frame: &CameraFrame, lo: Vec3, hi: Vec3) -> f32 {
    let eye = frame.position();
    let t = match frame.projection() {
        Projection::Perspective => (eye.clamp(lo, hi) - eye).length(),
        Projection::Orthographic => {
            let f = frame.forward;
            // The nearest corner along the view direction.
            let corner = Vec3::select(f.cmpge(Vec3::ZERO), lo, hi);
            (corner - eye).dot(f)
        }
    };
    t.max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::{MacrocellGrid, SkipGrid};
    use crate::camera::Camera;
    use crate::geometry::{Aabb, Ray};
    use crate::volume::AnyVolume;

    /// A sphere's distance field (×10) on an anisotropic grid, and its
    /// skip grid for iso value `iso`.
    fn sphere_cells(iso: f32) -> (Grid, SkipGrid) {
        let grid = Grid::new(UVec3::new(20, 17, 23), Vec3::new(1.0, 0.8, 1.2));
        let centre = Vec3::new(9.0, 8.0, 11.0);
        let volume = AnyVolume::from_fn(grid, |v| (v.as_vec3() - centre).length() * 10.0);
        let macrocells = MacrocellGrid::build_any(&volume, 4, None);
        let skip = SkipGrid::for_iso(&volume, &macrocells, iso);
        (grid, skip)
    }

    /// The straddling cells' boxes, grown as [`ProxyDepth::build`] grows
    /// them.
    fn grown_boxes(grid: &Grid, cells: &IsoCells) -> Vec<Aabb> {
        cells
            .straddling_cells()
            .map(|c| {
                let c = c.as_vec3();
                Aabb::new(
                    grid.voxel_to_world(c - Vec3::splat(MARGIN)),
                    grid.voxel_to_world(c + Vec3::splat(1.0 + MARGIN)),
                )
            })
            .collect()
    }

    /// `on_threads` gives each piece's result in the pieces' order and
    /// runs each piece once, for no pieces, one, and more pieces than
    /// threads.
    #[test]
    fn on_threads_runs_each_piece_once_and_keeps_their_order() {
        for n in [0usize, 1, 2, 3, 7] {
            let mut data: Vec<u32> = (0..100).collect();
            let pieces: Vec<&mut [u32]> = data.chunks_mut(100usize.div_ceil(n.max(1))).collect();
            let pieces: Vec<&mut [u32]> = pieces.into_iter().take(n).collect();
            let sums = on_threads(n.min(3), pieces, |p| {
                p.iter_mut().for_each(|v| *v += 1000);
                p.iter().sum::<u32>()
            });
            let chunk = 100usize.div_ceil(n.max(1));
            let expected: Vec<u32> = (0..n)
                .map(|k| {
                    (k * chunk..((k + 1) * chunk).min(100))
                        .map(|v| v as u32 + 1000)
                        .sum()
                })
                .collect();
            assert_eq!(sums, expected, "{n} pieces");
            // Each piece's values were changed exactly once.
            let touched = if n == 0 { 0 } else { (n * chunk).min(100) };
            assert!(
                data[..touched]
                    .iter()
                    .enumerate()
                    .all(|(i, &v)| v == i as u32 + 1000)
            );
            assert!(
                data[touched..]
                    .iter()
                    .enumerate()
                    .all(|(i, &v)| v == (touched + i) as u32)
            );
        }
    }

    /// DVR's proxy, drawn from the macrocells a TF makes visible (a ball,
    /// macrocells of 4 voxels, runs along z): before each pixel's first
    /// kept sample, moved as the frame driver moves it, lie only samples
    /// in empty macrocells, for both projections and eyes outside the
    /// grid, inside it in empty space and inside the ball, both coverages;
    /// and it pays: rays missing the ball are culled, others start past
    /// samples, and drawn ray by ray it culls more and starts later.
    #[test]
    fn dvr_depths_leave_only_empty_cells_before_the_first_sample() {
        use crate::integrator::RaySegment;
        let grid = Grid::new(UVec3::new(37, 30, 41), Vec3::new(1.0, 0.8, 1.2));
        let centre = Vec3::new(20.0, 14.0, 22.0);
        let volume = AnyVolume::from_fn(grid, |v| (v.as_vec3() - centre).length() * 10.0);
        let macrocells = MacrocellGrid::build_any(&volume, 4, None);
        // Visible within 7 voxels of the centre.
        let skip = SkipGrid::build(&macrocells, |lo, _| lo < 70.0);
        let runs = CellRuns::plain(&skip, false);
        assert_eq!(runs.side, 4.0);
        assert!(runs.runs.len() > 5 && skip.occupied_count() > runs.runs.len());
        let world = |v: Vec3| grid.voxel_to_world(v);
        for (eye, projection, outside) in [
            (Vec3::new(70.0, 45.0, -30.0), Projection::Perspective, true),
            (Vec3::new(70.0, 45.0, -30.0), Projection::Orthographic, true),
            (
                world(Vec3::new(3.0, 3.0, 3.0)),
                Projection::Perspective,
                false,
            ),
            (
                world(centre + Vec3::new(0.5, 0.3, 0.2)),
                Projection::Perspective,
                false,
            ),
        ] {
            let look = if outside {
                world(centre)
            } else {
                eye + Vec3::new(1.0, 0.6, 0.8)
            };
            let mut cam = Camera::look_at(eye, look, 48, 40);
            cam.projection = projection;
            cam.fov_y_deg = 70.0;
            let frame = cam.frame().unwrap();
            let rect = frame.screen_rect(&grid.bounds());
            let mut seen = Vec::new();
            for coverage in [Coverage::Blocks, Coverage::Rays] {
                let proxy = ProxyDepth::build(&frame, rect, &grid, runs, coverage);
                let (mut culled, mut reached, mut passed) = (0, 0, 0);
                for j in 0..40 {
                    for i in 0..48 {
                        let ray = frame.ray(i, j);
                        let Some(seg) = RaySegment::new(&grid, &ray, 0.3) else {
                            continue;
                        };
                        let t = proxy.at(i, j);
                        // A culled ray keeps no sample.
                        let first = match t {
                            f32::INFINITY => seg.count,
                            t => seg.first_index_at_or_after(t).min(seg.count),
                        };
                        let occupied = |k: u32| skip.is_occupied(skip.locate(seg.pos(k)).0);
                        for k in 0..first {
                            assert!(
                                !occupied(k),
                                "{eye} {projection:?} pixel {i},{j} sample {k}"
                            );
                        }
                        culled += t.is_infinite() as u32;
                        reached += (first..seg.count).any(occupied) as u32;
                        passed += first;
                    }
                }
                assert!(reached > 30, "{eye} {projection:?}: {reached}");
                // Inside the ball every ray starts in an occupied cell.
                let in_ball = (grid.world_to_voxel(eye) - centre).length() < 1.0;
                let enough = if in_ball { passed == 0 } else { passed > 1000 };
                assert!(enough, "{eye} {projection:?}: {passed}");
                if outside {
                    assert!(culled > 50, "{eye} {projection:?}: {culled}");
                }
                seen.push((culled, passed));
            }
            let ((c_blocks, p_blocks), (c_rays, p_rays)) = (seen[0], seen[1]);
            if projection == Projection::Perspective {
                assert!(c_rays >= c_blocks && p_rays >= p_blocks, "{eye}: {seen:?}");
                if outside {
                    assert!(c_rays > c_blocks && p_rays > p_blocks, "{eye}: {seen:?}");
                }
            } else {
                assert_eq!(seen[0], seen[1], "{eye}: drawn as blocks either way");
            }
        }
    }

    /// Every pixel's depth is at or before the nearest entry into a
    /// straddling cell's box (found here by brute force), finite wherever
    /// a ray enters one, for both projections; and some rays that enter
    /// the volume are culled.
    #[test]
    fn depths_bound_the_nearest_box_entries() {
        let (grid, skip) = sphere_cells(55.0);
        let cells = skip.iso_cells().unwrap();
        let boxes = grown_boxes(&grid, cells);
        assert!(boxes.len() > 100);
        let coverages = [Coverage::Blocks, Coverage::Rays];
        for (projection, coverage) in [Projection::Perspective, Projection::Orthographic]
            .into_iter()
            .flat_map(|p| coverages.map(|c| (p, c)))
        {
            let mut cam = Camera::look_at(
                Vec3::new(40.0, 25.0, -18.0),
                Vec3::new(8.0, 7.0, 12.0),
                48,
                40,
            );
            cam.projection = projection;
            let frame = cam.frame().unwrap();
            let rect = frame.screen_rect(&grid.bounds());
            let proxy =
                ProxyDepth::build(&frame, rect, &grid, CellRuns::straddling(cells), coverage);
            assert_eq!(proxy.boxes(), cells.straddling_runs().len());
            assert!(proxy.boxes() < boxes.len());
            let per_ray = coverage == Coverage::Rays && projection == Projection::Perspective;
            let (mut covered, mut culled, mut loose) = (0, 0, 0);
            for j in 0..40 {
                for i in 0..48 {
                    let ray = frame.ray(i, j);
                    let want = boxes
                        .iter()
                        .filter_map(|b| b.intersect(&ray).map(|(t_in, _)| t_in))
                        .fold(f32::INFINITY, f32::min);
                    let got = proxy.at(i, j);
                    assert!(got >= 0.0);
                    assert!(got <= want, "{projection:?} pixel {i},{j}: {got} > {want}");
                    covered += want.is_finite() as u32;
                    culled += (got.is_infinite() && grid.bounds().intersect(&ray).is_some()) as u32;
                    // Drawn ray by ray, the depth is the entry itself, up
                    // to rounding, and only rays entering a box see one.
                    if per_ray {
                        assert_eq!(got.is_finite(), want.is_finite(), "pixel {i},{j}");
                        loose += (got < want - 1e-4 * want.max(1.0)) as u32;
                    }
                }
            }
            assert_eq!(loose, 0, "{projection:?} {coverage:?}");
            assert!(culled > 20, "{projection:?}: {culled}");
            assert!(covered > 100, "{projection:?}: {covered}");
            // `culls` says of a rectangle what `at` says of its pixels,
            // for rectangles of every size and offset, partly outside
            // the buffer's too.
            let (mut yes, mut no) = (0, 0);
            for (w, h) in [(1, 1), (4, 4), (3, 5), (16, 16), (7, 2)] {
                for y0 in 0..40 - h {
                    for x0 in 0..48 - w {
                        let r = PixelRect {
                            x0,
                            y0,
                            x1: x0 + w,
                            y1: y0 + h,
                        };
                        let want = (y0..y0 + h)
                            .all(|j| (x0..x0 + w).all(|i| proxy.at(i, j) == f32::INFINITY));
                        assert_eq!(proxy.culls(&r), want, "{projection:?} {r:?}");
                        if want { yes += 1 } else { no += 1 }
                    }
                }
            }
            assert!(yes > 100 && no > 100, "{yes}/{no}");
            // `block_at` reads what `at` reads, lane by lane, for blocks
            // at every offset, inside the rectangle drawn and across its
            // edges.
            let (mut inside, mut across) = (0, 0);
            for y0 in 0..=40 - PACKET_H {
                for x0 in 0..=48 - PACKET_W {
                    let got = proxy.block_at(x0, y0);
                    for (l, &t) in got.iter().enumerate() {
                        let (i, j) = (x0 + l as u32 % PACKET_W, y0 + l as u32 / PACKET_W);
                        assert_eq!(t.to_bits(), proxy.at(i, j).to_bits(), "{x0},{y0} lane {l}");
                    }
                    let whole = rect.contains(x0, y0)
                        && rect.contains(x0 + PACKET_W - 1, y0 + PACKET_H - 1);
                    if whole { inside += 1 } else { across += 1 }
                }
            }
            assert!(inside > 50 && across > 50, "{inside}/{across}");
        }
    }

    /// The first pass's lane-wise kernel gives what `box_of` gives run by
    /// run, for eyes outside the grid, beside it and inside it (boxes
    /// reaching the eye plane, behind the eye), for any number of runs, of
    /// interpolation cells and of macrocells (side 4).
    #[test]
    fn box_rects_kernel_is_box_of_run_by_run() {
        let (grid, skip) = sphere_cells(55.0);
        let cells = skip.iso_cells().unwrap();
        let runs = cells.straddling_runs();
        assert!(runs.len() > 100);
        for eye in [
            Vec3::new(40.0, 25.0, -18.0),
            Vec3::new(9.0, 8.0, -3.0),
            Vec3::new(8.0, 7.0, 12.0),
        ] {
            let cam = Camera::look_at(eye, Vec3::new(8.0, 7.5, 13.0), 61, 47);
            let frame = cam.frame().unwrap();
            let rect = frame.screen_rect(&grid.bounds());
            for (n, side) in [0, 1, 15, 16, 17, runs.len()]
                .into_iter()
                .flat_map(|n| [(n, 1.0), (n / 4, 4.0)])
            {
                // With and without narrowed boxes.
                let shrink: Vec<[u8; 6]> = (0..n)
                    .map(|k| std::array::from_fn(|a| ((k * 7 + a * 3) % 3) as u8))
                    .collect();
                for shrink in [&[][..], &shrink[..]] {
                    let some = CellRuns {
                        runs: &runs[..n],
                        side,
                        shrink,
                    };
                    let want: Vec<_> = (0..n)
                        .filter_map(|k| box_of(&frame, &rect, &grid, some.voxel_box(k)))
                        .collect();
                    let got = simd::dispatch(BoxRects {
                        frame: &frame,
                        rect,
                        grid: &grid,
                        runs: some,
                        shift: BLOCK_SHIFT,
                    });
                    assert_eq!(got.len(), want.len(), "{eye} {n} {side}");
                    for (g, w) in got.iter().zip(&want) {
                        assert_eq!(g.blocks, w.blocks, "{eye} {n} {side}");
                        assert_eq!(g.t.to_bits(), w.t.to_bits(), "{eye} {n} {side}");
                        assert_eq!((g.lo, g.hi), (w.lo, w.hi), "{eye} {n} {side}");
                    }
                    if n == runs.len() {
                        assert!(!want.is_empty(), "{eye}");
                    }
                }
            }
        }
    }

    /// A shadow ray from any point goes no further than its light proxy's
    /// reach before it has left every straddling cell's box towards the
    /// light (brute force), for lights along and off the axes; and the
    /// reach cuts most rays well short of the volume's edge.
    #[test]
    fn light_reach_bounds_the_farthest_box_exits() {
        let (grid, skip) = sphere_cells(45.0);
        let cells = skip.iso_cells().unwrap();
        let boxes = grown_boxes(&grid, cells);
        let bounds = grid.bounds();
        let mut rng = fastrand::Rng::with_seed(7);
        for light in [
            Vec3::Y,
            Vec3::NEG_X,
            Vec3::new(0.6, 1.0, 0.4).normalize(),
            Vec3::new(-0.3, -0.2, 1.0).normalize(),
        ] {
            let proxy = LightProxy::build(light, &grid, cells).unwrap();
            let (mut cut, mut tried) = (0, 0);
            for _ in 0..3000 {
                let u = Vec3::new(rng.f32(), rng.f32(), rng.f32());
                let p = bounds.min + u * (bounds.max - bounds.min);
                let ray = Ray {
                    origin: p,
                    dir: light,
                };
                let want = boxes
                    .iter()
                    .filter_map(|b| b.intersect(&ray).map(|(_, t_out)| t_out))
                    .fold(f32::NEG_INFINITY, f32::max);
                let got = proxy.reach(p);
                assert!(got >= want, "light {light} point {p}: reach {got} < {want}");
                let edge = bounds.intersect(&ray).map_or(0.0, |(_, t)| t);
                tried += 1;
                cut += (got < 0.5 * edge) as u32;
            }
            assert!(cut * 4 > tried, "light {light}: {cut} of {tried} cut");
        }
    }
}
