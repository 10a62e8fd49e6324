//! `psr-mpi`: psr's reconstruction out of core with its slabs shared by the ranks of an MPI job
//! (issue 21), e.g. `mpirun -n 4 psr-mpi --in scan.ply --out mesh.ply --depth 12 --temp-dir
//! /shared/tmp`. The options are `psr`'s (`--out-of-core` implied, one slab per rank unless
//! `--slabs` or `--max-memory` says otherwise); every rank runs the same passes on its own
//! slabs, the ranks meet through `MPI_Allgather(v)`, and every rank writes its slabs of the mesh
//! into the one PLY rank 0 made, which is the one `psr --out-of-core` writes with the same
//! slabs, bit for bit. The temporary directory and the output must be ones that every rank
//! sees (one machine's disk, or a cluster's shared file system): a rank that does not find
//! rank 0's token in them stops the job at the start of the run (the directory) or before any
//! slab of the mesh is written (the output), with a message saying so.

use mpi::datatype::PartitionMut;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;
use std::cell::Cell;
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// Writes `line` and a newline to stderr in one write: `eprintln!` writes each piece of its
/// format apart, and mpirun, which forwards every rank's stderr, interleaved the ranks'
/// `--verbose` lines piece by piece ("psr-mpi: rank psr-mpi: rank 1: 23…"). A pipe takes a
/// write of up to 4096 bytes whole, so lines that short are never cut.
fn say(line: String) {
    use std::io::Write;
    let _ = std::io::stderr()
        .lock()
        .write_all(format!("{line}\n").as_bytes());
}

/// The ranks of `MPI_COMM_WORLD` as a [`psr::Team`], counting what passes through them.
struct World {
    comm: SimpleCommunicator,
    /// Meetings (gathers) so far.
    meetings: Cell<u64>,
    /// Bytes this rank contributed, and bytes it received from the others.
    sent: Cell<u64>,
    received: Cell<u64>,
    /// Time inside the gathers: waiting for the slowest rank, then the transfer.
    meeting: Cell<Duration>,
}

impl World {
    /// Ends the whole job (MPI_Abort) after saying why: a rank that cannot take part in a
    /// meeting must not leave the others waiting.
    fn abort(&self, why: &str) -> ! {
        say(format!(
            "psr-mpi: rank {}: {why}; ending the job",
            self.comm.rank()
        ));
        self.comm.abort(70)
    }
}

impl psr::Team for World {
    fn rank(&self) -> usize {
        self.comm.rank() as usize
    }

    fn size(&self) -> usize {
        self.comm.size() as usize
    }

    fn all_gather(&self, mine: Vec<u8>) -> Vec<Vec<u8>> {
        let started = Instant::now();
        let Ok(count) = Count::try_from(mine.len()) else {
            self.abort("a message of more than 2 GiB (MPI counts are 32-bit)")
        };
        let mut counts: Vec<Count> = vec![0; self.size()];
        self.comm.all_gather_into(&count, &mut counts[..]);
        let mut displacements = Vec::with_capacity(counts.len());
        let mut total: i64 = 0;
        for &c in &counts {
            displacements.push(total as Count);
            total += i64::from(c);
        }
        if total > i64::from(Count::MAX) {
            self.abort("the ranks' messages add up to more than 2 GiB (MPI counts are 32-bit)")
        }
        let mut all = vec![0u8; total as usize];
        {
            let mut partition = PartitionMut::new(&mut all[..], &counts[..], &displacements[..]);
            self.comm
                .all_gather_varcount_into(&mine[..], &mut partition);
        }
        self.meetings.set(self.meetings.get() + 1);
        self.sent.set(self.sent.get() + mine.len() as u64);
        self.received
            .set(self.received.get() + total as u64 - mine.len() as u64);
        self.meeting.set(self.meeting.get() + started.elapsed());
        let mut rest = &all[..];
        counts
            .iter()
            .map(|&c| {
                let (head, tail) = rest.split_at(c as usize);
                rest = tail;
                head.to_vec()
            })
            .collect()
    }
}

/// A rank's counters at one moment: seconds since the start, CPU seconds, seconds in meetings,
/// bytes sent and received, and the peak resident memory so far (KiB; 0 where the system does
/// not say).
#[derive(Clone, Copy, Default)]
struct Mark {
    seconds: f64,
    cpu: f64,
    meeting: f64,
    sent: u64,
    received: u64,
    peak_kib: u64,
}

/// What each stage took on this rank, from the marks where the stages began and the end: per
/// stage (a stage met twice, as the points when the cloud is cut again, counted once with both
/// spans), its time, CPU time, time in meetings and bytes received and sent, and the rank's
/// peak resident memory when the stage ended (the peak only grows, so the stage after which it
/// jumps is the one that raised it).
fn by_stage(marks: &[(psr::Stage, Mark)], end: &Mark) -> String {
    let mut totals: Vec<(psr::Stage, Mark)> = Vec::new();
    for (i, (stage, from)) in marks.iter().enumerate() {
        let to = marks.get(i + 1).map_or(end, |(_, m)| m);
        let index = match totals.iter().position(|(s, _)| s == stage) {
            Some(index) => index,
            None => {
                totals.push((*stage, Mark::default()));
                totals.len() - 1
            }
        };
        let total = &mut totals[index].1;
        total.seconds += to.seconds - from.seconds;
        total.cpu += to.cpu - from.cpu;
        total.meeting += to.meeting - from.meeting;
        total.sent += to.sent - from.sent;
        total.received += to.received - from.received;
        total.peak_kib = total.peak_kib.max(to.peak_kib);
    }
    totals
        .iter()
        .map(|(stage, t)| {
            format!(
                "{} {:.1} s ({:.1} s CPU, {:.1} s meeting, {:.1} MB in, {:.1} MB out, peak {} \
                 MiB)",
                stage.name(),
                t.seconds,
                t.cpu,
                t.meeting,
                t.received as f64 / 1e6,
                t.sent as f64 / 1e6,
                t.peak_kib / 1024
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The CPU time (user and system) this process has used, in seconds.
fn cpu_seconds() -> f64 {
    // SAFETY: getrusage writes the struct it is given; a zeroed rusage is a valid value.
    let usage = unsafe {
        let mut usage: libc::rusage = std::mem::zeroed();
        libc::getrusage(libc::RUSAGE_SELF, &mut usage);
        usage
    };
    let seconds = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    seconds(usage.ru_utime) + seconds(usage.ru_stime)
}

// Large blocks' pages reused from one stage to the next (src/allocator.rs).
#[cfg(target_os = "linux")]
#[global_allocator]
static ALLOCATOR: psr_cli::allocator::ReusingAllocator = psr_cli::allocator::ReusingAllocator;

fn main() -> ExitCode {
    let Some(universe) = mpi::initialize() else {
        eprintln!("psr-mpi: error: MPI could not be initialised (start it with mpirun or srun)");
        return ExitCode::from(1);
    };
    let team = World {
        comm: universe.world(),
        meetings: Cell::new(0),
        sent: Cell::new(0),
        received: Cell::new(0),
        meeting: Cell::new(Duration::ZERO),
    };
    let started = Instant::now();
    // Where each stage began on this rank: its time, CPU time and bytes so far.
    let mut marks: Vec<(psr::Stage, Mark)> = Vec::new();
    let mark = |team: &World| Mark {
        seconds: started.elapsed().as_secs_f64(),
        cpu: cpu_seconds(),
        meeting: team.meeting.get().as_secs_f64(),
        sent: team.sent.get(),
        received: team.received.get(),
        peak_kib: psr_cli::peak_resident_kib().unwrap_or(0),
    };
    let status = psr_cli::main_in_team(&team, &mut |stage| marks.push((stage, mark(&team))));
    let end = mark(&team);
    // With --verbose, every rank says what it exchanged and how long it waited (for
    // docs/distributed.md's measurements).
    if std::env::args().any(|a| a == "--verbose" || a == "-v") {
        say(format!(
            "psr-mpi: rank {}: {:.1} s ({:.1} s of CPU), of which {:.1} s in {} meetings; sent \
             {:.1} MB, received {:.1} MB{}",
            team.comm.rank(),
            started.elapsed().as_secs_f64(),
            cpu_seconds(),
            team.meeting.get().as_secs_f64(),
            team.meetings.get(),
            team.sent.get() as f64 / 1e6,
            team.received.get() as f64 / 1e6,
            psr_cli::peak_resident_kib()
                .map(|kib| format!("; peak {} MiB", kib / 1024))
                .unwrap_or_default()
        ));
        say(format!(
            "psr-mpi: rank {} by stage: {}",
            team.comm.rank(),
            by_stage(&marks, &end)
        ));
    }
    // (The universe is dropped after the run: MPI_Finalize on every rank.)
    status
}
