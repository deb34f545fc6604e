//! [`Fragment`]: what one ray contributes to sort-last compositing when the
//! volume is split between processes ([`crate::distributed`]).
//!
//! A part of a ray cannot resolve to its pixel on its own in every mode: a
//! maximum is only known once every part's maximum is, a mean needs every
//! part's sum and count. So each mode hands over the record its partial
//! results merge by ([`Integrator::fragment`](super::Integrator::fragment)),
//! with no background applied.

use glam::Vec4;

/// One ray's partial result. Which fields mean what depends on the mode:
///
/// | mode | `rgba` | `value` | `count` |
/// |---|---|---|---|
/// | dvr | premultiplied `C`, `A` | — | — |
/// | mip, minip | — | the extremum | 1 when a sample was taken |
/// | avg | — | the sum of the values | the number of samples |
/// | iso | the shaded colour, opaque | the hit's ray parameter | 1 on a hit |
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Fragment {
    /// Premultiplied colour and opacity.
    pub rgba: Vec4,
    /// The mode's scalar (extremum, sum, depth).
    pub value: f32,
    /// The mode's count (samples, hits).
    pub count: u32,
}

impl Fragment {
    /// Floats per fragment in [`Fragment::write`]'s encoding.
    pub const FLOATS: usize = 6;

    /// Appends the fragment as [`Fragment::FLOATS`] floats (the count as
    /// an `f32`: exact up to 2²⁴, above the 2²⁰ samples a ray may take).
    pub fn write(&self, out: &mut Vec<f32>) {
        out.extend_from_slice(&self.rgba.to_array());
        out.push(self.value);
        out.push(self.count as f32);
    }

    /// The fragment at the start of `floats` (at least
    /// [`Fragment::FLOATS`] long).
    pub fn read(floats: &[f32]) -> Fragment {
        Fragment {
            rgba: Vec4::from_slice(&floats[..4]),
            value: floats[4],
            count: floats[5] as u32,
        }
    }
}
