//! Writing meshes as Wavefront OBJ, and reading OBJ's geometry back.
//!
//! [`write_mesh`] writes, one per line:
//!
//! * `v x y z` per vertex, or `v x y z r g b` when the mesh has colours: the common extension
//!   of OBJ that MeshLab, Open3D, CloudCompare and trimesh read, with the components as the
//!   mesh holds them (0–1 for colours read from PLY; an alpha is dropped, the extension has
//!   none);
//! * `vn nx ny nz` per vertex when the mesh has vertex normals, in the vertices' order;
//! * `f a b c` per triangle with 1-based indices, or `f a//a b//b c//c` with normals (vertex
//!   and normal share the index).
//!
//! OBJ has nowhere to put the per-vertex density or other channels; they are not written (PLY
//! keeps them). Indices are text, so there is no limit on the vertex count; every index is
//! formed in 64-bit arithmetic.
//!
//! [`read_mesh`] reads an OBJ file's geometry: the first three numbers of each `v` line and
//! each `f` line's vertex indices (`i`, `i/t`, `i//n`, `i/t/n`; negative indices count back
//! from the last vertex given), polygons split into fans of triangles; every other statement
//! (`vn`, `vt`, groups, materials, lines) is skipped.

use std::fs::File;
use std::io::{self, BufRead, BufReader, Write};
use std::path::Path;

use crate::ply::{check_mesh, write_file, Chunk, MeshData};
use crate::Mesh;

/// Writes `mesh` as OBJ to the file `path` (see [`write_mesh_to`]).
pub fn write_mesh(path: &Path, mesh: &Mesh) -> io::Result<()> {
    write_file(path, |w| write_mesh_to(w, mesh))
}

/// Writes `mesh` as OBJ (see the [module documentation](self) for the layout). A mesh whose
/// per-vertex arrays disagree with its vertex count, or with a triangle naming a vertex that
/// does not exist, is refused before anything is written.
pub fn write_mesh_to(w: impl Write, mesh: &Mesh) -> io::Result<()> {
    check_mesh(mesh)?;
    let mut chunk = Chunk::new(w);
    let mut line: Vec<u8> = Vec::with_capacity(128);
    // Writing to a Vec cannot fail, so the results of write! into `line` are not checked.
    let _ = writeln!(
        line,
        "# written by psr {}: {} vertices, {} triangles",
        env!("CARGO_PKG_VERSION"),
        mesh.positions.len(),
        mesh.triangles.len()
    );
    chunk.put(&line)?;
    let colors = mesh.colors.as_ref();
    let components = colors.map_or(0, |c| c.components());
    let flat = colors.map_or(&[][..], |c| c.as_flattened());
    for (i, [x, y, z]) in mesh.positions.iter().enumerate() {
        line.clear();
        if mesh.origin == [0.0; 3] {
            let _ = write!(line, "v {x} {y} {z}");
        } else {
            // Relative to an origin (points given in f64): the sums in f64, as OBJ is text.
            let o = mesh.origin;
            let (x, y, z) = (o[0] + *x as f64, o[1] + *y as f64, o[2] + *z as f64);
            let _ = write!(line, "v {x} {y} {z}");
        }
        if components > 0 {
            let [r, g, b] = [0, 1, 2].map(|k| flat[i * components + k]);
            let _ = write!(line, " {r} {g} {b}");
        }
        line.push(b'\n');
        chunk.put(&line)?;
    }
    for [x, y, z] in &mesh.normals {
        line.clear();
        let _ = writeln!(line, "vn {x} {y} {z}");
        chunk.put(&line)?;
    }
    let with_normals = !mesh.normals.is_empty();
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|v| u64::from(v) + 1);
        line.clear();
        let _ = if with_normals {
            writeln!(line, "f {a}//{a} {b}//{b} {c}//{c}")
        } else {
            writeln!(line, "f {a} {b} {c}")
        };
        chunk.put(&line)?;
    }
    chunk.finish()
}

/// Reads the geometry of the OBJ file `path` (see [`read_mesh_from`]); errors name the path.
pub fn read_mesh(path: &Path) -> io::Result<MeshData> {
    let with_path = |e: io::Error| io::Error::new(e.kind(), format!("{}: {e}", path.display()));
    let file = File::open(path).map_err(|e| with_path(io::Error::new(e.kind(), "cannot open")))?;
    read_mesh_from(BufReader::new(file)).map_err(with_path)
}

/// Reads OBJ geometry: the positions of the `v` statements and the triangles of the `f`
/// statements (polygons as fans around their first corner). A malformed statement, an index
/// of 0 or one naming no vertex, or a face of fewer than three corners is an error naming its
/// line; so is an index past the 2³² vertices psr's meshes can index.
pub fn read_mesh_from(mut reader: impl BufRead) -> io::Result<MeshData> {
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let mut faces: Vec<([u64; 3], usize)> = Vec::new();
    let mut corners: Vec<u64> = Vec::new();
    let mut bytes = Vec::new();
    let mut line_number = 0usize;
    let bad = |line: usize, what: String| {
        io::Error::new(io::ErrorKind::InvalidData, format!("line {line}: {what}"))
    };
    loop {
        bytes.clear();
        if reader.read_until(b'\n', &mut bytes)? == 0 {
            break;
        }
        line_number += 1;
        let Ok(text) = std::str::from_utf8(&bytes) else {
            return Err(bad(line_number, "not UTF-8 text".into()));
        };
        let mut words = text.split_ascii_whitespace();
        match words.next() {
            Some("v") => {
                let mut xyz = [0.0f32; 3];
                for c in &mut xyz {
                    let word = words.next().ok_or_else(|| {
                        bad(line_number, "a vertex needs three coordinates".into())
                    })?;
                    *c = word
                        .parse()
                        .map_err(|_| bad(line_number, format!("'{word}' is not a coordinate")))?;
                }
                positions.push(xyz);
            }
            Some("f") => {
                corners.clear();
                for word in words {
                    let index = word.split('/').next().unwrap_or_default();
                    let index: i64 = index
                        .parse()
                        .map_err(|_| bad(line_number, format!("'{word}' is not a vertex index")))?;
                    let known = positions.len() as i64;
                    let resolved = match index {
                        1.. => index - 1,
                        0 => {
                            return Err(bad(
                                line_number,
                                "vertex index 0 (OBJ counts from 1)".into(),
                            ))
                        }
                        _ if -index <= known => known + index,
                        _ => {
                            return Err(bad(
                                line_number,
                                format!("vertex index {index} reaches before the first vertex"),
                            ))
                        }
                    };
                    corners.push(resolved as u64);
                }
                if corners.len() < 3 {
                    return Err(bad(
                        line_number,
                        "a face needs at least three corners".into(),
                    ));
                }
                for k in 2..corners.len() {
                    faces.push(([corners[0], corners[k - 1], corners[k]], line_number));
                }
            }
            _ => {}
        }
    }
    // Positive indices may name a vertex given later, so they are checked at the end.
    let n = positions.len() as u64;
    let mut triangles = Vec::with_capacity(faces.len());
    for (face, line) in faces {
        if let Some(&v) = face.iter().find(|&&v| v >= n) {
            return Err(bad(
                line,
                format!("a face names vertex {} of the {n} the file has", v + 1),
            ));
        }
        let Ok(t) = face
            .iter()
            .map(|&v| u32::try_from(v))
            .collect::<Result<Vec<u32>, _>>()
        else {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!("{n} vertices: psr's meshes index at most 2^32"),
            ));
        };
        triangles.push([t[0], t[1], t[2]]);
    }
    Ok((positions, triangles))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Channel, Colors};

    fn sample_mesh() -> Mesh {
        Mesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0e6, -3.3333333e-7, 0.1],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, -1.5],
            ],
            triangles: vec![[0, 1, 2], [0, 3, 1], [3, 2, 1]],
            densities: vec![1.0, 2.0, 0.5, 0.0],
            ..Mesh::default()
        }
    }

    fn to_text(mesh: &Mesh) -> String {
        let mut bytes = Vec::new();
        write_mesh_to(&mut bytes, mesh).unwrap();
        String::from_utf8(bytes).unwrap()
    }

    /// The lines of `text` that start with `keyword` and a space, without the keyword.
    fn statements<'a>(text: &'a str, keyword: &str) -> Vec<&'a str> {
        let prefix = format!("{keyword} ");
        text.lines()
            .filter_map(|l| l.strip_prefix(prefix.as_str()))
            .collect()
    }

    /// Proves: a mesh written as OBJ reads back with the same positions (exactly: the shortest
    /// text that gives the same f32) and triangles, with 1-based `f` lines and no density.
    #[test]
    fn meshes_round_trip() {
        let mesh = sample_mesh();
        let text = to_text(&mesh);
        assert_eq!(statements(&text, "f"), ["1 2 3", "1 4 2", "4 3 2"]);
        assert!(statements(&text, "vn").is_empty());
        assert!(!text.contains("value"));
        let (positions, triangles) = read_mesh_from(text.as_bytes()).unwrap();
        assert_eq!(positions, mesh.positions);
        assert_eq!(triangles, mesh.triangles);

        let path = std::env::temp_dir().join(format!("psr-obj-test-{}.obj", std::process::id()));
        write_mesh(&path, &mesh).unwrap();
        let back = read_mesh(&path);
        std::fs::remove_file(&path).unwrap();
        assert_eq!(back.unwrap(), (mesh.positions, mesh.triangles));
    }

    /// Proves: vertex normals become `vn` lines in the vertices' order with `f a//a` corners,
    /// colours the `v x y z r g b` extension (alpha dropped), and both come back as written;
    /// channels are not written.
    #[test]
    fn normals_and_colours_use_vn_and_the_colour_extension() {
        let mut mesh = sample_mesh();
        mesh.normals = vec![
            [0.0, 0.0, 1.0],
            [0.6, 0.0, -0.8],
            [0.0, 1.0, 0.0],
            [1.0, 0.0, 0.0],
        ];
        mesh.colors = Some(Colors::Rgba(vec![
            [1.0, 0.0, 0.0, 1.0],
            [0.0, 0.5, 0.25, 0.5],
            [0.0, 0.0, 1.0, 0.0],
            [0.1, 0.2, 0.3, 0.4],
        ]));
        mesh.channels = vec![Channel::new("intensity", vec![0.0; 4])];
        let text = to_text(&mesh);
        assert_eq!(
            statements(&text, "f"),
            ["1//1 2//2 3//3", "1//1 4//4 2//2", "4//4 3//3 2//2"]
        );
        let parse =
            |line: &str| -> Vec<f32> { line.split(' ').map(|w| w.parse().unwrap()).collect() };
        let normals: Vec<Vec<f32>> = statements(&text, "vn").into_iter().map(parse).collect();
        let expected: Vec<Vec<f32>> = mesh.normals.iter().map(|n| n.to_vec()).collect();
        assert_eq!(normals, expected);
        let Some(Colors::Rgba(rgba)) = &mesh.colors else {
            unreachable!()
        };
        for ((v, p), c) in statements(&text, "v")
            .into_iter()
            .zip(&mesh.positions)
            .zip(rgba)
        {
            assert_eq!(parse(v), [&p[..], &c[..3]].concat());
        }
        assert!(!text.contains("intensity"));
        let (positions, triangles) = read_mesh_from(text.as_bytes()).unwrap();
        assert_eq!((positions, triangles), (mesh.positions, mesh.triangles));
    }

    /// Proves: an inconsistent mesh is refused before a byte is written.
    #[test]
    fn inconsistent_meshes_are_refused() {
        let mut mesh = sample_mesh();
        mesh.normals = vec![[0.0, 0.0, 1.0]];
        let mut bytes = Vec::new();
        assert!(write_mesh_to(&mut bytes, &mesh).is_err());
        let mut mesh = sample_mesh();
        mesh.triangles.push([0, 1, 4]);
        assert!(write_mesh_to(&mut bytes, &mesh).is_err());
        assert!(bytes.is_empty());
    }

    /// Proves: the reader takes the forms of `f` corners other writers use, negative indices,
    /// polygons and statements it does not need, and names the line of what it cannot read.
    #[test]
    fn the_reader_takes_common_obj_and_names_bad_lines() {
        let text =
            "# a comment\nmtllib m.mtl\no square\nv 0 0 0\nv 1 0 0 1.0\nv 1 1 0 0.5 0.5 0.5\r\n\
                    v 0 1 0\nvt 0 0\nvn 0 0 1\ns off\nusemtl red\nf 1/1/1 2/1/1 3/1/1 4/1/1\n\
                    f -4//1 -2//1 -1//1\nl 1 2\n\nf 1/1 2/1 5/1\nv 0 0 1\n";
        let (positions, triangles) = read_mesh_from(text.as_bytes()).unwrap();
        assert_eq!(positions.len(), 5);
        assert_eq!(
            triangles,
            vec![[0, 1, 2], [0, 2, 3], [0, 2, 3], [0, 1, 4]],
            "fan, negative indices, a vertex given after its face"
        );
        for (bad, line, what) in [
            ("v 0 0 0\nv 1 0\n", 2, "three coordinates"),
            ("v 0 0 0\nv 1 x 0\n", 2, "'x'"),
            ("v 0 0 0\nf 0 1 1\n", 2, "index 0"),
            ("v 0 0 0\nf 1 1\n", 2, "three corners"),
            ("v 0 0 0\nf -2 1 1\n", 2, "before the first vertex"),
            ("v 0 0 0\nf 1 1 a/1\n", 2, "'a/1'"),
            (
                "v 0 0 0\nf 1 1 2\nv 1 1 1\nf 1 2 3\n",
                4,
                "vertex 3 of the 2",
            ),
        ] {
            let message = read_mesh_from(bad.as_bytes()).unwrap_err().to_string();
            assert!(
                message.contains(&format!("line {line}")) && message.contains(what),
                "{bad:?}: {message}"
            );
        }
    }
}
