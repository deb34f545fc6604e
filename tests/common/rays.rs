//! Single rays: one ray integrated with the library's integrators (the API
//! renderers are built from), and random rays and directions.

use glam::Vec3;
use glam::Vec4;
use raycaster::accel::SkipGrid;
use raycaster::geometry::Ray;
use raycaster::integrator::{
    DvrState, FrameContext, Integrator, IsoState, MipState, Occupancy, Phong, RaySegment,
    ShadingCache, Span,
};
use raycaster::prelude::*;
use raycaster::transfer::TfLut;

/// Integrates single rays with the library's integrators (the API renderers
/// are built from), for one volume, TF, step and mode.
pub struct RayLab<'a> {
    scene: &'a Scene,
    tf: &'a TransferFunction,
    lut: TfLut,
    skip: SkipGrid,
    /// The skip grid of modes that visit every cell (MIP).
    every: SkipGrid,
    step: f32,
    iso: f32,
    /// Phong shading in the frame context (none by default).
    shading: Option<Phong>,
    /// Directional lights (a headlight when empty) and shadow rays.
    lights: Vec<Vec3>,
    shadows: bool,
}

/// Work on one ray segment with the frame context of a concretely typed
/// volume.
trait RayJob {
    type Out;
    /// The job visits every macrocell (its integrator's occupancy is
    /// `Every`), rather than skipping the lab's empty ones.
    const EVERY_CELL: bool = false;
    fn run<V: Volume>(self, ctx: &FrameContext<'_, V>, seg: &RaySegment) -> Self::Out;
}

impl<'a> RayLab<'a> {
    /// For DVR and MIP: a macrocell is empty when the TF shows nothing in
    /// its value range.
    pub fn dvr(scene: &'a Scene, tf: &'a TransferFunction, step: f32) -> Self {
        Self::new(scene, tf, step, None)
    }

    /// For iso: a macrocell is empty when its value range misses `iso`.
    pub fn iso(scene: &'a Scene, tf: &'a TransferFunction, step: f32, iso: f32) -> Self {
        Self::new(scene, tf, step, Some(iso))
    }

    fn new(scene: &'a Scene, tf: &'a TransferFunction, step: f32, iso: Option<f32>) -> Self {
        let lut = TfLut::new(tf, step);
        let skip = match iso {
            // What a DVR frame builds: occupancy and the steady flags.
            None => Occupancy::Visible.skip_grid(scene, &lut, 0.0, None),
            Some(iso) => SkipGrid::for_iso(scene.volume(), scene.macrocells(), iso),
        };
        RayLab {
            scene,
            tf,
            lut,
            skip,
            every: SkipGrid::all_occupied(scene.macrocells()),
            step,
            iso: iso.unwrap_or(0.0),
            shading: None,
            lights: Vec::new(),
            shadows: false,
        }
    }

    /// The same lab with Phong shading on.
    pub fn shaded(self, phong: Phong) -> Self {
        RayLab {
            shading: Some(phong),
            ..self
        }
    }

    /// The same lab with directional lights towards `lights` (world, unit)
    /// instead of the headlight, and with shadow rays when `shadows`.
    pub fn lit(self, lights: &[Vec3], shadows: bool) -> Self {
        RayLab {
            lights: lights.to_vec(),
            shadows,
            ..self
        }
    }

    /// Runs `job` on the segment of `ray` inside the volume (`None` when
    /// the ray misses it).
    fn run<J: RayJob>(&self, ray: &Ray, ess: bool, job: J) -> Option<J::Out> {
        struct Visit<'l, 'a, J> {
            lab: &'l RayLab<'a>,
            seg: RaySegment,
            ess: bool,
            job: J,
        }
        impl<J: RayJob> VolumeVisitor for Visit<'_, '_, J> {
            type Output = J::Out;
            fn visit<V: Volume>(self, volume: &V) -> J::Out {
                let lab = self.lab;
                let ctx = FrameContext {
                    volume,
                    tf: lab.tf,
                    lut: &lab.lut,
                    macrocells: lab.scene.macrocells(),
                    skip: if J::EVERY_CELL { &lab.every } else { &lab.skip },
                    ess: self.ess,
                    ert: None,
                    shading: lab.shading,
                    iso_value: lab.iso,
                    lights: &lab.lights,
                    shadows: lab.shadows,
                    reflection: 0.0,
                    background: Vec3::ZERO,
                    light_proxies: &[],
                    iso_normals: Default::default(),
                    avg_norm: 255.0,
                    gradient_opacity: None,
                };
                self.job.run(&ctx, &self.seg)
            }
        }
        let seg = RaySegment::new(self.scene.grid(), ray, self.step)?;
        Some(self.scene.volume().visit(Visit {
            lab: self,
            seg,
            ess,
            job,
        }))
    }

    /// World-space iso hit, and the samples taken.
    pub fn iso_hit(&self, ray: &Ray, ess: bool) -> (Option<Vec3>, u64) {
        struct Iso;
        impl RayJob for Iso {
            type Out = (Option<Vec3>, u64);
            fn run<V: Volume>(self, ctx: &FrameContext<'_, V>, seg: &RaySegment) -> Self::Out {
                let mut st = IsoState::default();
                let n = st.integrate(Span::whole(ctx, seg));
                (
                    st.hit
                        .map(|h| ctx.volume.grid().voxel_to_world(h.pos.into())),
                    n,
                )
            }
        }
        self.run(ray, ess, Iso).unwrap_or((None, 0))
    }

    /// The iso colour of `ray` as [`Integrator::resolve`] gives it, and as
    /// [`Integrator::resolve_in`] gives it with `cache` carried over from
    /// the rays resolved before (as a tile loop does); `None` when the ray
    /// misses the volume.
    pub fn iso_colours(&self, ray: &Ray, cache: &mut ShadingCache) -> Option<(Vec4, Vec4)> {
        struct Iso<'c>(&'c mut ShadingCache);
        impl RayJob for Iso<'_> {
            type Out = (Vec4, Vec4);
            fn run<V: Volume>(self, ctx: &FrameContext<'_, V>, seg: &RaySegment) -> Self::Out {
                let mut st = IsoState::default();
                st.integrate(Span::whole(ctx, seg));
                (st.resolve(ctx), st.resolve_in(ctx, self.0))
            }
        }
        self.run(ray, true, Iso(cache))
    }

    pub fn dvr_state(&self, ray: &Ray, ess: bool) -> Option<(DvrState, u64)> {
        struct Dvr;
        impl RayJob for Dvr {
            type Out = (DvrState, u64);
            fn run<V: Volume>(self, ctx: &FrameContext<'_, V>, seg: &RaySegment) -> Self::Out {
                let mut st = DvrState::default();
                let n = st.integrate(Span::whole(ctx, seg));
                (st, n)
            }
        }
        self.run(ray, ess, Dvr)
    }

    pub fn mip_max(&self, ray: &Ray, ess: bool) -> Option<f32> {
        struct Mip;
        impl RayJob for Mip {
            type Out = f32;
            const EVERY_CELL: bool = true;
            fn run<V: Volume>(self, ctx: &FrameContext<'_, V>, seg: &RaySegment) -> f32 {
                let mut st = MipState::default();
                st.integrate(Span::whole(ctx, seg));
                st.value
            }
        }
        self.run(ray, ess, Mip)
    }
}

pub fn random_unit(rng: &mut fastrand::Rng) -> Vec3 {
    loop {
        let v = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 2.0 - Vec3::ONE;
        let l = v.length();
        if l > 0.1 && l <= 1.0 {
            return v / l;
        }
    }
}

/// A random ray from outside (or, for `inside`, within) `bounds` aimed at a
/// random point of the box.
pub fn random_ray(rng: &mut fastrand::Rng, lo: Vec3, hi: Vec3, inside: bool) -> Ray {
    let pick = |rng: &mut fastrand::Rng| {
        Vec3::new(
            lo.x + rng.f32() * (hi.x - lo.x),
            lo.y + rng.f32() * (hi.y - lo.y),
            lo.z + rng.f32() * (hi.z - lo.z),
        )
    };
    let target = pick(rng);
    let origin = if inside {
        pick(rng)
    } else {
        (lo + hi) * 0.5 + random_unit(rng) * (hi - lo).length() * 1.5
    };
    Ray {
        origin,
        dir: (target - origin).normalize(),
    }
}
