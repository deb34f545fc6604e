//! Wavefront OBJ, read with the `tobj` crate: `v` and `f` lines (any of the
//! `f v`, `f v/vt`, `f v//vn`, `f v/vt/vn` forms, negative indices counting
//! back from the last vertex), polygons fan-triangulated, every object and
//! group of the file merged into one mesh. Materials, normals and texture
//! coordinates are not needed and `.mtl` files are not opened.
//!
//! `tobj` is used rather than a parser of our own because it is maintained,
//! fuzzed and handles the many spellings of OBJ faces; its errors do not say
//! on which line the problem is, which is the one thing we give up.

use std::io::BufReader;
use std::path::Path;

use glam::DVec3;

use super::{Mesh, Problem};

/// Reads the OBJ file `path`.
pub fn read(path: &Path) -> Result<Mesh, Problem> {
    let file = std::fs::File::open(path)?;
    parse(&mut BufReader::new(file))
}

/// Parses OBJ text.
pub fn parse(reader: &mut impl std::io::BufRead) -> Result<Mesh, Problem> {
    let options = tobj::LoadOptions {
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    // No materials: an `mtllib` line is answered with an empty library.
    let (models, _) =
        tobj::load_obj_buf(reader, &options, |_| Ok((Vec::new(), Default::default())))
            .map_err(Problem::Obj)?;
    // Each model has its own positions and indices into them.
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    for model in &models {
        let m = &model.mesh;
        let base = vertices.len() as i64;
        vertices.extend(
            m.positions
                .chunks_exact(3)
                .map(|p| DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]))),
        );
        triangles.extend(
            m.indices
                .chunks_exact(3)
                .map(|t| [0, 1, 2].map(|k| base + i64::from(t[k]))),
        );
    }
    Mesh::from_polygons(vertices, triangles)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obj(text: &str) -> Result<Mesh, Problem> {
        parse(&mut text.as_bytes())
    }

    #[test]
    fn faces_in_every_form() {
        let m = obj("# a quad and a triangle\n\
                     v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n\
                     f 1/1/1 2/1/1 3/1/1 4/1/1\n\
                     v 0 0 1\n\
                     f -5//1 -4//1 -1//1\n")
        .unwrap();
        assert_eq!(m.triangles().len(), 3);
        let corners = m.triangle_corners();
        assert_eq!(
            corners[0],
            [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0)]
        );
        assert_eq!(
            corners[1],
            [DVec3::ZERO, DVec3::new(1.0, 1.0, 0.0), DVec3::Y]
        );
        assert_eq!(corners[2], [DVec3::ZERO, DVec3::X, DVec3::Z]);
    }

    #[test]
    fn bad_files_are_errors() {
        assert!(matches!(
            obj("v 0 0 0\nv 1 0 0\nf 1 2 3\n"),
            Err(Problem::Obj(_))
        ));
        assert!(matches!(obj("v 0 0 0\n"), Err(Problem::NoTriangles)));
        assert!(obj("v 0 x 0\nf 1 1 1\n").is_err());
        assert!(obj("f 1 2 3\n").is_err());
        assert!(obj("\u{0}\u{1}garbage").is_err());
    }
}
