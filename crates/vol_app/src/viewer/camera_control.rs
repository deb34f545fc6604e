//! Orbit, pan and zoom: the camera as a point on a sphere around a target.
//!
//! The camera sits at `target + distance·(cos φ·sin θ, sin φ, cos φ·cos θ)`
//! (azimuth θ, elevation φ) and looks at the target with +Y up, so azimuth 0
//! and elevation 0 is `vol_app render`'s default view from the +z side.
//! Mouse deltas come in UI points; nothing here knows about egui.

use glam::{Vec2, Vec3};
use raycaster::camera::Camera;
use raycaster::geometry::Aabb;

/// Degrees of rotation per point of mouse drag.
const ORBIT_DEG_PER_POINT: f32 = 0.4;
/// Zoom factor exponent per point of wheel scroll.
const ZOOM_PER_POINT: f32 = 0.001;
/// Elevation limit: at ±90° the up vector would be parallel to the view.
pub const MAX_ELEVATION: f32 = 89.0;
/// The vertical field of view of the viewer.
pub const FOV_Y_DEG: f32 = 45.0;

/// The viewer's camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrbitCamera {
    /// The point orbited around and looked at.
    pub target: Vec3,
    /// Azimuth θ in degrees, in (−180, 180].
    pub azimuth: f32,
    /// Elevation φ in degrees, in [−89, 89].
    pub elevation: f32,
    /// Distance from the target, world units.
    pub distance: f32,
    /// Vertical field of view in degrees.
    pub fov_y_deg: f32,
    home: Home,
}

/// What "reset camera" returns to.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Home {
    target: Vec3,
    distance: f32,
    radius: f32,
}

impl OrbitCamera {
    /// Azimuth of the initial three-quarter view.
    pub const HOME_AZIMUTH: f32 = 35.0;
    /// Elevation of the initial three-quarter view.
    pub const HOME_ELEVATION: f32 = 25.0;

    /// A camera looking at the centre of `bounds` from a three-quarter view,
    /// far enough that the whole box is in view for a canvas of `aspect`
    /// (width / height).
    pub fn framing(bounds: &Aabb, aspect: f32) -> Self {
        let aspect = if aspect.is_finite() && aspect > 0.0 {
            aspect
        } else {
            1.0
        };
        // The library's framing is rotation-independent (it fits the bounding
        // sphere), so its distance holds from any direction.
        let h = 1000u32;
        let w = ((h as f32 * aspect).round() as u32).max(1);
        let c = Camera::framing(bounds, w, h, FOV_Y_DEG);
        let home = Home {
            target: c.target,
            distance: (c.position - c.target).length(),
            radius: ((bounds.max - bounds.min).length() * 0.5).max(1e-3),
        };
        OrbitCamera {
            target: home.target,
            azimuth: Self::HOME_AZIMUTH,
            elevation: Self::HOME_ELEVATION,
            distance: home.distance,
            fov_y_deg: FOV_Y_DEG,
            home,
        }
    }

    /// Back to the initial view.
    pub fn reset(&mut self) {
        self.target = self.home.target;
        self.azimuth = Self::HOME_AZIMUTH;
        self.elevation = Self::HOME_ELEVATION;
        self.distance = self.home.distance;
    }

    /// The closest the camera may come to the target.
    pub fn min_distance(&self) -> f32 {
        self.home.radius * 0.05
    }

    /// The farthest the camera may go from the target.
    pub fn max_distance(&self) -> f32 {
        self.home.distance * 10.0
    }

    /// Rotates around the target by a mouse drag of `delta` points: dragging
    /// right turns the volume to the right, dragging down tips it towards
    /// the viewer.
    pub fn orbit(&mut self, delta: Vec2) {
        self.set_angles(
            self.azimuth - delta.x * ORBIT_DEG_PER_POINT,
            self.elevation + delta.y * ORBIT_DEG_PER_POINT,
        );
    }

    /// Sets azimuth (wrapped to (−180, 180]) and elevation (clamped).
    pub fn set_angles(&mut self, azimuth: f32, elevation: f32) {
        let mut a = (azimuth + 180.0).rem_euclid(360.0) - 180.0;
        if a == -180.0 {
            a = 180.0;
        }
        self.azimuth = a;
        self.elevation = elevation.clamp(-MAX_ELEVATION, MAX_ELEVATION);
    }

    /// Moves the target in the view plane by a drag of `delta` points on a
    /// canvas `view_height` points high, so the point under the cursor
    /// follows it (at the target's depth).
    pub fn pan(&mut self, delta: Vec2, view_height: f32) {
        if view_height <= 0.0 {
            return;
        }
        let (right, up) = self.right_up();
        let world_per_point =
            2.0 * self.distance * (self.fov_y_deg.to_radians() * 0.5).tan() / view_height;
        self.target += (-right * delta.x + up * delta.y) * world_per_point;
    }

    /// Moves towards the target for a positive wheel `scroll` (points), away
    /// for a negative one.
    pub fn zoom(&mut self, scroll: f32) {
        self.set_distance(self.distance * (-scroll * ZOOM_PER_POINT).exp());
    }

    /// Sets the distance, clamped to the allowed range (NaN is ignored).
    pub fn set_distance(&mut self, distance: f32) {
        if !distance.is_nan() {
            self.distance = distance.clamp(self.min_distance(), self.max_distance());
        }
    }

    /// Unit vector from the target towards the eye.
    pub fn direction(&self) -> Vec3 {
        let (a, e) = (self.azimuth.to_radians(), self.elevation.to_radians());
        Vec3::new(e.cos() * a.sin(), e.sin(), e.cos() * a.cos())
    }

    /// The eye position.
    pub fn position(&self) -> Vec3 {
        self.target + self.direction() * self.distance
    }

    /// The camera's right and true-up vectors (`r = normalize(d × U)`,
    /// `u = r × d`, as the library's camera).
    fn right_up(&self) -> (Vec3, Vec3) {
        let d = -self.direction();
        let right = d.cross(Vec3::Y).normalize_or(Vec3::X);
        (right, right.cross(d))
    }

    /// The library camera for an image of `width`×`height` pixels.
    pub fn camera(&self, width: u32, height: u32) -> Camera {
        let mut c = Camera::look_at(self.position(), self.target, width, height);
        c.fov_y_deg = self.fov_y_deg;
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box() -> Aabb {
        Aabb::new(Vec3::ZERO, Vec3::new(40.0, 20.0, 10.0))
    }

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-3 * (1.0 + b.length())
    }

    #[test]
    fn framing_sees_the_whole_box_from_any_direction() {
        let b = unit_box();
        for aspect in [0.5f32, 1.0, 2.0] {
            let mut cam = OrbitCamera::framing(&b, aspect);
            assert!(close(cam.target, b.center()));
            for (az, el) in [(0.0, 0.0), (35.0, 25.0), (-120.0, 80.0), (180.0, -60.0)] {
                cam.set_angles(az, el);
                let h = 200;
                let w = (h as f32 * aspect) as u32;
                let f = cam.camera(w, h).frame().unwrap();
                for corner in b.corners() {
                    let (x, y) = f.project(corner).unwrap();
                    assert!(
                        (0.0..=w as f32).contains(&x) && (0.0..=h as f32).contains(&y),
                        "corner {corner} at ({x}, {y}) outside {w}x{h} (az {az}, el {el})"
                    );
                }
            }
        }
    }

    #[test]
    fn zero_angles_look_from_plus_z_like_the_spec_default() {
        let b = unit_box();
        let mut cam = OrbitCamera::framing(&b, 1.0);
        cam.set_angles(0.0, 0.0);
        let lib = Camera::framing(&b, 300, 300, FOV_Y_DEG);
        assert!(close(cam.camera(300, 300).position, lib.position));
    }

    #[test]
    fn orbit_keeps_distance_and_target_and_wraps_azimuth() {
        let mut cam = OrbitCamera::framing(&unit_box(), 1.0);
        let (t, d) = (cam.target, cam.distance);
        for _ in 0..50 {
            cam.orbit(Vec2::new(37.0, -11.0));
            assert!((cam.position() - t).length() - d < 1e-3);
            assert!(cam.azimuth > -180.0 && cam.azimuth <= 180.0);
            assert!(cam.elevation.abs() <= MAX_ELEVATION);
        }
        assert_eq!(cam.target, t);
        assert_eq!(cam.elevation, -MAX_ELEVATION);
        // The camera never becomes degenerate, even at the pole.
        assert!(cam.camera(10, 10).frame().is_some());
    }

    #[test]
    fn dragging_right_moves_the_eye_left() {
        let mut cam = OrbitCamera::framing(&unit_box(), 1.0);
        cam.set_angles(0.0, 0.0);
        let before = cam.position();
        cam.orbit(Vec2::new(10.0, 0.0));
        // From +z looking at -z, "right" is +x: the eye moves to -x.
        assert!(cam.position().x < before.x);
        cam.set_angles(0.0, 0.0);
        cam.orbit(Vec2::new(0.0, 10.0));
        assert!(cam.position().y > before.y, "dragging down raises the eye");
    }

    #[test]
    fn pan_moves_the_target_with_the_cursor_in_the_view_plane() {
        let b = unit_box();
        let mut cam = OrbitCamera::framing(&b, 1.0);
        let h = 400u32;
        let before = cam.camera(h, h).frame().unwrap();
        let p = cam.target;
        let (x0, y0) = before.project(p).unwrap();
        // Drag 50 points right and 20 down on a 400-point canvas.
        cam.pan(Vec2::new(50.0, 20.0), h as f32);
        let after = cam.camera(h, h).frame().unwrap();
        let (x1, y1) = after.project(p).unwrap();
        assert!(((x1 - x0) - 50.0).abs() < 0.5, "{x0} -> {x1}");
        assert!(((y1 - y0) - 20.0).abs() < 0.5, "{y0} -> {y1}");
        // The view direction is unchanged.
        assert!(close(after.forward, before.forward));
        assert!((cam.target - p).dot(before.forward).abs() < 1e-3);
    }

    #[test]
    fn zoom_changes_only_the_distance_within_limits() {
        let mut cam = OrbitCamera::framing(&unit_box(), 1.0);
        let d = cam.distance;
        let dir = cam.direction();
        cam.zoom(100.0);
        assert!(cam.distance < d);
        assert!(close(cam.direction(), dir));
        cam.zoom(-200.0);
        assert!(cam.distance > d);
        cam.zoom(1e6);
        assert_eq!(cam.distance, cam.min_distance());
        cam.zoom(-1e6);
        assert_eq!(cam.distance, cam.max_distance());
        cam.set_distance(f32::NAN);
        assert_eq!(cam.distance, cam.max_distance());
    }

    #[test]
    fn reset_returns_home() {
        let b = unit_box();
        let home = OrbitCamera::framing(&b, 1.5);
        let mut cam = home;
        cam.orbit(Vec2::new(30.0, 40.0));
        cam.pan(Vec2::new(5.0, 5.0), 100.0);
        cam.zoom(50.0);
        assert_ne!(cam, home);
        cam.reset();
        assert_eq!(cam, home);
    }
}
