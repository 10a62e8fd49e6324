//! Evaluating the solved indicator function χ = Σ_o x_o B_o at any point.
//!
//! After the coarse-to-fine solve, every depth d holds z_d on its halo K_d: the coefficients of
//! its own unknowns plus the prolongation of everything coarser (see [`crate::system`]). So χ
//! near the core of depth d is a sum over just the 27 depth-d nodes around the point. At a point
//! p the deepest depth whose core functions reach p (p's cell has the `NEAR` flag) holds all of
//! χ(p): no finer node function is non-zero there, and every coarser one is included in z_d.

use crate::bspline::Degree;
use crate::grid::cell_of;
#[cfg(test)]
use crate::octree::SPLIT;
use crate::octree::{Octree, NEAR, NONE};
use glam::DVec3;

/// The solved indicator function: it owns the octree its coefficients live on, so that it can
/// outlive the reconstruction (`crate::ImplicitFunction`).
pub struct Indicator {
    pub tree: Octree,
    /// z_d on K_d for every depth.
    pub coefficients: Vec<Vec<f64>>,
}

/// Where χ near a point comes from: the deepest depth whose core functions reach the point and
/// the 27 nodes around the point's cell there (`NONE` where the halo has none). Points in the
/// same cell of the finest depth share it.
pub struct Block {
    depth: usize,
    inv_h: f64,
    nodes: [u32; 27],
}

impl Indicator {
    /// χ(p) for a point in unit-cube coordinates (0 far outside the tree).
    pub fn value(&self, p: DVec3) -> f64 {
        self.block(p).map_or(0.0, |b| self.value_in(&b, p))
    }

    /// ∇χ(p) for a point in unit-cube coordinates (zero far outside the tree).
    pub fn gradient(&self, p: DVec3) -> DVec3 {
        self.block(p)
            .map_or(DVec3::ZERO, |b| self.gradient_in(&b, p))
    }

    /// The block χ(p) comes from, `None` far outside the tree.
    pub fn block(&self, p: DVec3) -> Option<Block> {
        self.tree
            .levels
            .iter()
            .enumerate()
            .rev()
            .find_map(|(depth, level)| {
                let inv_h = (depth as f64).exp2();
                let cell = cell_of(p, inv_h);
                let (index, at) = level.find_place(cell)?;
                (level.flags[index as usize] & NEAR != 0).then(|| Block {
                    depth,
                    inv_h,
                    // Only the slots `block_slots` visits: at degree 1 the cell's corners.
                    nodes: if level.degree.first_node() == 1 {
                        level.corner_block_at(index, at)
                    } else {
                        level.block27_at(index, at)
                    },
                })
            })
    }

    /// χ(p) from the block of a point in p's cell.
    pub fn value_in(&self, block: &Block, p: DVec3) -> f64 {
        let degree = self.tree.levels[block.depth].degree;
        let (_, st) = degree.stencil27(p, block.inv_h);
        let x = &self.coefficients[block.depth];
        let mut sum = 0.0;
        for slot in block_slots(degree) {
            let n = block.nodes[slot];
            if n != NONE {
                sum += x[n as usize] * st[0][slot % 3] * st[1][(slot / 3) % 3] * st[2][slot / 9];
            }
        }
        sum
    }

    /// χ at the eight corners (x + 2y + 4z) of a cell of depth `depth`, from that cell's 27
    /// nodes there (`nodes`, as [`crate::octree::Level::block27_at`] gives them; `split`: bit
    /// `s` set when the node in slot `s` is `SPLIT`): at each corner the value
    /// [`Indicator::value`] gives, bit for bit, when the corner's own cell at depth `depth` is
    /// reached by core functions and no finer depth's cell is, `None` otherwise (χ there comes
    /// from another depth).
    ///
    /// No finer depth reaches a corner unless one of the eight nodes of depth `depth` around it
    /// (slots c − 1 and c per axis, c the corner's) is split: a cell of depth D > `depth` is
    /// `NEAR` only within one node of a core node of depth D, that node's ancestor at `depth`
    /// lies within those eight (floor((2^k p ± 1) / 2^k) is p or p − 1), and every ancestor of
    /// a core node is split. At the finest depth nothing is split.
    ///
    /// At a corner the B-spline weights per axis of the corner's block are ½, ½ and 0
    /// (exactly), so the sum runs over the eight nodes that touch the corner, all in the
    /// cell's block: the corners of a cell need no look-up of their own, and its 27
    /// coefficients are read once for all of them. With degree 1 the weights are 0, 1 and 0:
    /// χ at a corner is the coefficient of the node on it.
    pub fn corner_values(&self, depth: u32, nodes: &[u32; 27], split: u32) -> [Option<f64>; 8] {
        let depth = depth as usize;
        let flags = &self.tree.levels[depth].flags;
        let linear = self.tree.levels[depth].degree == Degree::One;
        let x = &self.coefficients[depth];
        // Degree 1 reads only each corner's own node: not the 27 (scattered reads, a tenth of
        // a degree-1 extraction's time on the bunny scans at depth 10).
        let coefficient = if linear {
            [None; 27]
        } else {
            nodes.map(|n| (n != NONE).then(|| x[n as usize]))
        };
        std::array::from_fn(|corner| {
            let c = [corner & 1, corner >> 1 & 1, corner >> 2 & 1];
            let own = nodes[(1 + c[0]) + 3 * (1 + c[1]) + 9 * (1 + c[2])];
            if own == NONE || flags[own as usize] & NEAR == 0 || split & CORNER_NODES[corner] != 0 {
                return None;
            }
            if linear {
                // `value_in`'s sum has one non-zero term, weight 1 · 1 · 1.
                return Some(x[own as usize]);
            }
            // `value_in`'s sum over the corner's block, in its order, without the slots of
            // weight zero; slot (i, j, k) there is node (c + i, c + j, c + k) of the cell's block.
            let mut sum = 0.0;
            for k in 0..2 {
                for j in 0..2 {
                    for i in 0..2 {
                        if let Some(x) = coefficient[(c[0] + i) + 3 * (c[1] + j) + 9 * (c[2] + k)] {
                            sum += x * 0.5 * 0.5 * 0.5;
                        }
                    }
                }
            }
            Some(sum)
        })
    }

    /// ∇χ(p) from the block of a point in p's cell: degree-2 B-splines have continuous first
    /// derivatives.
    ///
    /// With degree 1, ∇χ is discontinuous across cell faces: this is the gradient of the
    /// trilinear piece in the cell of p at the block's depth (the cell `block` was found from).
    pub fn gradient_in(&self, block: &Block, p: DVec3) -> DVec3 {
        let (value, slope) = self.tree.levels[block.depth]
            .degree
            .stencil27_with_slopes(p, block.inv_h);
        let x = &self.coefficients[block.depth];
        let mut g = DVec3::ZERO;
        for slot in block_slots(self.tree.levels[block.depth].degree) {
            let n = block.nodes[slot];
            if n == NONE {
                continue;
            }
            let (i, j, k) = (slot % 3, (slot / 3) % 3, slot / 9);
            g += x[n as usize]
                * DVec3::new(
                    slope[0][i] * value[1][j] * value[2][k],
                    value[0][i] * slope[1][j] * value[2][k],
                    value[0][i] * value[1][j] * slope[2][k],
                );
        }
        g * block.inv_h
    }
}

/// Per corner of a cell (x + 2y + 4z): the slots of its block (x fastest) of the eight nodes
/// around that corner, those with slot c or c + 1 per axis (node offsets c − 1 and c), as a
/// bit mask.
const CORNER_NODES: [u32; 8] = {
    let mut masks = [0u32; 8];
    let mut corner = 0;
    while corner < 8 {
        let mut slot = 0;
        while slot < 27 {
            let (i, j, k) = (slot % 3, (slot / 3) % 3, slot / 9);
            let (a, b, c) = (corner & 1, corner >> 1 & 1, corner >> 2 & 1);
            if (i == a || i == a + 1) && (j == b || j == b + 1) && (k == c || k == c + 1) {
                masks[corner] |= 1 << slot;
            }
            slot += 1;
        }
        corner += 1;
    }
    masks
};

/// The slots of a block (x fastest) whose functions can be non-zero in its cell, in slot
/// order: those whose nodes are all from [`Degree::first_node`] on, i.e. all 27 at degree 2
/// and the 8 on the cell's corners at degree 1 (what is left out has value and slope exactly
/// zero there, so that leaving it out changes no sum).
fn block_slots(degree: Degree) -> impl Iterator<Item = usize> {
    const ALL: [u8; 27] = [
        0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23, 24,
        25, 26,
    ];
    // The slots with every axis's node at 1 or 2.
    const CORNERS: [u8; 8] = [13, 14, 16, 17, 22, 23, 25, 26];
    let slots: &'static [u8] = if degree.first_node() == 1 {
        &CORNERS
    } else {
        &ALL
    };
    slots.iter().map(|&slot| slot as usize)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Boundary;

    /// The corners of every cell of every depth, read off the cell's 27 nodes and their split
    /// flags, give [`Indicator::value`] bit for bit wherever the shortcut applies, on sparse
    /// trees of both degrees (cells at the edge of the refined region fall back, and so do the
    /// corners beside split nodes, where a finer depth holds χ) with arbitrary coefficients.
    #[test]
    fn corner_values_from_the_cells_nodes_match_the_point_evaluation() {
        for degree in [Degree::One, Degree::Two] {
            let cells: Vec<Vec<[i32; 3]>> = (0..=5)
                .map(|d| {
                    let n = 1 << d;
                    (0..n)
                        .flat_map(|i| [[i, i / 2, n / 3], [n - 1 - i, i, i / 3]])
                        .collect()
                })
                .collect();
            let tree = Octree::build_for(cells, 2, Boundary::Neumann, degree);
            let coefficients: Vec<Vec<f64>> = tree
                .levels
                .iter()
                .map(|l| {
                    (0..l.len())
                        .map(|i| ((i * 7919) % 101) as f64 / 7.0 - 6.0)
                        .collect()
                })
                .collect();
            let chi = Indicator { tree, coefficients };
            let finest = chi.tree.levels.len() - 1;
            // Corners given at the finest depth and at coarser ones; corners whose own node is
            // NEAR but that fall back for a split node beside them, and how many of those the
            // cell's own depth would have got wrong.
            let (mut finest_given, mut coarser_given) = (0, 0);
            let (mut split_beside, mut finer_differs) = (0, 0);
            for (depth, level) in chi.tree.levels.iter().enumerate().skip(1) {
                let h = 1.0 / (1u32 << depth) as f64;
                for i in 0..level.len() as u32 {
                    let cell = level.coord(i);
                    let Some((index, at)) = level.find_place(cell) else {
                        continue;
                    };
                    let nodes = level.block27_at(index, at);
                    let split = (0..27)
                        .filter(|&s| {
                            nodes[s] != NONE && level.flags[nodes[s] as usize] & SPLIT != 0
                        })
                        .fold(0u32, |m, s| m | 1 << s);
                    let given = chi.corner_values(depth as u32, &nodes, split);
                    let unsplit = chi.corner_values(depth as u32, &nodes, 0);
                    for corner in 0..8 {
                        let p = DVec3::new(
                            (cell[0] + (corner & 1) as i32) as f64,
                            (cell[1] + (corner >> 1 & 1) as i32) as f64,
                            (cell[2] + (corner >> 2 & 1) as i32) as f64,
                        ) * h;
                        let weights = level.degree.stencil27(p, 1.0 / h).1;
                        match degree {
                            Degree::One => assert_eq!(weights, [[0.0, 1.0, 0.0]; 3]),
                            Degree::Two => assert_eq!(weights, [[0.5, 0.5, 0.0]; 3]),
                        }
                        let value = chi.value(p);
                        match (given[corner], unsplit[corner]) {
                            (Some(v), _) => {
                                assert_eq!(
                                    v.to_bits(),
                                    value.to_bits(),
                                    "{depth} {cell:?} {corner}"
                                );
                                if depth == finest {
                                    finest_given += 1;
                                } else {
                                    coarser_given += 1;
                                }
                            }
                            (None, Some(v)) => {
                                split_beside += 1;
                                finer_differs += usize::from(v != value);
                            }
                            (None, None) => {}
                        }
                    }
                }
            }
            assert!(
                finest_given > 1000 && coarser_given > 1000 && finer_differs > 100,
                "{degree:?}: {finest_given} {coarser_given} {split_beside} {finer_differs}"
            );
        }
    }

    /// With coefficients extended by the mirrors (node centres at i + ½, so node −1 − i is
    /// node i's image across the face at 0), Dirichlet's odd extension makes χ vanish on every
    /// face of the cube and Neumann's even one makes its normal derivative vanish there, for
    /// arbitrary coefficients; inside, χ is not zero.
    #[test]
    fn mirrors_put_the_boundary_condition_on_the_faces() {
        for boundary in [Boundary::Neumann, Boundary::Dirichlet] {
            let tree = Octree::build(vec![Vec::new(); 4], 3, boundary);
            let coefficients: Vec<Vec<f64>> = tree
                .levels
                .iter()
                .enumerate()
                .map(|(d, l)| {
                    let mut x = vec![0.0; l.len()];
                    if d == 3 {
                        crate::system::update_on_core(l, &mut x, |i, _| {
                            ((i * 7919) % 101) as f64 / 7.0 - 6.0
                        });
                    }
                    x
                })
                .collect();
            let chi = Indicator { tree, coefficients };
            let mut worst = 0.0f64;
            let mut inside = 0.0f64;
            for k in 0..=40 {
                for j in 0..=40 {
                    let (u, v) = (k as f64 / 40.0, j as f64 / 40.0);
                    for axis in 0..3 {
                        for face in [0.0, 1.0] {
                            let mut p = [u, v, u * v];
                            p[axis] = face;
                            let p = DVec3::from_array(p);
                            let on_face = if boundary == Boundary::Dirichlet {
                                chi.value(p)
                            } else {
                                chi.gradient(p)[axis]
                            };
                            worst = worst.max(on_face.abs());
                        }
                    }
                    inside = inside.max(chi.value(DVec3::new(0.1 + 0.8 * u, 0.5, v)).abs());
                }
            }
            assert!(
                worst < 1e-9 && inside > 1.0,
                "{boundary:?}: {worst} {inside}"
            );
        }
    }
}
