//! `psr-mpi`: psr's reconstruction out of core with its slabs shared by the ranks of an MPI job
//! (issue 21), e.g. `mpirun -n 4 psr-mpi --in scan.ply --out mesh.ply --depth 12 --temp-dir
//! /shared/tmp`. The options are `psr`'s (`--out-of-core` implied, one slab per rank unless
//! `--slabs` or `--max-memory` says otherwise); every rank runs the same passes on its own
//! slabs, the ranks meet through `MPI_Allgather(v)`, and rank 0 writes the mesh, which is the
//! one `psr --out-of-core` writes with the same slabs, bit for bit. The temporary directory
//! must be one that every rank sees (one machine's disk, or a cluster's shared file system).

use mpi::datatype::PartitionMut;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;
use std::process::ExitCode;

/// The ranks of `MPI_COMM_WORLD` as a [`psr::Team`].
struct World {
    comm: SimpleCommunicator,
}

impl World {
    /// Ends the whole job (MPI_Abort) after saying why: a rank that cannot take part in a
    /// meeting must not leave the others waiting.
    fn abort(&self, why: &str) -> ! {
        eprintln!("psr-mpi: rank {}: {why}; ending the job", self.comm.rank());
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

fn main() -> ExitCode {
    let Some(universe) = mpi::initialize() else {
        eprintln!("psr-mpi: error: MPI could not be initialised (start it with mpirun or srun)");
        return ExitCode::from(1);
    };
    let team = World {
        comm: universe.world(),
    };
    // (The universe is dropped after the run: MPI_Finalize on every rank.)
    psr_cli::main_in_team(&team)
}
