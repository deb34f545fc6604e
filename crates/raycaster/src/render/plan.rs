//! Per-frame preparation shared by all renderers: the validated camera and
//! step, the tabulated TF and the skip grid (cached per TF, step and mode,
//! for the last few of them: an interactive client alternates between
//! coarse-step previews and full-step frames, and must not rebuild both
//! tables at every switch).

use std::sync::Arc;

use super::proxy::{CellRuns, Coverage, LightProxy, ProxyDepth};
use crate::accel::{IsoCells, SkipGrid};
use crate::camera::{Camera, CameraFrame, PixelRect};
use crate::clip::ClipRegion;
use crate::error::{Error, Result};
use crate::geometry::Aabb;
use crate::integrator::{FrameContext, Integrator, IntegratorVisitor, Occupancy, Phong};
use crate::scene::Scene;
use crate::transfer::{TfLut, TransferFunction};
use crate::volume::Volume;

pub use super::options::RenderOptions;

/// Identity of what the cached LUT and skip grid were built for.
#[derive(Debug, Clone, PartialEq)]
struct PlanKey {
    scene: u64,
    tf: TransferFunction,
    step: u32,
    occupancy: Occupancy,
    /// The iso value's bits where the occupancy depends on it, else 0.
    iso: u32,
    /// The clip region the skip grid leaves out.
    clip: Option<ClipRegion>,
}

/// How many (TF, step, mode) combinations a [`PlanCache`] keeps: enough for
/// the steps of a client's preview and refinement levels.
const PLAN_CACHE_ENTRIES: usize = 6;

/// The TF tables and skip grids of the last few frames, reused while they
/// still apply; the least recently used is dropped first.
#[derive(Debug, Default)]
pub struct PlanCache {
    /// Most recently used first.
    entries: Vec<(PlanKey, Arc<(TfLut, SkipGrid)>)>,
    /// Lights' proxies, most recently used first, by the tables whose
    /// surface they were drawn for (compared by identity; holding the `Arc`
    /// keeps its address from being reused) and the light's direction.
    lights: Vec<(Prepared, [u32; 3], Option<Arc<LightProxy>>)>,
}

/// A frame's tabulated TF and skip grid, shared between frames.
type Prepared = Arc<(TfLut, SkipGrid)>;

/// How many lights' proxies a [`PlanCache`] keeps (each up to a few MB).
const LIGHT_CACHE_ENTRIES: usize = 4;

impl PlanCache {
    /// The LUT and skip grid for this scene, TF, step and mode.
    pub(crate) fn get(
        &mut self,
        scene: &Scene,
        tf: &TransferFunction,
        step: f32,
        options: &RenderOptions,
        clip: Option<&ClipRegion>,
    ) -> Arc<(TfLut, SkipGrid)> {
        struct OccupancyOf;
        impl IntegratorVisitor for OccupancyOf {
            type Output = Occupancy;
            fn visit<I: Integrator>(self) -> Occupancy {
                I::OCCUPANCY
            }
        }
        let occupancy = options.mode.visit(OccupancyOf);
        let key = PlanKey {
            scene: scene.id(),
            tf: tf.clone(),
            step: step.to_bits(),
            occupancy,
            iso: match occupancy {
                Occupancy::IsoValue => options.iso_value.to_bits(),
                Occupancy::Visible | Occupancy::Every => 0,
            },
            clip: clip.cloned(),
        };
        if let Some(i) = self.entries.iter().position(|(k, _)| *k == key) {
            let hit = self.entries.remove(i);
            let v = hit.1.clone();
            self.entries.insert(0, hit);
            return v;
        }
        // Another scene's tables can never be used again.
        self.entries.retain(|(k, _)| k.scene == key.scene);
        self.entries.truncate(PLAN_CACHE_ENTRIES - 1);
        let lut = TfLut::new(tf, step);
        let skip = occupancy.skip_grid(scene, &lut, options.iso_value, clip);
        let v = Arc::new((lut, skip));
        self.entries.insert(0, (key, v.clone()));
        v
    }

    /// The proxy of the light towards `light` (unit) for the surface of the
    /// fine level `cells` of `prepared`'s skip grid (on `grid`), drawn on
    /// first use and kept while that surface and light stay in use: shadow
    /// rays towards a fixed light (a turntable, an animation, a viewer
    /// whose light stays put) need it drawn once, not for every frame.
    pub(crate) fn light_proxy(
        &mut self,
        prepared: &Prepared,
        light: glam::Vec3,
        grid: &crate::volume::Grid,
        cells: &IsoCells,
    ) -> Option<Arc<LightProxy>> {
        let bits = light.to_array().map(f32::to_bits);
        let found = self
            .lights
            .iter()
            .position(|(p, b, _)| Arc::ptr_eq(p, prepared) && *b == bits);
        let entry = match found {
            Some(i) => self.lights.remove(i),
            None => {
                // Tables no longer cached are never used again.
                let entries = &self.entries;
                self.lights
                    .retain(|(p, ..)| entries.iter().any(|(_, e)| Arc::ptr_eq(p, e)));
                self.lights.truncate(LIGHT_CACHE_ENTRIES - 1);
                let proxy = LightProxy::build(light, grid, cells).map(Arc::new);
                (prepared.clone(), bits, proxy)
            }
        };
        let proxy = entry.2.clone();
        self.lights.insert(0, entry);
        proxy
    }

    /// How many tables are cached.
    #[cfg(test)]
    fn len(&self) -> usize {
        self.entries.len()
    }
}

/// Most samples one ray may take (2²⁰): a volume 10⁶ steps across. More
/// is a step chosen by mistake (a spacing of 1e-15 beside spacings of 1
/// makes the default step that small) and would never finish.
pub const MAX_SAMPLES_PER_RAY: f64 = (1u32 << 20) as f64;

/// How finely f32 must resolve a ray's parameter: consecutive samples
/// `t_in + k·s` stay at least 2³ ulps apart when `s ≥ t·2⁻²⁰`.
const T_RESOLUTION: f64 = 1.0 / (1u32 << 20) as f64;

/// Refuses a step that would make a frame take unbounded time or collapse
/// its sample positions, so every renderer's per-ray counting (done in
/// f32, see `RaySegment::new`) terminates after at most
/// [`MAX_SAMPLES_PER_RAY`] samples. Checked in f64 from the box's diagonal
/// and the camera's distance to its farthest corner.
pub(crate) fn check_sampling(bounds: &Aabb, eye: glam::Vec3, step: f32) -> Result<()> {
    if !(step.is_finite() && step > 0.0) {
        return Err(Error::option(
            "step",
            format!("{step} must be finite and > 0"),
        ));
    }
    let (lo, hi) = (bounds.min.as_dvec3(), bounds.max.as_dvec3());
    let diagonal = (hi - lo).length();
    if !diagonal.is_finite() {
        return Err(Error::option(
            "volume",
            format!("its extent {} is not finite in f32", hi - lo),
        ));
    }
    let step64 = f64::from(step);
    let samples = diagonal / step64 + 1.0;
    if samples > MAX_SAMPLES_PER_RAY {
        return Err(Error::option(
            "step",
            format!(
                "{} is too small for a volume {diagonal:.3e} world units across: \
                 a ray could take {samples:.3e} samples (at most {MAX_SAMPLES_PER_RAY}); \
                 use a step of at least {:.3e}",
                number(step),
                diagonal / (MAX_SAMPLES_PER_RAY - 1.0)
            ),
        ));
    }
    let far = bounds
        .corners()
        .iter()
        .map(|c| (c.as_dvec3() - eye.as_dvec3()).length())
        .fold(0.0f64, f64::max);
    if step64 < far * T_RESOLUTION {
        return Err(Error::option(
            "step",
            format!(
                "{} cannot be resolved in f32 at {far:.3e} world units from the camera \
                 (needs a step of at least {:.3e}); move the camera closer or use a larger step",
                number(step),
                far * T_RESOLUTION
            ),
        ));
    }
    Ok(())
}

/// A number for a message: plain when of ordinary size, else in e-notation
/// (a step of 9e-16 printed plainly is a row of zeros).
fn number(x: f32) -> String {
    if x == 0.0 || (1e-4..1e7).contains(&x.abs()) {
        x.to_string()
    } else {
        format!("{x:e}")
    }
}

/// Validated per-frame inputs common to every renderer.
pub struct FramePlan {
    pub camera: CameraFrame,
    pub rect: PixelRect,
    pub step: f32,
    pub prepared: Arc<(TfLut, SkipGrid)>,
    pub width: u32,
    pub height: u32,
    /// The options' lights as unit vectors.
    pub lights: Vec<glam::Vec3>,
    /// The options' clip region in voxel space (`None`: nothing clipped).
    pub clip: Option<ClipRegion>,
    /// The jitter seed when samples are jittered.
    pub jitter: Option<u32>,
    /// With empty-space skipping in exact iso mode and DVR: where each
    /// pixel's ray first meets a cell that can hold the surface or that
    /// the TF makes visible (its walk starts there; a pixel it calls empty
    /// meets none).
    pub proxy: Option<ProxyDepth>,
    /// What the proxy depths move: the start of the iso search
    /// ([`RaySegment::t_in`]) or, in DVR, the first sample kept
    /// ([`RaySegment::first`]), so that the samples stay where they are.
    ///
    /// [`RaySegment::t_in`]: crate::integrator::RaySegment::t_in
    /// [`RaySegment::first`]: crate::integrator::RaySegment::first
    pub proxy_moves_samples: bool,
    /// With shadows in exact iso mode with empty-space skipping: per light
    /// (in the order of [`FramePlan::lights`]), how far its shadow rays
    /// can meet a cell that can hold the surface (`None`: the whole way).
    pub light_proxies: Vec<Option<Arc<LightProxy>>>,
}

impl FramePlan {
    pub fn new(
        cache: &mut PlanCache,
        scene: &Scene,
        camera: &Camera,
        tf: &TransferFunction,
        options: &RenderOptions,
    ) -> Result<Self> {
        if !options.mode.samples_volume() {
            return Err(Error::option(
                "mode",
                format!(
                    "{} is not rendered from the volume's samples: use raycaster::metaballs::MetaballRenderer",
                    options.mode.name()
                ),
            ));
        }
        scene.check_source()?;
        let grid = scene.grid();
        let frame = camera.frame().ok_or_else(|| {
            Error::option(
                "camera",
                format!(
                    "degenerate (position {}, look-at {}, up {}, fov {}, size {}x{})",
                    camera.position,
                    camera.target,
                    camera.up,
                    camera.fov_y_deg,
                    camera.width,
                    camera.height
                ),
            )
        })?;
        let step = options.step_for(grid);
        check_sampling(&grid.bounds(), frame.position(), step)?;
        if !(options.ert_threshold > 0.0 && options.ert_threshold <= 1.0) {
            return Err(Error::option(
                "ERT threshold",
                format!("{} must be in (0, 1]", options.ert_threshold),
            ));
        }
        let mut lights = Vec::with_capacity(options.lights.len());
        for l in &options.lights {
            let unit = l.normalize_or_zero();
            if unit == glam::Vec3::ZERO || !unit.is_finite() {
                return Err(Error::option(
                    "light",
                    format!("direction {l} must be finite and not zero"),
                ));
            }
            lights.push(unit);
        }
        if !(0.0..=1.0).contains(&options.reflection) {
            return Err(Error::option(
                "reflection",
                format!("{} must be in [0, 1]", options.reflection),
            ));
        }
        options.clip.validate()?;
        if let Some(go) = options.gradient_opacity
            && !(go.g0.is_finite() && go.g1.is_finite() && go.g0 < go.g1)
        {
            return Err(Error::option(
                "gradient-opacity",
                format!("g0 = {} must be below g1 = {} (both finite)", go.g0, go.g1),
            ));
        }
        let clip = options.clip.region(grid);
        let prepared = cache.get(scene, tf, step, options, clip.as_ref());
        Ok(FramePlan {
            proxy: None,
            proxy_moves_samples: false,
            light_proxies: Vec::new(),
            clip,
            jitter: (options.jitter && options.mode != crate::integrator::RenderMode::Iso)
                .then_some(options.seed),
            lights,
            rect: frame.screen_rect(&grid.bounds()),
            camera: frame,
            step,
            prepared,
            width: camera.width,
            height: camera.height,
        })
    }

    /// Draws the frame's proxy depths ([`FramePlan::proxy`]) when the
    /// frame is exact iso or DVR with skipping, and for exact iso with
    /// shadows its lights' ([`FramePlan::light_proxies`]); the frame
    /// driver calls it for the
    /// rays it casts from the camera. A light's proxy depends on the light
    /// and the surface only, not on the camera: it is kept in `cache` for
    /// the next frames.
    pub fn draw_proxy(&mut self, cache: &mut PlanCache, scene: &Scene, options: &RenderOptions) {
        use crate::integrator::RenderMode;
        self.proxy = None;
        self.proxy_moves_samples = false;
        self.light_proxies = Vec::new();
        let grid = scene.grid();
        let skip = &self.prepared.1;
        if options.ess && options.mode == RenderMode::Dvr {
            // The macrocells the TF makes visible: a sample before the
            // nearest of them along its ray lies in an empty one.
            if ProxyDepth::pays(skip.occupied_count(), &self.rect) {
                let outside = self.eye_outside(grid, skip);
                // Narrowed from the TF's second frame on.
                let runs = if skip.proxy_drawn_before() && VisibleRuns::pays(skip, outside) {
                    scene.volume().visit(VisibleRuns {
                        skip,
                        lut: &self.prepared.0,
                        outside,
                    })
                } else {
                    CellRuns::plain(skip, outside)
                };
                self.proxy = Some(ProxyDepth::build(
                    &self.camera,
                    self.rect,
                    grid,
                    runs,
                    Coverage::Rays,
                ));
                self.proxy_moves_samples = true;
            }
            return;
        }
        let Some(cells) = skip.iso_cells() else {
            return;
        };
        if !(options.ess && options.mode == RenderMode::Iso) {
            return;
        }
        if ProxyDepth::pays(cells.straddling_count(), &self.rect) {
            let runs = CellRuns::straddling(cells);
            self.proxy = Some(ProxyDepth::build(
                &self.camera,
                self.rect,
                grid,
                runs,
                Coverage::Blocks,
            ));
        }
        if options.shadows && options.shading {
            self.light_proxies = self
                .lights
                .iter()
                .map(|&l| cache.light_proxy(&self.prepared, l, grid, cells))
                .collect();
        }
    }

    /// Whether every camera ray starts outside the skip grid's cells (a
    /// perspective eye outside them, with a voxel to spare), so that the
    /// first occupied cell a ray meets is one of
    /// [`SkipGrid::surface_runs`].
    fn eye_outside(&self, grid: &crate::volume::Grid, skip: &SkipGrid) -> bool {
        use crate::camera::Projection;
        if self.camera.projection() != Projection::Perspective {
            return false;
        }
        let side = skip.cell_side();
        let a = grid.voxel_to_world(glam::Vec3::splat(-1.0));
        let b = grid.voxel_to_world(skip.count().as_vec3() * side + 1.0);
        let cells = Aabb::new(a.min(b), a.max(b));
        !cells.contains(self.camera.position())
    }

    /// The integrators' view of this frame for the concretely typed
    /// `volume` of `scene`.
    pub fn context<'a, V: Volume>(
        &'a self,
        volume: &'a V,
        scene: &'a Scene,
        tf: &'a TransferFunction,
        options: &RenderOptions,
    ) -> FrameContext<'a, V> {
        self.context_with_range(volume, scene, tf, options, scene.value_range())
    }

    /// [`FramePlan::context`] with the data's value range given (it sets
    /// the shading's gradient threshold): a part of a distributed volume
    /// uses the whole volume's range, so every part shades alike.
    pub fn context_with_range<'a, V: Volume>(
        &'a self,
        volume: &'a V,
        scene: &'a Scene,
        tf: &'a TransferFunction,
        options: &RenderOptions,
        (lo, hi): (f32, f32),
    ) -> FrameContext<'a, V> {
        let shading = options.shading.then(|| {
            options
                .phong
                .unwrap_or_else(|| Phong::for_value_range(hi - lo))
        });
        FrameContext {
            volume,
            tf,
            lut: &self.prepared.0,
            macrocells: scene.macrocells(),
            skip: &self.prepared.1,
            ess: options.ess,
            ert: options.ert.then_some(options.ert_threshold),
            shading,
            iso_value: options.iso_value,
            lights: &self.lights,
            shadows: options.shadows,
            reflection: options.reflection,
            background: options.background,
            light_proxies: &self.light_proxies,
            iso_normals: options.iso_normals,
            avg_norm: <V::Sample as crate::sample::Sample>::TYPE.max_value(),
            gradient_opacity: options.gradient_opacity,
        }
    }
}

/// [`CellRuns::visible`] of `skip` for the volume visited, whose
/// visible interpolation cells `lut` says: the proxy's boxes narrowed from
/// the surface macrocells to where their visible voxels (and the parts
/// they share with interior cells) lie, so rays start nearer their first
/// visible sample and more of them are culled; for an eye not `outside`
/// the macrocells, all occupied ones narrowed. Found once per TF, by
/// reading every drawn cell's voxels.
struct VisibleRuns<'a> {
    skip: &'a SkipGrid,
    lut: &'a TfLut,
    outside: bool,
}

/// The most interpolation cells [`VisibleRuns`] reads (about 8 M, some
/// tens of milliseconds on two cores): a larger surface (a huge volume)
/// keeps its macrocell boxes, rather than reading (and mapping into
/// memory) the voxels of every surface cell, most of which no ray that
/// the first visible data stops would reach.
const MAX_NARROWED_CELLS: u64 = 1 << 23;

impl VisibleRuns<'_> {
    /// Whether narrowing the runs drawn for an eye `outside` the macrocells
    /// (or not) reads at most [`MAX_NARROWED_CELLS`].
    fn pays(skip: &SkipGrid, outside: bool) -> bool {
        let runs = skip.proxy_runs(outside);
        let cells: u64 = runs.iter().map(|&(_, n)| n as u64).sum();
        cells * (skip.cell_side() as u64).pow(3) <= MAX_NARROWED_CELLS
    }
}

impl<'a> crate::volume::VolumeVisitor for VisibleRuns<'a> {
    type Output = CellRuns<'a>;

    fn visit<V: Volume>(self, volume: &V) -> CellRuns<'a> {
        use glam::UVec3;
        let (skip, lut) = (self.skip, self.lut);
        let side = skip.cell_side() as u32;
        // One past the last interpolation cell per axis (one cell along an
        // axis of one voxel, whose corners repeat it).
        let end = volume.grid().last_cell() + UVec3::ONE;
        let visible = |c: UVec3| {
            // The macrocell's interpolation cells `lo..hi`, each visible
            // when the TF makes some value between its least and greatest
            // corner visible.
            let lo = c * side;
            let hi = ((c + UVec3::ONE) * side).min(end);
            let (mut first, mut last) = (hi, lo);
            // Neighbouring cells often share a range: the last answer.
            let mut known = (f32::NAN, f32::NAN, false);
            for x in lo.x..hi.x {
                for y in lo.y..hi.y {
                    for z in lo.z..hi.z {
                        let cell = UVec3::new(x, y, z);
                        let k = volume.corners(cell);
                        let (a, b) = k[1..]
                            .iter()
                            .fold((k[0], k[0]), |(a, b), &v| (a.min(v), b.max(v)));
                        if (a, b) != (known.0, known.1) {
                            known = (a, b, lut.any_visible(a, b));
                        }
                        if known.2 {
                            first = first.min(cell);
                            last = last.max(cell + UVec3::ONE);
                        }
                    }
                }
            }
            first.cmplt(last).all().then_some([first, last])
        };
        CellRuns::visible(skip, self.outside, visible)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{AnyVolume, Grid};
    use glam::{UVec3, Vec3};

    /// The value of a volume at a voxel-space point.
    struct At(Vec3);

    impl crate::volume::VolumeVisitor for At {
        type Output = f32;
        fn visit<V: Volume>(self, volume: &V) -> f32 {
            volume.sample(self.0)
        }
    }

    /// DVR's proxy from the surface macrocells (or, for an eye inside the
    /// grid, all occupied ones) narrowed to their visible voxels
    /// ([`VisibleRuns`]): before each pixel's first kept sample lies no
    /// sample the TF makes visible (balls of two visible values, one
    /// inside the other, in invisible noise, and a lattice of visible
    /// blocks; cells of 4 voxels; eyes outside the grid on several sides
    /// and inside it), and it starts rays later than the cells' own boxes
    /// do, some of them past every sample.
    #[test]
    fn visible_surface_depths_leave_only_invisible_samples_before_the_first() {
        use crate::accel::MacrocellGrid;
        use crate::camera::Camera;
        use crate::integrator::RaySegment;
        use crate::render::proxy::{CellRuns, Coverage, ProxyDepth};
        use crate::sample::SampleType;
        let grid = Grid::new(UVec3::new(45, 38, 50), Vec3::new(1.0, 0.9, 1.1));
        let (a, b) = (Vec3::new(20.0, 18.0, 24.0), Vec3::new(30.0, 20.0, 30.0));
        let mut rng = fastrand::Rng::with_seed(5);
        let balls = AnyVolume::from_fn(grid, |v| {
            let p = v.as_vec3();
            if (p - b).length() < 5.0 {
                100u8
            } else if (p - a).length() < 13.0 {
                95
            } else {
                rng.u8(..60)
            }
        });
        // Two visible voxels a side at the centre of every macrocell of a
        // block of them: rays that pass between those of the outer cells
        // meet those of the inner (interior) cells, through the faces they
        // share.
        let lattice = AnyVolume::from_fn(grid, |v| {
            let inside = v.cmpge(UVec3::splat(8)).all() && v.cmplt(UVec3::splat(37)).all();
            let m = v % 4;
            if inside && m.cmpge(UVec3::ONE).all() && m.cmple(UVec3::splat(2)).all() {
                95u8
            } else {
                0
            }
        });
        for volume in [balls, lattice] {
            let tf = TransferFunction::preset("shapes", SampleType::U8).unwrap();
            let step = 0.3;
            let lut = TfLut::new(&tf, step);
            let macrocells = MacrocellGrid::build_any(&volume, 4, None);
            let skip = SkipGrid::build(&macrocells, |lo, hi| lut.any_visible(lo, hi));
            let world = |v: Vec3| grid.voxel_to_world(v);
            // Eyes outside the grid (the surface cells narrowed), and
            // inside it in noise and in the big ball (all occupied cells
            // narrowed), each against the runs it narrows; in the ball,
            // every ray starts in visible data (nothing to pass).
            for (eye, outside, passes) in [
                (Vec3::new(80.0, 60.0, -30.0), true, true),
                (Vec3::new(-40.0, 20.0, 25.0), true, true),
                (Vec3::new(20.0, -50.0, 90.0), true, true),
                (world(Vec3::new(4.0, 3.0, 44.0)), false, true),
                (world(a + Vec3::new(2.0, -3.0, 1.0)), false, false),
            ] {
                let narrowed = volume.visit(VisibleRuns {
                    skip: &skip,
                    lut: &lut,
                    outside,
                });
                assert!(!narrowed.shrink.is_empty());
                let surface = CellRuns::plain(&skip, outside);
                let mut cam = Camera::look_at(eye, world(a), 48, 40);
                cam.fov_y_deg = 50.0;
                let frame = cam.frame().unwrap();
                let rect = frame.screen_rect(&grid.bounds());
                let first_kept = |runs| {
                    let proxy = ProxyDepth::build(&frame, rect, &grid, runs, Coverage::Rays);
                    let mut firsts = Vec::new();
                    for j in 0..40 {
                        for i in 0..48 {
                            let Some(seg) = RaySegment::new(&grid, &frame.ray(i, j), step) else {
                                continue;
                            };
                            let first = match proxy.at(i, j) {
                                f32::INFINITY => seg.count,
                                t => seg.first_index_at_or_after(t).min(seg.count),
                            };
                            firsts.push((seg, first));
                        }
                    }
                    firsts
                };
                let (mut later, mut visible_rays) = (0, 0);
                for ((seg, first), (_, before)) in
                    first_kept(narrowed).into_iter().zip(first_kept(surface))
                {
                    let visible = |k: u32| lut.lookup(volume.visit(At(seg.pos(k)))).w > 0.0;
                    for k in 0..first {
                        assert!(
                            !visible(k),
                            "eye {eye}: sample {k} before the first kept {first}"
                        );
                    }
                    assert!(first >= before);
                    later += (first > before) as u32;
                    visible_rays += (first..seg.count).any(visible) as u32;
                }
                assert!(
                    (later > 20 || !passes) && visible_rays > 50,
                    "eye {eye}: {later} later, {visible_rays} visible"
                );
            }
        }
    }

    #[test]
    fn alternating_steps_reuse_their_tables_and_old_ones_are_dropped() {
        let grid = Grid::new(UVec3::splat(8), Vec3::ONE);
        let scene = Scene::new(AnyVolume::from_fn(grid, |v| (v.x * 30) as u8));
        let tf = TransferFunction::preset("ramp", crate::sample::SampleType::U8).unwrap();
        let options = RenderOptions::default();
        let mut cache = PlanCache::default();
        let fine = cache.get(&scene, &tf, 0.5, &options, None);
        let coarse = cache.get(&scene, &tf, 1.0, &options, None);
        assert!(!Arc::ptr_eq(&fine, &coarse));
        // Back and forth: the same tables, nothing rebuilt.
        assert!(Arc::ptr_eq(
            &cache.get(&scene, &tf, 0.5, &options, None),
            &fine
        ));
        assert!(Arc::ptr_eq(
            &cache.get(&scene, &tf, 1.0, &options, None),
            &coarse
        ));
        assert_eq!(cache.len(), 2);
        // Many other steps: bounded, the least recently used goes first.
        for k in 0..PLAN_CACHE_ENTRIES {
            cache.get(&scene, &tf, 2.0 + k as f32, &options, None);
        }
        assert_eq!(cache.len(), PLAN_CACHE_ENTRIES);
        assert!(!Arc::ptr_eq(
            &cache.get(&scene, &tf, 0.5, &options, None),
            &fine
        ));
        // A new scene drops the old scene's tables.
        let other = Scene::new(AnyVolume::from_fn(grid, |v| (v.y * 30) as u8));
        cache.get(&other, &tf, 0.5, &options, None);
        assert_eq!(cache.len(), 1);
    }

    /// A light's proxy is drawn once for a surface and light and found
    /// again for the next frames, the same as a fresh one; another light,
    /// another iso value or dropped tables draw it anew, and the cache
    /// stays bounded. A second frame (with the cached proxy) is the first's.
    #[test]
    fn lights_proxies_are_kept_for_their_surface_and_light() {
        use crate::camera::Camera;
        use crate::integrator::RenderMode;
        use crate::render::{Renderer, SerialRenderer};
        let grid = Grid::new(UVec3::new(24, 20, 22), Vec3::new(1.0, 0.8, 1.2));
        let centre = grid.extent() * 0.5;
        let scene = Scene::new(AnyVolume::from_fn(grid, |v| {
            let p = v.as_vec3() * grid.spacing;
            (p - centre).length().min(p.y - 2.0 + 6.0)
        }));
        let tf = TransferFunction::preset("ramp", crate::sample::SampleType::F32).unwrap();
        let options = RenderOptions {
            mode: RenderMode::Iso,
            iso_value: 6.0,
            lights: vec![Vec3::new(0.3, 1.0, 0.2)],
            shadows: true,
            ..RenderOptions::default()
        };
        let mut cache = PlanCache::default();
        let prepared = cache.get(&scene, &tf, 0.5, &options, None);
        let cells = prepared.1.iso_cells().unwrap();
        let light = Vec3::new(0.6, 1.0, 0.4).normalize();
        let first = cache.light_proxy(&prepared, light, &grid, cells).unwrap();
        let again = cache.light_proxy(&prepared, light, &grid, cells).unwrap();
        assert!(Arc::ptr_eq(&first, &again));
        let fresh = LightProxy::build(light, &grid, cells).unwrap();
        let mut rng = fastrand::Rng::with_seed(4);
        for _ in 0..500 {
            let p = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * grid.extent();
            assert_eq!(first.reach(p).to_bits(), fresh.reach(p).to_bits());
        }
        // Other lights, up to the bound: the first is then drawn anew.
        for k in 0..LIGHT_CACHE_ENTRIES {
            let other = Vec3::new(k as f32 * 0.1, 1.0, -0.5).normalize();
            assert!(!Arc::ptr_eq(
                &cache.light_proxy(&prepared, other, &grid, cells).unwrap(),
                &first
            ));
        }
        assert!(cache.lights.len() <= LIGHT_CACHE_ENTRIES);
        let redrawn = cache.light_proxy(&prepared, light, &grid, cells).unwrap();
        assert!(!Arc::ptr_eq(&redrawn, &first));
        // Another iso value: other tables, another proxy.
        let iso7 = RenderOptions {
            iso_value: 7.0,
            ..options.clone()
        };
        let other = cache.get(&scene, &tf, 0.5, &iso7, None);
        let cells7 = other.1.iso_cells().unwrap();
        assert!(!Arc::ptr_eq(
            &cache.light_proxy(&other, light, &grid, cells7).unwrap(),
            &redrawn
        ));
        // Two frames of one renderer, the second with the cached proxy.
        let camera = Camera::look_at(centre + Vec3::new(5.0, 30.0, 40.0), centre, 64, 48);
        let mut renderer = SerialRenderer::new();
        let a = renderer.render(&scene, &camera, &tf, &options).unwrap();
        let b = renderer.render(&scene, &camera, &tf, &options).unwrap();
        assert_eq!(a.rgb, b.rgb);
        assert!(a.stats.covered > 500);
    }
}
