//! [`Balls`]: the particles of a metaball scene, from a volume (one ball per
//! voxel above a threshold) or from a points file (`.csv`, `.xyz`).

use std::path::Path;

use glam::{UVec3, Vec3};

use crate::error::{Error, Result};
use crate::geometry::Aabb;
use crate::sample::Sample;
use crate::volume::{AnyVolume, Volume, VolumeVisitor};

/// One ball: centre and radius (world units) and the value its colour is
/// looked up from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ball {
    /// Centre.
    pub center: Vec3,
    /// Radius of the kernel's support (`K = 0` beyond it), > 0.
    pub radius: f32,
    /// Data value (the voxel's, or the points file's `value` column; 0
    /// when there is none).
    pub value: f32,
}

/// The balls of a scene, in a fixed order (which makes frames
/// deterministic).
#[derive(Debug, Clone, Default)]
pub struct Balls {
    balls: Vec<Ball>,
    has_values: bool,
    /// Unique to the set made (its clones share it; the balls never change
    /// after), so a renderer can keep what it built from them.
    id: u64,
}

impl PartialEq for Balls {
    fn eq(&self, other: &Self) -> bool {
        self.has_values == other.has_values && self.balls == other.balls
    }
}

/// A new [`Balls::id`]; 0 is the default (empty) set's.
fn next_id() -> u64 {
    use std::sync::atomic::{AtomicU64, Ordering};
    static NEXT: AtomicU64 = AtomicU64::new(1);
    NEXT.fetch_add(1, Ordering::Relaxed)
}

/// How a volume becomes balls: one at the centre of every `stride`-th voxel
/// per axis whose value exceeds `threshold`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extraction {
    /// A voxel gives a ball when its value is greater than this (data units).
    pub threshold: f32,
    /// Take every `stride`-th voxel along each axis (>= 1).
    pub stride: u32,
    /// Ball radius in world units; `None`: [`Extraction::default_radius`].
    pub radius: Option<f32>,
    /// Fail when more balls than this would be made.
    pub max_balls: Option<usize>,
}

impl Extraction {
    /// The default radius for a grid of `spacing`: 1.5 times the distance
    /// between neighbouring balls along the coarsest axis
    /// (`1.5·stride·max spacing`), so that neighbours overlap and a solid
    /// region gives one surface.
    pub fn default_radius(spacing: Vec3, stride: u32) -> f32 {
        1.5 * stride.max(1) as f32 * spacing.max_element()
    }
}

/// The extensions of points files.
pub const POINTS_EXTENSIONS: [&str; 2] = ["csv", "xyz"];

impl Balls {
    /// Balls as given; `has_values` says whether their values mean anything
    /// (without, they are drawn white). Fails on a non-finite centre or a
    /// radius that is not finite and > 0.
    pub fn new(balls: Vec<Ball>, has_values: bool) -> Result<Self> {
        for (i, b) in balls.iter().enumerate() {
            if !(b.center.is_finite() && b.radius.is_finite() && b.radius > 0.0) {
                return Err(Error::option(
                    "balls",
                    format!(
                        "ball {i}: centre {} and radius {} must be finite, the radius > 0",
                        b.center, b.radius
                    ),
                ));
            }
        }
        Ok(Balls {
            balls,
            has_values,
            id: next_id(),
        })
    }

    /// Which set these are: equal for a set and its clones, different for
    /// sets made separately.
    pub fn id(&self) -> u64 {
        self.id
    }

    /// The balls.
    pub fn as_slice(&self) -> &[Ball] {
        &self.balls
    }

    /// How many.
    pub fn len(&self) -> usize {
        self.balls.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.balls.is_empty()
    }

    /// Whether the balls carry data values (their colour then comes from the
    /// transfer function).
    pub fn has_values(&self) -> bool {
        self.has_values
    }

    /// The box holding every ball's support, `None` when there are none.
    pub fn bounds(&self) -> Option<Aabb> {
        let mut it = self.balls.iter();
        let first = it.next()?;
        let r = Vec3::splat(first.radius);
        let (lo, hi) = it.fold((first.center - r, first.center + r), |(lo, hi), b| {
            let r = Vec3::splat(b.radius);
            (lo.min(b.center - r), hi.max(b.center + r))
        });
        Some(Aabb::new(lo, hi))
    }

    /// One ball at every `stride`-th voxel (per axis, from voxel 0) whose
    /// value exceeds the threshold, at the voxel's world position, with the
    /// voxel's value. Voxels are taken x slowest, z fastest.
    pub fn from_volume(volume: &AnyVolume, ex: &Extraction) -> Result<Self> {
        if ex.stride == 0 {
            return Err(Error::option("ball-stride", "must be at least 1"));
        }
        if !ex.threshold.is_finite() {
            return Err(Error::option("ball-threshold", "must be finite"));
        }
        let grid = *volume.grid();
        let radius = ex
            .radius
            .unwrap_or_else(|| Extraction::default_radius(grid.spacing, ex.stride));
        if !(radius.is_finite() && radius > 0.0) {
            return Err(Error::option(
                "ball-radius",
                format!("{radius} must be finite and > 0"),
            ));
        }
        struct Extract<'a> {
            ex: &'a Extraction,
            radius: f32,
        }
        impl VolumeVisitor for Extract<'_> {
            type Output = std::result::Result<Vec<Ball>, usize>;
            fn visit<V: Volume>(self, volume: &V) -> Self::Output {
                let grid = volume.grid();
                let cap = self.ex.max_balls.unwrap_or(usize::MAX);
                let s = self.ex.stride as usize;
                let mut out = Vec::new();
                for x in (0..grid.dims.x).step_by(s) {
                    for y in (0..grid.dims.y).step_by(s) {
                        for z in (0..grid.dims.z).step_by(s) {
                            let v = UVec3::new(x, y, z);
                            let value = volume.voxel(v).to_f32();
                            if value > self.ex.threshold {
                                if out.len() == cap {
                                    return Err(cap);
                                }
                                out.push(Ball {
                                    center: grid.voxel_to_world(v.as_vec3()),
                                    radius: self.radius,
                                    value,
                                });
                            }
                        }
                    }
                }
                Ok(out)
            }
        }
        match volume.visit(Extract { ex, radius }) {
            Ok(balls) => Ok(Balls {
                balls,
                has_values: true,
                id: next_id(),
            }),
            Err(cap) => Err(Error::TooManyBalls {
                what: format!(
                    "the volume (--ball-threshold {}, --ball-stride {})",
                    ex.threshold, ex.stride
                ),
                cap,
                hint: "raise --ball-threshold or --ball-stride, or the cap",
            }),
        }
    }

    /// True when `path` names a points file (extension `.csv` or `.xyz`,
    /// any case).
    pub fn is_points_file(path: &Path) -> bool {
        path.extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| POINTS_EXTENSIONS.iter().any(|p| e.eq_ignore_ascii_case(p)))
    }

    /// Reads a points file: see [`Balls::parse_points`].
    pub fn read_points(path: &Path, radius: Option<f32>, max_balls: Option<usize>) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Self::parse_points(&text, path, radius, max_balls)
    }

    /// Parses a points file (`path` only names it in errors): one ball a
    /// line, `x y z [radius [value]]`, the fields separated by commas
    /// and/or white space. Blank lines and lines starting with `#` or `//`
    /// are skipped, and so is a header line of names (`x,y,z,...`) before
    /// the first ball. A line without a radius takes `radius`, or when that
    /// is `None` 1.5 times the spacing of a cubic lattice of as many points
    /// spanning the points' box (`1.5·max extent/(∛n − 1)`; 1 for a lone
    /// point). Either every ball has a value or none has. A bad line fails
    /// with its number.
    pub fn parse_points(
        text: &str,
        path: &Path,
        radius: Option<f32>,
        max_balls: Option<usize>,
    ) -> Result<Self> {
        let bad = |line: usize, message: String| Error::Points {
            path: path.to_path_buf(),
            line,
            message,
        };
        if let Some(r) = radius
            && !(r.is_finite() && r > 0.0)
        {
            return Err(Error::option(
                "ball-radius",
                format!("{r} must be finite and > 0"),
            ));
        }
        let cap = max_balls.unwrap_or(usize::MAX);
        // (centre, radius if given, value if given)
        let mut rows: Vec<(Vec3, Option<f32>, Option<f32>)> = Vec::new();
        let mut values_line: Option<(usize, bool)> = None;
        let mut fields = Vec::with_capacity(5);
        for (n, raw) in text.lines().enumerate() {
            let line_no = n + 1;
            let line = raw.trim();
            if line.is_empty() || line.starts_with('#') || line.starts_with("//") {
                continue;
            }
            fields.clear();
            fields.extend(
                line.split(|c: char| c == ',' || c.is_whitespace())
                    .filter(|f| !f.is_empty()),
            );
            if rows.is_empty()
                && values_line.is_none()
                && fields
                    .iter()
                    .all(|f| f.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_'))
                && !fields.iter().any(|f| f.parse::<f32>().is_ok())
            {
                // A header of column names.
                continue;
            }
            if !(3..=5).contains(&fields.len()) {
                return Err(bad(
                    line_no,
                    format!(
                        "expected x,y,z[,radius[,value]] (3 to 5 numbers), found {} fields",
                        fields.len()
                    ),
                ));
            }
            let mut nums = [0.0f32; 5];
            for (o, f) in nums.iter_mut().zip(&fields) {
                *o = f
                    .parse::<f32>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| bad(line_no, format!("'{f}' is not a finite number")))?;
            }
            let r = (fields.len() >= 4).then_some(nums[3]);
            if let Some(r) = r
                && r <= 0.0
            {
                return Err(bad(line_no, format!("radius {r} must be > 0")));
            }
            let has_value = fields.len() == 5;
            match values_line {
                None => values_line = Some((line_no, has_value)),
                Some((first, v)) if v != has_value => {
                    return Err(bad(
                        line_no,
                        format!(
                            "{} a value but line {first} {} (every ball has a value or none has)",
                            if has_value { "gives" } else { "lacks" },
                            if v { "gives one" } else { "does not" }
                        ),
                    ));
                }
                Some(_) => {}
            }
            if rows.len() == cap {
                return Err(Error::TooManyBalls {
                    what: path.display().to_string(),
                    cap,
                    hint: "raise the cap",
                });
            }
            rows.push((
                Vec3::new(nums[0], nums[1], nums[2]),
                r,
                has_value.then_some(nums[4]),
            ));
        }
        let default_radius = radius.unwrap_or_else(|| lattice_radius(&rows));
        let has_values = values_line.is_some_and(|(_, v)| v);
        let balls = rows
            .into_iter()
            .map(|(center, r, value)| Ball {
                center,
                radius: r.unwrap_or(default_radius),
                value: value.unwrap_or(0.0),
            })
            .collect();
        Ok(Balls {
            balls,
            has_values,
            id: next_id(),
        })
    }
}

/// 1.5 times the spacing of a cubic lattice of `rows.len()` points spanning
/// their box; 1 when that is not positive (one point, all points equal).
fn lattice_radius(rows: &[(Vec3, Option<f32>, Option<f32>)]) -> f32 {
    let Some(first) = rows.first() else {
        return 1.0;
    };
    let (lo, hi) = rows
        .iter()
        .fold((first.0, first.0), |(lo, hi), r| (lo.min(r.0), hi.max(r.0)));
    let per_axis = (rows.len() as f32).cbrt() - 1.0;
    let r = 1.5 * (hi - lo).max_element() / per_axis.max(1.0);
    if r.is_finite() && r > 0.0 { r } else { 1.0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::Grid;

    fn parse(text: &str) -> Result<Balls> {
        Balls::parse_points(text, Path::new("pts.csv"), Some(0.5), None)
    }

    #[test]
    fn points_files_parse_with_comments_headers_and_optional_columns() {
        let b = parse("# balls\nx,y,z,radius\n\n1,2,3\n4 5 6 0.25\n// done\n").unwrap();
        assert_eq!(b.len(), 2);
        assert!(!b.has_values());
        assert_eq!(b.as_slice()[0].center, Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(b.as_slice()[0].radius, 0.5);
        assert_eq!(b.as_slice()[1].radius, 0.25);
        let b = parse("0,0,0,1,200\n1, 0, 0, 1, 100\n").unwrap();
        assert!(b.has_values());
        assert_eq!(b.as_slice()[1].value, 100.0);
        // Default radius without --ball-radius: the lattice spacing × 1.5.
        let b = Balls::parse_points(
            "0 0 0\n1 0 0\n0 1 0\n1 1 0\n0 0 1\n1 0 1\n0 1 1\n1 1 1\n",
            Path::new("p.xyz"),
            None,
            None,
        )
        .unwrap();
        assert!((b.as_slice()[0].radius - 1.5).abs() < 1e-5);
        assert!(Balls::is_points_file(Path::new("a/b.CSV")));
        assert!(Balls::is_points_file(Path::new("b.xyz")));
        assert!(!Balls::is_points_file(Path::new("b.vol")));
    }

    #[test]
    fn bad_lines_fail_with_the_file_and_line() {
        let cases = [
            (
                "1,2,3\n1,2\n",
                "pts.csv: line 2: expected x,y,z[,radius[,value]]",
            ),
            (
                "1,2,3\n\n1,2,x\n",
                "pts.csv: line 3: 'x' is not a finite number",
            ),
            ("1,2,3,-1\n", "pts.csv: line 1: radius -1 must be > 0"),
            (
                "1,2,3,1,5\n1,2,3\n",
                "pts.csv: line 2: lacks a value but line 1 gives one",
            ),
            ("1,2,3,1,2,3\n", "pts.csv: line 1: expected"),
            ("1,2,inf\n", "pts.csv: line 1: 'inf' is not a finite number"),
        ];
        for (text, want) in cases {
            let msg = parse(text).unwrap_err().to_string();
            assert!(msg.starts_with(want), "{msg:?} vs {want:?}");
            assert!(!msg.contains('\n'));
        }
        let e = Balls::parse_points("0,0,0\n1,1,1\n2,2,2\n", Path::new("p.csv"), None, Some(2))
            .unwrap_err()
            .to_string();
        assert!(e.contains("more than 2 balls"), "{e}");
    }

    #[test]
    fn a_volume_gives_one_ball_per_voxel_above_the_threshold() {
        let grid = Grid::new(UVec3::new(6, 5, 4), Vec3::new(1.0, 2.0, 0.5));
        // Value = x + y + z; above 5: count by brute force.
        let vol = AnyVolume::from_fn(grid, |v| (v.x + v.y + v.z) as u8);
        for stride in [1u32, 2, 3] {
            let ex = Extraction {
                threshold: 5.0,
                stride,
                radius: None,
                max_balls: None,
            };
            let balls = Balls::from_volume(&vol, &ex).unwrap();
            let mut want = 0;
            for x in (0..6).step_by(stride as usize) {
                for y in (0..5).step_by(stride as usize) {
                    for z in (0..4).step_by(stride as usize) {
                        want += (x + y + z > 5) as usize;
                    }
                }
            }
            assert_eq!(balls.len(), want, "stride {stride}");
            assert!(balls.has_values());
            for b in balls.as_slice() {
                let v = (b.center / grid.spacing).round().as_uvec3();
                assert!(b.value > 5.0 && b.value == (v.x + v.y + v.z) as f32);
                assert_eq!(b.radius, 1.5 * stride as f32 * 2.0);
            }
        }
        let ex = Extraction {
            threshold: 5.0,
            stride: 1,
            radius: Some(0.3),
            max_balls: Some(10),
        };
        let e = Balls::from_volume(&vol, &ex).unwrap_err().to_string();
        assert!(
            e.starts_with(
                "the volume (--ball-threshold 5, --ball-stride 1) gives more than 10 balls"
            ),
            "{e}"
        );
        let ex = Extraction { stride: 0, ..ex };
        assert!(Balls::from_volume(&vol, &ex).is_err());
    }
}
