//! Evaluating the solved indicator function χ = Σ_o x_o B_o at any point.
//!
//! After the coarse-to-fine solve, every depth d holds z_d on its halo K_d: the coefficients of
//! its own unknowns plus the prolongation of everything coarser (see [`crate::system`]). So χ
//! near the core of depth d is a sum over just the 27 depth-d nodes around the point. At a point
//! p the deepest depth whose core functions reach p (p's cell has the `NEAR` flag) holds all of
//! χ(p): no finer node function is non-zero there, and every coarser one is included in z_d.

#[cfg(test)]
use crate::bspline::stencil27;
use crate::bspline::Degree;
use crate::grid::cell_of;
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

    /// χ at the eight corners (x + 2y + 4z) of a cell of the finest depth, from that cell's 27
    /// nodes (`nodes`, as [`crate::octree::Level::block27_at`] gives them): at each corner the
    /// value [`Indicator::value`] gives, bit for bit, when the corner's own cell at the finest
    /// depth is reached by core functions, `None` otherwise (χ there comes from a coarser
    /// depth). At a corner the B-spline weights per axis of the corner's block are ½, ½ and 0
    /// (exactly), so the sum runs over the eight nodes that touch the corner, all in the
    /// cell's block: the corners of a cell need no look-up of their own, and its 27
    /// coefficients are read once for all of them. With degree 1 the weights are 0, 1 and 0:
    /// χ at a corner is the coefficient of the node on it.
    pub fn finest_corner_values(&self, nodes: &[u32; 27]) -> [Option<f64>; 8] {
        let depth = self.tree.levels.len() - 1;
        let flags = &self.tree.levels[depth].flags;
        let linear = self.tree.levels[depth].degree == Degree::One;
        let x = &self.coefficients[depth];
        let coefficient = nodes.map(|n| (n != NONE).then(|| x[n as usize]));
        std::array::from_fn(|corner| {
            let c = [corner & 1, corner >> 1 & 1, corner >> 2 & 1];
            let own = nodes[(1 + c[0]) + 3 * (1 + c[1]) + 9 * (1 + c[2])];
            if own == NONE || flags[own as usize] & NEAR == 0 {
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

    /// The corners of every cell of the finest depth, read off the cell's 27 nodes, give
    /// [`Indicator::value`] bit for bit wherever the shortcut applies, on a sparse tree (cells
    /// at the edge of the refined region fall back) with arbitrary coefficients.
    #[test]
    fn corner_values_from_the_cells_nodes_match_the_point_evaluation() {
        let cells: Vec<Vec<[i32; 3]>> = (0..=5)
            .map(|d| {
                let n = 1 << d;
                (0..n)
                    .flat_map(|i| [[i, i / 2, n / 3], [n - 1 - i, i, i / 3]])
                    .collect()
            })
            .collect();
        let tree = Octree::build(cells, 2, Boundary::Neumann);
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
        let depth = chi.tree.levels.len() - 1;
        let level = &chi.tree.levels[depth];
        let h = 1.0 / (1u32 << depth) as f64;
        let (mut shortcut, mut fallback) = (0, 0);
        for i in 0..level.len() as u32 {
            let cell = level.coord(i);
            let Some((index, at)) = level.find_place(cell) else {
                continue;
            };
            let nodes = level.block27_at(index, at);
            let values = chi.finest_corner_values(&nodes);
            for (corner, value) in values.into_iter().enumerate() {
                let p = DVec3::new(
                    (cell[0] + (corner & 1) as i32) as f64,
                    (cell[1] + (corner >> 1 & 1) as i32) as f64,
                    (cell[2] + (corner >> 2 & 1) as i32) as f64,
                ) * h;
                assert_eq!(stencil27(p, 1.0 / h).1, [[0.5, 0.5, 0.0]; 3]);
                match value {
                    Some(v) => {
                        assert_eq!(v.to_bits(), chi.value(p).to_bits(), "{cell:?} {corner}");
                        shortcut += 1;
                    }
                    None => fallback += 1,
                }
            }
        }
        assert!(shortcut > 1000 && fallback > 0, "{shortcut} {fallback}");
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
