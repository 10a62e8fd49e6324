//! Stage 7 — the isovalue (§4.4, §4.5): the surface is the level set of χ at γ, the average of
//! χ at the samples weighted by the area each sample stands for (and its confidence), so that
//! dense regions do not pull the level set towards themselves.

use crate::error::Result;
use crate::evaluate::Indicator;
use crate::parallel::{map_in_blocks, Watch};
use glam::DVec3;

/// γ = Σ_s w_s χ(s) / Σ_s w_s with w_s = area_s × confidence_s (0 when every weight is 0). χ
/// is evaluated in parallel; the sums run in sample order, so γ does not depend on the thread
/// count. The evaluation reports its progress to `watch` and stops when it is cancelled.
pub(crate) fn weighted_mean(
    chi: &Indicator,
    positions: &[DVec3],
    areas: &[f64],
    confidence: &[f64],
    watch: &Watch,
) -> Result<f64> {
    let values = map_in_blocks(positions, |&p| chi.value(p), watch, 0.0, 1.0)?;
    let mut num = 0.0;
    let mut den = 0.0;
    for s in 0..values.len() {
        let w = areas[s] * confidence[s];
        num += w * values[s];
        den += w;
    }
    Ok(if den > 0.0 { num / den } else { 0.0 })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::octree::Octree;
    use crate::Boundary;

    /// With χ = 1 everywhere in the tree (coefficients 1 on a complete level reproduce the
    /// constant) γ is 1 whatever the weights; weights pick between two regions of χ.
    #[test]
    fn the_isovalue_is_the_weighted_mean_of_chi_at_the_samples() {
        let tree = Octree::build(vec![Vec::new(); 4], 3, Boundary::Neumann);
        let ones: Vec<Vec<f64>> = tree.levels.iter().map(|l| vec![0.0; l.len()]).collect();
        let mut coefficients = ones;
        let finest = coefficients.len() - 1;
        coefficients[finest].iter_mut().for_each(|c| *c = 1.0);
        let chi = Indicator { tree, coefficients };
        let positions = [DVec3::new(0.3, 0.4, 0.5), DVec3::new(0.6, 0.6, 0.6)];
        let watch = Watch::new();
        let one = weighted_mean(&chi, &positions, &[1.0, 3.0], &[1.0, 1.0], &watch).unwrap();
        assert!((one - 1.0).abs() < 1e-12, "{one}");
        assert_eq!(
            weighted_mean(&chi, &positions, &[1.0, 1.0], &[0.0, 0.0], &watch).unwrap(),
            0.0
        );
    }
}
