//! Reconstruction out of core by a team of members (issue 21): each member does its own slabs,
//! as the ranks of `psr-mpi` do, and the mesh is the single process's, bit for bit. The team
//! here is threads of one process meeting at a barrier (the MPI team is tested by
//! `.ci/mpi.sh` with `mpirun`).

use psr::{OutOfCore, OutOfCoreError, OutOfCoreReport, Params, Team};
use psr_test_support::{data_or_skip, sample_sphere};
use std::path::{Path, PathBuf};
use std::sync::{Barrier, Mutex};

/// Members that are threads of this process: [`Team::all_gather`] posts each member's bytes on
/// a board and waits at a barrier until everyone's are there.
struct Threads {
    size: usize,
    barrier: Barrier,
    board: Mutex<Vec<Vec<u8>>>,
}

struct Member<'a> {
    team: &'a Threads,
    rank: usize,
}

impl Team for Member<'_> {
    fn rank(&self) -> usize {
        self.rank
    }

    fn size(&self) -> usize {
        self.team.size
    }

    fn all_gather(&self, mine: Vec<u8>) -> Vec<Vec<u8>> {
        self.team.board.lock().unwrap()[self.rank] = mine;
        self.team.barrier.wait();
        let all = self.team.board.lock().unwrap().clone();
        // Nobody posts the next message before everyone has read this one.
        self.team.barrier.wait();
        all
    }
}

/// Runs `members` members, member r on `inputs[r % inputs.len()]` (the same file for all,
/// unless a test says otherwise), each with `progress(rank, stage)` as its progress callback;
/// every member's result, in rank order.
fn run_team(
    members: usize,
    inputs: &[&Path],
    output: &Path,
    params: &Params,
    options: &OutOfCore,
    progress: impl Fn(usize, psr::Stage) -> bool + Sync,
) -> Vec<Result<OutOfCoreReport, OutOfCoreError>> {
    run_team_writing(members, inputs, &[output], params, options, progress)
}

/// As [`run_team`], member r writing to `outputs[r % outputs.len()]`: a test's stand-in for a
/// member on another machine, which sees another file under the output's name.
fn run_team_writing(
    members: usize,
    inputs: &[&Path],
    outputs: &[&Path],
    params: &Params,
    options: &OutOfCore,
    progress: impl Fn(usize, psr::Stage) -> bool + Sync,
) -> Vec<Result<OutOfCoreReport, OutOfCoreError>> {
    let team = Threads {
        size: members,
        barrier: Barrier::new(members),
        board: Mutex::new(vec![Vec::new(); members]),
    };
    std::thread::scope(|s| {
        let handles: Vec<_> = (0..members)
            .map(|rank| {
                let member = Member { team: &team, rank };
                let progress = &progress;
                let input = inputs[rank % inputs.len()];
                let output = outputs[rank % outputs.len()];
                s.spawn(move || {
                    psr::reconstruct_out_of_core_in_team(
                        input,
                        output,
                        params,
                        options,
                        &member,
                        &mut |stage, _| progress(rank, stage),
                    )
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    })
}

/// A fresh directory for one test, with a `tmp` directory for the runs' temporary directories.
fn test_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("psr-team-test-{test}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("tmp")).expect("a test directory");
    dir
}

/// `n` points of the unit sphere (seed `seed`) written as `sphere.ply` in `dir`.
fn sphere_file(dir: &Path, n: usize, seed: u64) -> PathBuf {
    sphere_file_named(dir, "sphere.ply", n, seed)
}

fn sphere_file_named(dir: &Path, name: &str, n: usize, seed: u64) -> PathBuf {
    sphere_file_with(dir, name, n, seed, |_| {})
}

/// As [`sphere_file_named`], the positions changed by `change` before they are written.
fn sphere_file_with(
    dir: &Path,
    name: &str,
    n: usize,
    seed: u64,
    change: impl FnOnce(&mut Vec<[f32; 3]>),
) -> PathBuf {
    let (mut positions, normals) = sample_sphere(n, 1.0, [0.0; 3], seed);
    change(&mut positions);
    let mut cloud = psr::ply::PlyPoints::default();
    cloud.positions = positions;
    cloud.normals = normals;
    let input = dir.join(name);
    psr::ply::write_point_cloud(&input, &cloud, psr::ply::PlyFormat::BinaryLittleEndian)
        .expect("written");
    input
}

fn entries(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir)
        .expect("readable")
        .map(|e| e.expect("an entry").path())
        .collect()
}

/// The mesh of one process in `slabs` slabs against those of teams of 2..=4 members: the same
/// bytes, the same report, no temporary file left.
fn same_mesh_for_every_team(test: &str, input: &Path, params: &Params, slabs: usize) {
    let options = OutOfCore::default().with_slabs(Some(slabs));
    let report = same_mesh_for_every_team_with(test, input, params, options);
    assert_eq!(report.slabs, slabs);
}

/// As [`same_mesh_for_every_team`], the slabs cut as `options` say; one process's report.
fn same_mesh_for_every_team_with(
    test: &str,
    input: &Path,
    params: &Params,
    options: OutOfCore,
) -> OutOfCoreReport {
    let dir = test_dir(test);
    let options = options.with_temp_dir(Some(dir.join("tmp")));
    let alone = dir.join("alone.ply");
    let report = psr::reconstruct_out_of_core(input, &alone, params, &options).expect("alone");
    let slabs = report.slabs;
    let expected = std::fs::read(&alone).expect("written");
    for members in 2..=4 {
        let output = dir.join(format!("team-{members}.ply"));
        let results = run_team(members, &[input], &output, params, &options, |_, _| true);
        for (rank, result) in results.into_iter().enumerate() {
            let theirs = result.unwrap_or_else(|e| panic!("{test}: member {rank}: {e}"));
            assert_eq!(
                (theirs.vertices, theirs.triangles, theirs.slabs),
                (report.vertices, report.triangles, report.slabs),
                "{test}: member {rank} of {members}"
            );
            assert_eq!(theirs.isovalue.to_bits(), report.isovalue.to_bits());
            assert_eq!(
                theirs.sample_noise.map(f64::to_bits),
                report.sample_noise.map(f64::to_bits),
                "{test}: member {rank} of {members}"
            );
            assert_eq!(
                theirs.screening_depth.to_bits(),
                report.screening_depth.to_bits()
            );
        }
        let written = std::fs::read(&output).expect("written by rank 0");
        assert!(
            written == expected,
            "{test}: {members} members wrote another mesh than one process"
        );
        assert!(
            entries(&dir.join("tmp")).is_empty(),
            "{test}: temporary files left"
        );
    }
    println!(
        "{test}: {} vertices, {} triangles in {slabs} slabs, the same bytes from 1 to 4 members",
        report.vertices, report.triangles
    );
    let _ = std::fs::remove_dir_all(&dir);
    report
}

/// Proves a team's mesh of a sphere is one process's, bit for bit, for 2, 3 and 4 members over
/// five slabs (so some members do two slabs and the last round is not full).
#[test]
fn a_team_writes_the_mesh_of_one_process_bit_for_bit() {
    let dir = test_dir("sphere-input");
    let input = sphere_file(&dir, 30_000, 11);
    let params = Params::default().with_depth(8).with_threads(1);
    same_mesh_for_every_team("sphere", &input, &params, 5);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves the same with the screening following the samples' noise (a sphere jittered by 0.004
/// of its radius): the members fit their slabs' cells and find the medians together, so every
/// member reads one process's σ and writes its mesh.
#[test]
fn a_team_following_the_noise_writes_the_mesh_of_one_process() {
    let dir = test_dir("noisy-input");
    let input = sphere_file_with(&dir, "noisy.ply", 30_000, 14, |positions| {
        *positions = psr_test_support::jitter_positions(positions, 0.004, 15);
    });
    let params = Params::default()
        .with_depth(8)
        .with_threads(1)
        .with_screening_follows_noise(true);
    let report = same_mesh_for_every_team_with(
        "noisy",
        &input,
        &params,
        OutOfCore::default().with_slabs(Some(5)),
    );
    let sigma = report.sample_noise.expect("an estimate");
    assert!(sigma > 0.002 && sigma < 0.005, "σ {sigma}");
    assert!(report.screening_depth < 8.0);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A budget the 30,000-point sphere at depth 8 fits in about six slabs (50 MiB is the least any
/// cut of it needs; 60 MiB cuts four).
const BUDGET: u64 = 56 << 20;

/// Proves the same when a memory budget cuts the slabs: every member measures the surface
/// from its part of the input, and the parts' measures join into the one process's, so the
/// members cut the same slabs (at least one per member) and write the same mesh.
#[test]
fn a_team_cut_by_a_memory_budget_writes_the_mesh_of_one_process() {
    let dir = test_dir("budget-input");
    let input = sphere_file(&dir, 30_000, 12);
    let params = Params::default()
        .with_depth(8)
        .with_threads(1)
        .with_max_memory(Some(BUDGET));
    let report = same_mesh_for_every_team_with("budget", &input, &params, OutOfCore::default());
    assert!(
        report.slabs >= 4,
        "the budget cut {} slabs: fewer than the largest team, which would cut more",
        report.slabs
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves the same with the points weighed by their confidence: each member carries its part's
/// weights into the slabs' files, and the density's counts summed slab by slab are one
/// process's.
#[test]
fn a_team_weighing_the_points_writes_the_mesh_of_one_process() {
    let dir = test_dir("weighted-input");
    let (positions, normals) = sample_sphere(30_000, 1.0, [0.0; 3], 13);
    let mut cloud = psr::ply::PlyPoints::default();
    cloud.confidence = Some(
        (0..positions.len())
            .map(|i| 0.5 + (i % 11) as f32 * 0.1)
            .collect(),
    );
    cloud.positions = positions;
    cloud.normals = normals;
    let input = dir.join("weighted.ply");
    psr::ply::write_point_cloud(&input, &cloud, psr::ply::PlyFormat::BinaryLittleEndian)
        .expect("written");
    let params = Params::default().with_depth(8).with_threads(1);
    let options = OutOfCore::default()
        .with_slabs(Some(5))
        .with_confidence(true);
    same_mesh_for_every_team_with("weighted", &input, &params, options);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves the same on the bunny's scans at depth 9 in four slabs.
#[test]
fn a_team_writes_the_bunny_of_one_process_bit_for_bit() {
    let test = "a_team_writes_the_bunny_of_one_process_bit_for_bit";
    let Some(input) = data_or_skip("bunny_scans.ply", test) else {
        return;
    };
    let params = Params::default().with_depth(9).with_threads(1);
    same_mesh_for_every_team("bunny", &input, &params, 4);
}

/// Proves a member that fails (cancelled while reading the points, solving, extracting or
/// writing its slab of the mesh) ends every member: itself with its own error, the others
/// naming it; no mesh is left and no temporary file.
#[test]
fn a_failing_member_ends_every_member_with_its_name() {
    let dir = test_dir("failure");
    let input = sphere_file(&dir, 20_000, 12);
    let options = OutOfCore::default()
        .with_slabs(Some(3))
        .with_temp_dir(Some(dir.join("tmp")));
    let params = Params::default().with_depth(8).with_threads(1);
    let output = dir.join("mesh.ply");
    for stop_at in [
        psr::Stage::Points,
        psr::Stage::Solve,
        psr::Stage::Extract,
        psr::Stage::Mesh,
    ] {
        let results = run_team(3, &[&input], &output, &params, &options, |rank, stage| {
            !(rank == 1 && stage == stop_at)
        });
        for (rank, result) in results.iter().enumerate() {
            match (rank, result) {
                (1, Err(OutOfCoreError::Reconstruction(psr::Error::Cancelled))) => {}
                (0 | 2, Err(OutOfCoreError::Member { rank: 1, message })) => {
                    assert!(message.contains("cancelled"), "{message}");
                }
                _ => panic!("{stop_at:?}: member {rank}: {result:?}"),
            }
        }
        assert!(!output.exists(), "{stop_at:?}: no mesh");
        assert!(
            entries(&dir.join("tmp")).is_empty(),
            "{stop_at:?}: files left"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves members given different inputs (here: another count of points) are refused by every
/// member alike, before any slab is cut: no mesh, no temporary file.
#[test]
fn members_reading_different_inputs_are_refused() {
    let dir = test_dir("different-inputs");
    let input = sphere_file(&dir, 20_000, 13);
    let other = sphere_file_named(&dir, "other.ply", 20_001, 13);
    let options = OutOfCore::default()
        .with_slabs(Some(2))
        .with_temp_dir(Some(dir.join("tmp")));
    let params = Params::default().with_depth(7).with_threads(1);
    let output = dir.join("mesh.ply");
    let results = run_team(2, &[&input, &other], &output, &params, &options, |_, _| {
        true
    });
    for (rank, result) in results.iter().enumerate() {
        match result {
            Err(OutOfCoreError::Reconstruction(psr::Error::InvalidParameter {
                name: "input",
                ..
            })) => {}
            other => panic!("member {rank}: {other:?}"),
        }
    }
    assert!(!output.exists(), "no mesh");
    assert!(entries(&dir.join("tmp")).is_empty(), "files left");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves each member checks its own part of the input: a NaN coordinate in the third of three
/// parts is refused by member 2 with the point's index in the whole file, and the others name
/// member 2 and that index; no mesh, no temporary file.
#[test]
fn a_bad_point_in_one_members_part_is_refused_with_its_index_in_the_file() {
    let dir = test_dir("bad-point");
    let input = sphere_file_with(&dir, "bad.ply", 20_000, 14, |positions| {
        positions[17_000][2] = f32::NAN;
    });
    let options = OutOfCore::default()
        .with_slabs(Some(3))
        .with_temp_dir(Some(dir.join("tmp")));
    let params = Params::default().with_depth(7).with_threads(1);
    let output = dir.join("mesh.ply");
    let results = run_team(3, &[&input], &output, &params, &options, |_, _| true);
    for (rank, result) in results.iter().enumerate() {
        match (rank, result) {
            (
                2,
                Err(OutOfCoreError::Reconstruction(psr::Error::NonFinitePosition {
                    index: 17_000,
                })),
            ) => {}
            (0 | 1, Err(OutOfCoreError::Member { rank: 2, message })) => {
                assert!(message.contains("17000"), "{message}");
            }
            _ => panic!("member {rank}: {result:?}"),
        }
    }
    assert!(!output.exists(), "no mesh");
    assert!(entries(&dir.join("tmp")).is_empty(), "files left");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves a member that does not see the file rank 0 made under the output's name (as on a
/// machine that does not share the output's file system) stops every member before any slab
/// is written, with a message saying the file must be shared: whether that member finds no
/// file there or an earlier run's mesh of the same length, which it would otherwise have
/// overwritten slab by slab into a broken mesh. No mesh is left, the other file is untouched
/// and no temporary file is left.
#[test]
fn a_member_that_does_not_see_the_output_is_refused() {
    let dir = test_dir("output-not-shared");
    let input = sphere_file(&dir, 20_000, 15);
    let options = OutOfCore::default()
        .with_slabs(Some(2))
        .with_temp_dir(Some(dir.join("tmp")));
    let params = Params::default().with_depth(7).with_threads(1);
    let output = dir.join("mesh.ply");
    let earlier = dir.join("earlier.ply");
    for result in run_team(2, &[&input], &earlier, &params, &options, |_, _| true) {
        result.expect("the earlier run");
    }
    let earlier_bytes = std::fs::read(&earlier).expect("the earlier mesh");
    let missing = dir.join("missing.ply");
    for elsewhere in [&earlier, &missing] {
        let results = run_team_writing(
            2,
            &[&input],
            &[&output, elsewhere],
            &params,
            &options,
            |_, _| true,
        );
        for (rank, result) in results.iter().enumerate() {
            let message = match (rank, result) {
                (1, Err(error @ OutOfCoreError::Output { .. })) => error.to_string(),
                (0, Err(OutOfCoreError::Member { rank: 1, message })) => message.clone(),
                _ => panic!("{}: member {rank}: {result:?}", elsewhere.display()),
            };
            assert!(message.contains("file system they share"), "{message}");
        }
        assert!(!output.exists(), "{}: no mesh", elsewhere.display());
        assert!(
            !missing.exists(),
            "no file made by the member that did not see it"
        );
        assert_eq!(
            std::fs::read(&earlier).expect("still there"),
            earlier_bytes,
            "the earlier mesh untouched"
        );
        assert!(entries(&dir.join("tmp")).is_empty(), "files left");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
