//! The command line, parsed with `clap`, and its validation into a
//! [`Config`]. The reference implementation's spellings are accepted as they
//! are: `--dims=X,Y,Z`, `--layout z` (bricked) and `-o` for `--output-file`.

use std::path::PathBuf;

use clap::{Parser, ValueEnum};
use glam::{UVec3, Vec3};
use raycaster::format::vol::{VolHeader, VolLayout};

use crate::error::{Error, Result};
use crate::generators::{GeneratorKind, Setup};

const AFTER_HELP: &str = "\
Generators and the options they use (defaults in brackets):
  shapes     --n-of-shapes [20] random spheres and axis-aligned cuboids whose
             diameter or sides are 0.5..1.5 x --object-size [32] voxels, placed
             inside the volume. Each shape has one value drawn uniformly from
             --sample [100] +-8; under the `shapes` transfer function values
             < 95 are nearly transparent, 95..99 translucent, >= 100 opaque.
             Later shapes cover earlier ones.
  solid      every voxel is --sample [100].
  noise      smooth fractal value noise in 0..=--sample [255]: --octaves [4]
             layers, the first with lattice cells of --object-size [32] voxels.
  sphere     a ball centred in the volume, --sample [255] at the centre falling
             smoothly to 0 at its surface; diameter --object-size [smallest
             extent].
  sdf        signed distance field of a CSG scene (cube & ball minus three
             cylinders, plus a torus), --object-size [smallest extent] across:
             128 on the surface, larger inside, +-128 over --band [8] voxels.
             Render it with --mode iso --iso 128. Does not use the seed.
  metaballs  --n-of-shapes [12] balls of Wyvill-kernel density with radii of
             0.5..1.5 x --object-size/2 [smallest extent / 4]; value =
             256 x density, so the iso surface density 1/2 is 128.
  mesh       signed distance field of the triangle mesh --mesh FILE (.obj,
             .ply ascii/binary, .stl ascii/binary): f32 samples, negative
             inside, written as NRRD or NIfTI (name the output .nrrd, .nii or
             .nii.gz; .vol cannot hold it). The mesh is scaled uniformly and
             centred so that its bounding box fits the grid with --margin [3]
             voxels to spare on the tightest axis. Distances are in the mesh's
             units and the file's spacing is the voxel size in mesh units, so
             world space is the mesh's (shifted: voxel 0,0,0 is at the mesh
             point printed). Exact distance to the nearest triangle; the sign
             is the majority of ray-crossing parities along x, y and z, so
             small holes do not flip it. Render it with --mode iso --iso 0.
             --shape, --layout and --seed are not used.
  plume      a time series of --frames [1] f32 frames mimicking a rocket
             engine's exhaust: a hot jet leaves a nozzle (diameter
             --object-size [0.4 x half the smaller of the y and z extents])
             in the middle of the x = 0 face, its front crossing the volume in about
             100 frames; it widens and cools downstream, snakes, sheds puffs,
             and --octaves [4] of noise carried with the flow stir it. Values
             in --value-range [0.99,1.5]: ambient gas just above LO (~1.0),
             the hottest plume near HI. Consecutive frames are close, and
             frame k depends only on k, --seed, --dims, --shape and these
             options, so a shorter run gives the first frames of a longer
             one. -o DIR/ (or any name without a volume extension) writes
             DIR/frame_0000.nrrd, frame_0001.nrrd, ... (raw f32 NRRD, name
             order = frame order); DIR must be empty or new unless --force,
             which also removes older frame_*.nrrd files beyond the new
             count. -o FILE.vseq packs every frame into one .vseq sequence
             (LZ4, lossless; repack with `vol_app pack` for zstd or f16).
             One frame may also go to a .nrrd, .nii or .nii.gz file.
             --layout, --sample and --n-of-shapes are not used.
Sizes of sphere, sdf, metaballs, noise and plume are in units of the finest spacing,
so objects stay round in world space whatever --shape is.

Layouts: linear (z fastest) or bricked (alias z): cubic bricks of --block-size
B in 2..=255 overlapping by one voxel (the .vol format in the README).

The same arguments and --seed give the same bytes, whatever the thread count;
without --seed a random seed is used and printed (but not with --quiet). The
file is written under a temporary name in the same directory and renamed when
complete; Ctrl-C or an error leaves no file behind (plume: each frame so, and
an error or Ctrl-C removes the frames already written).

Example (150 frames of a simulated exhaust plume, 1.2 GiB):
  vol_gen --dims 128,128,128 --generator plume --frames 150 --seed 1 \\
      -o volumes/plume/

Example (a distance field of a mesh):
  vol_gen --dims 129,129,101 --generator mesh --mesh tests/data/bunny.ply \\
      -o volumes/bunny_sdf.nrrd

Example (the seed thesis's benchmark volume):
  vol_gen --dims=800,800,800 --generator shapes --seed 2 --n-of-shapes 70 \\
      --sample 100 --output-file volumes/800shapes_block16.vol --layout z \\
      --block-size 16 --object-size 70";

/// Sample order of the output file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LayoutArg {
    /// One array, z fastest
    #[value(alias = "slices")]
    Linear,
    /// Overlapping cubic bricks of --block-size (the reference spelling is `z`)
    #[value(aliases = ["z", "block", "blocks", "brick"])]
    Bricked,
}

/// `vol_gen`'s arguments as given.
#[derive(Debug, Clone, Parser)]
#[command(
    name = "vol_gen",
    version,
    about = "Generates test volumes in the .vol format (26-byte header + u8 samples, linear or bricked), \
             signed distance fields of triangle meshes (f32 NRRD or NIfTI) and a time series \
             (--generator plume --frames N: a directory of f32 NRRD frames).",
    after_help = AFTER_HELP
)]
pub struct Cli {
    /// Volume dimensions in voxels, each at least 1
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_dims)]
    pub dims: UVec3,

    /// What to generate (see below)
    #[arg(long, short = 'g', value_enum)]
    pub generator: GeneratorKind,

    /// Sample order of the file
    #[arg(long, value_enum, default_value = "linear")]
    pub layout: LayoutArg,

    /// Brick side B for the bricked layout
    #[arg(long, value_name = "B", default_value_t = 16,
          value_parser = clap::value_parser!(u8).range(2..=255))]
    pub block_size: u8,

    /// Voxel spacing (the cell shape), each finite and > 0
    #[arg(long, visible_alias = "spacing", value_name = "SX,SY,SZ",
          default_value = "1,1,1", value_parser = parse_spacing)]
    pub shape: Vec3,

    /// Seed of every random choice [default: random, printed]
    #[arg(long, value_name = "N")]
    pub seed: Option<u64>,

    /// Output file
    #[arg(
        short = 'o',
        long = "output-file",
        value_name = "FILE",
        default_value = "volume.vol"
    )]
    pub output_file: PathBuf,

    /// Number of objects (shapes, metaballs)
    #[arg(long = "n-of-shapes", value_name = "N")]
    pub n_of_shapes: Option<u32>,

    /// Object size in voxels (meaning per generator, see below)
    #[arg(long, value_name = "N")]
    pub object_size: Option<u32>,

    /// Sample value (meaning per generator, see below)
    #[arg(long, value_name = "V")]
    pub sample: Option<u8>,

    /// Noise octaves, 1..=16 (noise, plume)
    #[arg(long, value_name = "N")]
    pub octaves: Option<u32>,

    /// SDF band: distance in voxels over which values go from 128 to 0 or 255
    #[arg(long, value_name = "VOXELS")]
    pub band: Option<f32>,

    /// Frames of the time series (plume only): -o names a directory
    #[arg(long, value_name = "N", default_value_t = 1,
          value_parser = clap::value_parser!(u32).range(1..))]
    pub frames: u32,

    /// Value range of --generator plume: ambient just above LO, hottest HI
    #[arg(long, value_name = "LO,HI", value_parser = parse_range)]
    pub value_range: Option<(f32, f32)>,

    /// Triangle mesh for --generator mesh (.obj, .ply or .stl)
    #[arg(long, value_name = "FILE")]
    pub mesh: Option<PathBuf>,

    /// Voxels between the mesh's bounding box and the grid's faces on the tightest axis (mesh)
    #[arg(long, value_name = "N", default_value_t = crate::mesh::field::DEFAULT_MARGIN)]
    pub margin: u32,

    /// Overwrite FILE if it exists
    #[arg(long, short = 'f')]
    pub force: bool,

    /// Print nothing but errors: no progress bar, summary or random seed
    #[arg(long, short = 'q')]
    pub quiet: bool,

    /// Worker threads [default: all cores]
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,
}

/// A validated run.
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    /// The file's header (dimensions, spacing, layout).
    pub header: VolHeader,
    /// Which generator.
    pub generator: GeneratorKind,
    /// Its parameters, with the seed.
    pub setup: Setup,
    /// Whether the seed was chosen at random.
    pub seed_was_random: bool,
    /// Output path.
    pub output: PathBuf,
    /// Overwrite an existing file.
    pub force: bool,
    /// Print nothing but errors (no progress bar, summary or random seed).
    pub quiet: bool,
    /// Worker threads, or all cores.
    pub threads: Option<usize>,
    /// The mesh of `--generator mesh`.
    pub mesh: Option<PathBuf>,
    /// `--margin`, in voxels.
    pub margin: u32,
    /// `--frames`: 1 except for a time series.
    pub frames: u32,
}

impl Config {
    /// Checks `cli` and fills in the seed.
    pub fn from_cli(cli: Cli) -> Result<Config> {
        let layout = match cli.layout {
            LayoutArg::Linear => VolLayout::Linear,
            LayoutArg::Bricked => VolLayout::Bricked {
                side: cli.block_size,
            },
        };
        let header = VolHeader {
            dims: cli.dims,
            spacing: cli.shape,
            layout,
        };
        // Rejects sizes that overflow u64 (message names the dimensions).
        header
            .file_len()
            .map_err(|e| Error::Usage(format!("--dims: {e}")))?;
        match (cli.generator, &cli.mesh) {
            (GeneratorKind::Mesh, None) => {
                return Err(Error::Usage(
                    "--generator mesh needs --mesh FILE (.obj, .ply or .stl)".into(),
                ));
            }
            (g, Some(_)) if g != GeneratorKind::Mesh => {
                return Err(Error::Usage(format!(
                    "--mesh is for --generator mesh, not {}",
                    g.name()
                )));
            }
            _ => {}
        }
        if cli.frames > 1 && cli.generator != GeneratorKind::Plume {
            return Err(Error::Usage(format!(
                "--frames {}: only --generator plume makes a time series; {} writes one volume",
                cli.frames,
                cli.generator.name()
            )));
        }
        if cli.value_range.is_some() && cli.generator != GeneratorKind::Plume {
            return Err(Error::Usage(format!(
                "--value-range is for --generator plume, not {}",
                cli.generator.name()
            )));
        }
        let seed_was_random = cli.seed.is_none() && cli.generator != GeneratorKind::Mesh;
        let seed = cli.seed.unwrap_or_else(|| fastrand::u64(..));
        Ok(Config {
            header,
            generator: cli.generator,
            setup: Setup {
                dims: cli.dims,
                spacing: cli.shape,
                seed,
                n_of_shapes: cli.n_of_shapes,
                object_size: cli.object_size,
                sample: cli.sample,
                octaves: cli.octaves,
                band: cli.band,
                value_range: cli.value_range,
            },
            seed_was_random,
            output: cli.output_file,
            force: cli.force,
            quiet: cli.quiet,
            threads: cli.threads.map(usize::from),
            mesh: cli.mesh,
            margin: cli.margin,
            frames: cli.frames,
        })
    }
}

/// Three comma-separated numbers.
fn parse_three<T: std::str::FromStr>(s: &str, what: &str) -> std::result::Result<[T; 3], String>
where
    T::Err: std::fmt::Display,
{
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!(
            "expected three {what} separated by commas, got {}",
            parts.len()
        ));
    }
    let mut out = Vec::with_capacity(3);
    for p in parts {
        out.push(p.parse::<T>().map_err(|e| format!("'{p}': {e}"))?);
    }
    out.try_into()
        .map_err(|_| "expected three values".to_string())
}

/// `X,Y,Z`, each in 1..=u32::MAX.
pub fn parse_dims(s: &str) -> std::result::Result<UVec3, String> {
    let d = parse_three::<u32>(s, "dimensions")?;
    for (axis, &v) in ['X', 'Y', 'Z'].iter().zip(&d) {
        if v == 0 {
            return Err(format!(
                "dimension {axis} is 0 (every dimension must be at least 1)"
            ));
        }
    }
    Ok(UVec3::from_array(d))
}

/// `LO,HI`, finite with LO < HI.
pub fn parse_range(s: &str) -> std::result::Result<(f32, f32), String> {
    let (lo, hi) = s
        .split_once(',')
        .ok_or_else(|| format!("expected LO,HI, got '{s}'"))?;
    let parse = |p: &str| {
        p.trim()
            .parse::<f32>()
            .map_err(|e| format!("'{}': {e}", p.trim()))
    };
    let (lo, hi) = (parse(lo)?, parse(hi)?);
    if !(lo.is_finite() && hi.is_finite() && lo < hi) {
        return Err(format!("{lo},{hi}: need finite LO < HI"));
    }
    Ok((lo, hi))
}

/// `SX,SY,SZ`, each finite and > 0.
pub fn parse_spacing(s: &str) -> std::result::Result<Vec3, String> {
    let v = parse_three::<f32>(s, "spacings")?;
    for (axis, &x) in ['X', 'Y', 'Z'].iter().zip(&v) {
        if !(x.is_finite() && x > 0.0) {
            return Err(format!(
                "spacing {axis} is {x} (must be finite and greater than 0)"
            ));
        }
    }
    Ok(Vec3::from_array(v))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(args: &[&str]) -> std::result::Result<Cli, clap::Error> {
        Cli::try_parse_from(std::iter::once("vol_gen").chain(args.iter().copied()))
    }

    /// The example at the end of `--help` (the benchmark volume's command), as
    /// arguments after the program name.
    fn help_example() -> Vec<&'static str> {
        let (_, example) = AFTER_HELP
            .split_once("Example (the seed thesis's benchmark volume):")
            .expect("the help ends with an example");
        let mut words = example.split_whitespace().filter(|w| *w != "\\");
        assert_eq!(words.next(), Some("vol_gen"));
        words.collect()
    }

    #[test]
    fn thesis_spellings() {
        let cli = parse(&help_example()).unwrap();
        let c = Config::from_cli(cli).unwrap();
        assert_eq!(c.header.dims, UVec3::splat(800));
        assert_eq!(c.header.layout, VolLayout::Bricked { side: 16 });
        assert_eq!(c.setup.seed, 2);
        assert!(!c.seed_was_random);
        assert_eq!(c.setup.n_of_shapes, Some(70));
        assert_eq!(c.setup.object_size, Some(70));
        assert_eq!(c.setup.sample, Some(100));
        assert_eq!(c.output, PathBuf::from("volumes/800shapes_block16.vol"));
        let cli = parse(&[
            "--dims", "4,5,6", "-g", "solid", "-o", "x.vol", "--shape", "1,2,0.5",
        ])
        .unwrap();
        let c = Config::from_cli(cli).unwrap();
        assert_eq!(c.header.layout, VolLayout::Linear);
        assert_eq!(c.header.spacing, Vec3::new(1.0, 2.0, 0.5));
        assert!(c.seed_was_random);
    }

    #[test]
    fn bad_values() {
        for args in [
            &["--dims", "0,5,5", "-g", "solid"][..],
            &["--dims", "5,5", "-g", "solid"],
            &["--dims", "5,5,x", "-g", "solid"],
            &["--dims", "5,5,5", "-g", "solid", "--shape", "1,NaN,1"],
            &["--dims", "5,5,5", "-g", "solid", "--shape", "1,-1,1"],
            &["--dims", "5,5,5", "-g", "solid", "--shape", "1,inf,1"],
            &["--dims", "5,5,5", "-g", "solid", "--block-size", "1"],
            &["--dims", "5,5,5", "-g", "solid", "--block-size", "256"],
            &["--dims", "5,5,5", "-g", "cubes"],
            &["--dims", "5,5,5", "-g", "solid", "--layout", "q"],
        ] {
            assert!(parse(args).is_err(), "{args:?}");
        }
        let cli = parse(&["--dims", "4294967295,4294967295,4294967295", "-g", "solid"]).unwrap();
        let err = Config::from_cli(cli).unwrap_err();
        assert!(err.to_string().contains("overflow"), "{err}");
    }
}
