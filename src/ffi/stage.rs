//! Progress: `psr_stage`, the pipeline stages reported to the progress callback,
//! `psr_stage_string`, their names, and `psr_progress_fn`, the callback's type.

use super::panic_boundary::guard_value;
use crate::Stage;
use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::sync::OnceLock;

/// The pipeline stages reported to the progress callback, numbered in pipeline order except
/// PSR_STAGE_NORMALS, which comes first (only when points were added without normals).
/// psr_stage_string gives their names.
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
    /// Estimating and orienting the normals of the points added with
    /// psr_reconstructor_add_positions, before all the others (numbered last because it was
    /// added later).
    Normals = 9,
    /// Trimming a mesh (psr_mesh_trim with psr_trim_options.progress set); never reported by
    /// psr_reconstructor_solve.
    Trim = 10,
}

impl From<Stage> for psr_stage {
    fn from(stage: Stage) -> Self {
        match stage {
            Stage::Normals => psr_stage::Normals,
            Stage::Points => psr_stage::Points,
            Stage::Octree => psr_stage::Octree,
            Stage::Density => psr_stage::Density,
            Stage::Splat => psr_stage::Splat,
            Stage::System => psr_stage::System,
            Stage::Solve => psr_stage::Solve,
            Stage::Isovalue => psr_stage::Isovalue,
            Stage::Extract => psr_stage::Extract,
            Stage::Mesh => psr_stage::Mesh,
            Stage::Trim => psr_stage::Trim,
        }
    }
}

/// The stage names as C strings, made once from [`Stage::name`], so that Rust and C share one
/// table of names. Written once and never changed: the only static of the C API filled at run
/// time.
static STAGE_NAMES: OnceLock<[CString; Stage::ALL.len()]> = OnceLock::new();

/// What psr_stage_string gives for a number that is no stage.
static UNKNOWN_STAGE: &CStr = c"unknown";

/// The short lower-case name of a stage, e.g. "density", as a static NUL-terminated string
/// (never free it): "points", "density", "octree", "splat", "system", "solve", "isovalue",
/// "extract", "mesh", "normals" or "trim", in psr_stage's order. Any int is accepted: unknown
/// values give "unknown". Never NULL.
#[no_mangle]
pub extern "C" fn psr_stage_string(stage: c_int) -> *const c_char {
    guard_value("psr_stage_string", UNKNOWN_STAGE.as_ptr(), || {
        let names = STAGE_NAMES.get_or_init(|| {
            Stage::ALL.map(|s| CString::new(s.name()).expect("stage names have no NUL"))
        });
        Stage::ALL
            .iter()
            .position(|&s| psr_stage::from(s) as c_int == stage)
            .map_or(UNKNOWN_STAGE.as_ptr(), |i| names[i].as_ptr())
    })
}

/// A progress callback: receives your user pointer, the current stage and the fraction of that
/// stage done (0 to 1, not necessarily reaching 1), and returns true to go on or false to cancel
/// (psr_reconstructor_solve then returns PSR_STATUS_CANCELLED and no mesh).
///
/// It is called only from inside psr_reconstructor_solve (or psr_mesh_trim, when set in its
/// psr_trim_options; the same rules hold there, with PSR_STAGE_TRIM), on the thread that called
/// it, never concurrently with itself. It is called while each stage runs, not only between
/// stages: the stage's work runs on psr's worker threads while the calling thread waits in
/// slices of at most 20 ms and calls it after each slice with the fraction of the stage done so
/// far (within a stage never less than the call before), then with 1 when the stage ends; so a
/// host that polls for a "stop" (a Cancel button, Ctrl-C) from the callback sees it within
/// about 20 ms plus the callback's own time. After it returns false it is not called again: the
/// stage stops at its next cancel point (docs/architecture.md lists them: batches of work
/// milliseconds apart, down to the bricks of the splat, the system and the solver and the
/// finest depth's octree passes; on a million points at depth 11 every stop measured returned
/// within 0.17 s on a 2-core machine at load 3, within 0.26 s at load 5-8) and
/// psr_reconstructor_solve returns once the reconstruction's memory is freed. The mesh never
/// depends on the callback. It must not call any function on the reconstructor being solved
/// (such calls are refused with PSR_STATUS_INVALID_ARGUMENT, and psr_reconstructor_free does
/// nothing); it may use other handles, psr_status_string, psr_stage_string and the version
/// functions. It must not unwind (no C++ exception or longjmp out of it).
pub type psr_progress_fn =
    Option<unsafe extern "C" fn(user: *mut c_void, stage: psr_stage, fraction: f32) -> bool>;

#[cfg(test)]
mod tests {
    use super::*;

    fn name(stage: c_int) -> &'static str {
        let p = psr_stage_string(stage);
        assert!(!p.is_null());
        // SAFETY: psr_stage_string returns a NUL-terminated string that lives as long as the
        // program (a literal, or a name in STAGE_NAMES, which is never changed or dropped).
        unsafe { CStr::from_ptr(p) }.to_str().unwrap()
    }

    /// Proves: psr_stage_string gives Stage::name for every stage, by psr_stage's numbers (so
    /// density before octree), the same static string every time, and "unknown" for any
    /// other int.
    #[test]
    fn stage_strings_are_the_stage_names_in_psr_stage_order() {
        let expected = [
            (psr_stage::Points, "points"),
            (psr_stage::Density, "density"),
            (psr_stage::Octree, "octree"),
            (psr_stage::Splat, "splat"),
            (psr_stage::System, "system"),
            (psr_stage::Solve, "solve"),
            (psr_stage::Isovalue, "isovalue"),
            (psr_stage::Extract, "extract"),
            (psr_stage::Mesh, "mesh"),
            (psr_stage::Normals, "normals"),
            (psr_stage::Trim, "trim"),
        ];
        for (stage, text) in expected {
            assert_eq!(name(stage as c_int), text);
        }
        for stage in Stage::ALL {
            assert_eq!(name(psr_stage::from(stage) as c_int), stage.name());
        }
        assert_eq!(
            psr_stage_string(psr_stage::Solve as c_int),
            psr_stage_string(psr_stage::Solve as c_int)
        );
        for unknown in [-1, 11, 12, c_int::MAX, c_int::MIN] {
            assert_eq!(name(unknown), "unknown");
        }
    }

    #[test]
    fn stages_keep_their_numbers() {
        for stage in Stage::ALL {
            assert_eq!(psr_stage::from(stage) as u32, stage as u32);
        }
    }
}
