//! [`AnyRenderer`]: a renderer of this crate chosen at run time by its
//! [`RendererKind`].

use super::object::resolve_threads;
use super::{
    Cancel, Frame, ObjectRenderer, RenderOptions, Renderer, SerialRenderer, TiledRenderer,
};
use crate::camera::Camera;
use crate::error::Result;
use crate::scene::Scene;
use crate::transfer::TransferFunction;

/// The renderers of this crate, by name.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum RendererKind {
    /// [`SerialRenderer`]: one thread, the reference.
    #[cfg_attr(feature = "clap", value(help = "One thread, the reference"))]
    Serial,
    /// [`TiledRenderer`]: screen tiles on a thread pool.
    #[cfg_attr(feature = "clap", value(help = "Screen tiles on a thread pool"))]
    Tiles,
    /// [`ObjectRenderer`]: bricks front to back into tiles. The default: the
    /// fastest measured on the benchmark frame and in other views (the
    /// README has the figures).
    #[default]
    #[cfg_attr(
        feature = "clap",
        value(
            help = "Object-parallel: bricks front to back into tiles (the default: the fastest measured)"
        )
    )]
    Object,
}

impl RendererKind {
    /// All kinds.
    pub const ALL: [RendererKind; 3] = [
        RendererKind::Serial,
        RendererKind::Tiles,
        RendererKind::Object,
    ];

    /// The name used on command lines.
    pub fn name(self) -> &'static str {
        match self {
            RendererKind::Serial => "serial",
            RendererKind::Tiles => "tiles",
            RendererKind::Object => "object",
        }
    }
}

/// Any renderer of this crate, chosen at run time.
pub struct AnyRenderer {
    kind: RendererKind,
    renderer: Box<dyn Renderer>,
}

impl std::fmt::Debug for AnyRenderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AnyRenderer")
            .field("kind", &self.kind)
            .field("threads", &self.renderer.threads())
            .finish()
    }
}

impl AnyRenderer {
    /// A renderer of `kind` with `threads` threads in all (0 = one per
    /// core; the serial renderer always uses one) and default options.
    pub fn new(kind: RendererKind, threads: usize) -> Result<Self> {
        let renderer: Box<dyn Renderer> = match kind {
            RendererKind::Serial => Box::new(SerialRenderer::new()),
            RendererKind::Tiles => Box::new(TiledRenderer::new(
                resolve_threads(threads),
                TiledRenderer::DEFAULT_TILE,
            )?),
            RendererKind::Object => Box::new(ObjectRenderer::new(threads)?),
        };
        Ok(AnyRenderer { kind, renderer })
    }

    /// Which renderer this is.
    pub fn kind(&self) -> RendererKind {
        self.kind
    }
}

impl Renderer for AnyRenderer {
    fn name(&self) -> &'static str {
        self.renderer.name()
    }

    fn threads(&self) -> usize {
        self.renderer.threads()
    }

    fn render_cancellable(
        &mut self,
        scene: &Scene,
        camera: &Camera,
        tf: &TransferFunction,
        options: &RenderOptions,
        cancel: Cancel<'_>,
    ) -> Result<Option<Frame>> {
        self.renderer
            .render_cancellable(scene, camera, tf, options, cancel)
    }
}
