//! Renderers: how the rays of a frame are scheduled.
//!
//! What happens along one ray lives in [`crate::integrator`]; this module
//! decides which rays are cast and on which threads. [`SerialRenderer`] is the
//! reference: one thread, pixel by pixel. [`TiledRenderer`] cuts the screen
//! rectangle the volume covers into tiles and integrates them on a thread
//! pool. Both take the same samples, so they give identical images.

mod frame;
mod plan;
mod serial;
mod tiled;

pub use frame::{Frame, FrameStats};
pub use plan::{PlanCache, RenderOptions};
pub use serial::SerialRenderer;
pub use tiled::TiledRenderer;

use crate::camera::Camera;
use crate::error::Result;
use crate::scene::{Scene, VolumeSource};
use crate::transfer::TransferFunction;

/// A renderer: turns a scene, camera, TF and options into a frame.
pub trait Renderer: Send {
    /// Short name (`serial`, `tiles`, `object`).
    fn name(&self) -> &'static str;
    /// Worker threads used.
    fn threads(&self) -> usize;
    /// Renders one frame.
    fn render<V: VolumeSource>(
        &mut self,
        scene: &Scene<V>,
        camera: &Camera,
        tf: &TransferFunction,
        options: &RenderOptions,
    ) -> Result<Frame>;
}
