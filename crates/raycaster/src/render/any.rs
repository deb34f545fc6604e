//! [`RendererKind`]: the renderers of this crate by name, and the
//! [`AnyRenderer`] a kind builds at run time.

use super::{ObjectRenderer, Renderer, SerialRenderer, TiledRenderer};
use crate::error::Result;

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
    /// [`TiledRenderer`]: screen tiles on a thread pool. The default: the
    /// fastest measured on the benchmark frame (both layouts, one and two
    /// threads, shaded and not), on the 2000³ volume and on the iso
    /// turntable since DVR rays start at the proxy depths (the README has
    /// the figures).
    #[default]
    #[cfg_attr(
        feature = "clap",
        value(help = "Screen tiles on a thread pool (the default: the fastest measured)")
    )]
    Tiles,
    /// [`ObjectRenderer`]: bricks front to back into tiles.
    #[cfg_attr(
        feature = "clap",
        value(
            help = "Object-parallel: bricks front to back into tiles (the seed thesis's design)"
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

/// A renderer chosen at run time (any [`Renderer`], this crate's or not).
pub type AnyRenderer = Box<dyn Renderer>;

impl RendererKind {
    /// A renderer of this kind with `threads` threads in all (0 = one per
    /// core; the serial renderer always uses one) and default options.
    pub fn renderer(self, threads: usize) -> Result<AnyRenderer> {
        Ok(match self {
            RendererKind::Serial => Box::new(SerialRenderer::new()),
            RendererKind::Tiles => {
                Box::new(TiledRenderer::new(threads, TiledRenderer::DEFAULT_TILE)?)
            }
            RendererKind::Object => Box::new(ObjectRenderer::new(threads)?),
        })
    }
}
