//! The mesh put together from the slabs' parts: the closed pieces that too few samples support
//! dropped across walls (as `components.rs` drops them in memory), then one PLY written slab by
//! slab, each vertex on a wall written once (by the first slab that has it) and the triangles
//! indexing it.

use super::scratch::{read_lists, scratch_error, write_lists, Scratch};
use super::seams::SlabPart;
use super::OutOfCoreError;
use crate::components::vertex_components;
use crate::density::DensityField;
use crate::points::UnitCubeMap;
use glam::DVec3;
use std::collections::HashMap;
use std::fs::File;
use std::io::{self, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

fn part_file(scratch: &Scratch, k: usize) -> PathBuf {
    scratch.file(&format!("slab-{k}.part"))
}

/// Writes slab k's part of the mesh to its file (its normals are not kept: the file is written
/// without them).
pub(crate) fn save_part(
    part: &SlabPart,
    scratch: &Scratch,
    k: usize,
) -> Result<(), OutOfCoreError> {
    let lists: Vec<Vec<u64>> = vec![
        part.vertices
            .iter()
            .flat_map(|v| v.to_array().map(f64::to_bits))
            .collect(),
        part.keys.clone(),
        part.shared.iter().map(|&s| s as u64).collect(),
        part.triangles
            .iter()
            .flat_map(|t| t.map(u64::from))
            .collect(),
    ];
    write_lists(&part_file(scratch, k), &lists)
}

/// Reads what [`save_part`] wrote.
pub(crate) fn load_part(scratch: &Scratch, k: usize) -> Result<SlabPart, OutOfCoreError> {
    let lists: Vec<Vec<u64>> = read_lists(&part_file(scratch, k))?;
    let [vertices, keys, shared, triangles] = <[Vec<u64>; 4]>::try_from(lists).map_err(|_| {
        OutOfCoreError::Reconstruction(crate::Error::Internal(
            "a slab's part file has the wrong number of lists".into(),
        ))
    })?;
    Ok(SlabPart {
        vertices: vertices
            .chunks_exact(3)
            .map(|c| {
                DVec3::new(
                    f64::from_bits(c[0]),
                    f64::from_bits(c[1]),
                    f64::from_bits(c[2]),
                )
            })
            .collect(),
        normals: Vec::new(),
        keys,
        shared: shared.iter().map(|&s| s as u8).collect(),
        triangles: triangles
            .chunks_exact(3)
            .map(|c| [c[0] as u32, c[1] as u32, c[2] as u32])
            .collect(),
    })
}

/// The connected pieces of the whole mesh from the slabs' parts: each part's pieces (by shared
/// vertices), joined where parts share a vertex.
pub(crate) struct Pieces {
    /// For slab k, the piece of each of its vertices (an index into the fields below).
    of_vertex: Vec<Vec<u32>>,
    /// Per piece: its triangles, the sum of its triangles' edge lengths.
    triangles: Vec<u64>,
    edge_sum: Vec<f64>,
    /// The piece with the most triangles (among equals the first met).
    largest: u32,
}

fn find(parent: &mut [u32], mut v: u32) -> u32 {
    while parent[v as usize] != v {
        let up = parent[parent[v as usize] as usize];
        parent[v as usize] = up;
        v = up;
    }
    v
}

impl Pieces {
    /// Labels the pieces of the parts `parts(k)` of `slabs` slabs, read in slab order.
    pub(crate) fn label(
        slabs: usize,
        mut part: impl FnMut(usize) -> Result<SlabPart, OutOfCoreError>,
    ) -> Result<Pieces, OutOfCoreError> {
        // Each part's local pieces are nodes of a union-find over the whole mesh.
        let mut parent: Vec<u32> = Vec::new();
        let mut local_of_vertex: Vec<Vec<u32>> = Vec::with_capacity(slabs);
        let mut triangles: Vec<u64> = Vec::new();
        let mut edge_sum: Vec<f64> = Vec::new();
        let mut at_key: HashMap<u64, u32> = HashMap::new();
        for k in 0..slabs {
            let part = part(k)?;
            let local = vertex_components(part.vertices.len(), &part.triangles);
            // The part's roots, numbered after the pieces of the slabs before it.
            let first = parent.len() as u32;
            let mut number: HashMap<u32, u32> = HashMap::new();
            let of_vertex: Vec<u32> = local
                .iter()
                .map(|root| {
                    let next = first + number.len() as u32;
                    *number.entry(*root).or_insert(next)
                })
                .collect();
            let added = number.len();
            parent.extend(first..first + added as u32);
            triangles.resize(parent.len(), 0);
            edge_sum.resize(parent.len(), 0.0);
            for t in &part.triangles {
                let piece = of_vertex[t[0] as usize] as usize;
                let [a, b, c] = t.map(|v| part.vertices[v as usize]);
                triangles[piece] += 1;
                edge_sum[piece] += a.distance(b) + b.distance(c) + c.distance(a);
            }
            for (v, &shared) in part.shared.iter().enumerate() {
                if shared == 0 {
                    continue;
                }
                let here = of_vertex[v];
                match at_key.get(&part.keys[v]) {
                    Some(&there) => {
                        let (a, b) = (find(&mut parent, here), find(&mut parent, there));
                        if a != b {
                            parent[a.max(b) as usize] = a.min(b);
                        }
                    }
                    None => {
                        at_key.insert(part.keys[v], here);
                    }
                }
            }
            local_of_vertex.push(of_vertex);
        }
        // Pieces renumbered by their roots, with their sums.
        let roots: Vec<u32> = (0..parent.len() as u32)
            .map(|p| find(&mut parent, p))
            .collect();
        let mut whole_triangles = vec![0u64; parent.len()];
        let mut whole_edges = vec![0.0f64; parent.len()];
        for (p, &root) in roots.iter().enumerate() {
            whole_triangles[root as usize] += triangles[p];
            whole_edges[root as usize] += edge_sum[p];
        }
        let largest = (0..parent.len())
            .max_by_key(|&r| (whole_triangles[r], std::cmp::Reverse(r)))
            .unwrap_or(0) as u32;
        Ok(Pieces {
            of_vertex: local_of_vertex
                .into_iter()
                .map(|of| of.into_iter().map(|p| roots[p as usize]).collect())
                .collect(),
            triangles: whole_triangles,
            edge_sum: whole_edges,
            largest,
        })
    }

    /// The piece with the most triangles: always kept.
    pub(crate) fn largest(&self) -> u32 {
        self.largest
    }

    /// The pieces (with triangles) for which `rule` holds.
    pub(crate) fn count_where(&self, rule: impl Fn(u32) -> bool) -> usize {
        (0..self.triangles.len() as u32)
            .filter(|&p| self.triangles[p as usize] > 0 && rule(p))
            .count()
    }

    /// The radius within which samples support a piece: a finest cell, or the piece's mean
    /// edge length where it is coarser (`components.rs`).
    fn radius(&self, piece: u32, finest_cell: f64) -> f64 {
        let p = piece as usize;
        let mean_edge = self.edge_sum[p] / (3 * self.triangles[p].max(1)) as f64;
        finest_cell.max(mean_edge)
    }
}

/// Counts, for every piece but the largest, the samples within its radius of one of its
/// vertices, a sample counted once per piece: each slab counts its own samples (`own(k)`,
/// unit cube) against the vertices of its part and of its neighbours' (a sample near a wall may
/// support a piece through the vertices beside it).
pub(crate) fn support(
    pieces: &Pieces,
    slabs: usize,
    finest_depth: u32,
    mut part: impl FnMut(usize) -> Result<SlabPart, OutOfCoreError>,
    mut own: impl FnMut(usize) -> Result<Vec<DVec3>, OutOfCoreError>,
) -> Result<Vec<u64>, OutOfCoreError> {
    let finest_cell = (-(finest_depth as f64)).exp2();
    let mut support = vec![0u64; pieces.triangles.len()];
    if pieces.triangles.iter().filter(|&&t| t > 0).count() <= 1 {
        return Ok(support);
    }
    for k in 0..slabs {
        // The vertices of the pieces in question around slab k, bucketed by the largest radius.
        let mut listed: Vec<(DVec3, u32)> = Vec::new();
        for j in k.saturating_sub(1)..(k + 2).min(slabs) {
            let part = part(j)?;
            for (v, &p) in part.vertices.iter().zip(&pieces.of_vertex[j]) {
                if p != pieces.largest {
                    listed.push((*v, p));
                }
            }
        }
        if listed.is_empty() {
            continue;
        }
        let bucket = listed.iter().fold(finest_cell, |a, &(_, p)| {
            a.max(pieces.radius(p, finest_cell))
        });
        let cell = |q: DVec3| -> [i64; 3] {
            let c = (q / bucket).floor();
            [c.x as i64, c.y as i64, c.z as i64]
        };
        let mut near: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
        for (i, (v, _)) in listed.iter().enumerate() {
            let c = cell(*v);
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        near.entry([c[0] + dx, c[1] + dy, c[2] + dz])
                            .or_default()
                            .push(i);
                    }
                }
            }
        }
        let mut pieces_here: Vec<u32> = Vec::new();
        for q in own(k)? {
            pieces_here.clear();
            if let Some(candidates) = near.get(&cell(q)) {
                for &i in candidates {
                    let (v, p) = listed[i];
                    let r = pieces.radius(p, finest_cell);
                    if q.distance_squared(v) <= r * r {
                        pieces_here.push(p);
                    }
                }
            }
            pieces_here.sort_unstable();
            pieces_here.dedup();
            for &p in &pieces_here {
                support[p as usize] += 1;
            }
        }
    }
    Ok(support)
}

/// Writes the kept pieces of the slabs' parts as one binary PLY at `output`: vertices in input
/// coordinates (`map`; relative to `origin` and in `double` when given, as the in-memory mesh
/// is written) with the sampling density (`value`), then the triangles. The vertex and face
/// entries go to two files in `scratch` while the slabs are read, then follow the header.
/// Returns the vertex and triangle counts.
#[allow(clippy::too_many_arguments)]
pub(crate) fn write_ply(
    output: &Path,
    scratch: &Scratch,
    slabs: usize,
    pieces: &Pieces,
    keep: &dyn Fn(u32) -> bool,
    map: &UnitCubeMap,
    origin: Option<DVec3>,
    density: &DensityField,
    mut part: impl FnMut(usize) -> Result<SlabPart, OutOfCoreError>,
) -> Result<(u64, u64), OutOfCoreError> {
    let vertex_path = scratch.file("mesh.vertices");
    let face_path = scratch.file("mesh.faces");
    let mut vertex_out = BufWriter::with_capacity(
        1 << 20,
        File::create(&vertex_path).map_err(scratch_error(
            "create the mesh's temporary files",
            &vertex_path,
        ))?,
    );
    let mut face_out = BufWriter::with_capacity(
        1 << 20,
        File::create(&face_path).map_err(scratch_error(
            "create the mesh's temporary files",
            &face_path,
        ))?,
    );
    let mut shared_ids: HashMap<u64, u32> = HashMap::new();
    let mut vertices = 0u64;
    let mut triangles = 0u64;
    for k in 0..slabs {
        let part = part(k)?;
        let of_vertex = &pieces.of_vertex[k];
        let mut id = vec![u32::MAX; part.vertices.len()];
        for (v, &p) in of_vertex.iter().enumerate() {
            if !keep(p) {
                continue;
            }
            if part.shared[v] != 0 {
                if let Some(&known) = shared_ids.get(&part.keys[v]) {
                    id[v] = known;
                    continue;
                }
            }
            if vertices >= i32::MAX as u64 {
                return Err(crate::Error::TooLarge {
                    what: "mesh vertices",
                    count: vertices as usize + 1,
                    limit: i32::MAX as usize,
                }
                .into());
            }
            id[v] = vertices as u32;
            if part.shared[v] != 0 {
                shared_ids.insert(part.keys[v], id[v]);
            }
            vertices += 1;
            let q = part.vertices[v];
            let mut entry: Vec<u8> = Vec::with_capacity(28);
            match origin {
                None => {
                    let p = map.to_input(q);
                    for c in [p.x as f32, p.y as f32, p.z as f32] {
                        entry.extend_from_slice(&c.to_le_bytes());
                    }
                }
                Some(origin) => {
                    let relative = (map.to_input(q) - origin).as_vec3();
                    for (o, c) in origin.to_array().iter().zip(relative.to_array()) {
                        entry.extend_from_slice(&(o + c as f64).to_le_bytes());
                    }
                }
            }
            entry.extend_from_slice(&(density.evaluate(q) as f32).to_le_bytes());
            vertex_out.write_all(&entry).map_err(scratch_error(
                "write the mesh's temporary files",
                &vertex_path,
            ))?;
        }
        for t in &part.triangles {
            if !keep(of_vertex[t[0] as usize]) {
                continue;
            }
            let mut entry = [0u8; 13];
            entry[0] = 3;
            for (a, &v) in t.iter().enumerate() {
                entry[1 + 4 * a..5 + 4 * a].copy_from_slice(&(id[v as usize] as i32).to_le_bytes());
            }
            face_out.write_all(&entry).map_err(scratch_error(
                "write the mesh's temporary files",
                &face_path,
            ))?;
            triangles += 1;
        }
    }
    vertex_out.flush().map_err(scratch_error(
        "write the mesh's temporary files",
        &vertex_path,
    ))?;
    face_out.flush().map_err(scratch_error(
        "write the mesh's temporary files",
        &face_path,
    ))?;
    drop((vertex_out, face_out));
    let position_type = if origin.is_some() { "double" } else { "float" };
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment written by psr {}\nelement vertex {vertices}\n\
         property {position_type} x\nproperty {position_type} y\nproperty {position_type} z\n\
         property float value\nelement face {triangles}\n\
         property list uchar int vertex_indices\nend_header\n",
        env!("CARGO_PKG_VERSION")
    );
    let output_error = |source: io::Error| OutOfCoreError::Output {
        path: output.to_path_buf(),
        source,
    };
    let mut out = BufWriter::with_capacity(1 << 20, File::create(output).map_err(output_error)?);
    let written = (|| {
        out.write_all(header.as_bytes()).map_err(output_error)?;
        for path in [&vertex_path, &face_path] {
            let mut input = BufReader::new(
                File::open(path).map_err(scratch_error("read the mesh's temporary files", path))?,
            );
            io::copy(&mut input, &mut out).map_err(output_error)?;
            std::fs::remove_file(path)
                .map_err(scratch_error("remove the mesh's temporary files", path))?;
        }
        out.flush().map_err(output_error)
    })();
    if written.is_err() {
        // No partial mesh is left under the output's name.
        drop(out);
        let _ = std::fs::remove_file(output);
    }
    written?;
    Ok((vertices, triangles))
}
