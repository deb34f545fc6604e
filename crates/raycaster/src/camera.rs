//! Cameras: a perspective or orthographic view that turns a pixel
//! into a ray, and projects a box to the screen rectangle it covers.

use glam::Vec3;

use crate::geometry::{Aabb, Ray};

/// Perspective or orthographic projection.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Projection {
    /// Rays leave the eye point.
    #[default]
    Perspective,
    /// Rays are parallel to the view direction; the image plane is
    /// `2·tan(fov/2)·|target − position|` high.
    Orthographic,
}

/// A camera: position, look-at point, up vector, vertical field of view and
/// image size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Eye position P.
    pub position: Vec3,
    /// Look-at point T.
    pub target: Vec3,
    /// Up vector U (need not be orthogonal to the view direction).
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub fov_y_deg: f32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Perspective or orthographic.
    pub projection: Projection,
}

/// The camera's orthonormal frame and the constants of the pixel-to-ray map,
/// computed once per frame.
#[derive(Debug, Clone, Copy)]
pub struct CameraFrame {
    /// Forward, `d = normalize(T − P)`.
    pub forward: Vec3,
    /// Right, `r = normalize(d × U)`.
    pub right: Vec3,
    /// True up, `u = r × d`.
    pub up: Vec3,
    /// `tan(fov/2)`.
    pub half_height: f32,
    /// `W/H`.
    pub aspect: f32,
    /// `|T − P|` (sizes the orthographic image plane).
    pub distance: f32,
    position: Vec3,
    projection: Projection,
    width: f32,
    height: f32,
}

/// An orthographic [`CameraFrame`]'s projection of world points as three
/// affine maps ([`CameraFrame::affine_projection`]).
#[derive(Debug, Clone, Copy)]
pub struct AffineProjection {
    rows: [(Vec3, f32); 3],
}

impl AffineProjection {
    /// `[x, y, depth]` of world point `p`: its continuous pixel coordinates
    /// as [`CameraFrame::project`] gives them (rounded a little
    /// differently), and its distance in front of the image plane the
    /// rays start on (negative behind it, where `project` gives `None`).
    #[inline]
    pub fn apply(&self, p: Vec3) -> [f32; 3] {
        self.rows.map(|(a, b)| p.dot(a) + b)
    }
}

/// A rectangle of pixels, `[x0, x1) × [y0, y1)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PixelRect {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}

impl PixelRect {
    /// Number of pixels.
    pub fn area(&self) -> u64 {
        (self.x1.saturating_sub(self.x0)) as u64 * (self.y1.saturating_sub(self.y0)) as u64
    }

    /// The rectangle cut into `side`×`side` tiles (smaller at the right and
    /// bottom edges), row by row.
    pub fn tiles(&self, side: u32) -> impl Iterator<Item = PixelRect> + '_ {
        let side = side.max(1);
        (self.y0..self.y1)
            .step_by(side as usize)
            .flat_map(move |y| {
                (self.x0..self.x1)
                    .step_by(side as usize)
                    .map(move |x| PixelRect {
                        x0: x,
                        y0: y,
                        x1: (x + side).min(self.x1),
                        y1: (y + side).min(self.y1),
                    })
            })
    }

    /// True when `(x, y)` is inside.
    pub fn contains(&self, x: u32, y: u32) -> bool {
        x >= self.x0 && x < self.x1 && y >= self.y0 && y < self.y1
    }

    /// True when it holds no pixel.
    pub fn is_empty(&self) -> bool {
        self.x0 >= self.x1 || self.y0 >= self.y1
    }

    /// The pixels both hold (the default, empty rectangle when none).
    pub fn intersect(&self, other: &PixelRect) -> PixelRect {
        let r = PixelRect {
            x0: self.x0.max(other.x0),
            y0: self.y0.max(other.y0),
            x1: self.x1.min(other.x1),
            y1: self.y1.min(other.y1),
        };
        if r.is_empty() {
            PixelRect::default()
        } else {
            r
        }
    }

    /// The smallest rectangle holding both (an empty one adds nothing).
    pub fn bounding(&self, other: &PixelRect) -> PixelRect {
        match (self.is_empty(), other.is_empty()) {
            (true, true) => PixelRect::default(),
            (true, false) => *other,
            (false, true) => *self,
            (false, false) => PixelRect {
                x0: self.x0.min(other.x0),
                y0: self.y0.min(other.y0),
                x1: self.x1.max(other.x1),
                y1: self.y1.max(other.y1),
            },
        }
    }
}

impl Camera {
    /// A perspective camera with up = +Y and a 45° field of view.
    pub fn look_at(position: Vec3, target: Vec3, width: u32, height: u32) -> Self {
        Camera {
            position,
            target,
            up: Vec3::Y,
            fov_y_deg: 45.0,
            width,
            height,
            projection: Projection::Perspective,
        }
    }

    /// A camera looking at the centre of `bounds` from the +z side, far enough
    /// that the whole box is in view (the default view of `vol_app render`).
    pub fn framing(bounds: &Aabb, width: u32, height: u32, fov_y_deg: f32) -> Self {
        let center = bounds.center();
        let radius = ((bounds.max - bounds.min).length() * 0.5).max(1e-3);
        let half = (fov_y_deg.to_radians() * 0.5).tan();
        let aspect = width as f32 / height.max(1) as f32;
        let half_min = half.min(half * aspect);
        // Distance at which a sphere of `radius` fits in the narrower half-angle.
        let sin = half_min / (1.0 + half_min * half_min).sqrt();
        let dist = radius / sin * 1.05;
        let mut c = Camera::look_at(center + Vec3::Z * dist, center, width, height);
        c.fov_y_deg = fov_y_deg;
        c
    }

    /// The frame of this camera, or `None` when it is degenerate (target at
    /// the eye, up parallel to the view direction, zero-sized image, or a field
    /// of view outside (0°, 180°)).
    pub fn frame(&self) -> Option<CameraFrame> {
        let to = self.target - self.position;
        let distance = to.length();
        let forward = to.try_normalize()?;
        let right = forward.cross(self.up).try_normalize()?;
        let up = right.cross(forward);
        if self.width == 0 || self.height == 0 || !(self.fov_y_deg > 0.0 && self.fov_y_deg < 180.0)
        {
            return None;
        }
        Some(CameraFrame {
            forward,
            right,
            up,
            half_height: (self.fov_y_deg.to_radians() * 0.5).tan(),
            aspect: self.width as f32 / self.height as f32,
            distance,
            position: self.position,
            projection: self.projection,
            width: self.width as f32,
            height: self.height as f32,
        })
    }
}

impl CameraFrame {
    /// The ray through the centre of pixel `(i, j)` (i from the left, j from
    /// the top), with a unit direction.
    #[inline]
    pub fn ray(&self, i: u32, j: u32) -> Ray {
        let (sx, sy) = self.image_plane(i, j);
        match self.projection {
            Projection::Perspective => Ray {
                origin: self.position,
                dir: (self.forward + sx * self.right + sy * self.up).normalize(),
            },
            Projection::Orthographic => Ray {
                origin: self.position + (sx * self.right + sy * self.up) * self.distance,
                dir: self.forward,
            },
        }
    }

    /// The unit directions of the perspective rays of pixels `(i[l], j[l])`,
    /// lane by lane, per axis: the bits [`CameraFrame::ray`] gives (the same
    /// operations in the same order), computed for all lanes at once so
    /// that the compiler can use vector instructions for the divisions and
    /// square roots that dominate a ray's set-up. Coordinates below 2²⁴.
    #[inline(always)]
    pub fn perspective_dirs<const N: usize>(&self, i: &[u32; N], j: &[u32; N]) -> [[f32; N]; 3] {
        let mut d = [[0.0f32; N]; 3];
        for l in 0..N {
            let (sx, sy) = self.image_plane(i[l], j[l]);
            let x = self.forward.x + sx * self.right.x + sy * self.up.x;
            let y = self.forward.y + sx * self.right.y + sy * self.up.y;
            let z = self.forward.z + sx * self.right.z + sy * self.up.z;
            // `Vec3::normalize`: times the reciprocal of the length.
            let r = 1.0 / ((x * x) + (y * y) + (z * z)).sqrt();
            d[0][l] = x * r;
            d[1][l] = y * r;
            d[2][l] = z * r;
        }
        d
    }

    /// Where the rays of pixel column `i` and pixel row `j` cross the image
    /// plane one unit ahead of the eye, along `right` and `up` (`x` depends
    /// on the column only, `y` on the row only): a perspective ray's
    /// direction is `forward + x·right + y·up` normalised, an orthographic
    /// ray starts `(x·right + y·up)·distance` from the eye. Coordinates
    /// below 2²⁴.
    #[inline(always)]
    pub(crate) fn image_plane(&self, i: u32, j: u32) -> (f32, f32) {
        // Through i32: the same value (below 2²⁴), and a conversion with a
        // vector instruction in lane-wise loops.
        let (fi, fj) = (i as i32 as f32, j as i32 as f32);
        (
            (2.0 * (fi + 0.5) / self.width - 1.0) * self.half_height * self.aspect,
            (1.0 - 2.0 * (fj + 0.5) / self.height) * self.half_height,
        )
    }

    /// Continuous pixel coordinates `(i, j)` whose ray passes through world
    /// point `p` (pixel centres are at `k + 0.5`), or `None` when `p` is not in
    /// front of the camera.
    pub fn project(&self, p: Vec3) -> Option<(f32, f32)> {
        let v = p - self.position;
        let z = v.dot(self.forward);
        let (sx, sy) = match self.projection {
            Projection::Perspective => {
                if z <= 1e-6 {
                    return None;
                }
                (v.dot(self.right) / z, v.dot(self.up) / z)
            }
            Projection::Orthographic => {
                if z < 0.0 {
                    return None;
                }
                (
                    v.dot(self.right) / self.distance,
                    v.dot(self.up) / self.distance,
                )
            }
        };
        let nx = sx / (self.half_height * self.aspect);
        let ny = sy / self.half_height;
        Some((
            (nx + 1.0) * 0.5 * self.width,
            (1.0 - ny) * 0.5 * self.height,
        ))
    }

    /// An orthographic frame's [`CameraFrame::project`] as affine maps,
    /// without its divisions (for projecting many points); `None` under
    /// perspective, which is not affine.
    pub fn affine_projection(&self) -> Option<AffineProjection> {
        if self.projection != Projection::Orthographic {
            return None;
        }
        let row = |axis: Vec3, scale: f32, offset: f32| {
            let a = axis * scale;
            (a, offset - self.position.dot(a))
        };
        let (w, h) = (self.width, self.height);
        Some(AffineProjection {
            rows: [
                row(
                    self.right,
                    0.5 * w / (self.distance * self.half_height * self.aspect),
                    0.5 * w,
                ),
                row(
                    self.up,
                    -0.5 * h / (self.distance * self.half_height),
                    0.5 * h,
                ),
                row(self.forward, 1.0, 0.0),
            ],
        })
    }

    /// The eye position P (for an orthographic camera, the centre of the
    /// image plane the rays start from).
    pub fn position(&self) -> Vec3 {
        self.position
    }

    /// Perspective or orthographic.
    pub fn projection(&self) -> Projection {
        self.projection
    }

    /// The whole image.
    pub fn full_rect(&self) -> PixelRect {
        PixelRect {
            x0: 0,
            y0: 0,
            x1: self.width as u32,
            y1: self.height as u32,
        }
    }

    /// The pixels whose rays (`t >= 0`) can meet the sphere of `center` and
    /// `radius`: the bounding square of its exact projection (under
    /// perspective, the tangent planes through the eye; orthographic, the
    /// disc), grown by one pixel and clamped to the image; the whole image
    /// when the sphere reaches the eye plane, `None` when it is wholly
    /// behind the eye or off screen.
    pub fn sphere_rect(&self, center: Vec3, radius: f32) -> Option<PixelRect> {
        let v = (center - self.position).as_dvec3();
        let x = v.dot(self.right.as_dvec3());
        let y = v.dot(self.up.as_dvec3());
        let z = v.dot(self.forward.as_dvec3());
        let r = radius as f64;
        if z < -r {
            return None;
        }
        let ((sx0, sx1), (sy0, sy1)) = match self.projection {
            Projection::Perspective => {
                if z <= r * (1.0 + 1e-6) {
                    return Some(self.full_rect());
                }
                // Tangent lines through the eye to the sphere's (disc)
                // projection on the plane of the axis and the view direction.
                let den = z * z - r * r;
                let range = |c: f64| {
                    let root = (c * c + den).sqrt();
                    ((c * z - r * root) / den, (c * z + r * root) / den)
                };
                (range(x), range(y))
            }
            Projection::Orthographic => {
                let d = self.distance as f64;
                (((x - r) / d, (x + r) / d), ((y - r) / d, (y + r) / d))
            }
        };
        self.window_rect((sx0, sx1), (sy0, sy1))
    }

    /// The pixels whose rays pass through the window `[sx0, sx1] × [sy0,
    /// sy1]` of the image plane at unit distance (orthographic: at the
    /// camera's distance, already divided by it), grown by one pixel and
    /// clamped to the image; `None` when empty.
    fn window_rect(&self, (sx0, sx1): (f64, f64), (sy0, sy1): (f64, f64)) -> Option<PixelRect> {
        let (w, h) = (self.width as f64, self.height as f64);
        let hx = self.half_height as f64 * self.aspect as f64;
        let hy = self.half_height as f64;
        let px0 = (sx0 / hx + 1.0) * 0.5 * w;
        let px1 = (sx1 / hx + 1.0) * 0.5 * w;
        let py0 = (1.0 - sy1 / hy) * 0.5 * h;
        let py1 = (1.0 - sy0 / hy) * 0.5 * h;
        // Pixel i's ray passes through i + 0.5; one pixel of margin for the
        // rays' f32 rounding.
        let rect = PixelRect {
            x0: (px0.floor() - 1.0).clamp(0.0, w) as u32,
            y0: (py0.floor() - 1.0).clamp(0.0, h) as u32,
            x1: (px1.ceil() + 1.0).clamp(0.0, w) as u32,
            y1: (py1.ceil() + 1.0).clamp(0.0, h) as u32,
        };
        (rect.x0 < rect.x1 && rect.y0 < rect.y1).then_some(rect)
    }

    /// The pixels whose rays can meet the box `[lo, hi]`: a bounding
    /// rectangle of its projection from the view-space extents of its
    /// centre (cheaper than projecting the eight corners, and no smaller),
    /// grown by one pixel and clamped to the image; the whole image when
    /// the box reaches the eye plane, `None` when it is wholly behind the
    /// camera or off screen.
    pub fn box_rect(&self, lo: Vec3, hi: Vec3) -> Option<PixelRect> {
        let half = 0.5 * (hi - lo);
        let c = 0.5 * (lo + hi) - self.position;
        let (cx, cy, cz) = (c.dot(self.right), c.dot(self.up), c.dot(self.forward));
        let radius = |axis: Vec3| (half * axis.abs()).element_sum();
        let (rx, ry, rz) = (radius(self.right), radius(self.up), radius(self.forward));
        let ((sx0, sx1), (sy0, sy1)) = match self.projection {
            Projection::Perspective => {
                if cz - rz <= 1e-6 {
                    return (cz + rz > 0.0).then(|| self.full_rect());
                }
                // x/z over the box's x in [c − r, c + r], z in [cz − rz,
                // cz + rz]: each end is reached at a corner of that range.
                let range = |c: f32, r: f32| {
                    let (a, b) = (c - r, c + r);
                    (
                        a / if a >= 0.0 { cz + rz } else { cz - rz },
                        b / if b >= 0.0 { cz - rz } else { cz + rz },
                    )
                };
                (range(cx, rx), range(cy, ry))
            }
            Projection::Orthographic => {
                if cz + rz < 0.0 {
                    return None;
                }
                let d = self.distance;
                (
                    ((cx - rx) / d, (cx + rx) / d),
                    ((cy - ry) / d, (cy + ry) / d),
                )
            }
        };
        let wide = |(a, b): (f32, f32)| (a as f64, b as f64);
        self.window_rect(wide((sx0, sx1)), wide((sy0, sy1)))
    }

    /// [`CameraFrame::box_rect`] of the `N` boxes `[lo, hi]` (lane `l`:
    /// `lo[a][l]` and `hi[a][l]` along axis `a`) for a perspective frame,
    /// with its arithmetic in the same order lane by lane, so that the
    /// compiler can do all lanes at once: the same rectangles, as
    /// `[x0, y0, x1, y1]` per lane, all 0 where `box_rect` gives `None`.
    #[inline(always)]
    pub(crate) fn box_rects<const N: usize>(
        &self,
        lo: &[[f32; N]; 3],
        hi: &[[f32; N]; 3],
    ) -> [[u32; N]; 4] {
        debug_assert_eq!(self.projection, Projection::Perspective);
        let (p, right, up, fwd) = (self.position, self.right, self.up, self.forward);
        let (w, h) = (self.width as f64, self.height as f64);
        let hx = self.half_height as f64 * self.aspect as f64;
        let hy = self.half_height as f64;
        let full = self.full_rect();
        let mut out = [[0u32; N]; 4];
        for l in 0..N {
            let half = [
                0.5 * (hi[0][l] - lo[0][l]),
                0.5 * (hi[1][l] - lo[1][l]),
                0.5 * (hi[2][l] - lo[2][l]),
            ];
            let c = [
                0.5 * (lo[0][l] + hi[0][l]) - p.x,
                0.5 * (lo[1][l] + hi[1][l]) - p.y,
                0.5 * (lo[2][l] + hi[2][l]) - p.z,
            ];
            let dot = |a: Vec3| (c[0] * a.x) + (c[1] * a.y) + (c[2] * a.z);
            let radius = |a: Vec3| half[0] * a.x.abs() + half[1] * a.y.abs() + half[2] * a.z.abs();
            let (cx, cy, cz) = (dot(right), dot(up), dot(fwd));
            let (rx, ry, rz) = (radius(right), radius(up), radius(fwd));
            let range = |c: f32, r: f32| {
                let (a, b) = (c - r, c + r);
                (
                    a / if a >= 0.0 { cz + rz } else { cz - rz },
                    b / if b >= 0.0 { cz - rz } else { cz + rz },
                )
            };
            let ((sx0, sx1), (sy0, sy1)) = (range(cx, rx), range(cy, ry));
            // `window_rect`.
            let (sx0, sx1, sy0, sy1) = (sx0 as f64, sx1 as f64, sy0 as f64, sy1 as f64);
            let px0 = (sx0 / hx + 1.0) * 0.5 * w;
            let px1 = (sx1 / hx + 1.0) * 0.5 * w;
            let py0 = (1.0 - sy1 / hy) * 0.5 * h;
            let py1 = (1.0 - sy0 / hy) * 0.5 * h;
            let clamp = |v: f64, hi: f64| {
                let v = if v < 0.0 { 0.0 } else { v };
                (if v > hi { hi } else { v }) as u32
            };
            let x0 = clamp(px0.floor() - 1.0, w);
            let y0 = clamp(py0.floor() - 1.0, h);
            let x1 = clamp(px1.ceil() + 1.0, w);
            let y1 = clamp(py1.ceil() + 1.0, h);
            let seen = x0 < x1 && y0 < y1;
            // A box reaching the eye plane: the whole image, unless it lies
            // wholly behind the eye.
            let near = cz - rz <= 1e-6;
            let whole = near && cz + rz > 0.0;
            let keep = !near && seen;
            out[0][l] = if keep { x0 } else { 0 };
            out[1][l] = if keep { y0 } else { 0 };
            out[2][l] = if keep {
                x1
            } else if whole {
                full.x1
            } else {
                0
            };
            out[3][l] = if keep {
                y1
            } else if whole {
                full.y1
            } else {
                0
            };
        }
        out
    }

    /// The pixels whose rays can hit `bounds`: the projected box's rectangle
    /// grown by one pixel, clamped to the image; the whole image when part of
    /// the box is behind the eye (the camera is inside or beside it).
    pub fn screen_rect(&self, bounds: &Aabb) -> PixelRect {
        let full = PixelRect {
            x0: 0,
            y0: 0,
            x1: self.width as u32,
            y1: self.height as u32,
        };
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for c in bounds.corners() {
            match self.project(c) {
                Some((x, y)) => {
                    lo = lo.min(Vec3::new(x, y, 0.0));
                    hi = hi.max(Vec3::new(x, y, 0.0));
                }
                None => return full,
            }
        }
        let clamp_x = |v: f32| v.clamp(0.0, self.width) as u32;
        let clamp_y = |v: f32| v.clamp(0.0, self.height) as u32;
        let rect = PixelRect {
            x0: clamp_x((lo.x - 1.5).floor()),
            y0: clamp_y((lo.y - 1.5).floor()),
            x1: clamp_x((hi.x + 1.5).ceil()),
            y1: clamp_y((hi.y + 1.5).ceil()),
        };
        if rect.x0 >= rect.x1 || rect.y0 >= rect.y1 {
            PixelRect::default()
        } else {
            rect
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `box_rects` gives `box_rect`'s rectangles lane by lane, for boxes
    /// on and off screen, behind the eye, and around it.
    #[test]
    fn box_rects_are_box_rect_lane_by_lane() {
        let mut rng = fastrand::Rng::with_seed(17);
        let (mut seen, mut whole, mut none) = (0, 0, 0);
        for k in 0..200 {
            let eye = Vec3::new(rng.f32() * 40.0 - 20.0, rng.f32() * 40.0 - 20.0, 30.0);
            let mut cam = Camera::look_at(eye, Vec3::new(rng.f32(), rng.f32(), 0.0), 333, 201);
            cam.fov_y_deg = 20.0 + 60.0 * rng.f32();
            let f = cam.frame().unwrap();
            let mut lo = [[0.0f32; 16]; 3];
            let mut hi = [[0.0f32; 16]; 3];
            let mut boxes = Vec::new();
            for l in 0..16 {
                let a = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 60.0 - 30.0;
                let size = Vec3::new(rng.f32(), rng.f32(), rng.f32())
                    * if k % 4 == 0 { 30.0 } else { 2.0 };
                for ax in 0..3 {
                    lo[ax][l] = a[ax];
                    hi[ax][l] = a[ax] + size[ax];
                }
                boxes.push((a, a + size));
            }
            let got = f.box_rects(&lo, &hi);
            for (l, &(a, b)) in boxes.iter().enumerate() {
                let want = f.box_rect(a, b);
                let lane = [got[0][l], got[1][l], got[2][l], got[3][l]];
                match want {
                    Some(r) => {
                        assert_eq!(lane, [r.x0, r.y0, r.x1, r.y1], "box {a} {b}");
                        if r == f.full_rect() {
                            whole += 1
                        } else {
                            seen += 1
                        }
                    }
                    None => {
                        assert_eq!(lane, [0; 4], "box {a} {b}");
                        none += 1;
                    }
                }
            }
        }
        assert!(
            seen > 500 && whole > 20 && none > 200,
            "{seen} {whole} {none}"
        );
    }

    #[test]
    fn centre_pixel_looks_at_target() {
        let cam = Camera::look_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, 101, 101);
        let f = cam.frame().unwrap();
        let r = f.ray(50, 50);
        assert!((r.dir - Vec3::NEG_Z).length() < 1e-6);
        // Pixel (0, 0) is top-left: ray goes left (-x) and up (+y).
        let r = f.ray(0, 0);
        assert!(r.dir.x < 0.0 && r.dir.y > 0.0);
    }

    #[test]
    fn the_affine_projection_is_the_orthographic_projection() {
        let mut cam = Camera::look_at(Vec3::new(3.0, 4.0, 12.0), Vec3::new(0.5, -1.0, 0.0), 64, 48);
        assert!(cam.frame().unwrap().affine_projection().is_none());
        cam.projection = Projection::Orthographic;
        let f = cam.frame().unwrap();
        let affine = f.affine_projection().unwrap();
        let mut rng = fastrand::Rng::with_seed(8);
        let mut behind = 0;
        for _ in 0..1000 {
            let p = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 30.0 - 15.0;
            let [x, y, depth] = affine.apply(p);
            let want = (p - f.position()).dot(f.forward);
            assert!((depth - want).abs() < 1e-4, "depth {depth} vs {want}");
            match f.project(p) {
                Some((px, py)) => {
                    assert!(depth >= -1e-4);
                    assert!(
                        (x - px).abs() < 1e-3 && (y - py).abs() < 1e-3,
                        "{x},{y} vs {px},{py}"
                    );
                }
                None => {
                    behind += 1;
                    assert!(depth < 1e-4);
                }
            }
        }
        assert!(behind > 0 && behind < 1000, "{behind} behind");
    }

    #[test]
    fn a_box_rect_holds_its_corners_projections() {
        let mut rng = fastrand::Rng::with_seed(7);
        for proj in [Projection::Perspective, Projection::Orthographic] {
            let mut cam =
                Camera::look_at(Vec3::new(3.0, 4.0, 12.0), Vec3::new(0.5, -1.0, 0.0), 64, 48);
            cam.projection = proj;
            let f = cam.frame().unwrap();
            let mut inside = 0;
            for _ in 0..500 {
                let lo = Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 12.0 - 6.0;
                let hi = lo + Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 2.0;
                let rect = f.box_rect(lo, hi);
                let corners = Aabb::new(lo, hi).corners();
                if let Some(rect) = rect
                    && rect == f.full_rect()
                {
                    continue;
                }
                for c in corners {
                    let Some((x, y)) = f.project(c) else {
                        panic!("{proj:?}: corner {c} not in front, rect {rect:?}");
                    };
                    if (0.0..64.0).contains(&x) && (0.0..48.0).contains(&y) {
                        let r = rect.expect("a corner on screen");
                        assert!(
                            r.contains(x as u32, y as u32),
                            "{proj:?} {c}: {x},{y} not in {r:?}"
                        );
                        inside += 1;
                    }
                }
            }
            assert!(inside > 500, "{proj:?}: {inside}");
        }
    }

    #[test]
    fn projection_inverts_ray() {
        for proj in [Projection::Perspective, Projection::Orthographic] {
            let mut cam =
                Camera::look_at(Vec3::new(3.0, 4.0, 12.0), Vec3::new(0.5, -1.0, 0.0), 64, 48);
            cam.projection = proj;
            cam.fov_y_deg = 60.0;
            let f = cam.frame().unwrap();
            for (i, j) in [(0, 0), (10, 20), (63, 47), (31, 5)] {
                let r = f.ray(i, j);
                let (x, y) = f.project(r.at(7.0)).unwrap();
                assert!((x - (i as f32 + 0.5)).abs() < 1e-3, "{proj:?} {x} {i}");
                assert!((y - (j as f32 + 0.5)).abs() < 1e-3, "{proj:?} {y} {j}");
            }
        }
    }

    #[test]
    fn every_pixel_whose_ray_meets_a_sphere_is_in_its_rect() {
        let mut rng = fastrand::Rng::with_seed(3);
        for n in 0..300 {
            let c = Vec3::new(
                rng.f32() * 6.0 - 3.0,
                rng.f32() * 6.0 - 3.0,
                rng.f32() * 6.0 - 3.0,
            );
            let radius = 0.1 + rng.f32() * 2.0;
            let pos = Vec3::new(rng.f32() * 16.0 - 8.0, rng.f32() * 16.0 - 8.0, 9.0);
            let mut cam = Camera::look_at(pos, Vec3::ZERO, 48, 32);
            cam.fov_y_deg = 20.0 + rng.f32() * 100.0;
            if n % 3 == 2 {
                cam.projection = Projection::Orthographic;
            }
            let Some(f) = cam.frame() else { continue };
            let rect = f.sphere_rect(c, radius);
            for j in 0..32 {
                for i in 0..48 {
                    let ray = f.ray(i, j);
                    let oc = c - ray.origin;
                    let b = oc.dot(ray.dir);
                    let h2 = oc.length_squared() - b * b;
                    let meets = h2 < radius * radius && b + (radius * radius - h2).sqrt() > 0.0;
                    if meets {
                        assert!(
                            rect.is_some_and(|r| r.contains(i, j)),
                            "pixel {i},{j} meets the sphere {c} {radius} but is outside {rect:?} ({cam:?})"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn every_pixel_whose_ray_hits_the_box_is_in_the_screen_rect() {
        let mut rng = fastrand::Rng::with_seed(7);
        let b = Aabb::new(Vec3::new(-1.0, -2.0, 0.5), Vec3::new(3.0, 1.0, 2.0));
        for n in 0..200 {
            let pos = Vec3::new(
                rng.f32() * 20.0 - 10.0,
                rng.f32() * 20.0 - 10.0,
                rng.f32() * 20.0 - 10.0,
            );
            let mut cam = Camera::look_at(pos, b.center(), 40, 30);
            cam.fov_y_deg = 20.0 + rng.f32() * 100.0;
            if n % 2 == 1 {
                cam.projection = Projection::Orthographic;
            }
            let Some(f) = cam.frame() else { continue };
            let rect = f.screen_rect(&b);
            for j in 0..30 {
                for i in 0..40 {
                    if b.intersect(&f.ray(i, j)).is_some() {
                        assert!(
                            rect.contains(i, j),
                            "pixel {i},{j} hits but is outside {rect:?} ({cam:?})"
                        );
                    }
                }
            }
        }
    }
}
