//! Triangle meshes and their signed distance fields (`--generator mesh`).
//!
//! A mesh file (OBJ, PLY or STL, chosen by its extension) is read into a
//! [`Mesh`]: shared vertices and triangles that index them. [`field`] fits the
//! mesh into the output grid and computes, at every voxel, the exact distance
//! to the nearest triangle ([`distance`], accelerated by the [`bvh`]) with the
//! sign from ray-crossing parity ([`sign`]): negative inside.
//!
//! | module | concept |
//! |---|---|
//! | this one | [`Mesh`], [`MeshError`], [`Mesh::load`] |
//! | [`obj`], [`ply`], [`stl`] | the readers |
//! | [`bvh`] | bounding volume hierarchy, nearest-triangle queries |
//! | [`distance`] | closest point on a triangle |
//! | [`sign`] | inside/outside by scanline crossing parity |
//! | [`field`] | placement in the grid, the SDF volume, the `vol_gen` job |

pub mod bvh;
pub mod distance;
pub mod field;
pub mod obj;
pub mod ply;
pub mod sign;
pub mod stl;

use std::path::{Path, PathBuf};

use glam::DVec3;

/// A triangle mesh: vertex positions and triangles of three vertex indices,
/// each index checked to be in range.
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    vertices: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
}

/// Why a mesh file could not be read: the file and the problem, shown as one
/// line `FILE: problem`.
#[derive(Debug, thiserror::Error)]
#[error("{}: {problem}", path.display())]
pub struct MeshError {
    /// The file.
    pub path: PathBuf,
    /// What is wrong with it.
    pub problem: Problem,
}

/// What is wrong with a mesh file.
#[derive(Debug, thiserror::Error)]
pub enum Problem {
    /// It could not be opened or read.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// The extension is none of the supported ones.
    #[error("unknown mesh format (use .obj, .ply or .stl)")]
    UnknownFormat,
    /// The OBJ reader's complaint (it does not say where).
    #[error("OBJ: {0}")]
    Obj(tobj::LoadError),
    /// A text line that does not parse.
    #[error("line {line}: {message}")]
    Syntax {
        /// 1-based line number.
        line: usize,
        /// What was expected.
        message: String,
    },
    /// A binary file shorter than its header says.
    #[error("truncated: {what} needs {expected} bytes, only {found} left")]
    Truncated {
        /// What was being read.
        what: String,
        /// Bytes it needs.
        expected: u64,
        /// Bytes there are.
        found: u64,
    },
    /// A header the reader cannot use.
    #[error("{0}")]
    Unsupported(String),
    /// A face names a vertex that does not exist.
    #[error("face {face} uses vertex {index}, but there are only {vertices} vertices")]
    IndexOutOfRange {
        /// 0-based face number.
        face: usize,
        /// The index (0-based).
        index: i64,
        /// Number of vertices.
        vertices: usize,
    },
    /// A vertex coordinate is NaN or infinite.
    #[error("vertex {0} has a coordinate that is not finite")]
    NonFinite(usize),
    /// Nothing to measure distances to.
    #[error("the mesh has no triangles")]
    NoTriangles,
    /// Every vertex is at one point.
    #[error("the mesh has no extent (all vertices at one point)")]
    NoExtent,
}

impl Mesh {
    /// A mesh of `vertices` and polygons given as vertex indices (0-based,
    /// possibly out of range: that is an error). Polygons of more than three
    /// vertices are fan-triangulated; polygons of fewer are skipped, as are
    /// triangles that repeat an index (they have no area and no inside).
    pub fn from_polygons<I, P>(vertices: Vec<DVec3>, polygons: I) -> Result<Mesh, Problem>
    where
        I: IntoIterator<Item = P>,
        P: AsRef<[i64]>,
    {
        if let Some(i) = vertices.iter().position(|v| !v.is_finite()) {
            return Err(Problem::NonFinite(i));
        }
        let n = vertices.len();
        let mut triangles = Vec::new();
        for (face, polygon) in polygons.into_iter().enumerate() {
            let polygon = polygon.as_ref();
            let mut idx = Vec::with_capacity(polygon.len());
            for &index in polygon {
                let ok = usize::try_from(index)
                    .ok()
                    .filter(|&i| i < n)
                    .and_then(|i| u32::try_from(i).ok());
                match ok {
                    Some(i) => idx.push(i),
                    None => {
                        return Err(Problem::IndexOutOfRange {
                            face,
                            index,
                            vertices: n,
                        });
                    }
                }
            }
            for k in 2..idx.len() {
                let t = [idx[0], idx[k - 1], idx[k]];
                if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                    triangles.push(t);
                }
            }
        }
        Mesh::new(vertices, triangles)
    }

    /// A mesh of already checked triangles; errors when there are none or
    /// the vertices span no extent.
    fn new(vertices: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> Result<Mesh, Problem> {
        if triangles.is_empty() {
            return Err(Problem::NoTriangles);
        }
        let mesh = Mesh {
            vertices,
            triangles,
        };
        let (lo, hi) = mesh.bounds();
        if (hi - lo).max_element() <= 0.0 {
            return Err(Problem::NoExtent);
        }
        Ok(mesh)
    }

    /// A mesh of triangle soup: every three vertices one triangle (STL).
    /// Vertices are not merged; nothing here needs shared vertices.
    pub fn from_soup(vertices: Vec<DVec3>) -> Result<Mesh, Problem> {
        let n = vertices.len() / 3;
        let polygons = (0..n as i64).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]);
        Mesh::from_polygons(vertices, polygons)
    }

    /// Reads `path`, the format chosen by its extension (`.obj`, `.ply`,
    /// `.stl`, any case).
    pub fn load(path: &Path) -> Result<Mesh, MeshError> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        let result = match ext.as_str() {
            "obj" => obj::read(path),
            "ply" => std::fs::read(path)
                .map_err(Problem::from)
                .and_then(|b| ply::parse(&b)),
            "stl" => std::fs::read(path)
                .map_err(Problem::from)
                .and_then(|b| stl::parse(&b)),
            _ => Err(Problem::UnknownFormat),
        };
        result.map_err(|problem| MeshError {
            path: path.to_path_buf(),
            problem,
        })
    }

    /// The vertex positions.
    pub fn vertices(&self) -> &[DVec3] {
        &self.vertices
    }

    /// The triangles, as indices into [`Mesh::vertices`].
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// The corners of triangle `t`.
    pub fn corners(&self, t: usize) -> [DVec3; 3] {
        self.triangles[t].map(|i| self.vertices[i as usize])
    }

    /// Every triangle's corners.
    pub fn triangle_corners(&self) -> Vec<[DVec3; 3]> {
        (0..self.triangles.len()).map(|t| self.corners(t)).collect()
    }

    /// The bounding box of the vertices that triangles use.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for t in &self.triangles {
            for &i in t {
                let v = self.vertices[i as usize];
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
        (lo, hi)
    }

    /// The same mesh with every vertex mapped by `f` (to grid coordinates).
    pub fn map_vertices(&self, f: impl Fn(DVec3) -> DVec3) -> Mesh {
        Mesh {
            vertices: self.vertices.iter().map(|&v| f(v)).collect(),
            triangles: self.triangles.clone(),
        }
    }
}

#[cfg(test)]
pub(crate) mod testing {
    //! Meshes for the tests: a cube and an icosphere, and a brute-force
    //! inside test.
    use super::*;

    /// The axis-aligned cube `[lo, hi]`, 12 triangles wound outwards.
    pub fn cube(lo: DVec3, hi: DVec3) -> Mesh {
        let v: Vec<DVec3> = (0..8)
            .map(|i| {
                DVec3::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                )
            })
            .collect();
        let quads: [[i64; 4]; 6] = [
            [0, 2, 3, 1], // z = lo
            [4, 5, 7, 6], // z = hi
            [0, 1, 5, 4], // y = lo
            [2, 6, 7, 3], // y = hi
            [0, 4, 6, 2], // x = lo
            [1, 3, 7, 5], // x = hi
        ];
        Mesh::from_polygons(v, quads).unwrap()
    }

    /// An icosahedron subdivided `levels` times, projected onto the sphere
    /// of `radius` around `centre`.
    pub fn icosphere(centre: DVec3, radius: f64, levels: u32) -> Mesh {
        let t = (1.0 + 5f64.sqrt()) / 2.0;
        let mut v: Vec<DVec3> = [
            [-1.0, t, 0.0],
            [1.0, t, 0.0],
            [-1.0, -t, 0.0],
            [1.0, -t, 0.0],
            [0.0, -1.0, t],
            [0.0, 1.0, t],
            [0.0, -1.0, -t],
            [0.0, 1.0, -t],
            [t, 0.0, -1.0],
            [t, 0.0, 1.0],
            [-t, 0.0, -1.0],
            [-t, 0.0, 1.0],
        ]
        .iter()
        .map(|p| DVec3::from_array(*p).normalize())
        .collect();
        let mut f: Vec<[usize; 3]> = vec![
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ];
        for _ in 0..levels {
            let mut mid = std::collections::HashMap::new();
            let mut midpoint = |a: usize, b: usize, v: &mut Vec<DVec3>| {
                *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    v.push(((v[a] + v[b]) / 2.0).normalize());
                    v.len() - 1
                })
            };
            let mut next = Vec::new();
            for [a, b, c] in f {
                let ab = midpoint(a, b, &mut v);
                let bc = midpoint(b, c, &mut v);
                let ca = midpoint(c, a, &mut v);
                next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
            }
            f = next;
        }
        let v = v.into_iter().map(|p| centre + p * radius).collect();
        Mesh::from_polygons(v, f.iter().map(|t| t.map(|i| i as i64))).unwrap()
    }

    /// The generalised winding number of `mesh` at `p` (1 inside a closed,
    /// consistently wound mesh, 0 outside): the sum of the triangles' signed
    /// solid angles over 4π (Van Oosterom and Strackee).
    pub fn winding_number(mesh: &Mesh, p: DVec3) -> f64 {
        let mut sum = 0.0;
        for t in 0..mesh.triangles().len() {
            let [a, b, c] = mesh.corners(t).map(|v| v - p);
            let (la, lb, lc) = (a.length(), b.length(), c.length());
            let num = a.dot(b.cross(c));
            let den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
            sum += 2.0 * num.atan2(den);
        }
        sum / (4.0 * std::f64::consts::PI)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polygons_are_fanned_and_checked() {
        let v = vec![
            DVec3::ZERO,
            DVec3::X,
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::Y,
            DVec3::Z,
        ];
        let m = Mesh::from_polygons(v.clone(), [vec![0, 1, 2, 3], vec![0, 1, 4]]).unwrap();
        assert_eq!(m.triangles(), &[[0, 1, 2], [0, 2, 3], [0, 1, 4]]);
        assert!(matches!(
            Mesh::from_polygons(v.clone(), [vec![0, 1, 5]]),
            Err(Problem::IndexOutOfRange { index: 5, .. })
        ));
        assert!(matches!(
            Mesh::from_polygons(v.clone(), [vec![0, -1, 2]]),
            Err(Problem::IndexOutOfRange { index: -1, .. })
        ));
        assert!(matches!(
            Mesh::from_polygons(v.clone(), [vec![0, 1]]),
            Err(Problem::NoTriangles)
        ));
        assert!(matches!(
            Mesh::from_polygons(vec![DVec3::ONE; 3], [vec![0, 1, 2]]),
            Err(Problem::NoExtent)
        ));
        let mut bad = v;
        bad[1].y = f64::NAN;
        assert!(matches!(
            Mesh::from_polygons(bad, [vec![0, 1, 2]]),
            Err(Problem::NonFinite(1))
        ));
    }

    #[test]
    fn test_meshes_are_closed() {
        let cube = testing::cube(DVec3::ZERO, DVec3::ONE);
        assert_eq!(cube.triangles().len(), 12);
        let w = testing::winding_number(&cube, DVec3::splat(0.5));
        assert!((w - 1.0).abs() < 1e-9, "{w}");
        assert!(testing::winding_number(&cube, DVec3::splat(1.5)).abs() < 1e-9);
        let s = testing::icosphere(DVec3::ZERO, 2.0, 2);
        assert_eq!(s.triangles().len(), 320);
        assert!((testing::winding_number(&s, DVec3::ZERO) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn every_reader_gives_the_same_triangles() {
        // A tetrahedron written in each format.
        let v = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.5],
        ];
        let f = [[0u32, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        let want: Vec<[DVec3; 3]> = f
            .iter()
            .map(|t| t.map(|i| DVec3::from_array(v[i as usize])))
            .collect();
        let mut obj_text = String::new();
        for p in v {
            obj_text += &format!("v {} {} {}\n", p[0], p[1], p[2]);
        }
        for t in f {
            obj_text += &format!("f {} {}/1 {}//1\n", t[0] + 1, t[1] + 1, t[2] + 1);
        }
        obj_text = format!("vt 0 0\nvn 0 0 1\n{obj_text}");
        let soup: Vec<[[f32; 3]; 3]> = f
            .iter()
            .map(|t| t.map(|i| v[i as usize].map(|c| c as f32)))
            .collect();
        let mut stl_text = String::from("solid tetra\n");
        for t in &soup {
            stl_text += "facet normal 0 0 0\nouter loop\n";
            for c in t {
                stl_text += &format!("vertex {} {} {}\n", c[0], c[1], c[2]);
            }
            stl_text += "endloop\nendfacet\n";
        }
        stl_text += "endsolid tetra\n";
        let meshes = [
            obj::parse(&mut obj_text.as_bytes()).unwrap(),
            stl::parse(&stl::tests::binary_stl(&soup)).unwrap(),
            stl::parse(stl_text.as_bytes()).unwrap(),
            ply::parse(&ply::tests::binary_ply(&v, &f, false)).unwrap(),
            ply::parse(&ply::tests::binary_ply(&v, &f, true)).unwrap(),
        ];
        for (k, m) in meshes.iter().enumerate() {
            assert_eq!(m.triangle_corners(), want, "reader {k}");
        }
    }

    #[test]
    fn damaged_files_never_panic() {
        let cube = testing::cube(DVec3::ZERO, DVec3::ONE);
        let v: Vec<[f64; 3]> = cube.vertices().iter().map(|p| p.to_array()).collect();
        let soup: Vec<[[f32; 3]; 3]> = cube
            .triangle_corners()
            .iter()
            .map(|t| t.map(|p| p.as_vec3().to_array()))
            .collect();
        let mut obj_text = String::new();
        for p in &v {
            obj_text += &format!("v {} {} {}\n", p[0], p[1], p[2]);
        }
        for t in cube.triangles() {
            obj_text += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
        }
        type Parser = fn(&[u8]) -> Result<Mesh, Problem>;
        let files: [(Vec<u8>, Parser); 4] = [
            (stl::tests::binary_stl(&soup), stl::parse),
            (
                ply::tests::binary_ply(&v, cube.triangles(), false),
                ply::parse,
            ),
            (
                ply::tests::binary_ply(&v, cube.triangles(), true),
                ply::parse,
            ),
            (obj_text.into_bytes(), |b: &[u8]| obj::parse(&mut &b[..])),
        ];
        let mut rng = fastrand::Rng::with_seed(12);
        for (good, parse) in files {
            assert!(parse(&good).is_ok());
            for cut in 0..good.len() {
                let _ = parse(&good[..cut]);
            }
            for _ in 0..3000 {
                let mut bad = good.clone();
                for _ in 0..rng.usize(1..4) {
                    let i = rng.usize(..bad.len());
                    bad[i] = if rng.bool() {
                        rng.u8(..)
                    } else {
                        b"0123456789 -\n"[rng.usize(..13)]
                    };
                }
                let _ = parse(&bad);
            }
        }
    }

    #[test]
    fn unknown_extension_and_missing_file() {
        let e = Mesh::load(Path::new("/nonexistent/bunny.xyz")).unwrap_err();
        assert!(e.to_string().contains("bunny.xyz"), "{e}");
        assert!(matches!(e.problem, Problem::UnknownFormat));
        let e = Mesh::load(Path::new("/nonexistent/bunny.ply")).unwrap_err();
        assert!(matches!(e.problem, Problem::Io(_)), "{e}");
        assert!(!e.to_string().contains('\n'));
    }
}
