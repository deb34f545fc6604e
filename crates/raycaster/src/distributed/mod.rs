//! Distributed rendering: sort-last ray casting of a volume split between
//! processes (SPEC §8 "Distributed rendering"), the parts a transport such
//! as MPI needs, with no transport in it.
//!
//! 1. **Partition** ([`partition`]): a k-d split of the voxel box into one
//!    region per rank, balanced by the weight of coarse cells (occupied
//!    macrocells for the frame's transfer function, or voxel count); a
//!    half-open ownership rule gives every sample position exactly one
//!    region.
//! 2. **Partial reading** ([`read`]): a rank reads only its region plus a
//!    ghost layer ([`ghost_layer`]) from the file, by seeks.
//! 3. **Rendering a part** ([`render`]): the frame's rays, clipped to the
//!    whole volume so the sample positions are the single-process ones,
//!    integrated over the samples the region owns into per-pixel
//!    [`Fragment`]s (premultiplied RGBA, extremum, sum, depth), no
//!    background.
//! 4. **Compositing** ([`composite`]): the parts' images merged in the
//!    regions' visibility order ([`Partition::visibility_order`]), then the
//!    background; [`exchange`] says how the images travel between ranks
//!    for it (gather to rank 0, direct send to band owners, binary swap)
//!    and simulates P ranks in one process.
//!
//! [`render_in_process`] runs all four in one process, part after part: the
//! reference the tests compare with a single-process render, and what a
//! transport's driver does with the parts spread over ranks.

pub mod composite;
pub mod exchange;
pub mod partition;
pub mod read;
pub mod render;

pub use crate::integrator::Fragment;
pub use composite::Compositor;
pub use exchange::{BinarySwap, CompositeMethod, CompositePlan, DirectSend, SwapRound, Traffic};
pub use partition::{Balance, CellWeights, Partition, Region, SwapPair, balance_cell};
pub use read::{PartFile, PartVolume, ReadPolicy, extract};
pub use render::{PartRenderer, PartScene, PartialImage};

use crate::accel::{MacrocellGrid, SkipGrid};
use crate::camera::Camera;
use crate::error::Result;
use crate::integrator::{Integrator, IntegratorVisitor, Occupancy};
use crate::render::RenderOptions;
use crate::scene::Scene;
use crate::transfer::{TfLut, TransferFunction};
use crate::volume::Grid;

/// The ghost layer a frame with `options` needs around each region: 1
/// voxel for trilinear sampling, 2 when central-difference gradients are
/// taken (shading, gradient opacity).
pub fn ghost_layer(options: &RenderOptions) -> u32 {
    if options.shading || options.gradient_opacity.is_some() {
        2
    } else {
        1
    }
}

/// Reads `region` of `file` with a ghost layer of `ghost` voxels and makes
/// its scene. The value range is the part's own until the caller sets the
/// whole volume's ([`PartScene::value_range`]). Returns the bytes read.
pub fn open_part(file: &PartFile, region: &Region, ghost: u32) -> Result<(PartScene, u64)> {
    let whole = file.grid();
    let (lo, hi) = region.data_box(whole.dims, ghost);
    let part = file.read_box(lo, hi)?;
    let scene = Scene::new(part.volume);
    let value_range = scene.value_range();
    Ok((
        PartScene {
            scene,
            region: *region,
            offset: part.offset,
            whole,
            value_range,
        },
        part.bytes_read,
    ))
}

/// The cell weights that balance a partition by the macrocells of `scene`
/// (the whole volume) that the frame's transfer function, iso value and
/// clipping leave occupied.
pub fn occupancy_weights(
    scene: &Scene,
    tf: &TransferFunction,
    options: &RenderOptions,
) -> CellWeights {
    occupancy_weights_of(scene.grid(), scene.macrocells(), tf, options)
}

/// The cell weights that balance a partition of a volume on `grid` whose
/// macrocells (any side, e.g. coarsened to [`balance_cell`]) have the
/// value ranges `cells`, by those the frame leaves occupied: the TF gives
/// some value of the range opacity (DVR, x-ray), the range holds the iso
/// value (iso), or every cell (MIP, MinIP, whose integrators decide per
/// cell); cells outside the clipping are empty.
pub fn occupancy_weights_of(
    grid: &Grid,
    cells: &MacrocellGrid,
    tf: &TransferFunction,
    options: &RenderOptions,
) -> CellWeights {
    struct OccupancyOf;
    impl IntegratorVisitor for OccupancyOf {
        type Output = Occupancy;
        fn visit<I: Integrator>(self) -> Occupancy {
            I::OCCUPANCY
        }
    }
    let step = options.step_for(grid);
    let lut = TfLut::new(tf, step);
    let clip = options.clip.region(grid);
    let iso = options.iso_value;
    let skip = match options.mode.visit(OccupancyOf) {
        Occupancy::Visible => {
            SkipGrid::build_clipped(cells, |lo, hi| lut.any_visible(lo, hi), clip.as_ref())
        }
        Occupancy::IsoValue => {
            SkipGrid::build_clipped(cells, |lo, hi| lo <= iso && iso <= hi, clip.as_ref())
        }
        Occupancy::Every => SkipGrid::build_clipped(cells, |_, _| true, clip.as_ref()),
    };
    CellWeights::macrocells(grid.dims, cells, |i| skip.is_occupied_index(i))
}

/// The value ranges of the whole volume's macrocells of side `cell` that
/// `region` holds, read from `file` (the region's box without a ghost
/// layer: a macrocell's voxels `[c·m, c·m + m]` lie inside the region when
/// its faces are on macrocell planes, as a partition on [`balance_cell`]
/// cells makes them). The result has an entry for every macrocell of the
/// whole grid, `(+∞, −∞)` for those the region does not hold, so the
/// parts' results combine by element-wise min and max
/// ([`merge_ranges`]) into the whole volume's grid, as an all-reduce
/// does.
pub fn region_macrocell_ranges(
    file: &PartFile,
    region: &Region,
    cell: u32,
) -> Result<RegionRanges> {
    let dims = file.grid().dims;
    let cell = cell.max(1);
    let last = dims - glam::UVec3::ONE;
    for a in 0..3 {
        for plane in [region.lo[a], region.hi[a]] {
            if plane % cell != 0 && plane != last[a] {
                return Err(crate::error::Error::option(
                    "ranks",
                    format!(
                        "region {} has a face at voxel plane {plane} (axis {a}), not on a \
                         macrocell plane of side {cell}",
                        region.index
                    ),
                ));
            }
        }
    }
    let count = MacrocellGrid::count_for(dims, cell);
    let mut ranges = vec![(f32::INFINITY, f32::NEG_INFINITY); count.element_product() as usize];
    let part = file.read_box(region.lo, region.hi)?;
    let local = MacrocellGrid::build_any(&part.volume, cell, None);
    let first = region.lo / cell;
    for x in 0..local.count.x {
        for y in 0..local.count.y {
            for z in 0..local.count.z {
                let c = glam::UVec3::new(x, y, z);
                let g = first + c;
                if g.cmplt(count).all() {
                    let i = ((g.x * count.y + g.y) * count.z + g.z) as usize;
                    ranges[i] = local.ranges[local.index(c)];
                }
            }
        }
    }
    Ok(RegionRanges {
        ranges,
        bytes_read: part.bytes_read,
        sample_type: part.volume.sample_type(),
    })
}

/// What [`region_macrocell_ranges`] found.
#[derive(Debug, Clone)]
pub struct RegionRanges {
    /// Per macrocell of the whole grid (x slowest, z fastest), its value
    /// range, `(+∞, −∞)` where the region holds none of its voxels.
    pub ranges: Vec<(f32, f32)>,
    /// Bytes read from the file.
    pub bytes_read: u64,
    /// The type of the samples read (data units: a rescaled file's type
    /// depends on its values).
    pub sample_type: crate::sample::SampleType,
}

/// Folds the macrocell ranges `part` into `into` (element-wise min of the
/// minima and max of the maxima).
pub fn merge_ranges(into: &mut [(f32, f32)], part: &[(f32, f32)]) {
    for (a, b) in into.iter_mut().zip(part) {
        *a = (a.0.min(b.0), a.1.max(b.1));
    }
}

/// The compositor for a frame with these settings on a volume of sample
/// type `sample`.
pub fn compositor(
    tf: &TransferFunction,
    options: &RenderOptions,
    sample: crate::sample::SampleType,
) -> Compositor {
    Compositor {
        mode: options.mode,
        tf: tf.clone(),
        ert: options.ert.then_some(options.ert_threshold),
        avg_norm: sample.max_value(),
        background: options.background,
    }
}

/// A frame rendered by [`render_in_process`].
#[derive(Debug, Clone)]
pub struct InProcessFrame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// RGB8, row-major.
    pub rgb: Vec<u8>,
    /// Bytes each part read from the file.
    pub bytes_read: Vec<u64>,
    /// Samples each part took.
    pub samples: Vec<u64>,
    /// Each part's partial image.
    pub parts: Vec<PartialImage>,
    /// The compositor that merged them.
    pub compositor: Compositor,
}

/// Splits `file` into `partition`'s regions, reads and renders each part
/// in turn (as the ranks of a distributed run would, each on its own),
/// and composites them in visibility order.
pub fn render_in_process(
    file: &PartFile,
    partition: &Partition,
    camera: &Camera,
    tf: &TransferFunction,
    options: &RenderOptions,
    threads: usize,
) -> Result<InProcessFrame> {
    let ghost = ghost_layer(options);
    let mut parts = Vec::new();
    let mut bytes_read = Vec::new();
    let mut range = (f32::INFINITY, f32::NEG_INFINITY);
    for region in partition.regions() {
        let (part, bytes) = open_part(file, region, ghost)?;
        range = (
            range.0.min(part.value_range.0),
            range.1.max(part.value_range.1),
        );
        bytes_read.push(bytes);
        parts.push(part);
    }
    let mut renderer = PartRenderer::new(threads)?;
    let mut images = Vec::new();
    for part in &mut parts {
        part.value_range = range;
        images.push(renderer.render(part, camera, tf, options)?);
    }
    let sample = parts[0].scene.volume().sample_type();
    let order = visibility_order(partition, camera, &file.grid());
    let compositor = compositor(tf, options, sample);
    let (width, height, rgb) = compositor.composite(order.iter().map(|&i| &images[i]))?;
    Ok(InProcessFrame {
        width,
        height,
        rgb,
        bytes_read,
        samples: images.iter().map(|i| i.samples).collect(),
        parts: images,
        compositor,
    })
}

/// The regions of `partition` front to back for `camera` over a volume on
/// `grid`.
pub fn visibility_order(
    partition: &Partition,
    camera: &Camera,
    grid: &crate::volume::Grid,
) -> Vec<usize> {
    let (projection, view) = view_of(camera, grid);
    partition.visibility_order(projection, view)
}

/// What decides the visibility order of k-d regions for `camera`: the
/// projection and the eye (perspective) or the view direction
/// (orthographic) in the voxel space of `grid`.
pub fn view_of(
    camera: &Camera,
    grid: &crate::volume::Grid,
) -> (crate::camera::Projection, glam::Vec3) {
    use crate::camera::Projection;
    let view = match camera.projection {
        Projection::Perspective => grid.world_to_voxel(camera.position),
        Projection::Orthographic => (camera.target - camera.position) / grid.spacing,
    };
    (camera.projection, view)
}
