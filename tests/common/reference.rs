//! An independent, deliberately naive implementation in `f64` of the
//! rendering rules: world space, camera, transfer function, integration.
//!
//! Written from the rules' text only: no lookup tables, no acceleration, no
//! shading, every quantity recomputed from its definition. It is slow and
//! obviously correct, which is the point: the library's images are compared
//! against it in `tests/reference_images.rs`.

/// A 3-vector of `f64`.
pub type V3 = [f64; 3];

pub fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

pub fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

pub fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub fn length(a: V3) -> f64 {
    dot(a, a).sqrt()
}

pub fn normalize(a: V3) -> V3 {
    scale(a, 1.0 / length(a))
}

// ------------------------------------------------------------------- volume

/// Samples on a grid in world space: sample (x, y, z) at
/// `origin + (x·sx, y·sy, z·sz)`, trilinear in between.
#[derive(Debug, Clone)]
pub struct RefVolume {
    /// X, Y, Z.
    pub dims: [usize; 3],
    /// sx, sy, sz.
    pub spacing: V3,
    /// World position of sample (0, 0, 0).
    pub origin: V3,
    /// Sample values, `index(x, y, z) = (x·Y + y)·Z + z`.
    pub values: Vec<f64>,
    /// The sample type's maximum (255 for u8, 1.0 for floats): the `avg` divisor.
    pub type_max: f64,
}

impl RefVolume {
    pub fn from_fn(
        dims: [usize; 3],
        spacing: V3,
        type_max: f64,
        mut f: impl FnMut(usize, usize, usize) -> f64,
    ) -> Self {
        let mut values = Vec::with_capacity(dims[0] * dims[1] * dims[2]);
        for x in 0..dims[0] {
            for y in 0..dims[1] {
                for z in 0..dims[2] {
                    values.push(f(x, y, z));
                }
            }
        }
        RefVolume {
            dims,
            spacing,
            origin: [0.0; 3],
            values,
            type_max,
        }
    }

    pub fn at(&self, x: usize, y: usize, z: usize) -> f64 {
        self.values[(x * self.dims[1] + y) * self.dims[2] + z]
    }

    /// `[origin, origin + (dims − 1)·spacing]`.
    pub fn bounds(&self) -> (V3, V3) {
        let mut hi = self.origin;
        for (a, h) in hi.iter_mut().enumerate() {
            *h += (self.dims[a] as f64 - 1.0) * self.spacing[a];
        }
        (self.origin, hi)
    }

    /// Trilinear interpolation of the 8 surrounding samples at world point `p`
    /// (clamped onto the grid).
    pub fn value_at(&self, p: V3) -> f64 {
        let mut lo = [0usize; 3];
        let mut hi = [0usize; 3];
        let mut frac = [0.0f64; 3];
        for a in 0..3 {
            let n = self.dims[a];
            let c = ((p[a] - self.origin[a]) / self.spacing[a]).clamp(0.0, (n - 1) as f64);
            let i = (c.floor() as usize).min(n.saturating_sub(2));
            lo[a] = i;
            hi[a] = (i + 1).min(n - 1);
            frac[a] = c - i as f64;
        }
        let mut sum = 0.0;
        for (ix, wx) in [(lo[0], 1.0 - frac[0]), (hi[0], frac[0])] {
            for (iy, wy) in [(lo[1], 1.0 - frac[1]), (hi[1], frac[1])] {
                for (iz, wz) in [(lo[2], 1.0 - frac[2]), (hi[2], frac[2])] {
                    sum += wx * wy * wz * self.at(ix, iy, iz);
                }
            }
        }
        sum
    }
}

// ------------------------------------------------------------------- camera

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RefProjection {
    Perspective,
    Orthographic,
}

/// A perspective or orthographic camera: eye P, look-at T, up U, vertical
/// field of view, image W×H.
#[derive(Debug, Clone, Copy)]
pub struct RefCamera {
    pub position: V3,
    pub target: V3,
    pub up: V3,
    pub fov_deg: f64,
    pub width: u32,
    pub height: u32,
    pub projection: RefProjection,
}

/// The orthonormal frame of a camera: d, r, u.
pub struct RefFrame {
    pub d: V3,
    pub r: V3,
    pub u: V3,
    pub h: f64,
    pub a: f64,
    pub dist: f64,
}

impl RefCamera {
    pub fn perspective(position: V3, target: V3, width: u32, height: u32) -> Self {
        RefCamera {
            position,
            target,
            up: [0.0, 1.0, 0.0],
            fov_deg: 45.0,
            width,
            height,
            projection: RefProjection::Perspective,
        }
    }

    pub fn frame(&self) -> RefFrame {
        let d = normalize(sub(self.target, self.position));
        let r = normalize(cross(d, self.up));
        let u = cross(r, d);
        RefFrame {
            d,
            r,
            u,
            h: (self.fov_deg.to_radians() / 2.0).tan(),
            a: self.width as f64 / self.height as f64,
            dist: length(sub(self.target, self.position)),
        }
    }

    /// Origin and unit direction of the ray of pixel (i, j): i from the left,
    /// j from the top. Orthographic rays start on the plane through P
    /// perpendicular to d, 2·h·dist(P, T) high.
    pub fn ray(&self, i: u32, j: u32) -> (V3, V3) {
        let f = self.frame();
        let sx = (2.0 * (i as f64 + 0.5) / self.width as f64 - 1.0) * f.h * f.a;
        let sy = (1.0 - 2.0 * (j as f64 + 0.5) / self.height as f64) * f.h;
        match self.projection {
            RefProjection::Perspective => (
                self.position,
                normalize(add(add(f.d, scale(f.r, sx)), scale(f.u, sy))),
            ),
            RefProjection::Orthographic => (
                add(
                    self.position,
                    scale(add(scale(f.r, sx), scale(f.u, sy)), f.dist),
                ),
                f.d,
            ),
        }
    }

    /// Continuous pixel coordinates of world point `p` (the centre of pixel
    /// (i, j) is (i + 0.5, j + 0.5)): the inverse of [`RefCamera::ray`].
    pub fn project(&self, p: V3) -> (f64, f64) {
        let f = self.frame();
        let v = sub(p, self.position);
        let (x, y) = match self.projection {
            RefProjection::Perspective => {
                let z = dot(v, f.d);
                (dot(v, f.r) / z, dot(v, f.u) / z)
            }
            RefProjection::Orthographic => (dot(v, f.r) / f.dist, dot(v, f.u) / f.dist),
        };
        // sx = (2·px/W − 1)·h·a  =>  px = (sx/(h·a) + 1)·W/2, likewise for y.
        let px = (x / (f.h * f.a) + 1.0) * 0.5 * self.width as f64;
        let py = (1.0 - y / f.h) * 0.5 * self.height as f64;
        (px, py)
    }
}

// ----------------------------------------------------------------------- TF

#[derive(Debug, Clone, Copy)]
pub struct RefTfPoint {
    pub value: f64,
    pub color: V3,
    pub opacity: f64,
}

/// A transfer function: linear (clamped outside the points) or step
/// (transparent below the first point); opacity per world unit.
#[derive(Debug, Clone)]
pub struct RefTf {
    pub step: bool,
    pub points: Vec<RefTfPoint>,
}

fn p(value: f64, color: V3, opacity: f64) -> RefTfPoint {
    RefTfPoint {
        value,
        color,
        opacity,
    }
}

fn c255(r: f64, g: f64, b: f64) -> V3 {
    [r / 255.0, g / 255.0, b / 255.0]
}

impl RefTf {
    /// The `shapes` preset, typed in from its definition.
    pub fn shapes() -> Self {
        RefTf {
            step: true,
            points: vec![
                p(85.001, c255(255.0, 30.0, 60.0), 0.02),
                p(95.001, c255(10.0, 60.0, 180.0), 0.3),
                p(100.001, c255(90.0, 210.0, 20.0), 0.6),
                p(115.0, [0.0; 3], 0.0),
            ],
        }
    }

    /// The `skull` preset, typed in from its definition.
    pub fn skull() -> Self {
        RefTf {
            step: true,
            points: vec![
                p(40.0, c255(227.0, 218.0, 201.0), 1.0),
                p(240.0, [0.0; 3], 0.0),
            ],
        }
    }

    /// The `ramp` preset for a type whose maximum is `max`.
    pub fn ramp(max: f64) -> Self {
        RefTf {
            step: false,
            points: vec![p(0.0, [1.0; 3], 0.0), p(max, [1.0; 3], 1.0)],
        }
    }

    pub fn linear(points: Vec<RefTfPoint>) -> Self {
        RefTf {
            step: false,
            points,
        }
    }

    pub fn point(value: f64, color: V3, opacity: f64) -> RefTfPoint {
        p(value, color, opacity)
    }

    /// (r, g, b, a) at value `v`, `a` per world unit.
    pub fn eval(&self, v: f64) -> [f64; 4] {
        let rgba = |q: &RefTfPoint| [q.color[0], q.color[1], q.color[2], q.opacity];
        let pts = &self.points;
        // The last point whose value is <= v.
        let mut last_le = None;
        for (i, q) in pts.iter().enumerate() {
            if q.value <= v {
                last_le = Some(i);
            }
        }
        if self.step {
            return match last_le {
                Some(i) => rgba(&pts[i]),
                None => [0.0; 4],
            };
        }
        let first = &pts[0];
        let last = &pts[pts.len() - 1];
        if v <= first.value {
            return rgba(first);
        }
        if v >= last.value {
            return rgba(last);
        }
        let i = last_le.expect("v > first point");
        let (a, b) = (&pts[i], &pts[i + 1]);
        let w = (v - a.value) / (b.value - a.value);
        let (ca, cb) = (rgba(a), rgba(b));
        [
            ca[0] + (cb[0] - ca[0]) * w,
            ca[1] + (cb[1] - ca[1]) * w,
            ca[2] + (cb[2] - ca[2]) * w,
            ca[3] + (cb[3] - ca[3]) * w,
        ]
    }
}

// --------------------------------------------------------------------- rays

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RefMode {
    Dvr,
    Mip,
    Minip,
    Avg,
    Iso(f64),
}

#[derive(Debug, Clone, Copy)]
pub struct RefOptions {
    pub mode: RefMode,
    /// Sampling step, world units.
    pub step: f64,
    /// ERT threshold (`None` = off).
    pub ert: Option<f64>,
    pub background: V3,
}

impl RefOptions {
    pub fn dvr(step: f64) -> Self {
        RefOptions {
            mode: RefMode::Dvr,
            step,
            ert: None,
            background: [0.0; 3],
        }
    }
}

/// The result of one ray.
#[derive(Debug, Clone, Copy, Default)]
pub struct RefRay {
    /// C (premultiplied).
    pub color: V3,
    /// A.
    pub alpha: f64,
    /// Samples taken at t_k.
    pub samples: u64,
    /// Iso mode: the ray parameter and world point of the hit.
    pub hit: Option<(f64, V3)>,
    /// Whether the ray hit the box.
    pub in_box: bool,
}

/// `[t_in, t_out]` of the ray against the box, `t_in` clamped to 0.
pub fn clip(bmin: V3, bmax: V3, o: V3, d: V3) -> Option<(f64, f64)> {
    let mut t_in = 0.0f64;
    let mut t_out = f64::INFINITY;
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a] < bmin[a] || o[a] > bmax[a] {
                return None;
            }
            continue;
        }
        let t0 = (bmin[a] - o[a]) / d[a];
        let t1 = (bmax[a] - o[a]) / d[a];
        t_in = t_in.max(t0.min(t1));
        t_out = t_out.min(t0.max(t1));
    }
    (t_in <= t_out).then_some((t_in, t_out))
}

/// Integrates one ray (unit direction `d`): samples at `t_k = t_in + k·s`
/// while `t_k <= t_out`, composited per mode.
pub fn integrate(vol: &RefVolume, tf: &RefTf, opt: &RefOptions, o: V3, d: V3) -> RefRay {
    integrate_with(vol, tf, opt, &RefExtras::default(), 0.0, o, d)
}

// ------------------------------------------- second-wave options (SPEC §8)

/// Clipping, gradient opacity and jitter (SPEC §8), in world coordinates.
#[derive(Debug, Clone, Default)]
pub struct RefExtras {
    /// Keep only samples in `[lo, hi]`.
    pub clip_box: Option<(V3, V3)>,
    /// Remove samples at `p` with `n·p > d`.
    pub planes: Vec<(V3, f64)>,
    /// `(g0, g1)`: opacity per unit length times
    /// `clamp((|∇f| − g0)/(g1 − g0), 0, 1)`.
    pub gradient_opacity: Option<(f64, f64)>,
    /// Jitter seed (`None`: no jitter).
    pub jitter_seed: Option<u32>,
}

impl RefExtras {
    /// Whether the sample at world point `p` is kept by the clipping rules.
    pub fn kept(&self, p: V3) -> bool {
        if let Some((lo, hi)) = self.clip_box
            && (0..3).any(|a| p[a] < lo[a] || p[a] > hi[a])
        {
            return false;
        }
        self.planes.iter().all(|&(n, d)| dot(n, p) <= d)
    }
}

/// The jitter `j ∈ [0, 1)` of pixel (i, j): the library's documented hash
/// (`raycaster::integrator::jitter`), typed in again from its description:
/// mix seed, i, j with three odd constants, three xor-shift-multiply
/// rounds, the top 24 bits over 2^24.
pub fn ref_jitter(i: u32, j: u32, seed: u32) -> f64 {
    let mut h: u32 =
        seed.wrapping_mul(0x9E3779B9) ^ i.wrapping_mul(0x85EBCA6B) ^ j.wrapping_mul(0xC2B2AE35);
    for (shift, mul) in [(16, 0x7FEB352Du32), (15, 0x846CA68B)] {
        h ^= h >> shift;
        h = h.wrapping_mul(mul);
    }
    h ^= h >> 16;
    (h >> 8) as f64 / 16777216.0
}

impl RefVolume {
    /// SPEC §8's gradient at world point `p`: per voxel the central
    /// differences `(v[i+1] − v[i−1]) / (2·spacing)`, indices clamped to
    /// the grid, trilinearly interpolated as the values are.
    pub fn gradient_at(&self, p: V3) -> V3 {
        let n = self.dims;
        let voxel_gradient = |x: usize, y: usize, z: usize| -> V3 {
            let idx = [x, y, z];
            let mut g = [0.0; 3];
            for a in 0..3 {
                let mut lo = idx;
                let mut hi = idx;
                lo[a] = idx[a].saturating_sub(1);
                hi[a] = (idx[a] + 1).min(n[a] - 1);
                g[a] = (self.at(hi[0], hi[1], hi[2]) - self.at(lo[0], lo[1], lo[2]))
                    / (2.0 * self.spacing[a]);
            }
            g
        };
        let mut lo = [0usize; 3];
        let mut hi = [0usize; 3];
        let mut frac = [0.0f64; 3];
        for a in 0..3 {
            let c = ((p[a] - self.origin[a]) / self.spacing[a]).clamp(0.0, (n[a] - 1) as f64);
            let i = (c.floor() as usize).min(n[a].saturating_sub(2));
            lo[a] = i;
            hi[a] = (i + 1).min(n[a] - 1);
            frac[a] = c - i as f64;
        }
        let mut sum = [0.0; 3];
        for (ix, wx) in [(lo[0], 1.0 - frac[0]), (hi[0], frac[0])] {
            for (iy, wy) in [(lo[1], 1.0 - frac[1]), (hi[1], frac[1])] {
                for (iz, wz) in [(lo[2], 1.0 - frac[2]), (hi[2], frac[2])] {
                    sum = add(sum, scale(voxel_gradient(ix, iy, iz), wx * wy * wz));
                }
            }
        }
        sum
    }
}

/// [`integrate`] with the SPEC §8 options: samples at
/// `t_k = t_in + (k + jitter)·s`, clipped samples contribute nothing,
/// gradient opacity scales the opacity per unit length (DVR).
pub fn integrate_with(
    vol: &RefVolume,
    tf: &RefTf,
    opt: &RefOptions,
    ext: &RefExtras,
    jitter: f64,
    o: V3,
    d: V3,
) -> RefRay {
    let (bmin, bmax) = vol.bounds();
    let mut out = RefRay::default();
    let Some((t_in, t_out)) = clip(bmin, bmax, o, d) else {
        return out;
    };
    out.in_box = true;
    let s = opt.step;
    let value = |t: f64| vol.value_at(add(o, scale(d, t)));
    if let RefMode::Iso(iso) = opt.mode {
        // SPEC §8: the first crossing of the interpolant itself, whatever
        // the step: found here by steps of 1/32 of the smallest spacing
        // and bisection.
        let fine = vol.spacing.iter().copied().fold(f64::INFINITY, f64::min) / 32.0;
        let side = value(t_in) >= iso;
        let mut a = t_in;
        while a < t_out {
            let b = (a + fine).min(t_out);
            if (value(b) >= iso) != side {
                let (mut ta, mut tb) = (a, b);
                for _ in 0..60 {
                    let tm = 0.5 * (ta + tb);
                    if (value(tm) >= iso) == side {
                        ta = tm;
                    } else {
                        tb = tm;
                    }
                }
                let th = 0.5 * (ta + tb);
                out.hit = Some((th, add(o, scale(d, th))));
                let e = tf.eval(iso);
                out.color = [e[0], e[1], e[2]];
                out.alpha = 1.0;
                break;
            }
            a = b;
        }
        out.samples = ((t_out - t_in) / s).floor() as u64 + 1;
        return out;
    }
    let mut max = f64::NEG_INFINITY;
    let mut min = f64::INFINITY;
    let mut sum = 0.0;
    let mut k = 0u64;
    loop {
        let t = t_in + (k as f64 + jitter) * s;
        if t > t_out {
            break;
        }
        k += 1;
        let p = add(o, scale(d, t));
        if !ext.kept(p) {
            continue;
        }
        let v = value(t);
        out.samples += 1;
        match opt.mode {
            RefMode::Dvr => {
                let e = tf.eval(v);
                let mut a = e[3];
                if let Some((g0, g1)) = ext.gradient_opacity
                    && a > 0.0
                {
                    let g = length(vol.gradient_at(p));
                    a *= ((g - g0) / (g1 - g0)).clamp(0.0, 1.0);
                }
                let alpha = 1.0 - (1.0 - a).powf(s);
                let w = (1.0 - out.alpha) * alpha;
                for (c, ec) in out.color.iter_mut().zip(e) {
                    *c += w * ec;
                }
                out.alpha += w;
                if let Some(thr) = opt.ert
                    && out.alpha >= thr
                {
                    break;
                }
            }
            RefMode::Mip => max = max.max(v),
            RefMode::Minip => min = min.min(v),
            RefMode::Avg => sum += v,
            RefMode::Iso(_) => unreachable!("iso returns above"),
        }
    }
    match opt.mode {
        RefMode::Mip if out.samples > 0 => {
            let e = tf.eval(max);
            out.color = [e[0] * e[3], e[1] * e[3], e[2] * e[3]];
            out.alpha = e[3];
        }
        RefMode::Minip if out.samples > 0 => {
            let e = tf.eval(min);
            out.color = [e[0] * e[3], e[1] * e[3], e[2] * e[3]];
            out.alpha = e[3];
        }
        RefMode::Avg if out.samples > 0 => {
            let g = sum / out.samples as f64 / vol.type_max;
            out.color = [g; 3];
            out.alpha = 1.0;
        }
        _ => {}
    }
    out
}

/// `rgb = C + (1 − A)·background`, clamped, `round(255·x)`.
pub fn to_rgb8(ray: &RefRay, background: V3) -> [u8; 3] {
    let mut px = [0u8; 3];
    for c in 0..3 {
        let x = ray.color[c] + (1.0 - ray.alpha) * background[c];
        px[c] = (255.0 * x.clamp(0.0, 1.0)).round() as u8;
    }
    px
}

/// Renders a whole RGB8 image, row-major from the top-left pixel.
pub fn render(vol: &RefVolume, cam: &RefCamera, tf: &RefTf, opt: &RefOptions) -> Vec<u8> {
    let mut rgb = Vec::with_capacity(3 * (cam.width * cam.height) as usize);
    for j in 0..cam.height {
        for i in 0..cam.width {
            let (o, d) = cam.ray(i, j);
            let r = integrate(vol, tf, opt, o, d);
            rgb.extend_from_slice(&to_rgb8(&r, opt.background));
        }
    }
    rgb
}

/// [`render`] with the SPEC §8 options (jitter from the pixel and seed).
pub fn render_with(
    vol: &RefVolume,
    cam: &RefCamera,
    tf: &RefTf,
    opt: &RefOptions,
    ext: &RefExtras,
) -> Vec<u8> {
    let mut rgb = Vec::with_capacity(3 * (cam.width * cam.height) as usize);
    for j in 0..cam.height {
        for i in 0..cam.width {
            let (o, d) = cam.ray(i, j);
            let jit = ext.jitter_seed.map_or(0.0, |seed| ref_jitter(i, j, seed));
            let r = integrate_with(vol, tf, opt, ext, jit, o, d);
            rgb.extend_from_slice(&to_rgb8(&r, opt.background));
        }
    }
    rgb
}
