//! Single rays: one ray integrated with the library's integrators (the API
//! renderers are built from), and random rays and directions.

use glam::Vec3;
use raycaster::accel::SkipGrid;
use raycaster::geometry::Ray;
use raycaster::integrator::{DvrState, FrameContext, IsoState, MipState, RaySegment};
use raycaster::prelude::*;
use raycaster::transfer::TfLut;

/// Integrates single rays with the library's integrators (the API renderers
/// are built from), for one volume, TF, step and mode.
pub struct RayLab<'a, V: Volume> {
    scene: &'a Scene<V>,
    tf: &'a TransferFunction,
    lut: TfLut,
    skip: SkipGrid,
    step: f32,
    iso: f32,
}

impl<'a, V: Volume> RayLab<'a, V> {
    /// For DVR and MIP: a macrocell is empty when the TF shows nothing in
    /// its value range.
    pub fn dvr(scene: &'a Scene<V>, tf: &'a TransferFunction, step: f32) -> Self {
        Self::new(scene, tf, step, None)
    }

    /// For iso: a macrocell is empty when its value range misses `iso`.
    pub fn iso(scene: &'a Scene<V>, tf: &'a TransferFunction, step: f32, iso: f32) -> Self {
        Self::new(scene, tf, step, Some(iso))
    }

    fn new(scene: &'a Scene<V>, tf: &'a TransferFunction, step: f32, iso: Option<f32>) -> Self {
        let lut = TfLut::new(tf, step);
        let skip = match iso {
            None => SkipGrid::build(scene.macrocells(), |lo, hi| lut.any_visible(lo, hi)),
            Some(iso) => SkipGrid::build(scene.macrocells(), |lo, hi| lo <= iso && iso <= hi),
        };
        RayLab {
            scene,
            tf,
            lut,
            skip,
            step,
            iso: iso.unwrap_or(0.0),
        }
    }

    fn ctx(&self, ess: bool) -> FrameContext<'_, V> {
        FrameContext {
            volume: self.scene.volume(),
            tf: self.tf,
            lut: &self.lut,
            macrocells: self.scene.macrocells(),
            skip: &self.skip,
            ess,
            ert: None,
            shading: None,
            iso_value: self.iso,
            avg_norm: 255.0,
        }
    }

    fn segment(&self, ray: &Ray) -> Option<RaySegment> {
        RaySegment::new(self.scene.volume().grid(), ray, self.step)
    }

    /// World-space iso hit, and the samples taken.
    pub fn iso_hit(&self, ray: &Ray, ess: bool) -> (Option<Vec3>, u64) {
        let Some(seg) = self.segment(ray) else {
            return (None, 0);
        };
        let mut st = IsoState::default();
        let n = st.integrate(&self.ctx(ess), &seg, 0, seg.count);
        let grid = self.scene.volume().grid();
        (st.hit.map(|(p, _)| grid.voxel_to_world(p)), n)
    }

    pub fn dvr_state(&self, ray: &Ray, ess: bool) -> Option<(DvrState, u64)> {
        let seg = self.segment(ray)?;
        let mut st = DvrState::default();
        let n = st.integrate(&self.ctx(ess), &seg, 0, seg.count);
        Some((st, n))
    }

    pub fn mip_max(&self, ray: &Ray, ess: bool) -> Option<f32> {
        let seg = self.segment(ray)?;
        let mut st = MipState::default();
        st.integrate(&self.ctx(ess), &seg, 0, seg.count);
        Some(st.max)
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
