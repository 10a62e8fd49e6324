//! Evaluating the solved indicator function χ = Σ_o x_o B_o at any point.
//!
//! After the coarse-to-fine solve, every depth d holds z_d on its halo K_d: the coefficients of
//! its own unknowns plus the prolongation of everything coarser (see [`crate::system`]). So χ
//! near the core of depth d is a sum over just the 27 depth-d nodes around the point. At a point
//! p the deepest depth whose core functions reach p (p's cell has the `NEAR` flag) holds all of
//! χ(p): no finer node function is non-zero there, and every coarser one is included in z_d.

use crate::density::stencil27;
use crate::octree::{Octree, NEAR, NONE};
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
        self.locate(p).map_or(0.0, |(d, cell, inv_h)| {
            let (_, stencil) = stencil27(p, inv_h);
            evaluate_block(&self.tree.levels[d], cell, &stencil, &self.coefficients[d])
        })
    }

    /// ∇χ(p) for a point in unit-cube coordinates (zero far outside the tree), from the same
    /// 27 nodes as [`Indicator::value`]: degree-2 B-splines have continuous first derivatives.
    pub fn gradient(&self, p: DVec3) -> DVec3 {
        self.locate(p).map_or(DVec3::ZERO, |(d, cell, inv_h)| {
            let (value, slope) = stencil27_with_slopes(p, inv_h);
            let x = &self.coefficients[d];
            let mut g = DVec3::ZERO;
            for (slot, &n) in self.tree.levels[d].block27(cell).iter().enumerate() {
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
            g * inv_h
        })
    }

    /// The deepest depth whose core functions reach p, p's cell there and 1/h of that depth.
    fn locate(&self, p: DVec3) -> Option<(usize, u32, f64)> {
        self.tree
            .levels
            .iter()
            .enumerate()
            .rev()
            .find_map(|(d, level)| {
                let inv_h = (d as f64).exp2();
                let cell = level.find(cell_of(p, inv_h))?;
                (level.flags[cell as usize] & NEAR != 0).then_some((d, cell, inv_h))
            })
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
