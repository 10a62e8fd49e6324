//! Evaluating the solved indicator function χ = Σ_o x_o B_o at any point.
//!
//! After the coarse-to-fine solve, every depth d holds z_d on its halo K_d: the coefficients of
//! its own unknowns plus the prolongation of everything coarser (see [`crate::system`]). So χ
//! near the core of depth d is a sum over just the 27 depth-d nodes around the point. At a point
//! p the deepest depth whose core functions reach p (p's cell has the `NEAR` flag) holds all of
//! χ(p): no finer node function is non-zero there, and every coarser one is included in z_d.

use crate::density::stencil27;
use crate::octree::{Octree, NEAR};
use crate::system::{cell_of, evaluate_block};
use glam::DVec3;

/// The solved indicator function.
pub struct Indicator<'t> {
    pub tree: &'t Octree,
    /// z_d on K_d for every depth.
    pub coefficients: Vec<Vec<f64>>,
}

impl Indicator<'_> {
    /// χ(p) for a point in unit-cube coordinates (0 far outside the tree).
    pub fn value(&self, p: DVec3) -> f64 {
        for (d, level) in self.tree.levels.iter().enumerate().rev() {
            let inv_h = (d as f64).exp2();
            if let Some(cell) = level.find(cell_of(p, inv_h)) {
                if level.flags[cell as usize] & NEAR != 0 {
                    let (_, stencil) = stencil27(p, inv_h);
                    return evaluate_block(level, cell, &stencil, &self.coefficients[d]);
                }
            }
        }
        0.0
    }
}
