//! Evaluating the solved indicator function χ = Σ_o x_o B_o at any point.
//!
//! After the coarse-to-fine solve, every depth d holds z_d on its halo K_d: the coefficients of
//! its own unknowns plus the prolongation of everything coarser (see [`crate::system`]). So χ
//! near the core of depth d is a sum over just the 27 depth-d nodes around the point. At a point
//! p the deepest depth whose core functions reach p (p's cell has the `NEAR` flag) holds all of
//! χ(p): no finer node function is non-zero there, and every coarser one is included in z_d.

use crate::density::stencil27;
use crate::octree::{Octree, NEAR, NONE};
use crate::system::cell_of;
use glam::DVec3;

/// The solved indicator function.
pub struct Indicator<'t> {
    pub tree: &'t Octree,
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

impl Indicator<'_> {
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
                    nodes: level.block27_at(index, at),
                })
            })
    }

    /// χ(p) from the block of a point in p's cell.
    pub fn value_in(&self, block: &Block, p: DVec3) -> f64 {
        let (_, st) = stencil27(p, block.inv_h);
        let x = &self.coefficients[block.depth];
        let mut sum = 0.0;
        for (slot, &n) in block.nodes.iter().enumerate() {
            if n != NONE {
                sum += x[n as usize] * st[0][slot % 3] * st[1][(slot / 3) % 3] * st[2][slot / 9];
            }
        }
        sum
    }

    /// ∇χ(p) from the block of a point in p's cell: degree-2 B-splines have continuous first
    /// derivatives.
    pub fn gradient_in(&self, block: &Block, p: DVec3) -> DVec3 {
        let (value, slope) = stencil27_with_slopes(p, block.inv_h);
        let x = &self.coefficients[block.depth];
        let mut g = DVec3::ZERO;
        for (slot, &n) in block.nodes.iter().enumerate() {
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

/// The 27-node weights of [`stencil27`] with, per axis, the B-spline derivatives beside the
/// values (in node-width units: multiply by 1/h for d/dx).
fn stencil27_with_slopes(p: DVec3, inv_h: f64) -> ([[f64; 3]; 3], [[f64; 3]; 3]) {
    let (cell, value) = stencil27(p, inv_h);
    let t = p * inv_h;
    let mut slope = [[0.0; 3]; 3];
    for axis in 0..3 {
        for (k, slot) in slope[axis].iter_mut().enumerate() {
            *slot = crate::bspline::derivative(t[axis] - (cell[axis] as f64 - 0.5 + k as f64));
        }
    }
    (value, slope)
}
