//! The operator A_d = L_d + S_d of one depth, applied matrix-free: the Laplacian
//! ⟨∇B_o, ∇B_o′⟩ brick by brick (see [`super::bricks`]) plus the screening term (see
//! [`super::screening`]).

use super::bricks::CoreBricks;
#[cfg(doc)]
use super::rhs::{divergence, divergence_of_prolonged};
use super::screening::{padded, Proxies, ScreeningCells};
#[cfg(doc)]
use super::{fill_mirrors, update_on_core};
use crate::octree::{Level, CORE};

/// The screening term's sweep over the core bricks: each brick collects from the screening
/// cells within one node of it the 27 block values `contribute` gives for a cell (W_q χ(q) for
/// [`DepthOperator::apply`], W_q t for [`DepthOperator::add_screening_target`]), folded back
/// across the cube's faces with the level's sign, and adds α times them to its core nodes in
/// `out`.
fn screening_sweep(
    level: &Level,
    bricks: &CoreBricks,
    cells: &ScreeningCells,
    scale: f64,
    out: &mut [f64],
    proxy: impl Fn(usize, usize) -> ([[f64; 3]; 3], f64) + Sync,
) {
    bricks.for_each_brick::<0, ()>(
        |_, _, _| {},
        out,
        vec![(); bricks.len()],
        |_, scratch, cb, core_nodes, ()| {
            let acc = &mut scratch.screened;
            acc.fill(0.0);
            cells.accumulate(level, cb, &bricks.around[cb], level.face_sign, acc, &proxy);
            core_nodes.for_each(|o, [x, y, z]| *o += scale * acc[padded(x, y, z)]);
        },
    );
}

/// The operator A_d = L_d + S_d of one depth, with its scratch space.
pub struct DepthOperator<'a> {
    pub level: &'a Level,
    pub proxies: &'a Proxies,
    /// Weight of the screening term.
    pub screening: f64,
    /// The bricks holding core nodes: the Laplacian is applied brick by brick.
    bricks: CoreBricks,
    /// The cells whose proxies screen this depth, by brick (`None` without screening).
    screening_cells: Option<ScreeningCells>,
    /// W_q χ(q) at every proxy during a product (empty without screening).
    weighted_chi: Vec<f64>,
    /// Degree 1 with Neumann boundaries: the core nodes on the cube's faces (by position in
    /// the core) and the scale of their Laplacian rows ([`Level::face_scale`]).
    face_rows: Vec<(usize, f64)>,
}

impl<'a> DepthOperator<'a> {
    /// `screening` is the weight α_d of the screening term at this depth.
    pub fn new(level: &'a Level, proxies: &'a Proxies, screening: f64) -> Self {
        let screens = screening > 0.0 && !proxies.is_empty();
        // The proxies' stencils (their degree) and the sweeps over the level's blocks (the
        // level's degree: degree 1 skips the block's first node on each axis) must agree.
        assert!(
            !screens || proxies.degree == level.degree,
            "proxies of degree {:?} on a level of degree {:?}",
            proxies.degree,
            level.degree
        );
        let bricks = CoreBricks::new(level);
        let screening_cells = screens.then(|| ScreeningCells::new(level, proxies, &bricks));
        let face_rows = level
            .faces
            .iter()
            .filter(|f| level.flags[f.inside as usize] & CORE != 0)
            .map(|f| {
                let position = level.core.partition_point(|&c| c < f.inside);
                (position, Level::face_scale(f.flips))
            })
            .collect();
        DepthOperator {
            level,
            proxies,
            screening,
            bricks,
            screening_cells,
            weighted_chi: if screens {
                vec![0.0; proxies.len()]
            } else {
                Vec::new()
            },
            face_rows,
        }
    }

    /// The core nodes on the cube's faces whose rows are scaled, and their scales (degree 1
    /// with Neumann boundaries; empty otherwise): the right-hand side's rows ⟨∇B_o, V⟩ there
    /// must be scaled likewise.
    pub fn face_rows(&self) -> &[(usize, f64)] {
        &self.face_rows
    }

    /// The Laplacian's output at the face rows times their scales.
    fn scale_face_rows(&self, out: &mut [f64]) {
        for &(position, scale) in &self.face_rows {
            out[position] *= scale;
        }
    }

    /// `out[c]` = (A · input)(core node c), for `input` given on all of K_d with its mirror
    /// nodes filled (see [`fill_mirrors`]): the prolonged coarser solution, or a
    /// conjugate-gradient direction (zero beyond the core but at the mirrors, see
    /// [`update_on_core`]).
    ///
    /// The Laplacian h·(D⊗M⊗M + M⊗D⊗M + M⊗M⊗D) is applied brick by brick (see `CoreBricks`);
    /// the screening term α·Σ_q W_q B_o(q) χ(q) in two sweeps over the bricks (see
    /// `ScreeningCells`): W_q χ(q) at every proxy, read from the Laplacian's input window of the
    /// proxy's brick, then each core brick collects from the proxies within one node of it.
    pub fn apply(&mut self, input: &[f64], out: &mut [f64]) {
        let level = self.level;
        let proxies = self.proxies;
        let bricks = &self.bricks;
        let Some(cells) = &self.screening_cells else {
            bricks.laplacian(level, input, level.width(), None, out);
            self.scale_face_rows(out);
            return;
        };
        let chi = &mut self.weighted_chi;
        bricks.laplacian(
            level,
            input,
            level.width(),
            Some((cells, proxies, chi)),
            out,
        );
        for &(position, scale) in &self.face_rows {
            out[position] *= scale;
        }
        cells.weigh_outside_core_bricks(level, proxies, input, chi);
        let chi = &*chi;
        screening_sweep(level, bricks, cells, self.screening, out, |slot, q| {
            (proxies.stencil(q), chi[slot])
        });
    }

    /// Adds α·Σ_q W_q t φ_o(q) to `out[c]` at every core node c (in core order), φ_o the
    /// node's folded function: the right-hand side that turns the screening term
    /// α·Σ_q W_q χ(q)² into α·Σ_q W_q (χ(q) − t)², pulling χ to `target` t at the samples
    /// instead of to 0. Nothing without screening. Summed as [`DepthOperator::apply`]'s
    /// screening sweep sums, with W_q t in place of W_q χ(q), into `out` itself (no vector
    /// beside it).
    pub fn add_screening_target(&mut self, target: f64, out: &mut [f64]) {
        let level = self.level;
        let proxies = self.proxies;
        let bricks = &self.bricks;
        let Some(cells) = &self.screening_cells else {
            return;
        };
        screening_sweep(level, bricks, cells, self.screening, out, |_, q| {
            (proxies.stencil(q), proxies.weight[q] * target)
        });
    }

    /// ⟨∇B_o, V⟩ at every core node (in core order) for a field V whose coefficients on K_d
    /// (x, y, z at node n) `v(n)` gives: [`divergence`] restricted to the core, computed brick
    /// by brick as (1/h)·(G_x(M_y M_z v_x) + M_x(G_y M_z v_y + M_y G_z v_z)). `v` is called
    /// once per node for every brick window it lies in (about 3.4 times on average). The
    /// pipeline uses [`divergence_of_prolonged`]; this is the node-by-node
    /// reference the tests check it and [`divergence`] against.
    #[cfg(test)]
    pub fn divergence_on_core(&mut self, v: impl Fn(usize) -> [f64; 3] + Sync) -> Vec<f64> {
        let level = self.level;
        let bricks = &self.bricks;
        let mut out = vec![0.0; level.core.len()];
        bricks.divergence(
            |cb, windows, _| bricks.gather(level, cb, &v, windows),
            level.degree,
            1.0 / level.width(),
            &mut out,
        );
        out
    }

    /// The diagonal of A on the core (for Jacobi preconditioning).
    pub fn diagonal(&mut self) -> Vec<f64> {
        let level = self.level;
        let t = level.degree.tables();
        let lap = level.width() * 3.0 * t.stiffness[2] * t.mass[2] * t.mass[2];
        let mut out = vec![lap; level.core.len()];
        self.scale_face_rows(&mut out);
        let Some(cells) = &self.screening_cells else {
            return out;
        };
        let proxies = self.proxies;
        let scale = self.screening;
        self.bricks.for_each_brick::<0, ()>(
            |_, _, _| {},
            &mut out,
            vec![(); self.bricks.len()],
            |_, scratch, cb, core_nodes, ()| {
                let acc = &mut scratch.screened;
                acc.fill(0.0);
                cells.accumulate(level, cb, &self.bricks.around[cb], 1.0, acc, |_, q| {
                    let squared = proxies.stencil(q).map(|axis| axis.map(|b| b * b));
                    (squared, proxies.weight[q])
                });
                core_nodes.for_each(|o, [x, y, z]| *o += scale * acc[padded(x, y, z)]);
            },
        );
        out
    }
}
