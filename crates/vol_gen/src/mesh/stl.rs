//! STL, binary and ASCII.
//!
//! Binary: an 80-byte header, a `u32` triangle count, then 50 bytes per
//! triangle (normal, three vertices as little-endian `f32`, a `u16`
//! attribute). ASCII: `solid` … `facet normal` / `outer loop` / three
//! `vertex x y z` / `endloop` / `endfacet` … `endsolid`. Normals are ignored
//! (the distance field does not need them, and many files have none).
//!
//! Which of the two a file is cannot be told from its first word: many
//! binary exporters begin the free-form header with `solid` too. A file is
//! binary when its length is exactly `84 + 50·count`; otherwise it is
//! ASCII when it starts with `solid` and is all text, and a binary file of
//! the wrong length (truncated) when not. The `stl_io` crate decides by the first
//! line alone, so it rejects such binary files (and ASCII files whose
//! `solid` line has no name); that is why this reader is our own.

use glam::DVec3;

use super::{Mesh, Problem};

/// Parses an STL file's bytes.
pub fn parse(bytes: &[u8]) -> Result<Mesh, Problem> {
    let count = bytes
        .get(80..84)
        .map(|c| u64::from(u32::from_le_bytes([c[0], c[1], c[2], c[3]])));
    let binary_len = count.map(|n| 84 + 50 * n);
    if binary_len == Some(bytes.len() as u64) {
        return parse_binary(bytes);
    }
    let starts_solid = bytes
        .iter()
        .position(|c| !c.is_ascii_whitespace())
        .is_some_and(|i| bytes[i..].starts_with(b"solid"));
    // Binary STL almost always holds NUL or other control bytes (the count,
    // the attribute words), text never does.
    let is_text = bytes
        .iter()
        .all(|&c| c.is_ascii_whitespace() || (c.is_ascii() && !c.is_ascii_control()));
    if starts_solid && is_text {
        return parse_ascii(bytes);
    }
    match (count, binary_len) {
        (Some(n), Some(len)) => Err(Problem::Truncated {
            what: format!("binary STL of {n} triangles"),
            expected: len,
            found: bytes.len() as u64,
        }),
        _ => Err(Problem::Truncated {
            what: "a binary STL header".into(),
            expected: 84,
            found: bytes.len() as u64,
        }),
    }
}

fn parse_binary(bytes: &[u8]) -> Result<Mesh, Problem> {
    // The length was checked against the count, so every record is there.
    let vertices = bytes[84..]
        .chunks_exact(50)
        .flat_map(|record| {
            (0..3).map(move |k| {
                let f = |i: usize| {
                    let o = 12 + 12 * k + 4 * i;
                    f64::from(f32::from_le_bytes([
                        record[o],
                        record[o + 1],
                        record[o + 2],
                        record[o + 3],
                    ]))
                };
                DVec3::new(f(0), f(1), f(2))
            })
        })
        .collect();
    Mesh::from_soup(vertices)
}

fn parse_ascii(bytes: &[u8]) -> Result<Mesh, Problem> {
    let text = String::from_utf8_lossy(bytes);
    let mut vertices = Vec::new();
    let mut in_loop = 0;
    let mut last_line = 0;
    for (i, line) in text.lines().enumerate() {
        let line_no = i + 1;
        last_line = line_no;
        let words: Vec<&str> = line.split_whitespace().collect();
        let syntax = |message: String| Problem::Syntax {
            line: line_no,
            message,
        };
        match words.first().copied() {
            Some("vertex") => {
                if words.len() != 4 {
                    return Err(syntax("expected 'vertex x y z'".into()));
                }
                let mut p = [0.0; 3];
                for (k, w) in words[1..].iter().enumerate() {
                    p[k] = w
                        .parse::<f64>()
                        .map_err(|_| syntax(format!("'{w}' is not a number")))?;
                }
                vertices.push(DVec3::from_array(p));
                in_loop += 1;
            }
            Some("outer") => in_loop = 0,
            Some("endloop") => {
                if in_loop != 3 {
                    return Err(syntax(format!(
                        "a facet with {in_loop} vertices (STL facets have 3)"
                    )));
                }
            }
            Some("solid" | "facet" | "endfacet" | "endsolid") | None => {}
            Some(other) => return Err(syntax(format!("unexpected '{other}'"))),
        }
    }
    if vertices.len() % 3 != 0 {
        return Err(Problem::Syntax {
            line: last_line,
            message: "the file ends inside a facet".into(),
        });
    }
    Mesh::from_soup(vertices)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A binary STL of `triangles`; the header starts with "solid", as many
    /// exporters write it.
    pub fn binary_stl(triangles: &[[[f32; 3]; 3]]) -> Vec<u8> {
        let mut out = b"solid exported by a CAD program".to_vec();
        out.resize(80, b' ');
        out.extend((triangles.len() as u32).to_le_bytes());
        for t in triangles {
            out.extend([0u8; 12]);
            for v in t {
                for c in v {
                    out.extend(c.to_le_bytes());
                }
            }
            out.extend([0u8; 2]);
        }
        out
    }

    const TRIS: [[[f32; 3]; 3]; 2] = [
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        [[0.0, 0.0, 0.0], [0.0, 0.0, 2.5], [1.0, 0.0, 0.0]],
    ];

    fn corners(m: &Mesh) -> Vec<[DVec3; 3]> {
        m.triangle_corners()
    }

    fn want() -> Vec<[DVec3; 3]> {
        TRIS.iter()
            .map(|t| t.map(|v| DVec3::from_array(v.map(f64::from))))
            .collect()
    }

    #[test]
    fn binary_and_ascii() {
        assert_eq!(corners(&parse(&binary_stl(&TRIS)).unwrap()), want());
        let ascii = "solid\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n\
                     vertex 0 1 0\n  endloop\n endfacet\n facet normal 0 -1 0\n outer loop\n\
                     vertex 0 0 0\n vertex 0 0 2.5e0\n vertex 1 0 0\n endloop\n endfacet\nendsolid\n";
        assert_eq!(corners(&parse(ascii.as_bytes()).unwrap()), want());
    }

    #[test]
    fn malformed_files_are_errors() {
        let good = binary_stl(&TRIS);
        let mut cut = good[..good.len() - 7].to_vec();
        // A header that does not start with "solid": clearly binary, short.
        cut[..5].copy_from_slice(b"xxxxx");
        let e = parse(&cut).unwrap_err();
        assert!(matches!(e, Problem::Truncated { expected: 184, .. }), "{e}");
        // Truncated, with a header that starts with "solid".
        assert!(matches!(
            parse(&good[..120]),
            Err(Problem::Truncated { .. })
        ));
        assert!(parse(&good[..50]).is_err());
        assert!(matches!(parse(&binary_stl(&[])), Err(Problem::NoTriangles)));
        let e = parse(b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0\n")
            .unwrap_err();
        assert!(e.to_string().contains("line 5"), "{e}");
        let e = parse(b"solid x\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\n").unwrap_err();
        assert!(e.to_string().contains("2 vertices"), "{e}");
        let e = parse(b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n").unwrap_err();
        assert!(e.to_string().contains("inside a facet"), "{e}");
        let mut nan = TRIS;
        nan[1][2][0] = f32::NAN;
        assert!(matches!(
            parse(&binary_stl(&nan)),
            Err(Problem::NonFinite(5))
        ));
    }
}
