//! Stage 5 — the linear system (§4.3), applied matrix-free.
//!
//! At depth d the unknowns are the coefficients x_o of the core nodes. The system is
//!
//! ```text
//!   Σ_o′ ( ⟨∇B_o, ∇B_o′⟩ + α·2^d·Σ_q W_q B_o(q) B_o′(q) ) x_o′ = ⟨∇B_o, V⟩ − (same operator)(χ_coarser)
//! ```
//!
//! the Laplacian (the paper's L up to sign: ⟨ΔF, F′⟩ = −⟨∇F, ∇F′⟩) plus the screening term of
//! Kazhdan & Hoppe 2013 over "proxy" samples q (the weighted mean of the samples in each node,
//! with their summed weight W_q). The 2^d factor keeps the balance between the two terms the same
//! at every depth (the Laplacian's entries scale with the node width, the screening's with its
//! square). α = 0 is the 2006 method.
//!
//! Same-depth stencils are tensor products of the 1-D tables of [`crate::bspline`], so they are
//! applied as three 1-D passes (5 taps each; 3 at degree 1) instead of 125-entry rows:
//! `⟨∇B_o, ∇B_o′⟩ = h (D⊗M⊗M + M⊗D⊗M + M⊗M⊗D)` and `⟨∇B_o, F̃_o′⟩·v = (1/h)(G⊗M⊗M vx + …)`.
//! The passes run brick by brick on dense 12³ windows gathered from the halo (`CoreBricks`):
//! over the bricks holding core nodes for the operator in the solve, over every brick of K_d
//! for the right-hand side's divergence on the whole halo (restricted to coarser depths).
//! The screening term runs on the same core windows (`ScreeningCells`). Both are exact wherever
//! the input is supported on K_d (see [`crate::octree`]): every node a core node's stencil
//! reaches is in the halo.
//!
//! Cross-depth terms use the two-scale relation ([`crate::bspline::REFINE`]) instead of
//! cross-depth tables: coarser coefficients are prolonged into the current depth's halo, and the
//! divergence of finer vector-field coefficients is restricted to coarser nodes. Both are exact.

mod bricks;
mod carry;
mod operator;
mod rhs;
mod screening;
mod simd;
#[cfg(test)]
mod tests;
mod transfer;

pub(crate) use crate::octree::fill_mirrors;
pub(crate) use carry::FieldCarry;
pub(crate) use operator::DepthOperator;
pub(crate) use rhs::{
    coarser_divergences, finest_right_hand_side, right_hand_sides, update_on_core,
};
pub(crate) use screening::{
    proxy_depth, sample_groups, sample_weights, sample_weights_from_totals, screening_depth,
    Proxies, ScreeningWeights,
};
pub(crate) use transfer::prolong;
