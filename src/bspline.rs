//! The degree-2 B-spline node functions and their exact 1-D inner-product tables (§4.1, §4.3).
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
    let cell = t.floor();
    let c = [cell.x as i32, cell.y as i32, cell.z as i32];
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
}
