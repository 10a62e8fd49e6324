//! The coarser depths' V carried to the finer depths: at depth d the right-hand side is
//! ⟨∇B_o, V⟩ for the whole field, whose part from the depths below d (the "coarse divergence")
//! is ⟨∇B_o, A_{d−1}⟩ with A_d = V_d + A_{d−1} prolonged to depth d (A_0 = V_0).
//!
//! The carry runs coarse to fine as the depths are splatted ([`FieldCarry::push`]): each
//! depth's V is added to the carried field, whose divergence at the next depth is kept (one
//! `f64` per core node) and which is dropped once the next depth has taken it. So at most two
//! depths' V are alive at once, and none through the solve: before, every depth's V (three
//! `f64` per halo node) waited from the splat to its depth's solve, a third of the peak memory
//! of the Happy Buddha at depth 11. The additions are the ones the solve made when it carried
//! V itself, in the same order, so the coefficients are the same, bit for bit.

use super::rhs::divergence_of_prolonged;
use super::transfer::ProlongedField;
use crate::error::Result;
use crate::octree::{fill_mirrors_field, Octree};

/// V carried from depth to depth up to `last`, and the coarse divergences it leaves at the
/// depths above.
pub(crate) struct FieldCarry<'t> {
    tree: &'t Octree,
    /// The reconstruction's finest depth: its V is spent on its own ρ, so nothing is added to
    /// it, and nothing is carried beyond it.
    finest: usize,
    /// The last depth carried: its field is kept (a base's hand-off) instead of carried on.
    last: usize,
    /// The field of the depth pushed last, with every coarser depth's in it (mirror nodes
    /// filled once carried), until the next depth takes it.
    carried: Option<(usize, [Vec<f64>; 3])>,
    /// Index d: the coarse divergence at K_d's core nodes, in core order (empty where nothing
    /// was carried: the root, the depths of a base below the slabs).
    coarse_div: Vec<Vec<f64>>,
}

impl<'t> FieldCarry<'t> {
    /// A carry from the root of `tree`, up to depth `last` (the finest for a whole
    /// reconstruction; a base's last depth, whose field [`FieldCarry::finish`] then hands
    /// over), in a reconstruction whose finest depth is `finest`.
    pub(crate) fn new(tree: &'t Octree, finest: u32, last: usize) -> Self {
        FieldCarry {
            tree,
            finest: finest as usize,
            last,
            carried: None,
            coarse_div: vec![Vec::new(); tree.levels.len().max(last + 1)],
        }
    }

    /// A carry that starts from a base's hand-off: `field`, V of depth `depth` with every
    /// coarser depth's in it, on a tree whose depths up to `depth` are the base's; carried to
    /// the depth above at once, then up to the finest.
    pub(crate) fn from_base(
        tree: &'t Octree,
        depth: usize,
        field: [Vec<f64>; 3],
        pool: &rayon::ThreadPool,
    ) -> Result<Self> {
        let finest = tree.max_depth();
        let mut carry = FieldCarry::new(tree, finest, finest as usize);
        carry.carry(depth, field, pool)?;
        Ok(carry)
    }

    /// Takes V of depth `depth` (the depths pushed in order, from the root or from the depth
    /// above the base; not the finest, whose V is spent on its own ρ).
    pub(crate) fn push(
        &mut self,
        depth: usize,
        mut v: [Vec<f64>; 3],
        pool: &rayon::ThreadPool,
    ) -> Result<()> {
        if let Some((below, field)) = self.carried.take() {
            debug_assert_eq!(below + 1, depth, "depths pushed in order");
            let prolonged = self.prolonged(below, &field);
            pool.install(|| prolonged.add_to(&mut v));
        }
        if depth < self.last {
            self.carry(depth, v, pool)
        } else {
            self.carried = Some((depth, v));
            Ok(())
        }
    }

    /// The coarse divergence of every depth (index d; empty where nothing was carried), and
    /// the last depth's field with every coarser depth's in it when the carry stopped before
    /// the finest (a base's hand-off).
    pub(crate) fn finish(self) -> (Vec<Vec<f64>>, Option<[Vec<f64>; 3]>) {
        let handed_over = self
            .carried
            .filter(|(depth, _)| *depth == self.last && self.last < self.finest)
            .map(|(_, field)| field);
        (self.coarse_div, handed_over)
    }

    /// `field` at depth d read for the last time but once: its divergence at depth d + 1
    /// kept, and itself kept for depth d + 1 to take unless that is the finest.
    fn carry(
        &mut self,
        d: usize,
        mut field: [Vec<f64>; 3],
        pool: &rayon::ThreadPool,
    ) -> Result<()> {
        fill_mirrors_field(&self.tree.levels[d], &mut field);
        let div = pool.install(|| divergence_of_prolonged(&self.prolonged(d, &field)))?;
        self.coarse_div[d + 1] = div;
        if d + 1 < self.finest {
            self.carried = Some((d, field));
        }
        Ok(())
    }

    /// The field of depth d prolonged to depth d + 1 (F̃ halves in width: ×1/8).
    fn prolonged<'a>(&'a self, d: usize, field: &'a [Vec<f64>; 3]) -> ProlongedField<'a> {
        ProlongedField {
            coarse: &self.tree.levels[d],
            fine: &self.tree.levels[d + 1],
            field: [&field[0], &field[1], &field[2]],
            scale: 0.125,
        }
    }
}
