//! Footprints: the pixels whose rays can reach a box.

use glam::Vec3;

use crate::camera::{Camera, CameraFrame, PixelRect, Projection};
use crate::geometry::Aabb;

/// The pixels whose rays can pass through the world-space box `b`: the
/// rectangle of its projection grown by 1.5 pixels and clamped to the image,
/// or `None` when no pixel's ray can reach it.
///
/// For a perspective camera the box is clipped at a plane just in front of
/// the eye; anything visible between the eye and that plane lies within a
/// small ball around the eye, and a box reaching into that ball gets the
/// whole image.
pub(super) fn footprint(frame: &CameraFrame, camera: &Camera, b: &Aabb) -> Option<PixelRect> {
    let (w, h) = (camera.width as f32, camera.height as f32);
    let full = PixelRect {
        x0: 0,
        y0: 0,
        x1: camera.width,
        y1: camera.height,
    };
    let corners = b.corners();
    let mut cam = [Vec3::ZERO; 8];
    for (c, p) in cam.iter_mut().zip(corners) {
        let v = p - camera.position;
        *c = Vec3::new(v.dot(frame.right), v.dot(frame.up), v.dot(frame.forward));
    }
    let size = (b.max - b.min).length();
    let (hx, hy) = (frame.half_height * frame.aspect, frame.half_height);
    let (near, lateral) = match camera.projection {
        Projection::Perspective => {
            let near = 1e-2 * size.max(1e-6);
            // Points in view closer than `near` lie within this radius.
            let radius = near * (1.0 + hx * hx + hy * hy).sqrt();
            let closest = camera.position.clamp(b.min, b.max);
            let tolerance = 1e-5 * (camera.position.abs().max_element() + size);
            if (closest - camera.position).length() <= radius * 1.01 + tolerance {
                return Some(full);
            }
            (near, None)
        }
        Projection::Orthographic => (0.0, Some(frame.distance)),
    };
    let to_pixels = |c: Vec3| -> (f32, f32) {
        let (sx, sy) = match lateral {
            Some(d) => (c.x / d, c.y / d),
            None => (c.x / c.z, c.y / c.z),
        };
        ((sx / hx + 1.0) * 0.5 * w, (1.0 - sy / hy) * 0.5 * h)
    };
    let (mut lo_x, mut lo_y) = (f32::INFINITY, f32::INFINITY);
    let (mut hi_x, mut hi_y) = (f32::NEG_INFINITY, f32::NEG_INFINITY);
    let mut add = |c: Vec3| {
        let (x, y) = to_pixels(c);
        lo_x = lo_x.min(x);
        lo_y = lo_y.min(y);
        hi_x = hi_x.max(x);
        hi_y = hi_y.max(y);
    };
    // Vertices of the box clipped to z >= near: the corners in front and
    // the points where edges cross the plane.
    for c in cam {
        if c.z >= near {
            add(c);
        }
    }
    for i in 0..8usize {
        for bit in [1usize, 2, 4] {
            let j = i | bit;
            if j == i {
                continue;
            }
            let (a, b) = (cam[i], cam[j]);
            if (a.z >= near) != (b.z >= near) {
                let s = ((near - a.z) / (b.z - a.z)).clamp(0.0, 1.0);
                let mut p = a + (b - a) * s;
                p.z = near.max(p.z);
                add(p);
            }
        }
    }
    if !(lo_x <= hi_x && lo_y <= hi_y) {
        return None;
    }
    let clamp_x = |v: f32| v.clamp(0.0, w) as u32;
    let clamp_y = |v: f32| v.clamp(0.0, h) as u32;
    let rect = PixelRect {
        x0: clamp_x((lo_x - 1.5).floor()),
        y0: clamp_y((lo_y - 1.5).floor()),
        x1: clamp_x((hi_x + 1.5).ceil()),
        y1: clamp_y((hi_y + 1.5).ceil()),
    };
    (rect.x0 < rect.x1 && rect.y0 < rect.y1).then_some(rect)
}

/// `a ∩ b`, `None` when empty.
pub(super) fn intersect(a: &PixelRect, b: &PixelRect) -> Option<PixelRect> {
    let r = PixelRect {
        x0: a.x0.max(b.x0),
        y0: a.y0.max(b.y0),
        x1: a.x1.min(b.x1),
        y1: a.y1.min(b.y1),
    };
    (r.x0 < r.x1 && r.y0 < r.y1).then_some(r)
}
