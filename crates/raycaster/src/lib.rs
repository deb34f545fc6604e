//! CPU volume ray casting.
//!
//! `raycaster` reads volumes (the `.vol` format, linear or bricked; NRRD,
//! NIfTI-1, DICOM series, raw; 8/16-bit integer and float samples; in RAM or
//! memory-mapped), and renders them by ray casting: trilinear sampling,
//! transfer functions with opacity correction, Phong shading from gradients,
//! DVR / MIP / x-ray / isosurface modes, early ray termination and
//! empty-space skipping over a macrocell distance field.
//!
//! The map of the crate follows the pipeline:
//!
//! | module | concept |
//! |---|---|
//! | [`format`](mod@format) | file formats: headers, detection, reading and writing |
//! | [`storage`] | samples in RAM or memory-mapped |
//! | [`volume`] | the [`Volume`](volume::Volume) trait, linear and bricked layouts, trilinear sampling |
//! | [`accel`] | macrocell value ranges and the skip distance field |
//! | [`camera`] | perspective and orthographic cameras, screen rectangles |
//! | [`transfer`] | transfer functions, presets, lookup tables |
//! | [`integrator`] | what happens along one ray, per mode |
//! | [`metaballs`] | implicit surfaces of balls from a volume or a points file |
//! | [`render`] | which rays are cast on which threads |
//! | [`scene`] | a volume plus its acceleration data |
//! | [`sequence`] | time series: frames of one geometry, decoded ahead of a player |
//! | [`units`] | numbers and byte counts as people read them |
//! | `cli` | the programs' shared command-line behaviour (feature `clap`) |
//!
//! # Example
//!
//! Render a sphere built in memory and check the centre pixel is lit:
//!
//! ```
//! use glam::{UVec3, Vec3};
//! use raycaster::prelude::*;
//!
//! // A 32³ volume holding a solid ball of value 200.
//! let grid = Grid::new(UVec3::splat(32), Vec3::ONE);
//! let volume = AnyVolume::from_fn(grid, |v| {
//!     if (v.as_vec3() - Vec3::splat(15.5)).length() < 10.0 { 200u8 } else { 0 }
//! });
//! let scene = Scene::new(volume);
//! let camera = Camera::framing(&scene.grid().bounds(), 64, 64, 45.0);
//! let tf = TransferFunction::preset("skull", SampleType::U8).unwrap();
//! let frame = SerialRenderer::new()
//!     .render(&scene, &camera, &tf, &RenderOptions::default())
//!     .unwrap();
//! assert!(frame.pixel(32, 32)[0] > 100);
//! assert_eq!(frame.pixel(0, 0), [0, 0, 0]);
//! ```
//!
//! To open a file of any supported format, use [`format::open`] (or
//! [`format::open_file`] for a description of what the file stores) and
//! wrap the volume in a [`Scene`](scene::Scene); transfer function values are
//! in the data's units (Hounsfield units for CT):
//!
//! ```no_run
//! use raycaster::prelude::*;
//! let volume = raycaster::format::open("head_ct.nii.gz".as_ref(), LoadMode::Map)?;
//! let tf = TransferFunction::preset("ct-bone", volume.sample_type()).unwrap();
//! let scene = Scene::new(volume);
//! # Ok::<(), raycaster::Error>(())
//! ```

#![warn(missing_docs)]

pub mod accel;
pub mod camera;
#[cfg(feature = "clap")]
pub mod cli;
pub mod clip;
pub mod distributed;
pub mod error;
pub mod format;
pub mod geometry;
pub mod integrator;
pub mod metaballs;
pub mod render;
pub mod sample;
pub mod scene;
pub mod sequence;
pub mod simd;
pub mod storage;
pub mod transfer;
pub mod units;
pub mod volume;

pub use error::{Error, FormatError, Result};

/// The types most programs need.
pub mod prelude {
    pub use crate::camera::{Camera, Projection};
    pub use crate::integrator::{Phong, RenderMode};
    pub use crate::render::{
        AnyRenderer, Cancel, Frame, FrameRequest, FrameStats, FrontEvent, FrontOptions,
        ObjectConfig, ObjectRenderer, Quality, RenderOptions, Renderer, RendererFront,
        RendererKind, SerialRenderer, TaskOrder, TiledRenderer,
    };
    pub use crate::sample::{Sample, SampleType};
    pub use crate::scene::Scene;
    pub use crate::storage::LoadMode;
    pub use crate::transfer::{Interpolation, TfPoint, TransferFunction};
    pub use crate::volume::{AnyVolume, AxisOrder, Grid, Layout, Volume, VolumeVisitor};
}
