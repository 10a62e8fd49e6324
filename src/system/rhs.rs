//! Right-hand sides: ⟨∇B_o, V⟩, the divergence of the splatted vector field V tested against
//! each node function, brick by brick; and vectors kept on the core with their mirrors
//! (Neumann, Dirichlet) filled.

use super::bricks::CoreBricks;
use super::transfer::{restrict_into, ProlongedField};
use crate::error::Result;
use crate::memory::zeroed;
use crate::octree::{fill_mirrors, Level, Octree};
use crate::parallel::for_each_indexed;

/// Sets x[core node i] = f(i, x[core node i]) for every core position i (in parallel, in fixed
/// chunks), then refills the mirror nodes: how a vector that lives on the core is kept on K_d.
pub fn update_on_core(level: &Level, x: &mut [f64], f: impl Fn(usize, f64) -> f64 + Sync) {
    for_each_indexed(&level.core, x, |i, v| *v = f(i, *v));
    fill_mirrors(level, x);
}

/// ⟨∇B_o, V_d⟩ for every node of K_d, where V_d = Σ v_o′ B_o′/h³ (unit-integral node
/// functions, §4.1) has coefficients `v` (x, y, z components) on K_d, which is dropped when it
/// returns; [`divergence_of`] for a field that is kept.
pub fn divergence(level: &Level, v: [Vec<f64>; 3]) -> Result<Vec<f64>> {
    divergence_of(level, &v)
}

/// [`divergence`] of a field that is kept. Brick by brick over every brick of K_d, on 12³
/// windows of the three components gathered from the 27 bricks around (values beyond K_d are
/// zero), as (1/h)·(G_x(M_y M_z v_x) + M_x(G_y M_z v_y + M_y G_z v_z)): one sweep and no
/// halo-sized scratch, where nine axis passes over the whole halo read and wrote it 18 times.
pub fn divergence_of(level: &Level, v: &[Vec<f64>; 3]) -> Result<Vec<f64>> {
    let bricks = CoreBricks::whole_level(level);
    let mut out = zeroed(level.len(), "a right-hand side")?;
    bricks.divergence(
        |cb, windows, _| {
            for (window, component) in windows.iter_mut().zip(v) {
                bricks.gather_values(level, cb, component, window);
            }
        },
        level.degree,
        1.0 / level.width(),
        &mut out,
    );
    Ok(out)
}

/// ⟨∇B_o, V⟩ at every core node of `field.fine` (in core order) for V a coarser field prolonged
/// to that depth ([`divergence`] restricted to the core, brick by brick): each core brick's
/// window computes the prolongation from the coarse nodes under it, instead of every window
/// node finding its eight parents (every node lies in about 3.4 windows).
pub fn divergence_of_prolonged(field: &ProlongedField<'_>) -> Result<Vec<f64>> {
    let level = field.fine;
    let bricks = CoreBricks::new(level);
    let mut out = zeroed(level.core.len(), "a coarse right-hand side")?;
    bricks.divergence(
        |cb, windows, scratch| bricks.gather_prolonged(field, cb, windows, scratch),
        level.degree,
        1.0 / level.width(),
        &mut out,
    );
    Ok(out)
}

/// The finest depth's ρ from its V (mirrors filled): its own divergence, no finer depth
/// restricting into it; V is dropped.
pub(crate) fn finest_right_hand_side(level: &Level, v: [Vec<f64>; 3]) -> Result<Vec<f64>> {
    let mut rho = divergence(level, v)?;
    fill_mirrors(level, &mut rho);
    Ok(rho)
}

/// The coarser depths' own divergences, root first, in the order the carry of V asks for:
/// each depth's V (`splat(d)`) gives ⟨∇B_o, V_d⟩ on K_d, for [`right_hand_sides`], before it
/// goes to `take_v(d, V)` (a [`super::FieldCarry`], which adds the coarser depths' V into it,
/// or the out-of-core base's parts).
pub(crate) fn coarser_divergences(
    tree: &Octree,
    mut splat: impl FnMut(usize) -> Result<[Vec<f64>; 3]>,
    mut take_v: impl FnMut(usize, [Vec<f64>; 3]) -> Result<()>,
) -> Result<Vec<Vec<f64>>> {
    let finest = tree.max_depth() as usize;
    let mut own = Vec::with_capacity(finest);
    for (d, level) in tree.levels.iter().enumerate().take(finest) {
        let v = splat(d)?;
        own.push(divergence_of(level, &v)?);
        take_v(d, v)?;
    }
    Ok(own)
}

/// ρ_d = ⟨∇B_o, Σ_{e ≥ d} V_e⟩ on every halo K_d (index d), finest first: each depth's own
/// divergence plus the finer depth's ρ restricted (exactly) to it. `rho_finest` is the finest
/// depth's (see [`divergence`]); `own[d]` is ⟨∇B_o, V_d⟩ on K_d for the coarser depths
/// ([`divergence_of`] of V_d alone, computed as each depth is splatted, before
/// [`super::FieldCarry`] takes its V), turned into ρ_d in place. `progress(fraction)` is
/// called after each depth's restriction, the fraction counting the work as the finer depth's
/// nodes, and may stop the work.
pub(crate) fn right_hand_sides(
    tree: &Octree,
    rho_finest: Vec<f64>,
    own: Vec<Vec<f64>>,
    mut progress: impl FnMut(f32) -> Result<()>,
) -> Result<Vec<Vec<f64>>> {
    let max_depth = tree.max_depth() as usize;
    debug_assert_eq!(own.len(), max_depth);
    let work: usize = (1..=max_depth).map(|d| tree.levels[d].len()).sum();
    let mut done = 0;
    let mut rho: Vec<Vec<f64>> = Vec::with_capacity(tree.levels.len());
    rho.push(rho_finest);
    for (d, mut r) in own.into_iter().enumerate().rev() {
        let level = &tree.levels[d];
        let finer: &Vec<f64> = rho.last().expect("finer level computed first");
        restrict_into(level, &tree.levels[d + 1], finer, &mut r);
        fill_mirrors(level, &mut r);
        rho.push(r);
        done += tree.levels[d + 1].len();
        progress(done as f32 / work.max(1) as f32)?;
    }
    rho.reverse();
    Ok(rho)
}
