//! `psr-mpi` under `mpirun` (issue 21): the mesh of 1 to 4 ranks is `psr --out-of-core`'s with
//! the same slabs, bit for bit; a rank that is stopped or killed ends the job, with its rank
//! named on rank 0, never a hang; no temporary file is left; a temporary directory or output
//! the ranks do not share is refused with the reason; every rank's `--verbose` lines come out
//! whole. Built and run with the `mpi`
//! feature only (`.ci/mpi.sh`), which needs Open MPI's `mpirun`.
#![cfg(feature = "mpi")]

use psr_test_support::{data_or_skip, sample_sphere};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

const PSR: &str = env!("CARGO_BIN_EXE_psr");
const PSR_MPI: &str = env!("CARGO_BIN_EXE_psr-mpi");

/// A fresh directory of this test's own, with `tmp/` for the runs' temporary directories.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("psr-mpi-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("tmp")).unwrap();
    dir
}

/// `mpirun -n ranks psr-mpi args`, not yet waited for; `mark` is put in every rank's
/// environment so that a test can find its ranks.
fn mpirun(ranks: usize, args: &[String], mark: &str) -> Child {
    Command::new("mpirun")
        .args(["--allow-run-as-root", "--oversubscribe", "-n"])
        .arg(ranks.to_string())
        .args(["-x", "PSR_MPI_TEST_MARK"])
        .arg(PSR_MPI)
        .args(args)
        .env("PSR_MPI_TEST_MARK", mark)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("mpirun runs (Open MPI installed?)")
}

/// Waits for `child` at most `limit`; its output, or a panic naming a hang.
fn wait_within(child: Child, limit: Duration, what: &str) -> Output {
    let id = child.id();
    let (done, waited) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = done.send(child.wait_with_output());
    });
    match waited.recv_timeout(limit) {
        Ok(output) => output.expect("waited"),
        Err(_) => {
            // SAFETY: kill has no memory-safety preconditions.
            unsafe { libc::kill(id as i32, libc::SIGKILL) };
            panic!("{what}: mpirun still running after {limit:?} (a hang)");
        }
    }
}

fn run_args(input: &Path, output: &Path, dir: &Path, depth: u32, slabs: usize) -> Vec<String> {
    [
        "--in",
        input.to_str().unwrap(),
        "--out",
        output.to_str().unwrap(),
        "--depth",
        &depth.to_string(),
        "--threads",
        "1",
        "--slabs",
        &slabs.to_string(),
        "--temp-dir",
        dir.join("tmp").to_str().unwrap(),
    ]
    .map(String::from)
    .to_vec()
}

/// `n` points of the unit sphere (seed `seed`) written as `sphere.ply` in `dir`.
fn sphere_input(dir: &Path, n: usize, seed: u64) -> PathBuf {
    let (positions, normals) = sample_sphere(n, 1.0, [0.0; 3], seed);
    let mut cloud = psr::ply::PlyPoints::default();
    cloud.positions = positions;
    cloud.normals = normals;
    let input = dir.join("sphere.ply");
    psr::ply::write_point_cloud(&input, &cloud, psr::ply::PlyFormat::BinaryLittleEndian).unwrap();
    input
}

fn leftovers(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir.join("tmp"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect()
}

/// The mesh of `psr --out-of-core` against `psr-mpi`'s with 1 to 4 ranks, same slabs.
fn same_mesh_from_one_to_four_ranks(name: &str, input: &Path, depth: u32, slabs: usize) {
    same_mesh_from_one_to_four_ranks_with(name, input, depth, slabs, &[]);
}

/// As [`same_mesh_from_one_to_four_ranks`], both programs given the options `extra` too.
fn same_mesh_from_one_to_four_ranks_with(
    name: &str,
    input: &Path,
    depth: u32,
    slabs: usize,
    extra: &[&str],
) {
    let dir = scratch(name);
    let alone = dir.join("alone.ply");
    let mut args = run_args(input, &alone, &dir, depth, slabs);
    args.extend(extra.iter().map(|a| a.to_string()));
    args.push("--out-of-core".into());
    let status = Command::new(PSR).args(&args).status().expect("psr runs");
    assert!(status.success(), "{name}: psr --out-of-core");
    let expected = std::fs::read(&alone).unwrap();
    for ranks in 1..=4 {
        let output = dir.join(format!("ranks-{ranks}.ply"));
        let started = Instant::now();
        // At two ranks, --verbose too: every rank then reports its stages (and the mesh is
        // the same).
        let mut args = run_args(input, &output, &dir, depth, slabs);
        args.extend(extra.iter().map(|a| a.to_string()));
        let verbose = ranks == 2;
        if verbose {
            args.push("--verbose".into());
        }
        let done = wait_within(mpirun(ranks, &args, name), Duration::from_secs(600), name);
        let stderr = String::from_utf8_lossy(&done.stderr);
        assert!(done.status.success(), "{name}, {ranks} ranks: {stderr}");
        if verbose {
            for rank in 0..ranks {
                let head = format!("psr-mpi: rank {rank} by stage: ");
                let line = stderr
                    .lines()
                    .find(|l| l.starts_with(&head))
                    .unwrap_or_else(|| panic!("{name}: no stage line of rank {rank}: {stderr}"));
                for stage in ["points", "system", "solve", "isovalue", "extract", "mesh"] {
                    assert!(line.contains(&format!("{stage} ")), "{name}: {line}");
                }
                assert_eq!(line.matches(" MiB)").count(), 6, "{name}: {line}");
            }
        }
        // Rank 0 reports, once.
        assert_eq!(
            stderr.matches(" slabs, base depth ").count(),
            1,
            "{name}: {stderr}"
        );
        if verbose && extra.contains(&"--screening-follows-noise") {
            assert_eq!(
                stderr.matches("(the samples' noise: ").count(),
                1,
                "{name}: {stderr}"
            );
        }
        assert!(
            std::fs::read(&output).unwrap() == expected,
            "{name}: {ranks} ranks wrote another mesh than psr --out-of-core"
        );
        assert!(leftovers(&dir).is_empty(), "{name}: {:?}", leftovers(&dir));
        println!(
            "{name}: {ranks} ranks, {slabs} slabs, depth {depth}: the same {} bytes in {:.1} s",
            expected.len(),
            started.elapsed().as_secs_f64()
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves the ranks' mesh of a synthetic sphere is one process's, bit for bit, for 1 to 4 ranks
/// over five slabs (uneven: some ranks do two).
#[test]
fn a_sphere_from_one_to_four_ranks_is_one_process_mesh() {
    let dir = scratch("sphere-input");
    let input = sphere_input(&dir, 30_000, 21);
    same_mesh_from_one_to_four_ranks("sphere", &input, 8, 5);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves the same on the bunny's scans at depth 9 in four slabs.
#[test]
fn the_bunny_from_one_to_four_ranks_is_one_process_mesh() {
    let test = "the_bunny_from_one_to_four_ranks_is_one_process_mesh";
    if let Some(input) = data_or_skip("bunny_scans.ply", test) {
        same_mesh_from_one_to_four_ranks("bunny", &input, 9, 4);
    }
}

/// Proves the same on the bunny's scans with the screening following their noise: the ranks fit
/// their slabs' cells and meet for the medians, and rank 0 reports the noise it read.
#[test]
fn the_bunny_following_its_noise_from_one_to_four_ranks_is_one_process_mesh() {
    let test = "the_bunny_following_its_noise_from_one_to_four_ranks_is_one_process_mesh";
    if let Some(input) = data_or_skip("bunny_scans.ply", test) {
        same_mesh_from_one_to_four_ranks_with(
            "bunny-noise",
            &input,
            9,
            4,
            &["--screening-follows-noise"],
        );
    }
}

/// Proves the same on the Happy Buddha's scans at depth 9 in four slabs.
#[test]
fn the_happy_buddha_from_one_to_four_ranks_is_one_process_mesh() {
    let test = "the_happy_buddha_from_one_to_four_ranks_is_one_process_mesh";
    if let Some(input) = data_or_skip("happy_buddha_scans.ply", test) {
        same_mesh_from_one_to_four_ranks("buddha", &input, 9, 4);
    }
}

/// The process ids of the ranks of the job marked `mark`, by rank, once they all run.
fn ranks_of(mark: &str, ranks: usize) -> Vec<i32> {
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let mut found = vec![None; ranks];
        for entry in std::fs::read_dir("/proc").unwrap().flatten() {
            let Ok(pid) = entry.file_name().to_string_lossy().parse::<i32>() else {
                continue;
            };
            let Ok(environ) = std::fs::read(entry.path().join("environ")) else {
                continue;
            };
            let vars: Vec<&[u8]> = environ.split(|&b| b == 0).collect();
            let marked = vars
                .iter()
                .any(|v| *v == format!("PSR_MPI_TEST_MARK={mark}").as_bytes());
            let is_rank = std::fs::read_link(entry.path().join("exe"))
                .is_ok_and(|exe| exe.file_name().is_some_and(|n| n == "psr-mpi"));
            if !(marked && is_rank) {
                continue;
            }
            let rank = vars.iter().find_map(|v| {
                std::str::from_utf8(v)
                    .ok()?
                    .strip_prefix("OMPI_COMM_WORLD_RANK=")?
                    .parse::<usize>()
                    .ok()
            });
            if let Some(rank) = rank.filter(|&r| r < ranks) {
                found[rank] = Some(pid);
            }
        }
        if found.iter().all(Option::is_some) {
            return found.into_iter().flatten().collect();
        }
        assert!(
            Instant::now() < deadline,
            "the ranks of {mark} did not start"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// A job of three ranks on the bunny at depth 9 whose rank 1 gets `signal` once it has worked
/// for a while; mpirun's output and what is left in the temporary directories' parent (`None`
/// when the bunny is absent).
fn signal_rank_one(name: &str, signal: i32) -> Option<(Output, Vec<PathBuf>)> {
    let test = format!("signal_rank_one {name}");
    let input = data_or_skip("bunny_scans.ply", &test)?;
    let dir = scratch(name);
    let output = dir.join("mesh.ply");
    let mark = format!("{name}-{}", std::process::id());
    let child = mpirun(3, &run_args(&input, &output, &dir, 9, 3), &mark);
    let pids = ranks_of(&mark, 3);
    std::thread::sleep(Duration::from_secs(3));
    // SAFETY: kill has no memory-safety preconditions.
    unsafe { libc::kill(pids[1], signal) };
    let done = wait_within(child, Duration::from_secs(120), name);
    assert!(!output.exists(), "{name}: no mesh is written");
    let left = leftovers(&dir);
    let _ = std::fs::remove_dir_all(&dir);
    Some((done, left))
}

/// Proves a rank stopped by SIGTERM ends every rank at their next meeting: rank 0 names it and
/// its reason, the job fails, rank 0 removes the temporary directory.
#[test]
fn a_rank_stopped_ends_the_job_with_its_rank_named_on_rank_0() {
    let Some((done, left)) = signal_rank_one("sigterm", libc::SIGTERM) else {
        return;
    };
    let stderr = String::from_utf8_lossy(&done.stderr);
    assert!(!done.status.success(), "{stderr}");
    assert!(
        stderr
            .contains("psr: error: reconstruction failed: rank 1 failed: reconstruction cancelled"),
        "{stderr}"
    );
    assert!(left.is_empty(), "{left:?}");
}

/// Proves a rank killed outright (as the kernel's out-of-memory killer would) ends the job
/// instead of leaving the other ranks waiting at their next meeting.
#[test]
fn a_rank_killed_ends_the_job() {
    let Some((done, _)) = signal_rank_one("sigkill", libc::SIGKILL) else {
        return;
    };
    let stderr = String::from_utf8_lossy(&done.stderr);
    assert!(!done.status.success(), "{stderr}");
    assert!(
        stderr.contains("signal 9"),
        "mpirun names the killed rank: {stderr}"
    );
}

/// Whether this machine lets a process give itself a mount namespace (`unshare -m`: root, or a
/// kernel allowing user namespaces), which the tests of node-local directories need.
fn mount_namespaces_allowed() -> bool {
    Command::new("unshare")
        .args(["-m", "--propagation", "private", "true"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// `mpirun -n ranks psr-mpi args` with every rank in a mount namespace of its own in which
/// `local` is a fresh, empty file system: what a directory on each node's own disk (its
/// `/tmp`) is to the ranks of a cluster. Its output, once done (within two minutes).
fn mpirun_node_local(ranks: usize, local: &Path, args: &[String]) -> Output {
    std::fs::create_dir_all(local).unwrap();
    let child = Command::new("mpirun")
        .args(["--allow-run-as-root", "--oversubscribe", "-n"])
        .arg(ranks.to_string())
        .args(["unshare", "-m", "--propagation", "private", "sh", "-c"])
        .arg(r#"mount -t tmpfs psr-node-local "$0" && exec "$@""#)
        .arg(local)
        .arg(PSR_MPI)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("mpirun runs (Open MPI installed?)");
    wait_within(child, Duration::from_secs(120), "node-local")
}

/// Proves a temporary directory or an output that the ranks do not share (each rank sees its
/// own, as on a cluster's nodes with their own `/tmp`) ends the job with rank 1 named and the
/// reason given, before the run reads the input (the directory) or writes any slab of the mesh
/// (the output); no file is left in the shared directories.
#[test]
fn a_directory_or_output_the_ranks_do_not_share_is_refused() {
    if !mount_namespaces_allowed() {
        eprintln!(
            "skipping a_directory_or_output_the_ranks_do_not_share_is_refused: this machine \
             does not allow mount namespaces (unshare -m), which stand in for separate nodes"
        );
        return;
    }
    let dir = scratch("node-local");
    let input = sphere_input(&dir, 20_000, 22);
    let local = dir.join("node-local");
    let shared_output = dir.join("mesh.ply");
    let mut local_temp = run_args(&input, &shared_output, &dir, 7, 2);
    let temp_at = local_temp.len() - 1;
    local_temp[temp_at] = local.to_str().unwrap().into();
    let local_output = run_args(&input, &local.join("mesh.ply"), &dir, 7, 2);
    for (args, reason) in [
        (local_temp, "could not find the temporary directory"),
        (local_output, "could not write the mesh to"),
    ] {
        let done = mpirun_node_local(2, &local, &args);
        let stderr = String::from_utf8_lossy(&done.stderr);
        assert!(!done.status.success(), "{stderr}");
        assert!(
            stderr.contains(&format!(
                "psr: error: reconstruction failed: rank 1 failed: {reason}"
            )) && stderr.contains("on a file system they share"),
            "{stderr}"
        );
        assert!(!shared_output.exists(), "no mesh");
        assert!(leftovers(&dir).is_empty(), "{:?}", leftovers(&dir));
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Proves every rank's `--verbose` lines reach mpirun's output whole, one line each, however
/// the ranks' writes meet (they were interleaved piece by piece when each line went out in
/// several writes).
#[test]
fn every_ranks_verbose_lines_come_whole() {
    let dir = scratch("verbose");
    let input = sphere_input(&dir, 20_000, 23);
    let mut args = run_args(&input, &dir.join("mesh.ply"), &dir, 7, 4);
    args.push("--verbose".into());
    let done = wait_within(
        mpirun(4, &args, "verbose"),
        Duration::from_secs(120),
        "verbose",
    );
    let stderr = String::from_utf8_lossy(&done.stderr);
    assert!(done.status.success(), "{stderr}");
    for rank in 0..4 {
        let totals: Vec<&str> = stderr
            .lines()
            .filter(|l| l.starts_with(&format!("psr-mpi: rank {rank}: ")))
            .collect();
        assert!(
            totals.len() == 1
                && totals[0].contains(" s of CPU), of which ")
                && totals[0].contains(" meetings; sent ")
                && totals[0].ends_with(" MiB"),
            "rank {rank}: {totals:?}\n{stderr}"
        );
        let stages: Vec<&str> = stderr
            .lines()
            .filter(|l| l.starts_with(&format!("psr-mpi: rank {rank} by stage: points ")))
            .collect();
        assert!(
            stages.len() == 1 && stages[0].contains("), mesh ") && stages[0].ends_with(" MiB)"),
            "rank {rank}: {stages:?}\n{stderr}"
        );
    }
    assert_eq!(stderr.matches("psr-mpi: rank").count(), 8, "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}
