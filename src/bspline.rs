//! The B-spline node functions and their exact 1-D inner-product tables (§4.1, §4.3): degree 2
//! (the default) and degree 1 ([`Degree`]).
//!
//! The base function is the box filter convolved with itself three times,
//! `b(t) = 3/4 − t²` for |t| ≤ 1/2, `(|t| − 3/2)²/2` for 1/2 ≤ |t| ≤ 3/2, and 0 beyond: support
//! [−1.5, 1.5], unit integral, and its integer translates sum to one. A node o at depth d with
//! integer index i (centre (i + ½)·h, width h = 2^−d) carries B_o(p) = Π_axes b(p/h − i − ½).
//!
//! Every inner product the system needs is a product of three 1-D integrals of b and b′ between
//! two translates δ = i′ − i apart at the same depth (cross-depth terms are handled exactly by
//! the two-scale relation, see [`REFINE`]). With t in node widths:
//!
//! * `M(δ) = ∫ b(t) b(t−δ) dt` (mass), so ∫B_o B_o′ = h³ M M M;
//! * `D(δ) = ∫ b′(t) b′(t−δ) dt` (stiffness), so ∫∇B_o·∇B_o′ = h (D M M + M D M + M M D);
//! * `G(δ) = ∫ b′(t) b(t−δ) dt` (advection), so ∫∂_x B_o B_o′ = h² G M M.
//!
//! The tables are integrated exactly (Gauss–Legendre, exact for these piecewise polynomials on
//! each piece) when first used; no numerical integration happens at reconstruction time.
//!
//! **Degree 1** (PoissonRecon's and Open3D's default) uses the hat `b₁(t) = max(0, 1 − |t|)`,
//! support [−1, 1]. Hats centred on cell centres do not nest (a coarse hat's kinks fall on fine
//! cell corners, where no fine hat has one), so degree-1 node functions sit on cell *corners*:
//! the node with integer index i carries b₁(p/h − i), centred on its cell's lower corner i·h
//! (degree 2 centres node i at (i + ½)·h). The nodes whose functions are non-zero in cell c are
//! then c and c + 1 along each axis, a subset of degree 2's c − 1, c, c + 1, so the same octree
//! node sets, 3×3×3 blocks and 5-wide windows hold them (the first slot of a block and the
//! outer taps of the tables are zero). Its tables over δ ∈ [−1, 1] are M = (1/6, 2/3, 1/6),
//! D = (−1, 2, −1), G = (½, 0, −½), and the two-scale relation is the node at coarse corner i =
//! fine corner 2i + ½·(fine corners 2i ± 1) ([`Degree::refine`]).

use crate::grid::cell_of;
use glam::DVec3;
use std::sync::OnceLock;

/// Two-scale relation: a node function at depth d equals the sum over the four child-depth
/// translates 2i−1, 2i, 2i+1, 2i+2 with these weights (index 0 ↔ offset −1).
pub const REFINE: [f64; 4] = [0.25, 0.75, 0.75, 0.25];

/// b(t), the degree-2 B-spline.
#[inline]
pub fn value(t: f64) -> f64 {
    let a = t.abs();
    if a < 0.5 {
        0.75 - a * a
    } else if a < 1.5 {
        let u = a - 1.5;
        0.5 * u * u
    } else {
        0.0
    }
}

/// b′(t).
#[inline]
pub fn derivative(t: f64) -> f64 {
    let a = t.abs();
    let d = if a < 0.5 {
        -2.0 * a
    } else if a < 1.5 {
        a - 1.5
    } else {
        0.0
    };
    if t < 0.0 {
        -d
    } else {
        d
    }
}

/// The degree of the node functions: 2 (the default, continuous gradients) or 1 (hats, half the
/// stencil width per axis). See the module documentation for where the nodes sit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Degree {
    /// Piecewise-linear hats centred on cell corners.
    One,
    /// Piecewise-quadratic B-splines centred on cell centres.
    #[default]
    Two,
}

impl Degree {
    /// Where node i's function is centred, in node widths: i + this.
    #[cfg(test)]
    pub fn centre_offset(self) -> f64 {
        match self {
            Degree::One => 0.0,
            Degree::Two => 0.5,
        }
    }

    /// The 1-D base function at `t` node widths from its centre.
    #[cfg(test)]
    pub fn value(self, t: f64) -> f64 {
        match self {
            Degree::One => hat(t),
            Degree::Two => value(t),
        }
    }

    /// How many nodes the same-depth tables reach on each side: 2 at degree 2, 1 at degree 1
    /// (whose tables are zero at δ = ±2).
    #[inline]
    pub fn table_reach(self) -> usize {
        match self {
            Degree::One => 1,
            Degree::Two => 2,
        }
    }

    /// Of the three nodes per axis around a cell (c − 1, c, c + 1, as [`Degree::stencil27`]
    /// lists them), the first whose function can be non-zero in the cell: 1 at degree 1 (node
    /// c − 1's hat, on the corner below the cell, is zero there with its slope), 0 at degree 2.
    /// Sums over a cell's 3×3×3 block may start at this node on every axis: what they leave
    /// out is exactly zero.
    #[inline]
    pub fn first_node(self) -> usize {
        match self {
            Degree::One => 1,
            Degree::Two => 0,
        }
    }

    /// The offsets, per axis, of the nodes whose functions are non-zero in the cell c
    /// (from node c + first offset to node c + last): c − 1..=c + 1 at degree 2, the cell's
    /// corners c..=c + 1 at degree 1 (see [`Degree::first_node`]).
    pub fn nodes_over_a_cell(self) -> std::ops::RangeInclusive<i32> {
        self.first_node() as i32 - 1..=1
    }

    /// The same-depth tables (5 wide for both degrees: degree 1's are zero at δ = ±2).
    pub fn tables(self) -> &'static Tables {
        match self {
            Degree::One => {
                static TABLES: OnceLock<Tables> = OnceLock::new();
                TABLES.get_or_init(|| Tables {
                    mass: offsets(|t, d| hat(t) * hat(t - d)),
                    stiffness: offsets(|t, d| hat_derivative(t) * hat_derivative(t - d)),
                    advection: offsets(|t, d| hat_derivative(t) * hat(t - d)),
                })
            }
            Degree::Two => tables(),
        }
    }

    /// The two-scale relation along one axis, seen from a fine node: a fine node of coordinate
    /// f = 2m + parity takes `[own, partner]` = `refine(parity)` of the coarse nodes m and
    /// m − 1 (parity 0) or m + 1 (parity 1). Degree 2: ¾ and ¼ either way ([`REFINE`]); degree
    /// 1: a fine corner on a coarse corner takes all of it (1, 0), one between two coarse
    /// corners half of each (½, ½).
    #[inline]
    pub fn refine(self, parity: usize) -> [f64; 2] {
        match (self, parity & 1) {
            (Degree::Two, _) => [REFINE[1], REFINE[0]],
            (Degree::One, 0) => [1.0, 0.0],
            (Degree::One, _) => [0.5, 0.5],
        }
    }

    /// [`stencil27`] for this degree: the nodes c − 1, c, c + 1 per axis around the cell c
    /// holding `p` and their function values at `p` (degree 1: the first is 0).
    #[inline]
    pub fn stencil27(self, p: DVec3, inv_h: f64) -> ([i32; 3], [[f64; 3]; 3]) {
        match self {
            Degree::Two => stencil27(p, inv_h),
            Degree::One => {
                let t = p * inv_h;
                let c = cell_of(p, inv_h);
                let w = std::array::from_fn(|axis| {
                    let f = t[axis] - c[axis] as f64;
                    [0.0, 1.0 - f, f]
                });
                (c, w)
            }
        }
    }

    /// [`Degree::stencil27`] with, per axis, the derivatives beside the values (in node
    /// widths), of the pieces in p's cell.
    #[inline]
    pub fn stencil27_with_slopes(self, p: DVec3, inv_h: f64) -> ([[f64; 3]; 3], [[f64; 3]; 3]) {
        let (cell, value) = self.stencil27(p, inv_h);
        let slope = match self {
            Degree::One => [[0.0, -1.0, 1.0]; 3],
            Degree::Two => {
                let t = p * inv_h;
                std::array::from_fn(|axis| {
                    std::array::from_fn(|k| {
                        derivative(t[axis] - (cell[axis] as f64 - 0.5 + k as f64))
                    })
                })
            }
        };
        (value, slope)
    }
}

/// b₁(t) = max(0, 1 − |t|), the degree-1 B-spline (hat).
#[inline]
pub fn hat(t: f64) -> f64 {
    (1.0 - t.abs()).max(0.0)
}

/// b₁′(t): +1 on [−1, 0), −1 on [0, 1), 0 elsewhere.
#[inline]
pub fn hat_derivative(t: f64) -> f64 {
    if (-1.0..0.0).contains(&t) {
        1.0
    } else if (0.0..1.0).contains(&t) {
        -1.0
    } else {
        0.0
    }
}

/// The three same-depth 1-D tables, indexed by δ + 2 for δ ∈ [−2, 2].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tables {
    pub mass: [f64; 5],
    pub stiffness: [f64; 5],
    pub advection: [f64; 5],
}

/// The tables, integrated once per process (pure data; sharing them is not global state).
pub fn tables() -> &'static Tables {
    static TABLES: OnceLock<Tables> = OnceLock::new();
    TABLES.get_or_init(|| Tables {
        mass: offsets(|t, d| value(t) * value(t - d)),
        stiffness: offsets(|t, d| derivative(t) * derivative(t - d)),
        advection: offsets(|t, d| derivative(t) * value(t - d)),
    })
}

fn offsets(f: impl Fn(f64, f64) -> f64) -> [f64; 5] {
    let mut out = [0.0; 5];
    for (k, o) in out.iter_mut().enumerate() {
        let delta = k as f64 - 2.0;
        *o = integrate_piecewise(|t| f(t, delta));
    }
    out
}

/// Integrates a function that is a polynomial of degree ≤ 4 on every interval between
/// consecutive half-integers, over [−4, 4] (enough for any pair of translates ≤ 2 apart).
fn integrate_piecewise(f: impl Fn(f64) -> f64) -> f64 {
    // 3-point Gauss–Legendre is exact for degree ≤ 5.
    let nodes = [-(0.6f64).sqrt(), 0.0, (0.6f64).sqrt()];
    let weights = [5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0];
    let mut sum = 0.0;
    let mut a = -4.0;
    while a < 4.0 {
        let mid = a + 0.25;
        for (x, w) in nodes.iter().zip(weights) {
            sum += w * 0.25 * f(mid + 0.25 * x);
        }
        a += 0.5;
    }
    sum
}

/// The node coordinates whose functions may be non-zero at `p` (3 per axis) and the function
/// values, at a depth of width 1/`inv_h`.
#[inline]
pub fn stencil27(p: DVec3, inv_h: f64) -> ([i32; 3], [[f64; 3]; 3]) {
    let t = p * inv_h;
    let c = cell_of(p, inv_h);
    let mut w = [[0.0; 3]; 3];
    for axis in 0..3 {
        // Node c−1+k has centre c−½+k; b at t − centre.
        for (k, slot) in w[axis].iter_mut().enumerate() {
            *slot = value(t[axis] - (c[axis] as f64 - 0.5 + k as f64));
        }
    }
    (c, w)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-14
    }

    #[test]
    fn b_spline_is_a_unit_partition_of_unity() {
        for k in 0..100 {
            let t = k as f64 / 100.0;
            let sum: f64 = (-3..=3).map(|i| value(t - i as f64)).sum();
            assert!(close(sum, 1.0));
            let dsum: f64 = (-3..=3).map(|i| derivative(t - i as f64)).sum();
            assert!(dsum.abs() < 1e-14);
        }
        assert!(close(integrate_piecewise(value), 1.0));
    }

    #[test]
    fn mass_table_is_the_quintic_b_spline_at_integers() {
        // ∫ b(t) b(t−δ) dt is the degree-5 B-spline at δ: 11/20, 13/60, 1/120.
        let m = tables().mass;
        for (got, want) in m.iter().zip([
            1.0 / 120.0,
            13.0 / 60.0,
            11.0 / 20.0,
            13.0 / 60.0,
            1.0 / 120.0,
        ]) {
            assert!(close(*got, want), "{got} vs {want}");
        }
    }

    #[test]
    fn stiffness_table_is_minus_the_second_derivative_of_the_quintic() {
        // −B5″(δ) = −(B3(δ+1) − 2 B3(δ) + B3(δ−1)): 1, −1/3, −1/6; sums to zero (constants).
        let d = tables().stiffness;
        for (got, want) in d
            .iter()
            .zip([-1.0 / 6.0, -1.0 / 3.0, 1.0, -1.0 / 3.0, -1.0 / 6.0])
        {
            assert!(close(*got, want), "{got} vs {want}");
        }
    }

    #[test]
    fn advection_table_is_the_antisymmetric_first_derivative() {
        // G(δ) = B5′(δ) = B4(δ + ½) − B4(δ − ½): 5/12 at δ = −1, 1/24 at δ = −2.
        let g = tables().advection;
        for (got, want) in g
            .iter()
            .zip([1.0 / 24.0, 5.0 / 12.0, 0.0, -5.0 / 12.0, -1.0 / 24.0])
        {
            assert!(close(*got, want), "{got} vs {want}");
        }
    }

    #[test]
    fn refinement_reproduces_the_coarse_function() {
        for k in -160..=160 {
            let t = k as f64 / 40.0; // coarse units, centre at 0
            let fine: f64 = REFINE
                .iter()
                .enumerate()
                .map(|(j, w)| w * value(2.0 * t - (j as f64 - 1.5)))
                .sum();
            assert!(close(fine, value(t)), "t={t}");
        }
    }

    #[test]
    fn degree_one_tables_are_the_hats_closed_forms() {
        let t = Degree::One.tables();
        let want = Tables {
            mass: [0.0, 1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0, 0.0],
            stiffness: [0.0, -1.0, 2.0, -1.0, 0.0],
            advection: [0.0, 0.5, 0.0, -0.5, 0.0],
        };
        for (got, want) in [
            (t.mass, want.mass),
            (t.stiffness, want.stiffness),
            (t.advection, want.advection),
        ] {
            for (g, w) in got.iter().zip(want) {
                assert!(close(*g, w), "{got:?} vs {want:?}");
            }
        }
        // Degree 2's tables are the ones it always had.
        assert_eq!(Degree::Two.tables(), tables());
    }

    #[test]
    fn hats_are_a_partition_of_unity_and_refine_by_parity() {
        for k in 0..100 {
            let t = k as f64 / 100.0;
            let sum: f64 = (-2..=2).map(|i| hat(t - i as f64)).sum();
            assert!(close(sum, 1.0));
        }
        // Coarse node at corner 0 (coarse units) from the fine nodes around it: fine node f
        // (centre f/2 in coarse units) takes refine(f & 1)[0] of its own parent ⌊f/2⌋ and
        // refine(f & 1)[1] of its partner (⌊f/2⌋ − 1 for even f, + 1 for odd): summed over the
        // fine nodes whose own parent or partner is 0.
        for degree in [Degree::One, Degree::Two] {
            for k in -160..=160 {
                let t = k as f64 / 40.0;
                let c = degree.centre_offset();
                let mut fine = 0.0;
                for f in -6i32..=6 {
                    let m = f.div_euclid(2);
                    let parity = f.rem_euclid(2) as usize;
                    let partner = if parity == 0 { m - 1 } else { m + 1 };
                    let [own_w, partner_w] = degree.refine(parity);
                    let w = if m == 0 { own_w } else { 0.0 }
                        + if partner == 0 { partner_w } else { 0.0 };
                    fine += w * degree.value(2.0 * t - (f as f64 + c));
                }
                assert!(close(fine, degree.value(t - c)), "{degree:?} t={t}");
            }
        }
    }

    #[test]
    fn degree_one_stencil_is_the_two_hats_of_the_cell_corners() {
        let (c, w) = Degree::One.stencil27(DVec3::new(0.3, 0.55, 0.875), 4.0);
        assert_eq!(c, [1, 2, 3]);
        for (axis, f) in [0.2, 0.2, 0.5].into_iter().enumerate() {
            assert_eq!(w[axis][0], 0.0);
            assert!(close(w[axis][1], 1.0 - f) && close(w[axis][2], f), "{w:?}");
        }
        // The same as the hats of the nodes c − 1 + k (centres at their index).
        let p = DVec3::new(0.3, 0.55, 0.875);
        let (value, slope) = Degree::One.stencil27_with_slopes(p, 4.0);
        for axis in 0..3 {
            for k in 0..3 {
                let t = p[axis] * 4.0 - (c[axis] - 1 + k as i32) as f64;
                assert!(close(value[axis][k], hat(t)));
                if k > 0 {
                    assert!(close(slope[axis][k], hat_derivative(t)));
                }
            }
        }
        // Degree 2's stencil is the one it always had.
        assert_eq!(Degree::Two.stencil27(p, 4.0), stencil27(p, 4.0));
    }
}
