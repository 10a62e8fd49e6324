//! The mesh put together from the slabs' parts: the closed pieces that too few samples support
//! dropped across walls (as `components.rs` drops them in memory), then one PLY into which each
//! slab writes its vertices and triangles at offsets summed over the slabs before it, each
//! vertex on a wall written once (by the first slab that has it) and the triangles indexing it.
//! Every step is done by the team's members slab by slab ([`rounds`]); what crosses slabs (the
//! pieces' sizes, the vertices on walls, the counts) is gathered and folded in slab order, so
//! the file is the same whatever the team's size.

use super::field::FieldBySlab;
use super::scratch::{fresh_token, read_lists, write_lists, Scratch};
use super::seams::{SlabPart, SHARED_ABOVE, SHARED_BELOW};
use super::team::{checked_by_others, from_first, rounds, Packer, Team, Unpacker};
use super::OutOfCoreError;
use crate::components::vertex_components;
use crate::points::UnitCubeMap;
use glam::DVec3;
use std::collections::{BTreeMap, HashMap};
use std::fs::{File, OpenOptions};
use std::io::{self, BufWriter, Read, Seek, SeekFrom, Write};
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
        OutOfCoreError::internal("a slab's part file has the wrong number of lists")
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

/// The local pieces of one part: per vertex, its piece numbered in the order the vertices first
/// meet the pieces, and how many there are.
fn local_pieces(part: &SlabPart) -> (Vec<u32>, usize) {
    let roots = vertex_components(part.vertices.len(), &part.triangles);
    let mut number: HashMap<u32, u32> = HashMap::new();
    let of_vertex = roots
        .iter()
        .map(|root| {
            let next = number.len() as u32;
            *number.entry(*root).or_insert(next)
        })
        .collect();
    (of_vertex, number.len())
}

/// The connected pieces of the whole mesh from the slabs' parts: each part's pieces (by shared
/// vertices) are nodes, numbered slab by slab, joined where parts share a vertex. Every member
/// of the team holds the same [`Pieces`], built from a summary of each part (its pieces' sums
/// and its wall vertices), never from the parts themselves.
pub(crate) struct Pieces {
    /// Per slab, the first of its nodes (and the node count last).
    first_node: Vec<u32>,
    /// Per node, its piece of the whole mesh (the lowest node joined to it).
    piece_of_node: Vec<u32>,
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

/// Packs `list`'s (key, number, sides) entries, the vertices of a part on its walls with
/// their [`SlabPart::shared`] bits.
fn pack_walls(p: &mut Packer, list: &[(u64, u64, u8)]) {
    p.u64s(&list.iter().map(|e| e.0).collect::<Vec<_>>());
    p.u64s(&list.iter().map(|e| e.1).collect::<Vec<_>>());
    p.bytes(&list.iter().map(|e| e.2).collect::<Vec<_>>());
}

fn unpack_walls(u: &mut Unpacker<'_>) -> Result<Vec<(u64, u64, u8)>, OutOfCoreError> {
    let keys = u.u64s()?;
    let numbers = u.u64s()?;
    let sides = u.bytes()?;
    if keys.len() != numbers.len() || keys.len() != sides.len() {
        return Err(OutOfCoreError::internal("a part's wall list is cut short"));
    }
    Ok(keys
        .into_iter()
        .zip(numbers)
        .zip(sides)
        .map(|((k, n), &s)| (k, n, s))
        .collect())
}

/// Packs `list`'s (key, number) pairs as two lists.
fn pack_keyed(p: &mut Packer, list: &[(u64, u64)]) {
    p.u64s(&list.iter().map(|e| e.0).collect::<Vec<_>>());
    p.u64s(&list.iter().map(|e| e.1).collect::<Vec<_>>());
}

fn unpack_keyed(u: &mut Unpacker<'_>) -> Result<Vec<(u64, u64)>, OutOfCoreError> {
    let keys = u.u64s()?;
    let numbers = u.u64s()?;
    if keys.len() != numbers.len() {
        return Err(OutOfCoreError::internal("a part's wall list is cut short"));
    }
    Ok(keys.into_iter().zip(numbers).collect())
}

impl Pieces {
    /// Labels the pieces of the `slabs` slabs' parts (`part(k)`): each member summarises the
    /// parts of its slabs, and every member joins the summaries in slab order. A vertex on a
    /// wall is in the parts on both sides ([`SHARED_BELOW`], [`SHARED_ABOVE`]), so a part's
    /// pieces are joined to the pieces of the part below it through the keys of the wall
    /// between them.
    pub(crate) fn label(
        team: &dyn Team,
        slabs: usize,
        part: &dyn Fn(usize) -> Result<SlabPart, OutOfCoreError>,
        go_on: &mut dyn FnMut(usize) -> bool,
    ) -> Result<Pieces, OutOfCoreError> {
        let mut parent: Vec<u32> = Vec::new();
        let mut first_node: Vec<u32> = Vec::with_capacity(slabs + 1);
        let mut triangles: Vec<u64> = Vec::new();
        let mut edge_sum: Vec<f64> = Vec::new();
        // By key, the first node of each vertex on a wall that a slab not yet folded uses.
        let mut open: HashMap<u64, u32> = HashMap::new();
        rounds(
            team,
            slabs,
            |k| {
                if !go_on(k) {
                    return Err(OutOfCoreError::Reconstruction(crate::Error::Cancelled));
                }
                let part = part(k)?;
                let (of_vertex, count) = local_pieces(&part);
                let mut piece_triangles = vec![0u64; count];
                let mut piece_edges = vec![0.0f64; count];
                for t in &part.triangles {
                    let piece = of_vertex[t[0] as usize] as usize;
                    let [a, b, c] = t.map(|v| part.vertices[v as usize]);
                    piece_triangles[piece] += 1;
                    piece_edges[piece] += a.distance(b) + b.distance(c) + c.distance(a);
                }
                let walls: Vec<(u64, u64, u8)> = (0..part.vertices.len())
                    .filter(|&v| part.shared[v] != 0)
                    .map(|v| (part.keys[v], u64::from(of_vertex[v]), part.shared[v]))
                    .collect();
                let mut p = Packer::default();
                p.u64s(&piece_triangles);
                p.f64s(&piece_edges);
                pack_walls(&mut p, &walls);
                Ok(p.bytes)
            },
            |_, bytes| {
                let mut u = Unpacker::new(bytes);
                let piece_triangles = u.u64s()?;
                let piece_edges = u.f64s()?;
                let walls = unpack_walls(&mut u)?;
                if piece_edges.len() != piece_triangles.len() {
                    return Err(OutOfCoreError::internal(
                        "a part's piece sums are cut short",
                    ));
                }
                let first = parent.len() as u32;
                let count = piece_triangles.len() as u32;
                if walls.iter().any(|e| e.1 >= u64::from(count)) {
                    return Err(OutOfCoreError::internal(
                        "a part's wall vertex names a piece it does not have",
                    ));
                }
                first_node.push(first);
                parent.extend(first..first + count);
                triangles.extend(piece_triangles);
                edge_sum.extend(piece_edges);
                for (key, local, sides) in walls {
                    let here = first + local as u32;
                    let there = *open.entry(key).or_insert(here);
                    let (a, b) = (find(&mut parent, here), find(&mut parent, there));
                    if a != b {
                        parent[a.max(b) as usize] = a.min(b);
                    }
                    if sides & SHARED_ABOVE == 0 {
                        open.remove(&key);
                    }
                }
                Ok(())
            },
        )?;
        first_node.push(parent.len() as u32);
        // Pieces numbered by their roots, with their sums.
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
            first_node,
            piece_of_node: roots,
            triangles: whole_triangles,
            edge_sum: whole_edges,
            largest,
        })
    }

    /// The piece of each vertex of slab k's part.
    fn of_vertices(&self, k: usize, part: &SlabPart) -> Result<Vec<u32>, OutOfCoreError> {
        let (local, count) = local_pieces(part);
        let nodes = self.first_node[k] as usize..self.first_node[k + 1] as usize;
        if nodes.len() != count {
            return Err(OutOfCoreError::internal(
                "a part changed between its passes",
            ));
        }
        let pieces = &self.piece_of_node[nodes];
        Ok(local.into_iter().map(|l| pieces[l as usize]).collect())
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
/// support a piece through the vertices beside it). Each member counts for its slabs; the
/// counts are added on every member.
pub(crate) fn support(
    team: &dyn Team,
    pieces: &Pieces,
    slabs: usize,
    finest_depth: u32,
    part: &dyn Fn(usize) -> Result<SlabPart, OutOfCoreError>,
    own: &dyn Fn(usize) -> Result<Vec<DVec3>, OutOfCoreError>,
    go_on: &mut dyn FnMut(usize) -> bool,
) -> Result<Vec<u64>, OutOfCoreError> {
    let finest_cell = (-(finest_depth as f64)).exp2();
    let mut support = vec![0u64; pieces.triangles.len()];
    if pieces.triangles.iter().filter(|&&t| t > 0).count() <= 1 {
        return Ok(support);
    }
    rounds(
        team,
        slabs,
        |k| {
            if !go_on(k) {
                return Err(OutOfCoreError::Reconstruction(crate::Error::Cancelled));
            }
            let counted = slab_support(pieces, slabs, k, finest_cell, part, own)?;
            let mut p = Packer::default();
            pack_keyed(&mut p, &counted);
            Ok(p.bytes)
        },
        |_, bytes| {
            for (piece, count) in unpack_keyed(&mut Unpacker::new(bytes))? {
                *support.get_mut(piece as usize).ok_or_else(|| {
                    OutOfCoreError::internal("a slab's support names a piece that is not")
                })? += count;
            }
            Ok(())
        },
    )?;
    Ok(support)
}

/// Slab k's part of [`support`]: (piece, samples) for the pieces its own samples support.
fn slab_support(
    pieces: &Pieces,
    slabs: usize,
    k: usize,
    finest_cell: f64,
    part: &dyn Fn(usize) -> Result<SlabPart, OutOfCoreError>,
    own: &dyn Fn(usize) -> Result<Vec<DVec3>, OutOfCoreError>,
) -> Result<Vec<(u64, u64)>, OutOfCoreError> {
    // The vertices of the pieces in question around slab k, bucketed by the largest radius.
    let mut listed: Vec<(DVec3, u32)> = Vec::new();
    for j in k.saturating_sub(1)..(k + 2).min(slabs) {
        let part = part(j)?;
        for (v, p) in part.vertices.iter().zip(pieces.of_vertices(j, &part)?) {
            if p != pieces.largest {
                listed.push((*v, p));
            }
        }
    }
    if listed.is_empty() {
        return Ok(Vec::new());
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
    let mut counted: BTreeMap<u32, u64> = BTreeMap::new();
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
            *counted.entry(p).or_default() += 1;
        }
    }
    Ok(counted
        .into_iter()
        .map(|(p, n)| (u64::from(p), n))
        .collect())
}

/// How the kept pieces are written to one PLY: the file's header and where each slab's
/// vertices and triangles go in it, and, for each of this member's slabs, the numbers of the
/// vertices it shares with slabs below it, which the first of those writes.
pub(crate) struct MeshLayout {
    header: String,
    vertices: u64,
    triangles: u64,
    /// Per slab, the number of its first vertex and first triangle in the file.
    first_vertex: Vec<u64>,
    first_triangle: Vec<u64>,
    /// Per slab of this member (None for the others'), the numbers of its vertices that slabs
    /// below it write, by key.
    wall_below: Vec<Option<HashMap<u64, u32>>>,
    vertex_bytes: u64,
}

/// A vertex entry's bytes: three floats and the value, or three doubles and the value.
fn vertex_entry_bytes(double: bool) -> u64 {
    if double {
        28
    } else {
        16
    }
}

const TRIANGLE_ENTRY_BYTES: u64 = 13;

impl MeshLayout {
    /// Counts what each slab writes (its kept vertices but those a slab below it also uses,
    /// which the first of those writes, and its kept triangles), and numbers the vertices on
    /// walls as the file has them: each member counts its slabs, and every member adds the
    /// counts in slab order.
    pub(crate) fn plan(
        team: &dyn Team,
        pieces: &Pieces,
        slabs: usize,
        keep: &dyn Fn(u32) -> bool,
        double: bool,
        part: &dyn Fn(usize) -> Result<SlabPart, OutOfCoreError>,
    ) -> Result<MeshLayout, OutOfCoreError> {
        let (rank, size) = (team.rank(), team.size());
        let mine = |k: usize| k % size == rank;
        let mut first_vertex = Vec::with_capacity(slabs);
        let mut first_triangle = Vec::with_capacity(slabs);
        let mut wall_below: Vec<Option<HashMap<u64, u32>>> = (0..slabs).map(|_| None).collect();
        let (mut vertices, mut triangles) = (0u64, 0u64);
        // By key, the number of each vertex on a wall that a slab not yet folded uses.
        let mut open: HashMap<u64, u32> = HashMap::new();
        rounds(
            team,
            slabs,
            |k| {
                let part = part(k)?;
                let of_vertex = pieces.of_vertices(k, &part)?;
                let mut written = 0u64;
                // The kept vertices on walls: (key, number among this slab's entries or
                // FROM_BELOW, sides).
                let mut walls: Vec<(u64, u64, u8)> = Vec::new();
                for (v, &p) in of_vertex.iter().enumerate() {
                    if !keep(p) {
                        continue;
                    }
                    let number = if part.shared[v] & SHARED_BELOW != 0 {
                        FROM_BELOW
                    } else {
                        written += 1;
                        written - 1
                    };
                    if part.shared[v] != 0 {
                        walls.push((part.keys[v], number, part.shared[v]));
                    }
                }
                let kept_triangles = part
                    .triangles
                    .iter()
                    .filter(|t| keep(of_vertex[t[0] as usize]))
                    .count() as u64;
                let mut p = Packer::default();
                p.u64(written);
                p.u64(kept_triangles);
                pack_walls(&mut p, &walls);
                Ok(p.bytes)
            },
            |k, bytes| {
                let mut u = Unpacker::new(bytes);
                let written = u.u64()?;
                let kept_triangles = u.u64()?;
                let walls = unpack_walls(&mut u)?;
                first_vertex.push(vertices);
                first_triangle.push(triangles);
                let mut below = HashMap::new();
                for (key, number, sides) in walls {
                    let id = if number == FROM_BELOW {
                        let id = *open.get(&key).ok_or_else(|| {
                            OutOfCoreError::internal(
                                "a vertex on a wall is missing from the slabs below",
                            )
                        })?;
                        if mine(k) {
                            below.insert(key, id);
                        }
                        id
                    } else {
                        (vertices + number) as u32
                    };
                    if sides & SHARED_ABOVE != 0 {
                        open.insert(key, id);
                    } else {
                        open.remove(&key);
                    }
                }
                if mine(k) {
                    wall_below[k] = Some(below);
                }
                vertices += written;
                triangles += kept_triangles;
                if vertices > i32::MAX as u64 {
                    return Err(crate::Error::TooLarge {
                        what: "mesh vertices",
                        count: vertices as usize,
                        limit: i32::MAX as usize,
                    }
                    .into());
                }
                Ok(())
            },
        )?;
        let position_type = if double { "double" } else { "float" };
        let header = format!(
            "ply\nformat binary_little_endian 1.0\ncomment written by psr {}\n\
             element vertex {vertices}\n\
             property {position_type} x\nproperty {position_type} y\nproperty {position_type} z\n\
             property float value\nelement face {triangles}\n\
             property list uchar int vertex_indices\nend_header\n",
            env!("CARGO_PKG_VERSION")
        );
        Ok(MeshLayout {
            header,
            vertices,
            triangles,
            first_vertex,
            first_triangle,
            wall_below,
            vertex_bytes: vertex_entry_bytes(double),
        })
    }

    /// The file's length.
    fn file_bytes(&self) -> u64 {
        self.header.len() as u64
            + self.vertices * self.vertex_bytes
            + self.triangles * TRIANGLE_ENTRY_BYTES
    }

    /// How many of the file's last bytes carry the team's token until the slabs are written:
    /// eight, or the whole body when it is shorter (none for an empty mesh, which no member
    /// writes to).
    fn token_bytes(&self) -> usize {
        (self.file_bytes() - self.header.len() as u64).min(8) as usize
    }
}

/// In [`MeshLayout::plan`]'s summaries: the vertex is written by the slab below.
const FROM_BELOW: u64 = u64::MAX;

/// Writes the kept pieces of the slabs' parts as one binary PLY at `output`, laid out by
/// `layout`: rank 0 makes the file at its full length with the header, then each member writes
/// its slabs' vertices and triangles where `layout` puts them. Vertices are in input
/// coordinates (`map`; relative to `origin` and in `double` when given, as the in-memory mesh
/// is written) with the sampling density (`value`). On any member's error no file is left at
/// `output`. Returns the vertex and triangle counts.
#[allow(clippy::too_many_arguments)]
pub(crate) fn write_ply(
    team: &dyn Team,
    output: &Path,
    layout: &MeshLayout,
    pieces: &Pieces,
    keep: &dyn Fn(u32) -> bool,
    map: &UnitCubeMap,
    origin: Option<DVec3>,
    density: &FieldBySlab,
    part: &dyn Fn(usize) -> Result<SlabPart, OutOfCoreError>,
    go_on: &mut dyn FnMut(usize) -> bool,
) -> Result<(u64, u64), OutOfCoreError> {
    let output_error = |source: io::Error| OutOfCoreError::Output {
        path: output.to_path_buf(),
        source,
    };
    let slabs = layout.first_vertex.len();
    // Rank 0 makes the file; with more than one member its last bytes (which the last slab
    // written overwrites) hold a fresh token, and every other member must read that token in
    // the file it sees before any slab is written. A member on another machine that does not
    // share the output's file system would otherwise write its slabs into a file of its own:
    // an error if none is there, but a silently broken mesh were a file of the same length
    // left there by an earlier run.
    let alone = team.size() == 1;
    let made = from_first(
        team,
        || {
            let mut file = File::create(output).map_err(output_error)?;
            file.write_all(layout.header.as_bytes())
                .map_err(output_error)?;
            file.set_len(layout.file_bytes()).map_err(output_error)?;
            let token = fresh_token();
            if !alone {
                let mark = &token.to_le_bytes()[..layout.token_bytes()];
                file.seek(SeekFrom::Start(layout.file_bytes() - mark.len() as u64))
                    .and_then(|_| file.write_all(mark))
                    .map_err(output_error)?;
            }
            Ok(token)
        },
        |token, p| p.u64(*token),
        |u| u.u64(),
    );
    // On an error every member has it (`from_first`): no meeting to hold.
    let checked =
        made.and_then(|token| checked_by_others(team, || find_output_token(output, layout, token)));
    let written = checked.and_then(|()| {
        rounds(
            team,
            slabs,
            |k| {
                if !go_on(k) {
                    return Err(OutOfCoreError::Reconstruction(crate::Error::Cancelled));
                }
                write_slab(output, layout, k, pieces, keep, map, origin, density, part)?;
                Ok(Vec::new())
            },
            |_, _| Ok(()),
        )
    });
    if written.is_err() && team.rank() == 0 {
        // No partial mesh is left under the output's name.
        let _ = std::fs::remove_file(output);
    }
    written?;
    Ok((layout.vertices, layout.triangles))
}

/// Whether the file at `output` is the one the team's first member made: as long as the
/// layout says and ending with the first [`MeshLayout::token_bytes`] bytes of `token`.
fn find_output_token(output: &Path, layout: &MeshLayout, token: u64) -> Result<(), OutOfCoreError> {
    let not_shared = |found: &dyn std::fmt::Display| OutOfCoreError::Output {
        path: output.to_path_buf(),
        source: io::Error::other(format!(
            "{found}: this member does not see the file the team's first member made (every \
             member must write the same file: with members on several machines, one on a file \
             system they share)"
        )),
    };
    let mark = &token.to_le_bytes()[..layout.token_bytes()];
    let mut file = File::open(output).map_err(|e| not_shared(&e))?;
    let len = file.metadata().map_err(|e| not_shared(&e))?.len();
    if len != layout.file_bytes() {
        return Err(not_shared(&format!(
            "{len} bytes where the mesh takes {}",
            layout.file_bytes()
        )));
    }
    let mut found = vec![0u8; mark.len()];
    file.seek(SeekFrom::Start(len - mark.len() as u64))
        .and_then(|_| file.read_exact(&mut found))
        .map_err(|e| not_shared(&e))?;
    if found != mark {
        return Err(not_shared(&"another run's bytes"));
    }
    Ok(())
}

/// Slab k's vertices and triangles, written where `layout` puts them in `output`.
#[allow(clippy::too_many_arguments)]
fn write_slab(
    output: &Path,
    layout: &MeshLayout,
    k: usize,
    pieces: &Pieces,
    keep: &dyn Fn(u32) -> bool,
    map: &UnitCubeMap,
    origin: Option<DVec3>,
    density: &FieldBySlab,
    part: &dyn Fn(usize) -> Result<SlabPart, OutOfCoreError>,
) -> Result<(), OutOfCoreError> {
    let output_error = |source: io::Error| OutOfCoreError::Output {
        path: output.to_path_buf(),
        source,
    };
    let part = part(k)?;
    let density = density.for_vertices(
        part.vertices
            .iter()
            .fold(f64::INFINITY..=f64::NEG_INFINITY, |x, q| {
                x.start().min(q.x)..=x.end().max(q.x)
            }),
    )?;
    let of_vertex = pieces.of_vertices(k, &part)?;
    let wall_below = layout.wall_below[k].as_ref().ok_or_else(|| {
        OutOfCoreError::internal("a slab is written by a member that did not plan it")
    })?;
    let file = OpenOptions::new()
        .write(true)
        .open(output)
        .map_err(output_error)?;
    let at = |bytes: u64| -> Result<BufWriter<&File>, OutOfCoreError> {
        let mut out = BufWriter::with_capacity(1 << 20, &file);
        out.seek(SeekFrom::Start(bytes)).map_err(output_error)?;
        Ok(out)
    };
    let header = layout.header.len() as u64;
    let mut vertex_out = at(header + layout.first_vertex[k] * layout.vertex_bytes)?;
    let mut id = vec![u32::MAX; part.vertices.len()];
    let mut next = layout.first_vertex[k];
    for (v, &p) in of_vertex.iter().enumerate() {
        if !keep(p) {
            continue;
        }
        if part.shared[v] & SHARED_BELOW != 0 {
            id[v] = *wall_below.get(&part.keys[v]).ok_or_else(|| {
                OutOfCoreError::internal("a vertex on a wall is missing from the slab below")
            })?;
            continue;
        }
        id[v] = next as u32;
        next += 1;
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
        entry.extend_from_slice(&(density.evaluate(q)? as f32).to_le_bytes());
        vertex_out.write_all(&entry).map_err(output_error)?;
    }
    vertex_out.flush().map_err(output_error)?;
    drop(vertex_out);
    let end = layout
        .first_vertex
        .get(k + 1)
        .copied()
        .unwrap_or(layout.vertices);
    if next != end {
        return Err(OutOfCoreError::internal(
            "a slab wrote another number of vertices than it planned",
        ));
    }
    let mut face_out = at(header
        + layout.vertices * layout.vertex_bytes
        + layout.first_triangle[k] * TRIANGLE_ENTRY_BYTES)?;
    for t in &part.triangles {
        if !keep(of_vertex[t[0] as usize]) {
            continue;
        }
        let mut entry = [0u8; TRIANGLE_ENTRY_BYTES as usize];
        entry[0] = 3;
        for (a, &v) in t.iter().enumerate() {
            entry[1 + 4 * a..5 + 4 * a].copy_from_slice(&(id[v as usize] as i32).to_le_bytes());
        }
        face_out.write_all(&entry).map_err(output_error)?;
    }
    face_out.flush().map_err(output_error)
}
