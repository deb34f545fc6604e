//! Integrators: what happens along one ray.
//!
//! A ray is a [`RaySegment`]: sample positions `t_k = t_in + k·s` for
//! `k = 0, 1, …` while `t_k <= t_out`, clipped to the volume's box. Each mode
//! is an [`Integrator`]: a small per-ray state that takes the samples of a
//! range of indices (so a renderer can integrate a ray piece by piece, brick
//! by brick) and finally resolves to a premultiplied colour. Empty-space
//! skipping reaches an integrator as runs of sample indices
//! ([`Span::runs`]): empty runs it may jump over, occupied ones with
//! their macrocell.
//!
//! Adding a mode: a file with a state type implementing [`Integrator`], a
//! [`RenderMode`] variant, and its arm in [`RenderMode::visit`].

mod avg;
mod batch;
mod block;
mod dvr;
mod fragment;
mod iso;
mod mip;
mod none;
mod segment;
mod shading;

pub use avg::AvgState;
pub use block::{BLOCK, PACKET_H, PACKET_W, RayBlock};
pub use dvr::DvrState;
pub use fragment::Fragment;
pub use iso::{CellCubic, IsoHit, IsoNormals, IsoState, ShadingCache};

pub use mip::{Extremum, Max, Min, MinipState, MipState, ProjectionState};
pub use none::NoSamples;
pub use segment::{RaySegment, jitter};
pub use shading::Phong;

use glam::{Vec3, Vec4};

use crate::accel::{MacrocellGrid, SkipGrid, SkipRuns};
use crate::clip::ClipRegion;
use crate::scene::Scene;
use crate::transfer::{TfLut, TransferFunction};
use crate::volume::Volume;

/// The rendering mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum RenderMode {
    /// Direct volume rendering: front-to-back compositing.
    #[default]
    #[cfg_attr(
        feature = "clap",
        value(help = "Direct volume rendering (front-to-back compositing)")
    )]
    Dvr,
    /// Maximum intensity projection.
    #[cfg_attr(feature = "clap", value(help = "Maximum intensity projection"))]
    Mip,
    /// Minimum intensity projection.
    #[cfg_attr(feature = "clap", value(help = "Minimum intensity projection"))]
    Minip,
    /// Mean value along the ray ("x-ray").
    #[cfg_attr(feature = "clap", value(help = "Mean value along each ray (x-ray)"))]
    Avg,
    /// First crossing of an iso value, shaded.
    #[cfg_attr(feature = "clap", value(help = "Isosurface at --iso"))]
    Iso,
    /// The surface of metaballs made from the volume or a points file
    /// (rendered by [`crate::metaballs`], not from the volume's samples).
    #[cfg_attr(
        feature = "clap",
        value(help = "Metaballs: balls from voxels above --ball-threshold or a points file")
    )]
    Metaballs,
}

impl RenderMode {
    /// The name used on command lines.
    pub fn name(self) -> &'static str {
        match self {
            RenderMode::Dvr => "dvr",
            RenderMode::Mip => "mip",
            RenderMode::Minip => "minip",
            RenderMode::Avg => "avg",
            RenderMode::Iso => "iso",
            RenderMode::Metaballs => "metaballs",
        }
    }

    /// Runs `visitor` with the integrator of this mode: the one place a mode
    /// becomes a type.
    pub fn visit<T: IntegratorVisitor>(self, visitor: T) -> T::Output {
        match self {
            RenderMode::Dvr => visitor.visit::<DvrState>(),
            RenderMode::Mip => visitor.visit::<MipState>(),
            RenderMode::Minip => visitor.visit::<MinipState>(),
            RenderMode::Avg => visitor.visit::<AvgState>(),
            RenderMode::Iso => visitor.visit::<IsoState>(),
            RenderMode::Metaballs => visitor.visit::<NoSamples>(),
        }
    }

    /// Whether the mode is rendered from the volume's samples by an
    /// [`Integrator`] (every mode but [`RenderMode::Metaballs`]).
    pub fn samples_volume(self) -> bool {
        self != RenderMode::Metaballs
    }
}

/// Code that runs with the integrator type of a [`RenderMode`].
pub trait IntegratorVisitor {
    /// What the visit returns.
    type Output;
    /// Runs with `I` the mode's integrator.
    fn visit<I: Integrator>(self) -> Self::Output;
}

/// Which macrocells a mode may skip.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Occupancy {
    /// A cell is occupied when the TF gives any of its values opacity.
    Visible,
    /// A cell is occupied when its value range holds the iso value.
    IsoValue,
    /// Every cell is occupied: the integrator decides per cell from the
    /// macrocell ranges (e.g. MIP skips cells that cannot raise its maximum).
    Every,
}

impl Occupancy {
    /// The skip grid of this occupancy over the macrocells of `scene`, for
    /// the frame's TF table and iso value; cells holding nothing `clip`
    /// keeps are empty whatever the occupancy.
    pub fn skip_grid(
        self,
        scene: &Scene,
        lut: &TfLut,
        iso: f32,
        clip: Option<&ClipRegion>,
    ) -> SkipGrid {
        let cells = scene.macrocells();
        match self {
            Occupancy::Visible => {
                SkipGrid::build_clipped(cells, |lo, hi| lut.any_visible(lo, hi), clip)
                    .with_steady(cells, |lo, hi| lut.constant_over(lo, hi))
            }
            Occupancy::IsoValue => SkipGrid::for_iso_clipped(scene.volume(), cells, iso, clip),
            Occupancy::Every => SkipGrid::build_clipped(cells, |_, _| true, clip),
        }
    }
}

/// Samples `start..end` of one ray, with the frame they belong to: what an
/// [`Integrator`] takes in one step.
#[derive(Clone, Copy)]
pub struct Span<'a, V: Volume> {
    /// The frame.
    pub ctx: &'a FrameContext<'a, V>,
    /// The ray.
    pub seg: &'a RaySegment,
    /// First sample index.
    pub start: u32,
    /// One past the last sample index (integrators clamp `start..end` to
    /// the ray's kept samples `seg.first..seg.count`).
    pub end: u32,
}

impl<'a, V: Volume> Span<'a, V> {
    /// Samples `start..end` of `seg`.
    #[inline(always)]
    pub fn new(ctx: &'a FrameContext<'a, V>, seg: &'a RaySegment, start: u32, end: u32) -> Self {
        Span {
            ctx,
            seg,
            start,
            end,
        }
    }

    /// The whole ray: its kept samples `first..count`.
    #[inline(always)]
    pub fn whole(ctx: &'a FrameContext<'a, V>, seg: &'a RaySegment) -> Self {
        Self::new(ctx, seg, seg.first, seg.count)
    }

    /// The span's samples in runs, empty or occupied by the frame's skip
    /// grid; one run of unknown occupancy when ESS is off.
    #[inline(always)]
    pub fn runs(&self) -> SkipRuns<'a> {
        SkipRuns::new(
            self.ctx.ess.then_some(self.ctx.skip),
            self.seg,
            self.start,
            self.end,
        )
    }

    /// [`Span::runs`], with consecutive occupied macrocells of one `key`
    /// in one run ([`SkipRuns::merging`]).
    #[inline(always)]
    pub fn runs_merging<K: Fn(usize) -> Option<u64>>(&self, key: K) -> SkipRuns<'a, K> {
        SkipRuns::merging(
            self.ctx.ess.then_some(self.ctx.skip),
            self.seg,
            self.start,
            self.end,
            key,
        )
    }
}

/// A rendering mode's per-ray state and the rule that advances it.
///
/// Renderers are generic over the integrator (one monomorphised tile loop
/// per mode and volume type), so a state is plain data in a buffer, and
/// calls are never dispatched per sample or per pixel.
pub trait Integrator: Copy + Default + Send + Sync + std::fmt::Debug + 'static {
    /// Whether a brick whose macrocells are all empty for the frame's skip
    /// grid can be left out of the frame (true when empty space contributes
    /// nothing, as in DVR).
    const CULLS_EMPTY_BRICKS: bool = false;

    /// Whether splitting rays into pieces per brick pays: false for modes
    /// that can drop nothing up front, whose rays the object renderer then
    /// integrates whole.
    const SPLITS_RAYS: bool = true;

    /// Which macrocells this mode may skip.
    const OCCUPANCY: Occupancy = Occupancy::Every;

    /// Integrates the samples of `span`; returns how many were taken.
    fn integrate<V: Volume>(&mut self, span: Span<'_, V>) -> u64;

    /// Whether the tile loop hands this integrator the whole rays of
    /// neighbouring pixels together ([`Integrator::integrate_packet`]).
    const PACKETS: bool = false;

    /// Integrates the whole rays of the lanes `block.searched` of a block
    /// of neighbouring pixels, lane `l`'s into `rays[l]`; returns the
    /// samples taken. Each ray must come out as [`Integrator::integrate`]
    /// of its whole span would leave it, whichever rays it is handed with.
    /// This default integrates them one by one.
    #[inline(always)]
    fn integrate_packet<V: Volume>(
        ctx: &FrameContext<'_, V>,
        rays: &mut [Self; BLOCK],
        block: &RayBlock,
    ) -> u64 {
        integrate_each(ctx, rays, block)
    }

    /// True when nothing more can change this ray (ERT, a hit).
    fn is_done(&self) -> bool {
        false
    }

    /// What a tile loop keeps from one pixel's [`Integrator::resolve_in`]
    /// to the next (`()` for modes that keep nothing).
    type Scratch: Default;

    /// Premultiplied colour and opacity of the finished ray.
    fn resolve<V: Volume>(&self, ctx: &FrameContext<'_, V>) -> Vec4;

    /// [`Integrator::resolve`] for the pixels of one tile in turn, with
    /// `scratch` kept between them (a tile's neighbouring rays share
    /// work); the same result.
    #[inline(always)]
    fn resolve_in<V: Volume>(
        &self,
        ctx: &FrameContext<'_, V>,
        scratch: &mut Self::Scratch,
    ) -> Vec4 {
        let _ = scratch;
        self.resolve(ctx)
    }

    /// [`Integrator::resolve_in`] for the rays of the lanes `lanes` of one
    /// block (as [`Integrator::integrate_packet`] left them), lane `l`'s
    /// into `out[l]`: the same colours, found together where the rays can
    /// share work. This default resolves them one by one.
    #[inline(always)]
    fn resolve_packet<V: Volume>(
        rays: &[Self; BLOCK],
        lanes: u32,
        ctx: &FrameContext<'_, V>,
        scratch: &mut Self::Scratch,
        out: &mut [Vec4; BLOCK],
    ) {
        for l in crate::simd::lanes_of(lanes) {
            out[l] = rays[l].resolve_in(ctx, scratch);
        }
    }

    /// What this (part of a) ray hands over for sort-last compositing: the
    /// record that the parts of a ray merge by (see [`Fragment`]).
    fn fragment<V: Volume>(&self, ctx: &FrameContext<'_, V>) -> Fragment;
}

/// [`Integrator::integrate_packet`] one ray at a time: each searched lane
/// of `block` integrates the whole of its segment.
#[inline(always)]
pub(crate) fn integrate_each<V: Volume, I: Integrator>(
    ctx: &FrameContext<'_, V>,
    rays: &mut [I; BLOCK],
    block: &RayBlock,
) -> u64 {
    crate::simd::lanes_of(block.searched)
        .map(|l| rays[l].integrate(Span::whole(ctx, &block.segment(l))))
        .sum()
}

/// Everything an integrator needs for one frame: the volume, the tabulated
/// TF, the skip structures and the options. Cheap to copy (references).
pub struct FrameContext<'a, V: Volume> {
    /// The volume.
    pub volume: &'a V,
    /// The transfer function as given (evaluated exactly for MIP and iso).
    pub tf: &'a TransferFunction,
    /// The TF tabulated for this frame's step.
    pub lut: &'a TfLut,
    /// Value ranges per macrocell (MIP skipping).
    pub macrocells: &'a MacrocellGrid,
    /// Occupancy for this TF / iso value (DVR and iso skipping).
    pub skip: &'a SkipGrid,
    /// Empty-space skipping on.
    pub ess: bool,
    /// Early ray termination threshold (`None` = off).
    pub ert: Option<f32>,
    /// Phong parameters (`None` = unshaded).
    pub shading: Option<Phong>,
    /// Iso value for [`RenderMode::Iso`].
    pub iso_value: f32,
    /// Directional lights of [`RenderMode::Iso`]: unit world directions
    /// towards each light; empty for a headlight.
    pub lights: &'a [Vec3],
    /// Shadow rays towards each light ([`RenderMode::Iso`]).
    pub shadows: bool,
    /// The share of a hit's colour seen in the mirror direction
    /// ([`RenderMode::Iso`]; 0 = no reflection rays).
    pub reflection: f32,
    /// The background colour (what a reflection ray that leaves the
    /// volume sees).
    pub background: Vec3,
    /// Per light of [`FrameContext::lights`] (or none at all): how far
    /// its shadow rays can meet a cell that can hold the surface, which
    /// ends their walks early (`None`: walk to the volume's edge).
    pub light_proxies: &'a [Option<std::sync::Arc<crate::render::proxy::LightProxy>>],
    /// How [`RenderMode::Iso`] finds its normals.
    pub iso_normals: IsoNormals,
    /// Divisor of [`RenderMode::Avg`].
    pub avg_norm: f32,
    /// Gradient opacity of [`RenderMode::Dvr`] (`None` = off).
    pub gradient_opacity: Option<GradientOpacity>,
}

/// Gradient-magnitude opacity (SPEC §8): the TF's opacity per unit length
/// is multiplied by `w = clamp((|∇f| − g0)/(g1 − g0), 0, 1)` before step
/// correction, `∇f` the shading gradient (world units). Since `w <= 1`, a
/// value the TF leaves transparent stays transparent, so the skip grid of
/// the TF alone remains correct.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GradientOpacity {
    /// Gradient magnitude at and below which the opacity is 0.
    pub g0: f32,
    /// Gradient magnitude at and above which the opacity is the TF's.
    pub g1: f32,
}

impl GradientOpacity {
    /// The weight `w` of gradient magnitude `g`.
    #[inline(always)]
    pub fn weight(&self, g: f32) -> f32 {
        ((g - self.g0) / (self.g1 - self.g0)).clamp(0.0, 1.0)
    }

    /// A table entry `e` (premultiplied, step-corrected for `step`) with
    /// its opacity per unit length `a` scaled to `w·a`: `a` is recovered
    /// from `α = 1 − (1 − a)^step`, corrected again, and the colour
    /// rescaled with the opacity.
    #[inline]
    pub fn scale(&self, e: Vec4, w: f32, step: f32) -> Vec4 {
        let a = 1.0 - (1.0 - e.w).max(0.0).powf(1.0 / step);
        let alpha = 1.0 - (1.0 - w * a).powf(step);
        e * (alpha / e.w)
    }
}
