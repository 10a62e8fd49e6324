//! Progress: `psr_stage`, the pipeline stages reported to the progress callback, and
//! `psr_progress_fn`, the callback's type.

use crate::Stage;
use std::ffi::c_void;

/// The pipeline stages reported to the progress callback, in order.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum psr_stage {
    /// Copying the points and mapping them into the unit cube.
    Points = 0,
    /// Estimating the sampling density (it decides the depths the octree needs).
    Density = 1,
    /// Building the octree.
    Octree = 2,
    /// Splatting the normals into the vector field.
    Splat = 3,
    /// Assembling the linear system.
    System = 4,
    /// Solving it, depth by depth.
    Solve = 5,
    /// Computing the isovalue.
    Isovalue = 6,
    /// Extracting the isosurface.
    Extract = 7,
    /// Assembling the output mesh.
    Mesh = 8,
}

impl From<Stage> for psr_stage {
    fn from(stage: Stage) -> Self {
        match stage {
            Stage::Points => psr_stage::Points,
            Stage::Octree => psr_stage::Octree,
            Stage::Density => psr_stage::Density,
            Stage::Splat => psr_stage::Splat,
            Stage::System => psr_stage::System,
            Stage::Solve => psr_stage::Solve,
            Stage::Isovalue => psr_stage::Isovalue,
            Stage::Extract => psr_stage::Extract,
            Stage::Mesh => psr_stage::Mesh,
        }
    }
}

/// A progress callback: receives your user pointer, the current stage and the fraction of that
/// stage done (0 to 1, not necessarily reaching 1), and returns true to go on or false to cancel
/// (psr_reconstructor_solve then returns PSR_STATUS_CANCELLED and no mesh).
///
/// It is called only from inside psr_reconstructor_solve, on the thread that called it, never
/// concurrently with itself. It must not call any function on the reconstructor being solved
/// (such calls are refused with PSR_STATUS_INVALID_ARGUMENT, and psr_reconstructor_free does
/// nothing); it may use other handles, psr_status_string and the version functions. It must not
/// unwind (no C++ exception or longjmp out of it).
pub type psr_progress_fn =
    Option<unsafe extern "C" fn(user: *mut c_void, stage: psr_stage, fraction: f32) -> bool>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stages_keep_their_numbers() {
        for stage in Stage::ALL {
            assert_eq!(psr_stage::from(stage) as u32, stage as u32);
        }
    }
}
