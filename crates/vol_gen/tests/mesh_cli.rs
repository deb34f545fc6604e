//! End-to-end tests of `vol_gen --generator mesh`: a cube written as OBJ,
//! PLY and STL gives the box's signed distance field in NRRD and NIfTI (read
//! back with the library's readers), the committed bunny gives a closed
//! surface, and bad input is one line on stderr, exit code non-zero and no
//! file.

mod common;

use std::path::Path;

use common::{TempDir, args_around, run, run_ok, stderr};
use glam::{UVec3, Vec3};
use raycaster::format;
use raycaster::storage::LoadMode;

/// The cube [-1, 1]³ with one quad per face, as OBJ text (the faces in
/// several `f` spellings, one with negative indices).
const CUBE_OBJ: &str = "\
v -1 -1 -1\nv 1 -1 -1\nv -1 1 -1\nv 1 1 -1\nv -1 -1 1\nv 1 -1 1\nv -1 1 1\nv 1 1 1\n\
vn 0 0 1\nvt 0 0\n\
f 1 3 4 2\nf 5/1 6/1 8/1 7/1\nf 1//1 2//1 6//1 5//1\nf -6/1/1 -2/1/1 -1/1/1 -5/1/1\n\
f 1 5 7 3\nf 2 4 8 6\n";

/// The cube's triangles (from the OBJ quads, fanned).
fn cube_triangles() -> Vec<[[f32; 3]; 3]> {
    let v = |i: usize| {
        let i = i - 1;
        [i & 1, i & 2, i & 4].map(|b| if b == 0 { -1.0 } else { 1.0 })
    };
    let quads = [
        [1, 3, 4, 2],
        [5, 6, 8, 7],
        [1, 2, 6, 5],
        [3, 7, 8, 4],
        [1, 5, 7, 3],
        [2, 4, 8, 6],
    ];
    quads
        .iter()
        .flat_map(|q| [[v(q[0]), v(q[1]), v(q[2])], [v(q[0]), v(q[2]), v(q[3])]])
        .collect()
}

fn cube_stl() -> Vec<u8> {
    let mut out = vec![b' '; 80];
    let tris = cube_triangles();
    out.extend((tris.len() as u32).to_le_bytes());
    for t in &tris {
        out.extend([0u8; 12]);
        for c in t.iter().flatten() {
            out.extend(c.to_le_bytes());
        }
        out.extend([0u8; 2]);
    }
    out
}

fn cube_ply() -> Vec<u8> {
    let tris = cube_triangles();
    let mut out = format!(
        "ply\nformat binary_big_endian 1.0\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nelement face {}\n\
         property list uchar uint vertex_indices\nend_header\n",
        3 * tris.len(),
        tris.len()
    )
    .into_bytes();
    for c in tris.iter().flatten().flatten() {
        out.extend(c.to_be_bytes());
    }
    for t in 0..tris.len() as u32 {
        out.push(3);
        for k in 0..3 {
            out.extend((3 * t + k).to_be_bytes());
        }
    }
    out
}

fn box_sdf(p: Vec3) -> f32 {
    let q = p.abs() - Vec3::ONE;
    q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
}

/// Checks that `file` holds the cube's SDF on a 21×17×15 grid with the
/// default margin of 3: the tightest axis is z, 14 − 6 = 8 voxels over 2
/// units, so the spacing is 0.25 and the grid is centred on the cube.
fn assert_cube_sdf(file: &Path) {
    let v = format::open(file, LoadMode::Ram).unwrap();
    let dims = UVec3::new(21, 17, 15);
    assert_eq!(v.grid().dims, dims);
    assert_eq!(v.grid().spacing, Vec3::splat(0.25));
    let centre = (dims - UVec3::ONE).as_vec3() / 2.0;
    for x in 0..dims.x {
        for y in 0..dims.y {
            for z in 0..dims.z {
                let p = UVec3::new(x, y, z);
                let mesh_point = (p.as_vec3() - centre) * 0.25;
                let want = box_sdf(mesh_point);
                let got = v.value(p);
                assert!(
                    (got - want).abs() < 1e-5,
                    "{}: {p}: {got} vs {want}",
                    file.display()
                );
            }
        }
    }
}

#[test]
fn a_cube_in_every_format_gives_its_sdf() {
    let dir = TempDir::new("mesh-cube");
    let inputs = [
        ("cube.obj", CUBE_OBJ.as_bytes().to_vec()),
        ("cube.STL", cube_stl()),
        ("cube.ply", cube_ply()),
    ];
    for (name, bytes) in inputs {
        let mesh = dir.path(name);
        std::fs::write(&mesh, bytes).unwrap();
        for out in ["sdf.nrrd", "sdf.nii", "sdf.nii.gz"] {
            let out = dir.path(&format!("{name}.{out}"));
            let before = args_around(
                "--dims 21,17,15 --generator mesh --quiet --mesh",
                &mesh,
                "-o",
            );
            let mut args = before.clone();
            args.push(out.to_str().unwrap());
            run_ok(&args);
            assert_cube_sdf(&out);
        }
    }
}

#[test]
fn the_bunny_is_closed_and_negative_inside() {
    let bunny = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/bunny.ply");
    let dir = TempDir::new("mesh-bunny");
    let out = dir.path("bunny.nrrd");
    let args = args_around(
        "--dims 40,40,32 --generator mesh --margin 2 --mesh",
        &bunny,
        "-o",
    );
    let mut args = args;
    args.push(out.to_str().unwrap());
    let run = run_ok(&args);
    assert!(stderr(&run).contains("3674 triangles"), "{}", stderr(&run));
    let v = format::open(&out, LoadMode::Ram).unwrap();
    let dims = v.grid().dims;
    let mut inside = 0;
    for x in 0..dims.x {
        for y in 0..dims.y {
            for z in 0..dims.z {
                let p = UVec3::new(x, y, z);
                let d = v.value(p);
                let border = p.cmpeq(UVec3::ZERO).any() || p.cmpeq(dims - UVec3::ONE).any();
                if border {
                    // The margin keeps the grid's faces outside, at least
                    // one voxel (minus rounding) from the surface.
                    assert!(d > 0.9 * v.grid().spacing.x, "{p}: {d}");
                }
                inside += usize::from(d < 0.0);
            }
        }
    }
    // The bunny fills roughly a fifth of its bounding box's grid.
    let share = inside as f64 / (dims.x * dims.y * dims.z) as f64;
    assert!((0.1..0.4).contains(&share), "{share}");
}

#[test]
fn help_documents_the_mesh_generator() {
    let out = run_ok(&["--help"]);
    let help = String::from_utf8_lossy(&out.stdout);
    for word in ["mesh", "--mesh", "--margin", ".nrrd", ".ply", "negative"] {
        assert!(help.contains(word), "{word}");
    }
}

#[test]
fn bad_input_is_one_line_and_no_file() {
    let dir = TempDir::new("mesh-bad");
    let good = dir.path("cube.obj");
    std::fs::write(&good, CUBE_OBJ).unwrap();
    let truncated = dir.path("cut.stl");
    let stl = cube_stl();
    std::fs::write(&truncated, &stl[..stl.len() - 10]).unwrap();
    let out_of_range = dir.path("range.obj");
    std::fs::write(&out_of_range, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n").unwrap();
    let empty = dir.path("empty.ply");
    std::fs::write(
        &empty,
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
         property float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n",
    )
    .unwrap();
    let missing = dir.path("missing.obj");
    let out = dir.path("out.nrrd");
    let vol = dir.path("x.vol");
    // `--dims D -g GENERATOR [--mesh MESH] -o OUT`.
    let args = |dims: &'static str, generator: &'static str, mesh: Option<&Path>, out: &Path| {
        let mut a = vec![
            "--dims".to_string(),
            dims.into(),
            "-g".into(),
            generator.into(),
        ];
        if let Some(m) = mesh {
            a.extend(["--mesh".into(), m.to_str().unwrap().into()]);
        }
        a.extend(["-o".into(), out.to_str().unwrap().into()]);
        a
    };
    let cases = [
        (args("9,9,9", "mesh", Some(&good), &vol), "float format"),
        (args("9,9,9", "mesh", None, &out), "needs --mesh"),
        (
            args("9,9,9", "solid", Some(&good), &out),
            "--generator mesh",
        ),
        (args("9,9,9", "mesh", Some(&missing), &out), "missing.obj"),
        (args("9,9,9", "mesh", Some(&truncated), &out), "truncated"),
        (
            args("9,9,9", "mesh", Some(&out_of_range), &out),
            "out of bounds",
        ),
        (args("9,9,9", "mesh", Some(&empty), &out), "no triangles"),
        (args("6,60,60", "mesh", Some(&good), &out), "margin"),
    ];
    for (args, expected) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let result = run(&args);
        let err = stderr(&result);
        assert!(!result.status.success(), "{args:?}");
        assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
        assert!(err.contains(expected), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(!out.exists() && !vol.exists(), "{args:?}");
    }
}
