//! PLY (Stanford polygon files): `ascii`, `binary_little_endian` and
//! `binary_big_endian`. The `vertex` element's `x`, `y`, `z` may be of any
//! scalar type (float and double in practice); the `face` element's list
//! `vertex_indices` (or `vertex_index`, as some exporters spell it) may use
//! any integer types for its count and entries. Other elements and
//! properties (normals, colours, edges, materials) are read past.
//!
//! Hand-written rather than taken from `ply-rs`: that crate has had no
//! release since 2020, and all we need is the header and three properties,
//! which is a page of code with errors that say which line or element is
//! wrong.

use glam::DVec3;

use super::{Mesh, Problem};

/// A scalar property type of the PLY header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }
}

/// One property of an element: a scalar or a list (count type, item type).
#[derive(Debug, Clone)]
enum Property {
    Scalar(Scalar, String),
    List(Scalar, Scalar, String),
}

/// One element of the header and its properties.
#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: u64,
    properties: Vec<Property>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Encoding {
    Ascii,
    Binary { big_endian: bool },
}

/// The parsed header and where the body starts.
struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    body: usize,
    /// Lines in the header (ASCII bodies count lines from here).
    lines: usize,
}

fn syntax(line: usize, message: impl Into<String>) -> Problem {
    Problem::Syntax {
        line,
        message: message.into(),
    }
}

fn parse_header(bytes: &[u8]) -> Result<Header, Problem> {
    let mut pos = 0;
    let mut line_no = 0;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let Some(len) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(syntax(line_no + 1, "the header has no 'end_header' line"));
        };
        let raw = &bytes[pos..pos + len];
        pos += len + 1;
        line_no += 1;
        let line = std::str::from_utf8(raw)
            .map_err(|_| syntax(line_no, "the header is not text"))?
            .trim();
        let words: Vec<&str> = line.split_whitespace().collect();
        if line_no == 1 {
            if line != "ply" {
                return Err(syntax(1, "not a PLY file (the first line is not 'ply')"));
            }
            continue;
        }
        match words.as_slice() {
            [] | ["comment", ..] | ["obj_info", ..] => {}
            ["format", kind, _version] => {
                encoding = Some(match *kind {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::Binary { big_endian: false },
                    "binary_big_endian" => Encoding::Binary { big_endian: true },
                    other => return Err(syntax(line_no, format!("unknown format '{other}'"))),
                });
            }
            ["element", name, count] => {
                let count = count
                    .parse::<u64>()
                    .map_err(|_| syntax(line_no, format!("bad element count '{count}'")))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                });
            }
            ["property", "list", count_ty, item_ty, name] => {
                let (Some(c), Some(i)) = (Scalar::parse(count_ty), Scalar::parse(item_ty)) else {
                    return Err(syntax(line_no, format!("unknown type in '{line}'")));
                };
                if !c.is_integer() {
                    return Err(syntax(line_no, "a list count must be an integer type"));
                }
                let element = elements
                    .last_mut()
                    .ok_or_else(|| syntax(line_no, "a property before any element"))?;
                element
                    .properties
                    .push(Property::List(c, i, name.to_string()));
            }
            ["property", ty, name] => {
                let ty = Scalar::parse(ty)
                    .ok_or_else(|| syntax(line_no, format!("unknown type '{ty}'")))?;
                let element = elements
                    .last_mut()
                    .ok_or_else(|| syntax(line_no, "a property before any element"))?;
                element
                    .properties
                    .push(Property::Scalar(ty, name.to_string()));
            }
            ["end_header"] => break,
            _ => return Err(syntax(line_no, format!("cannot read header line '{line}'"))),
        }
    }
    let encoding = encoding.ok_or_else(|| syntax(2, "the header has no 'format' line"))?;
    Ok(Header {
        encoding,
        elements,
        body: pos,
        lines: line_no,
    })
}

/// Reads scalars from the body, ASCII tokens or binary values.
trait Body {
    /// The next scalar of type `ty`; `what` names it for errors.
    fn scalar(&mut self, ty: Scalar, what: &dyn Fn() -> String) -> Result<f64, Problem>;
}

struct Binary<'a> {
    bytes: &'a [u8],
    pos: usize,
    big_endian: bool,
}

impl Body for Binary<'_> {
    fn scalar(&mut self, ty: Scalar, what: &dyn Fn() -> String) -> Result<f64, Problem> {
        let n = ty.size();
        let left = self.bytes.len() - self.pos;
        if left < n {
            return Err(Problem::Truncated {
                what: what(),
                expected: n as u64,
                found: left as u64,
            });
        }
        let mut b = [0u8; 8];
        b[..n].copy_from_slice(&self.bytes[self.pos..self.pos + n]);
        self.pos += n;
        if self.big_endian {
            b[..n].reverse();
        }
        Ok(match ty {
            Scalar::I8 => f64::from(b[0] as i8),
            Scalar::U8 => f64::from(b[0]),
            Scalar::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
            Scalar::U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
            Scalar::I32 => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::F64 => f64::from_le_bytes(b),
        })
    }
}

struct Ascii<'a> {
    text: &'a [u8],
    pos: usize,
    line: usize,
}

impl Body for Ascii<'_> {
    fn scalar(&mut self, _ty: Scalar, what: &dyn Fn() -> String) -> Result<f64, Problem> {
        while let Some(&c) = self.text.get(self.pos) {
            if !c.is_ascii_whitespace() {
                break;
            }
            if c == b'\n' {
                self.line += 1;
            }
            self.pos += 1;
        }
        let start = self.pos;
        while self
            .text
            .get(self.pos)
            .is_some_and(|c| !c.is_ascii_whitespace())
        {
            self.pos += 1;
        }
        if start == self.pos {
            return Err(syntax(
                self.line,
                format!("the file ends before {}", what()),
            ));
        }
        let token = String::from_utf8_lossy(&self.text[start..self.pos]);
        token
            .parse::<f64>()
            .map_err(|_| syntax(self.line, format!("'{token}' is not a number ({})", what())))
    }
}

/// Parses a PLY file's bytes.
pub fn parse(bytes: &[u8]) -> Result<Mesh, Problem> {
    let header = parse_header(bytes)?;
    let body = &bytes[header.body..];
    match header.encoding {
        Encoding::Ascii => read_elements(
            &header.elements,
            &mut Ascii {
                text: body,
                pos: 0,
                line: header.lines + 1,
            },
            body.len(),
        ),
        Encoding::Binary { big_endian } => read_elements(
            &header.elements,
            &mut Binary {
                bytes: body,
                pos: 0,
                big_endian,
            },
            body.len(),
        ),
    }
}

/// A list length or index: an integer that fits `i64`.
fn integer(v: f64, what: &dyn Fn() -> String) -> Result<i64, Problem> {
    if v.fract() == 0.0 && v.abs() < 9.0e15 {
        Ok(v as i64)
    } else {
        Err(Problem::Unsupported(format!(
            "{} is {v}, not an integer",
            what()
        )))
    }
}

fn read_elements(
    elements: &[Element],
    body: &mut dyn Body,
    body_len: usize,
) -> Result<Mesh, Problem> {
    let vertex = elements
        .iter()
        .find(|e| e.name == "vertex")
        .ok_or_else(|| Problem::Unsupported("no 'vertex' element".into()))?;
    let axis = |name: &str| {
        vertex
            .properties
            .iter()
            .position(|p| matches!(p, Property::Scalar(_, n) if n == name))
            .ok_or_else(|| Problem::Unsupported(format!("the vertex element has no '{name}'")))
    };
    let xyz = [axis("x")?, axis("y")?, axis("z")?];
    // A count in the header is not trusted for allocation: at most one item
    // per byte of the body can really follow.
    let cap = |count: u64| count.min(body_len as u64) as usize;
    let mut vertices = Vec::new();
    let mut faces: Vec<Vec<i64>> = Vec::new();
    for element in elements {
        if element.properties.is_empty() {
            // Nothing to read however large the count (and looping over a
            // count of 10¹² would hang).
            continue;
        }
        let is_vertex = element.name == "vertex";
        let is_face = element.name == "face";
        if is_vertex {
            vertices.reserve(cap(element.count));
        } else if is_face {
            faces.reserve(cap(element.count));
        }
        for i in 0..element.count {
            let mut p = [0.0; 3];
            let mut polygon = Vec::new();
            for (k, property) in element.properties.iter().enumerate() {
                match property {
                    Property::Scalar(ty, name) => {
                        let what = || format!("{} {i} property '{name}'", element.name);
                        let v = body.scalar(*ty, &what)?;
                        if is_vertex && let Some(axis) = xyz.iter().position(|&a| a == k) {
                            p[axis] = v;
                        }
                    }
                    Property::List(count_ty, item_ty, name) => {
                        let what = || format!("{} {i} list '{name}'", element.name);
                        let n = integer(body.scalar(*count_ty, &what)?, &what)?;
                        let wanted =
                            is_face && (name == "vertex_indices" || name == "vertex_index");
                        for _ in 0..n {
                            let v = body.scalar(*item_ty, &what)?;
                            if wanted {
                                polygon.push(integer(v, &what)?);
                            }
                        }
                    }
                }
            }
            if is_vertex {
                vertices.push(DVec3::from_array(p));
            } else if is_face {
                faces.push(polygon);
            }
        }
    }
    Mesh::from_polygons(vertices, faces)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A binary PLY of `vertices` (as f32 or f64) and triangles (u8 count,
    /// u32 or i32 indices), with an extra property and element to skip.
    pub fn binary_ply(vertices: &[[f64; 3]], faces: &[[u32; 3]], big_endian: bool) -> Vec<u8> {
        let order = if big_endian { "big" } else { "little" };
        let mut out = format!(
            "ply\nformat binary_{order}_endian 1.0\ncomment test\n\
             element vertex {}\nproperty double x\nproperty float y\nproperty double z\n\
             property uchar red\n\
             element face {}\nproperty list uchar int vertex_index\n\
             element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n",
            vertices.len(),
            faces.len()
        )
        .into_bytes();
        let put = |b: &mut Vec<u8>, mut bytes: Vec<u8>| {
            if big_endian {
                bytes.reverse();
            }
            b.extend(bytes);
        };
        for v in vertices {
            put(&mut out, v[0].to_le_bytes().to_vec());
            put(&mut out, (v[1] as f32).to_le_bytes().to_vec());
            put(&mut out, v[2].to_le_bytes().to_vec());
            out.push(200);
        }
        for f in faces {
            out.push(3);
            for &i in f {
                put(&mut out, (i as i32).to_le_bytes().to_vec());
            }
        }
        put(&mut out, 0i32.to_le_bytes().to_vec());
        put(&mut out, 1i32.to_le_bytes().to_vec());
        out
    }

    const TETRA: [[f64; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.5],
    ];
    const FACES: [[u32; 3]; 4] = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];

    fn expected() -> Mesh {
        Mesh::from_polygons(
            TETRA.iter().map(|v| DVec3::from_array(*v)).collect(),
            FACES.iter().map(|f| f.map(i64::from)),
        )
        .unwrap()
    }

    #[test]
    fn ascii_and_both_binaries() {
        let ascii = "ply\r\nformat ascii 1.0\r\nelement vertex 4\r\nproperty float x\r\n\
                     property float y\r\nproperty float z\r\nelement face 4\r\n\
                     property list uchar uint vertex_indices\r\nend_header\r\n\
                     0 0 0\r\n1 0 0\r\n0 1 0\r\n0 0 1.5\r\n3 0 2 1\r\n3 0 1 3\r\n3 0 3 2\r\n3 1 2 3\r\n"
            .as_bytes();
        assert_eq!(parse(ascii).unwrap(), expected());
        for big in [false, true] {
            let m = parse(&binary_ply(&TETRA, &FACES, big)).unwrap();
            assert_eq!(m, expected(), "big endian {big}");
        }
    }

    #[test]
    fn malformed_files_are_errors() {
        let good = binary_ply(&TETRA, &FACES, false);
        for cut in [0, 3, 40, good.len() - 20, good.len() - 9] {
            let e = parse(&good[..cut]).unwrap_err();
            assert!(!e.to_string().contains('\n'), "{e}");
        }
        let e = parse(&good[..good.len() - 20]).unwrap_err();
        assert!(matches!(e, Problem::Truncated { .. }), "{e}");
        let bad = binary_ply(&TETRA, &[[0, 1, 7]], false);
        assert!(matches!(
            parse(&bad),
            Err(Problem::IndexOutOfRange { index: 7, .. })
        ));
        let no_faces = binary_ply(&TETRA, &[], true);
        assert!(matches!(parse(&no_faces), Err(Problem::NoTriangles)));
        let e =
            parse(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n")
                .unwrap_err();
        assert!(e.to_string().contains("'y'"), "{e}");
        let e = parse(
            b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
              property float z\nend_header\n0 0 0\n1 0 zero\n",
        )
        .unwrap_err();
        assert!(e.to_string().contains("line 9"), "{e}");
        // A huge count in the header is an error, not an allocation.
        let e = parse(
            b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000000\n\
              property float x\nproperty float y\nproperty float z\nend_header\n",
        )
        .unwrap_err();
        assert!(matches!(e, Problem::Truncated { .. }), "{e}");
        assert!(parse(b"PK\x03\x04 not a ply").is_err());
    }
}
