//! Command-line definitions.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use glam::Vec3;
use raycaster::integrator::IsoNormals;
use raycaster::metaballs::Kernel;
use raycaster::prelude::{RenderMode, RendererKind, TaskOrder};

/// Volume viewer and headless renderer for CPU ray casting.
#[derive(Debug, Parser)]
#[command(name = "vol_app", version, about, long_about = None)]
#[command(args_conflicts_with_subcommands = true)]
#[command(
    after_help = "Without a subcommand the interactive viewer opens on FILE, or on the \
built-in demo volume.\n\nViewer controls: left drag orbits, right drag pans, the wheel zooms, \
double-click resets the camera; drop a file on the window to open it. In a slice view, left \
click or drag moves the cursor, right drag sets window (horizontally) and level (vertically)."
)]
pub struct Cli {
    /// What to do; without a subcommand the interactive viewer opens.
    #[command(subcommand)]
    pub command: Option<Command>,
    /// The viewer's options.
    #[command(flatten)]
    pub viewer: ViewerArgs,
}

/// Options of the interactive viewer (`vol_app [FILE]`).
#[derive(Debug, Args)]
pub struct ViewerArgs {
    /// Volume to open in the viewer (.vol, .nrrd, .nhdr, .nii, .nii.gz, a
    /// DICOM directory or file, a folder of frames or holding one volume
    /// file, raw with --raw-dims/--raw-type). Without it, the built-in demo
    /// volume.
    pub file: Option<PathBuf>,
    /// Transfer function for the first volume: shapes, skull, ramp, ct-bone,
    /// ct-soft, mr-default.
    #[arg(long, value_name = "NAME")]
    pub tf_preset: Option<String>,
    /// Transfer function JSON file for the first volume (format in the README).
    #[arg(long, value_name = "FILE.json", conflicts_with = "tf_preset")]
    pub tf: Option<PathBuf>,
    /// How to read a headerless FILE.
    #[command(flatten)]
    pub raw: RawArgs,
    /// Neither read nor write the macrocell cache file next to each volume
    /// opened (see `vol_app render --help`).
    #[arg(long)]
    pub no_cache: bool,
    /// The most memory (GiB) a volume read or decoded into RAM may take
    /// (gzip NRRD/NIfTI, DICOM, converted raw data, packed sequences); a
    /// larger one is refused with a message. Memory-mapped files do not
    /// count. Default: three quarters of the physical memory.
    #[arg(long, value_name = "GIB", value_parser = parse_positive_gib)]
    pub max_memory: Option<f64>,
    /// For a sequence FILE (4-D NIfTI/NRRD, folder of frames, .vseq): the
    /// frame to show first, from 0 (play with Space, step with N / M).
    #[arg(long, value_name = "K")]
    pub frame: Option<u32>,
    /// What the viewer shows: the 3D view, the axial/coronal/sagittal
    /// slices, or both (2x2); switchable in the window.
    #[arg(long, value_enum, value_name = "3d|slices|2x2")]
    pub layout: Option<vol_app::viewer::slices::Layout>,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render a volume to a PNG without a window, optionally timing it.
    Render(Box<RenderArgs>),
    /// Describe a volume file: format, dimensions, sample type, spacing,
    /// value range, orientation as stored, size on disk and in memory.
    Info(InfoArgs),
    /// Convert a volume to another format, chosen by OUT's name: .vol,
    /// .nrrd, .nii, .nii.gz, .raw/.bin (x fastest, little-endian).
    Convert(ConvertArgs),
    /// Pack a sequence of volumes (a 4-D NIfTI/NRRD, a directory of frame
    /// files, or another .vseq) into a .vseq file: frames compressed one by
    /// one, any frame readable without the others (from the key frame
    /// before it when --key-interval is above 1).
    Pack(PackArgs),
}

/// `vol_app pack INPUT -o OUT.vseq`.
#[derive(Debug, Args)]
#[command(
    after_help = "The layout of .vseq files is in the README. LZ4 decodes fastest, zstd packs smaller; --f16 halves f32 frames (about 3 significant digits, lossy); --key-interval K > 1 stores frames between key frames as differences from the previous frame (lossless; smaller for slowly changing data; a frame then decodes from the key frame before it, at most K frames).\n\nExamples:\n  vol_app pack volumes/plume/ -o volumes/plume.vseq --codec zstd --f16\n  vol_app pack fmri.nii.gz -o fmri.vseq --codec lz4 --key-interval 8"
)]
pub struct PackArgs {
    /// The sequence to pack: a 4-D .nii/.nii.gz/.nrrd, a directory of volume
    /// files (frames in name order), or a .vseq.
    pub input: PathBuf,
    /// The .vseq file to write; it appears only when complete.
    #[arg(short = 'o', long = "out", value_name = "OUT.vseq")]
    pub output: PathBuf,
    /// Codec of the frames' chunks.
    #[arg(long, value_enum, default_value_t = raycaster::format::vseq::Codec::Lz4)]
    pub codec: raycaster::format::vseq::Codec,
    /// zstd level (1 fast .. 22 smallest).
    #[arg(long, value_name = "N", default_value_t = 3, value_parser = clap::value_parser!(i32).range(1..=22))]
    pub level: i32,
    /// Store f32 frames as half floats (lossy).
    #[arg(long)]
    pub f16: bool,
    /// A key frame every K frames, difference frames between (1: all key frames).
    #[arg(long, value_name = "K", default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub key_interval: u32,
    /// KiB of stored samples per chunk (chunks decode in parallel; small
    /// chunks compress worse).
    #[arg(long, value_name = "KIB", default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..=1048576))]
    pub chunk_kib: u32,
    /// Do not byte-shuffle chunks before compressing them.
    #[arg(long)]
    pub no_shuffle: bool,
    /// Store each sample as its difference from its neighbour along x (the
    /// delta filter; helps smooth data, hurts noisy data).
    #[arg(long)]
    pub delta: bool,
    /// Replace OUT if it exists.
    #[arg(long)]
    pub force: bool,
    /// Print the result as one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// `vol_app convert IN OUT`.
#[derive(Debug, Args)]
#[command(
    after_help = "Samples keep their type, except for .vol (8-bit): other data is mapped \
linearly from --window (default: the value range) to 0..255.\n\nExamples:\n  vol_app convert \
head.nii.gz head.nrrd --gzip\n  vol_app convert series_dir/ ct.nii.gz\n  vol_app convert ct.nii.gz \
ct.vol --window -1000,2000 --layout bricked --block-size 16"
)]
pub struct ConvertArgs {
    /// Volume file or DICOM directory to read.
    pub input: PathBuf,
    /// File to write; it appears only when complete and is never
    /// overwritten without --force.
    pub output: PathBuf,
    /// Replace OUT if it exists.
    #[arg(long)]
    pub force: bool,
    /// gzip-encode an .nrrd output.
    #[arg(long)]
    pub gzip: bool,
    /// Layout of a .vol output.
    #[arg(long, value_enum, default_value_t = VolLayoutArg::Linear)]
    pub layout: VolLayoutArg,
    /// Brick side of a bricked .vol output.
    #[arg(long, value_name = "B", default_value_t = 16, value_parser = clap::value_parser!(u8).range(2..))]
    pub block_size: u8,
    /// For a .vol output: the data values mapped to 0 and 255.
    #[arg(long, value_name = "LO,HI", allow_hyphen_values = true, value_parser = parse_window)]
    pub window: Option<(f32, f32)>,
    /// How to read a headerless input.
    #[command(flatten)]
    pub raw: RawArgs,
}

/// `.vol` layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum VolLayoutArg {
    /// z fastest, one array.
    Linear,
    /// Overlapping bricks of --block-size.
    Bricked,
}

/// `vol_app info FILE`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// Volume file, DICOM directory, sequence (.vseq, 4-D file) or
    /// directory of frame files.
    pub file: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Neither read nor write the macrocell cache (FILE.m<N>.rcidx): build
    /// the value ranges from the samples.
    #[arg(long)]
    pub no_cache: bool,
    /// How to read a headerless file.
    #[command(flatten)]
    pub raw: RawArgs,
}

/// Frames `start..end` (end excluded; `None`: to the last frame).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameRange {
    pub start: u32,
    pub end: Option<u32>,
}

fn parse_frames(s: &str) -> Result<FrameRange, String> {
    let bad = || format!("'{s}' is not a frame range: expected A..B, A..=B or A..");
    let (a, b) = s.split_once("..").ok_or_else(bad)?;
    let start: u32 = a.trim().parse().map_err(|_| bad())?;
    let end = match b.trim() {
        "" => None,
        b => Some(match b.strip_prefix('=') {
            Some(b) => b
                .trim()
                .parse::<u32>()
                .map_err(|_| bad())?
                .saturating_add(1),
            None => b.parse().map_err(|_| bad())?,
        }),
    };
    if end.is_some_and(|e| e <= start) {
        return Err(format!("frame range '{s}' is empty"));
    }
    Ok(FrameRange { start, end })
}

/// Raw sample order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum RawOrder {
    /// x changes fastest: index = (z·Y + y)·X + x (most published raw data).
    Xfast,
    /// z changes fastest: index = (x·Y + y)·Z + z (the .vol order).
    Zfast,
}

/// The description of a headerless (raw) file.
#[derive(Debug, Clone, Args)]
#[command(next_help_heading = "Raw files (no header)")]
pub struct RawArgs {
    /// Read FILE as raw samples with these dimensions (needs --raw-type).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_dims, requires = "raw_type")]
    pub raw_dims: Option<glam::UVec3>,
    /// Raw sample type: u8, i8, u16le, u16be, i16le, i16be, f32le, f32be.
    #[arg(long, value_name = "TYPE", value_parser = parse_raw_type, requires = "raw_dims")]
    pub raw_type: Option<(raycaster::sample::SampleType, raycaster::format::Endian)>,
    /// Raw voxel spacing.
    #[arg(long, value_name = "SX,SY,SZ", value_parser = parse_vec3, default_value = "1,1,1", requires = "raw_dims")]
    pub raw_spacing: Vec3,
    /// Bytes to skip at the start of a raw file.
    #[arg(long, value_name = "BYTES", default_value_t = 0, requires = "raw_dims")]
    pub raw_offset: u64,
    /// Which axis changes fastest in a raw file.
    #[arg(long, value_enum, default_value_t = RawOrder::Xfast, requires = "raw_dims")]
    pub raw_order: RawOrder,
}

impl RawArgs {
    /// The library's open options for these arguments.
    pub fn open_options(
        &self,
        mode: raycaster::storage::LoadMode,
    ) -> raycaster::format::OpenOptions {
        use raycaster::volume::AxisOrder;
        let raw = match (self.raw_dims, self.raw_type) {
            (Some(dims), Some((sample, endian))) => Some(raycaster::format::RawOptions {
                dims,
                sample,
                endian,
                spacing: self.raw_spacing,
                offset: self.raw_offset,
                order: match self.raw_order {
                    RawOrder::Xfast => AxisOrder::XFast,
                    RawOrder::Zfast => AxisOrder::ZFast,
                },
            }),
            _ => None,
        };
        raycaster::format::OpenOptions {
            mode,
            raw,
            progress: crate::progress::bar("decoding"),
            volume: 0,
            max_memory: None,
        }
    }
}

/// The library's scene options: the macrocell side, the cache unless
/// `no_cache`, and a progress bar for building the macrocell grid.
pub fn scene_options(macrocell: Option<u32>, no_cache: bool) -> raycaster::scene::SceneOptions {
    use raycaster::accel::cache::CachePolicy;
    raycaster::scene::SceneOptions {
        macrocell,
        cache: if no_cache {
            CachePolicy::Off
        } else {
            CachePolicy::Auto
        },
        cache_dir: None,
        progress: crate::progress::bar("building the macrocell grid"),
    }
}

/// `on` or `off`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Switch {
    /// Enabled.
    On,
    /// Disabled.
    Off,
}

impl Switch {
    pub fn on(self) -> bool {
        self == Switch::On
    }
}

/// Options of `vol_app render`.
#[derive(Debug, Args)]
#[command(
    after_help = "Vector options take comma-separated numbers, negative ones as they are: \
--camera-pos -120.5,40,300.\n\nExample (the seed thesis's benchmark frame):\n  vol_app render \
volumes/800shapes_block16.vol --size 700x700 --camera-pos 1100,1100,1100 --look-at 0,0,0 --fov 60 \
--step 0.2 --tf-preset shapes --repeat 5 --stats"
)]
pub struct RenderArgs {
    /// Volume file (.vol, .nrrd, .nhdr, .nii, .nii.gz, a DICOM directory or
    /// file, UC Davis .vol, or raw with --raw-dims/--raw-type) or sequence
    /// (.vseq, a 4-D file, a directory of frame files); a directory holding
    /// one volume file (beside a licence or readme) is that file; with --mode
    /// metaballs also a points file (.csv, .xyz: x,y,z[,radius[,value]] a
    /// line). Without it, the built-in demo volume is rendered.
    pub file: Option<PathBuf>,
    /// Output PNG (RGB8). Default: out.png, unless --stats is given. With
    /// --frames: the directory the frames go to (frame_0000.png, ...;
    /// default frames/, none with --stats); with --turntable: a directory
    /// (DIR/) or an animated GIF (FILE.gif).
    #[arg(long, value_name = "PNG")]
    pub out: Option<PathBuf>,
    /// The frame of a sequence to render (from 0).
    #[arg(long, value_name = "K", default_value_t = 0, conflicts_with = "frames")]
    pub frame: u32,
    /// Render frames A..B of a sequence (B excluded; A..=B includes it; A..
    /// runs to the end), decoding ahead while rendering; --out DIR/ writes
    /// one PNG per frame, --stats prints per-frame decode and render times.
    #[arg(long, value_name = "A..B", value_parser = parse_frames, conflicts_with_all = ["repeat", "progressive"])]
    pub frames: Option<FrameRange>,
    /// Render N frames of a turntable: the camera (--camera-pos, or the
    /// default) orbits the volume's centre about --axis, keeping its
    /// distance and elevation; --out DIR/ writes frame_0000.png, ...,
    /// --out FILE.gif one looping animated GIF.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=100_000), conflicts_with_all = ["frames", "repeat", "progressive", "stats"])]
    pub turntable: Option<u32>,
    /// The world axis the turntable turns about (right-handed).
    #[arg(long, value_enum, value_name = "x|y|z", default_value_t = vol_app::turntable::TurnAxis::Y, requires = "turntable")]
    pub axis: vol_app::turntable::TurnAxis,
    /// Frames per second of a turntable GIF (GIF delays are whole
    /// hundredths of a second: 25 is exact, 24 plays at 25).
    #[arg(
        long,
        value_name = "FPS",
        default_value_t = 25.0,
        requires = "turntable"
    )]
    pub fps: f32,
    /// Image size in pixels.
    #[arg(long, value_name = "WxH", default_value = "700x700", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Camera position (world units). Default: on the +z side of the volume's
    /// centre, far enough to see all of it.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true, value_parser = parse_vec3)]
    pub camera_pos: Option<Vec3>,
    /// Point the camera looks at. Default: the volume's centre.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true, value_parser = parse_vec3)]
    pub look_at: Option<Vec3>,
    /// Camera up vector.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true, value_parser = parse_vec3, default_value = "0,1,0")]
    pub up: Vec3,
    /// Vertical field of view in degrees (for --ortho it sizes the view).
    #[arg(long, value_name = "DEG", default_value_t = 45.0)]
    pub fov: f32,
    /// Orthographic projection instead of perspective.
    #[arg(long)]
    pub ortho: bool,
    /// Sampling step in world units. Default: half the smallest spacing.
    #[arg(long, value_name = "S")]
    pub step: Option<f32>,
    /// Transfer function JSON file (format in the README).
    #[arg(long, value_name = "FILE.json", conflicts_with = "tf_preset")]
    pub tf: Option<PathBuf>,
    /// Named transfer function: shapes, skull, ramp, ct-bone, ct-soft, mr-default.
    #[arg(long, value_name = "NAME")]
    pub tf_preset: Option<String>,
    /// Rendering mode.
    #[arg(long, value_enum, default_value_t = RenderMode::Dvr)]
    pub mode: RenderMode,
    /// Iso value for --mode iso. Default: the middle of the data's value range.
    #[arg(long, value_name = "V", allow_hyphen_values = true)]
    pub iso: Option<f32>,
    /// --mode metaballs: a voxel gives a ball when its value exceeds this
    /// (data units). Default: 30 % of the way up the data's value range
    /// (the seed's 0.3 of normalised intensity).
    #[arg(long, value_name = "T", allow_hyphen_values = true)]
    pub ball_threshold: Option<f32>,
    /// --mode metaballs: take every N-th voxel along each axis.
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub ball_stride: u32,
    /// --mode metaballs: ball radius in world units (a points file's radius
    /// column wins). Default: 1.5·stride·(largest voxel spacing) for a
    /// volume; for a points file 1.5 times the spacing of a cubic lattice of
    /// as many points filling their box.
    #[arg(long, value_name = "R", allow_hyphen_values = true)]
    pub ball_radius: Option<f32>,
    /// --mode metaballs: the kernel.
    #[arg(long, value_enum, default_value_t = Kernel::Wyvill)]
    pub kernel: Kernel,
    /// --mode metaballs: the surface is where the summed field equals this.
    #[arg(
        long,
        value_name = "T",
        default_value_t = 0.5,
        allow_hyphen_values = true
    )]
    pub field_threshold: f32,
    /// --mode metaballs: fail when the volume or file gives more balls than
    /// this (0 = no cap).
    #[arg(long, value_name = "N", default_value_t = 2_000_000)]
    pub max_balls: usize,
    /// Phong shading from gradients.
    #[arg(long, value_enum, default_value_t = Switch::On)]
    pub shading: Switch,
    /// --mode iso and metaballs: a directional light, the world direction towards it
    /// (repeat for more lights). Default: one headlight.
    #[arg(long = "light", value_name = "DX,DY,DZ", allow_hyphen_values = true, value_parser = parse_vec3)]
    pub lights: Vec<Vec3>,
    /// --mode iso and metaballs: cast a shadow ray towards each light from
    /// every hit (in iso mode none towards the headlight, which casts no
    /// shadow the eye can see).
    #[arg(long, value_enum, default_value_t = Switch::Off)]
    pub shadows: Switch,
    /// --mode iso: one mirror bounce; K (0..1) is the share of each hit's
    /// colour that the ray reflected about the normal sees (the surface,
    /// lit and shadowed as the primary hits are, or the background). 0 = off.
    #[arg(long, value_name = "K", default_value_t = 0.0)]
    pub reflection: f32,
    /// --mode iso: how the surface normal is found.
    #[arg(long, value_enum, default_value_t = IsoNormals::Gradient)]
    pub normals: IsoNormals,
    /// Keep only samples inside this world-space box (SPEC §8).
    #[arg(long, value_name = "X0,Y0,Z0,X1,Y1,Z1", allow_hyphen_values = true, value_parser = parse_clip_box)]
    pub clip_box: Option<(Vec3, Vec3)>,
    /// Remove samples at p with n·p > d (world space); repeat for up to 6
    /// planes.
    #[arg(long = "clip-plane", value_name = "NX,NY,NZ,D", allow_hyphen_values = true, value_parser = parse_clip_plane)]
    pub clip_planes: Vec<raycaster::clip::ClipPlane>,
    /// --mode dvr: scale the TF's opacity by clamp((|∇f| − G0)/(G1 − G0), 0, 1),
    /// |∇f| the gradient magnitude in data units per world unit.
    #[arg(long, value_name = "G0,G1", allow_hyphen_values = true, value_parser = parse_gradient_opacity)]
    pub gradient_opacity: Option<(f32, f32)>,
    /// Jitter the samples per pixel (trades wood-grain banding for noise).
    #[arg(long, value_enum, default_value_t = Switch::Off)]
    pub jitter: Switch,
    /// Seed of the per-pixel jitter.
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub seed: u32,
    /// Early ray termination.
    #[arg(long, value_enum, default_value_t = Switch::On)]
    pub ert: Switch,
    /// Opacity at which early ray termination stops a ray.
    #[arg(long, value_name = "A", default_value_t = 0.99)]
    pub ert_threshold: f32,
    /// Empty-space skipping.
    #[arg(long, value_enum, default_value_t = Switch::On)]
    pub ess: Switch,
    /// Which renderer schedules the rays.
    #[arg(long, value_enum, default_value_t = RendererKind::Tiles)]
    pub renderer: RendererKind,
    /// Threads in all (0 = all cores). The serial renderer always uses one.
    #[arg(long, value_name = "N", default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=1024))]
    pub threads: u32,
    /// Tile side in pixels for the tiles and object renderers (default: the
    /// renderer's measured default).
    #[arg(long, value_name = "PX", value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub tile: Option<u32>,
    /// Brick side in voxels for the object renderer (default: measured,
    /// whole storage bricks for a bricked file).
    #[arg(long, value_name = "VOXELS", value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub brick: Option<u32>,
    /// Object renderer: how many of the --threads only composite (0 = the
    /// render threads composite their own tasks).
    #[arg(long, value_name = "N", default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=1023))]
    pub composite_threads: u32,
    /// Object renderer: after a task a render thread continues with the same
    /// tile (tile-first, the default) or returns it to the shared queue.
    #[arg(long, value_enum, default_value_t = TaskOrder::TileFirst)]
    pub task_order: TaskOrder,
    /// Background colour, each channel 0..1.
    #[arg(long, value_name = "R,G,B", value_parser = parse_vec3, default_value = "0,0,0")]
    pub background: Vec3,
    /// Render N times after one warm-up and report the median.
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub repeat: u32,
    /// Print one JSON object of timings and counters on stdout.
    #[arg(long)]
    pub stats: bool,
    /// Render what the viewer renders: N preview frames of a camera
    /// orbiting 2° per frame, each at the size and step the viewer's
    /// picker chooses from the frames timed before it, then the refinement
    /// (1/4, 1/2, full resolution) once still; reports each frame's time.
    /// --out saves the final frame.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=100_000), conflicts_with = "repeat")]
    pub progressive: Option<u32>,
    /// Read the file into RAM instead of memory-mapping it.
    #[arg(long)]
    pub in_ram: bool,
    /// Macrocell side in voxels for empty-space skipping (default: the
    /// volume's own choice).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub macrocell: Option<u32>,
    /// Neither read nor write the macrocell cache (FILE.m<N>.rcidx, kept
    /// next to the volume or in the per-user cache directory): build the
    /// value ranges from the samples.
    #[arg(long)]
    pub no_cache: bool,
    /// Sort-last distributed rendering under MPI (`mpirun -n P vol_app
    /// render FILE --distributed ...`): each rank reads and renders one
    /// part of the volume, rank 0 composites and writes the PNG and
    /// --stats. Needs a vol_app built with the mpi feature (`cargo build
    /// --release --workspace --features vol_app/mpi`).
    #[arg(long, conflicts_with_all = ["frames", "turntable", "progressive"])]
    pub distributed: bool,
    /// With --distributed: read only each rank's part of the file (part;
    /// .vol, raw NRRD and NIfTI) or the whole file on every rank (whole;
    /// any format, e.g. gzip-compressed).
    #[arg(
        long,
        value_name = "HOW",
        default_value = "part",
        requires = "distributed"
    )]
    pub distributed_read: raycaster::distributed::ReadPolicy,
    /// With --distributed: what the k-d split of the volume balances.
    /// occupancy: the macrocells the frame's TF (iso value, clipping)
    /// leaves occupied, from the volume's macrocell cache (written by the
    /// first run, or by any open without --no-cache) or else a first pass
    /// in which each rank reads a voxel-balanced part; voxels: voxel count
    /// alone, no first pass.
    #[arg(
        long,
        value_name = "WHAT",
        default_value = "occupancy",
        requires = "distributed"
    )]
    pub balance: raycaster::distributed::Balance,
    /// With --distributed: how the ranks' partial images are composited.
    /// gather: all to rank 0, which merges them; direct-send: each rank
    /// owns a band of rows and merges the fragments the others send it,
    /// rank 0 gathers the finished bands; binary-swap: log2(P) pairwise
    /// exchanges of image halves along the k-d tree (P a power of two,
    /// otherwise direct send). Default direct-send: of direct send and
    /// binary swap the faster at P = 4 in the README's measurements, and
    /// it works for any P.
    #[arg(
        long,
        value_name = "HOW",
        default_value = "direct-send",
        requires = "distributed"
    )]
    pub composite: raycaster::distributed::CompositeMethod,
    /// How to read a headerless file.
    #[command(flatten)]
    pub raw: RawArgs,
}

/// Parses the command line; on error prints one line (or the help text) and
/// returns the exit code.
pub fn parse() -> Result<Cli, ExitCode> {
    let mut cli = Cli::try_parse().map_err(|e| raycaster::cli::parse_failure("vol_app", &e))?;
    // A folder holding one volume file (a scan beside its licence or
    // readme) stands for that file.
    let resolve = |path: &mut PathBuf| {
        if let std::borrow::Cow::Owned(file) = raycaster::sequence::resolve_dir(path) {
            *path = file;
        }
    };
    match &mut cli.command {
        Some(Command::Render(args)) => args.file.iter_mut().for_each(resolve),
        Some(Command::Info(args)) => resolve(&mut args.file),
        Some(Command::Convert(args)) => resolve(&mut args.input),
        Some(Command::Pack(args)) => resolve(&mut args.input),
        None => cli.viewer.file.iter_mut().for_each(resolve),
    }
    Ok(cli)
}

fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!("expected three comma-separated numbers, got '{s}'"));
    }
    let mut v = [0.0f32; 3];
    for (o, p) in v.iter_mut().zip(&parts) {
        *o = p
            .parse::<f32>()
            .map_err(|_| format!("'{p}' is not a number"))?;
        if !o.is_finite() {
            return Err(format!("'{p}' is not a finite number"));
        }
    }
    Ok(Vec3::from_array(v))
}

/// `n` comma-separated finite numbers.
fn parse_numbers(s: &str, n: usize, what: &str) -> Result<Vec<f32>, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != n {
        return Err(format!("expected {what}, got '{s}'"));
    }
    parts
        .iter()
        .map(|p| {
            p.parse::<f32>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("'{p}' is not a finite number"))
        })
        .collect()
}

fn parse_clip_box(s: &str) -> Result<(Vec3, Vec3), String> {
    let v = parse_numbers(s, 6, "six numbers X0,Y0,Z0,X1,Y1,Z1")?;
    let (lo, hi) = (Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]));
    if lo.cmpgt(hi).any() {
        return Err(format!(
            "the box is empty: X0,Y0,Z0 = {},{},{} must not exceed X1,Y1,Z1 = {},{},{}",
            v[0], v[1], v[2], v[3], v[4], v[5]
        ));
    }
    Ok((lo, hi))
}

fn parse_clip_plane(s: &str) -> Result<raycaster::clip::ClipPlane, String> {
    let v = parse_numbers(s, 4, "four numbers NX,NY,NZ,D")?;
    let normal = Vec3::new(v[0], v[1], v[2]);
    if normal == Vec3::ZERO {
        return Err("the normal NX,NY,NZ must not be zero".into());
    }
    Ok(raycaster::clip::ClipPlane {
        normal,
        offset: v[3],
    })
}

/// A size in GiB: finite and positive.
fn parse_positive_gib(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("'{s}' is not a positive number of GiB")),
    }
}

fn parse_gradient_opacity(s: &str) -> Result<(f32, f32), String> {
    let v = parse_numbers(s, 2, "two numbers G0,G1")?;
    if v[0] >= v[1] {
        return Err(format!("G0 = {} must be below G1 = {}", v[0], v[1]));
    }
    Ok((v[0], v[1]))
}

fn parse_window(s: &str) -> Result<(f32, f32), String> {
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| format!("expected LO,HI, got '{s}'"))?;
    let p = |t: &str| {
        t.trim()
            .parse::<f32>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("'{t}' is not a finite number"))
    };
    let (lo, hi) = (p(a)?, p(b)?);
    if hi <= lo {
        return Err(format!("window {lo},{hi} is empty (LO must be below HI)"));
    }
    Ok((lo, hi))
}

fn parse_dims(s: &str) -> Result<glam::UVec3, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let v: Vec<u32> = parts
        .iter()
        .map(|p| p.parse::<u32>().ok().filter(|&d| d >= 1))
        .collect::<Option<_>>()
        .filter(|v: &Vec<u32>| v.len() == 3)
        .ok_or_else(|| format!("expected three positive integers X,Y,Z, got '{s}'"))?;
    Ok(glam::UVec3::new(v[0], v[1], v[2]))
}

fn parse_raw_type(
    s: &str,
) -> Result<(raycaster::sample::SampleType, raycaster::format::Endian), String> {
    raycaster::format::RawOptions::parse_type(s).ok_or_else(|| {
        format!("unknown raw type '{s}' (known: u8, i8, u16le, u16be, i16le, i16be, f32le, f32be)")
    })
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WIDTHxHEIGHT, got '{s}'"))?;
    let p = |t: &str| {
        t.trim()
            .parse::<u32>()
            .ok()
            .filter(|&v| (1..=16384).contains(&v))
            .ok_or_else(|| format!("'{t}' is not a size in 1..=16384"))
    };
    Ok((p(w)?, p(h)?))
}

/// Prints each of `warnings` on stderr as `vol_app: warning: ...`.
pub fn warn_all(warnings: &[String]) {
    for w in warnings {
        eprintln!("vol_app: warning: {w}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vectors_accept_negative_numbers() {
        assert_eq!(
            parse_vec3("-120.5,40,300").unwrap(),
            Vec3::new(-120.5, 40.0, 300.0)
        );
        assert!(parse_vec3("1,2").is_err());
        assert!(parse_vec3("1,2,x").is_err());
        assert!(parse_vec3("1,2,inf").is_err());
        assert_eq!(parse_size("700x500").unwrap(), (700, 500));
        assert!(parse_size("0x5").is_err());
    }

    #[test]
    fn negative_camera_position_parses_as_a_value() {
        let cli = Cli::try_parse_from([
            "vol_app",
            "render",
            "f.vol",
            "--camera-pos",
            "-1,-2,-3",
            "--iso",
            "-5",
        ])
        .unwrap();
        let Some(Command::Render(a)) = cli.command else {
            panic!()
        };
        assert_eq!(a.camera_pos, Some(Vec3::new(-1.0, -2.0, -3.0)));
        assert_eq!(a.iso, Some(-5.0));
    }

    #[test]
    fn a_file_without_a_subcommand_is_for_the_viewer() {
        let cli = Cli::try_parse_from(["vol_app", "head.vol", "--tf-preset", "skull"]).unwrap();
        assert!(cli.command.is_none());
        assert_eq!(cli.viewer.file, Some(PathBuf::from("head.vol")));
        assert_eq!(cli.viewer.tf_preset.as_deref(), Some("skull"));
        let cli = Cli::try_parse_from(["vol_app"]).unwrap();
        assert!(cli.command.is_none() && cli.viewer.file.is_none());
        let cli = Cli::try_parse_from(["vol_app", "render", "x.vol"]).unwrap();
        assert!(matches!(cli.command, Some(Command::Render(_))));
    }
}
