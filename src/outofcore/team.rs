//! The processes that share one reconstruction out of core (issue 21): a [`Team`] of members,
//! each running the same run with the same arguments, each doing the slabs it owns in every
//! pass.
//!
//! The members meet only at [`gather`]: every member contributes its step's result (bytes, or
//! its error) and receives every member's, in rank order, so that all of them leave a step
//! together, all with the step's data or all with an error (the failing member's own, the
//! others' naming the rank and its message). Between meetings a member returns no error of its
//! own: whatever fails is carried to the next meeting. That is what keeps a failure on one
//! member from leaving the others waiting.
//!
//! The slabs of a pass are done in rounds ([`rounds`]): round j gives slab j·N + r to the
//! member of rank r, then the round's results are gathered and folded in slab order, so that
//! every sum over slabs is the same fold in the same order whatever N is: the mesh of N
//! members is the mesh of one, bit for bit.
//!
//! What the members share beside the meetings is the temporary directory (the slabs' files):
//! one machine's disk, or a cluster's shared file system.

use super::OutOfCoreError;
use crate::Error;

/// The members of one reconstruction out of core (the ranks of an MPI communicator, or a
/// single process, [`Alone`]), for [`crate::reconstruct_out_of_core_in_team`].
///
/// Every member runs the same reconstruction with the same input, output and parameters; each
/// does the slabs it owns in each pass, and they exchange what the passes sum over slabs
/// through [`Team::all_gather`] and the slabs' files through the temporary directory, which
/// must be the same directory for all of them (`OutOfCore::temp_dir` on a file system every
/// member sees). Rank 0 makes and removes that directory and makes the output file, into
/// which every member writes its slabs of the mesh.
pub trait Team {
    /// This member's rank, in 0..[`Team::size`].
    fn rank(&self) -> usize;

    /// How many members the team has (at least 1).
    fn size(&self) -> usize;

    /// Every member's `mine`, in rank order, given to every member: a collective operation,
    /// which every member calls the same number of times in the same order (the
    /// reconstruction makes sure of that, errors included). An implementation that cannot
    /// communicate (a member lost) must not return: it ends the process, as MPI's default
    /// error handler does, rather than let one member go on alone.
    fn all_gather(&self, mine: Vec<u8>) -> Vec<Vec<u8>>;
}

/// A team of one: the reconstruction in this process only (what
/// [`crate::reconstruct_out_of_core`] uses).
#[derive(Debug, Clone, Copy, Default)]
pub struct Alone;

impl Team for Alone {
    fn rank(&self) -> usize {
        0
    }

    fn size(&self) -> usize {
        1
    }

    fn all_gather(&self, mine: Vec<u8>) -> Vec<Vec<u8>> {
        vec![mine]
    }
}

/// One step's result from every member, in rank order, when every member's step succeeded;
/// otherwise this member's own error, or (when its step succeeded) the first failed member's,
/// as [`OutOfCoreError::Member`].
pub(crate) fn gather(
    team: &dyn Team,
    mine: Result<Vec<u8>, OutOfCoreError>,
) -> Result<Vec<Vec<u8>>, OutOfCoreError> {
    match mine {
        Ok(bytes) => exchange(team, Ok(bytes))
            .map_err(|(rank, message)| OutOfCoreError::Member { rank, message }),
        Err(e) => {
            let _ = exchange(team, Err(e.to_string()));
            Err(e)
        }
    }
}

/// Every member's bytes in rank order, or the first failed member's rank and message.
fn exchange(
    team: &dyn Team,
    mine: Result<Vec<u8>, String>,
) -> Result<Vec<Vec<u8>>, (usize, String)> {
    let message = match mine {
        Ok(bytes) => [&[0u8][..], &bytes].concat(),
        Err(text) => [&[1u8][..], text.as_bytes()].concat(),
    };
    let all = team.all_gather(message);
    if all.len() != team.size() {
        return Err((
            team.rank(),
            format!("a team of {} gathered {} results", team.size(), all.len()),
        ));
    }
    match all.iter().position(|m| m.first() != Some(&0)) {
        Some(rank) => Err((
            rank,
            String::from_utf8_lossy(all[rank].get(1..).unwrap_or(&[])).into_owned(),
        )),
        None => Ok(all.into_iter().map(|mut m| m.split_off(1)).collect()),
    }
}

/// This member's `result` of a step once every member has finished the step: an error if
/// any member's failed (as [`gather`]).
pub(crate) fn agreed<T>(
    team: &dyn Team,
    result: Result<T, OutOfCoreError>,
) -> Result<T, OutOfCoreError> {
    agreed_with(team, result, |_| Vec::new()).map(|(value, _)| value)
}

/// As [`agreed`], the meeting also carrying `tell(value)` from every member: this member's
/// value and every member's bytes, in rank order.
pub(crate) fn agreed_with<T>(
    team: &dyn Team,
    result: Result<T, OutOfCoreError>,
    tell: impl FnOnce(&T) -> Vec<u8>,
) -> Result<(T, Vec<Vec<u8>>), OutOfCoreError> {
    match result {
        Ok(value) => {
            let told = gather(team, Ok(tell(&value)))?;
            Ok((value, told))
        }
        Err(e) => Err(gather(team, Err(e)).expect_err("a failed step fails")),
    }
}

/// Every member but rank 0 runs `check` (of what rank 0 made for the team); then they meet,
/// so that a member whose check failed ends every member. Nothing to check or meet alone.
pub(crate) fn checked_by_others(
    team: &dyn Team,
    check: impl FnOnce() -> Result<(), OutOfCoreError>,
) -> Result<(), OutOfCoreError> {
    if team.size() == 1 {
        return Ok(());
    }
    agreed(team, if team.rank() == 0 { Ok(()) } else { check() })
}

/// Rank 0's `value` (made by rank 0 only, with `make`) given to every member.
pub(crate) fn from_first<T>(
    team: &dyn Team,
    make: impl FnOnce() -> Result<T, OutOfCoreError>,
    pack: impl FnOnce(&T, &mut Packer),
    unpack: impl FnOnce(&mut Unpacker<'_>) -> Result<T, OutOfCoreError>,
) -> Result<T, OutOfCoreError> {
    if team.rank() == 0 {
        match make() {
            Ok(value) => {
                let mut packer = Packer::default();
                pack(&value, &mut packer);
                gather(team, Ok(packer.bytes)).map(|_| value)
            }
            Err(e) => agreed(team, Err(e)),
        }
    } else {
        let all = gather(team, Ok(Vec::new()))?;
        unpack(&mut Unpacker::new(&all[0]))
    }
}

/// Does the `slabs` slabs' `work` in rounds: in round j the member of rank r does slab
/// j·N + r (N members), the round's results are gathered, and `fold` gets every slab's
/// result of the round in slab order, on every member. So every member folds every slab's
/// result in the order of the slabs, whatever N is, with one result per member in memory.
pub(crate) fn rounds(
    team: &dyn Team,
    slabs: usize,
    mut work: impl FnMut(usize) -> Result<Vec<u8>, OutOfCoreError>,
    mut fold: impl FnMut(usize, &[u8]) -> Result<(), OutOfCoreError>,
) -> Result<(), OutOfCoreError> {
    let n = team.size();
    for round in 0..slabs.div_ceil(n) {
        let k = round * n + team.rank();
        let mine = if k < slabs { work(k) } else { Ok(Vec::new()) };
        let all = gather(team, mine)?;
        for (r, bytes) in all.iter().enumerate() {
            let k = round * n + r;
            if k < slabs {
                fold(k, bytes)?;
            }
        }
    }
    Ok(())
}

/// Little-endian words for [`gather`]: numbers and lists of them.
#[derive(Debug, Default)]
pub(crate) struct Packer {
    pub(crate) bytes: Vec<u8>,
}

impl Packer {
    pub(crate) fn u64(&mut self, v: u64) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    pub(crate) fn f64(&mut self, v: f64) {
        self.u64(v.to_bits());
    }

    pub(crate) fn u64s(&mut self, list: &[u64]) {
        self.u64(list.len() as u64);
        self.bytes.reserve(list.len() * 8);
        for &v in list {
            self.u64(v);
        }
    }

    pub(crate) fn f64s(&mut self, list: &[f64]) {
        self.u64(list.len() as u64);
        self.bytes.reserve(list.len() * 8);
        for &v in list {
            self.f64(v);
        }
    }

    pub(crate) fn bytes(&mut self, bytes: &[u8]) {
        self.u64(bytes.len() as u64);
        self.bytes.extend_from_slice(bytes);
    }

    /// `list` as the steps between consecutive values (the first from 0), each zigzagged (a
    /// small step back is a small number too) and written in seven bits a byte: sorted keys a
    /// few apart, or cells of a surface in Morton order, take one or two bytes a value instead
    /// of eight. Any values come back, bit for bit ([`Unpacker::u64s_by_steps`]).
    pub(crate) fn u64s_by_steps(&mut self, list: &[u64]) {
        let mut steps = Vec::with_capacity(list.len() * 2);
        let mut previous = 0u64;
        for &v in list {
            let step = v.wrapping_sub(previous) as i64;
            let mut zigzag = ((step << 1) ^ (step >> 63)) as u64;
            while zigzag >= 0x80 {
                steps.push(zigzag as u8 | 0x80);
                zigzag >>= 7;
            }
            steps.push(zigzag as u8);
            previous = v;
        }
        self.u64(list.len() as u64);
        self.bytes(&steps);
    }
}

/// Reads what a [`Packer`] wrote, in the same order.
#[derive(Debug)]
pub(crate) struct Unpacker<'a> {
    bytes: &'a [u8],
}

impl<'a> Unpacker<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        Unpacker { bytes }
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], OutOfCoreError> {
        if self.bytes.len() < n {
            return Err(Error::Internal(format!(
                "a member's message ended early ({} bytes left, {n} wanted)",
                self.bytes.len()
            ))
            .into());
        }
        let (head, rest) = self.bytes.split_at(n);
        self.bytes = rest;
        Ok(head)
    }

    pub(crate) fn u64(&mut self) -> Result<u64, OutOfCoreError> {
        let word: [u8; 8] = self.take(8)?.try_into().expect("8 bytes");
        Ok(u64::from_le_bytes(word))
    }

    pub(crate) fn f64(&mut self) -> Result<f64, OutOfCoreError> {
        self.u64().map(f64::from_bits)
    }

    fn len(&mut self) -> Result<usize, OutOfCoreError> {
        let n = self.u64()? as usize;
        if n > self.bytes.len() {
            return Err(Error::Internal(format!(
                "a member's message lists {n} values in {} bytes",
                self.bytes.len()
            ))
            .into());
        }
        Ok(n)
    }

    pub(crate) fn u64s(&mut self) -> Result<Vec<u64>, OutOfCoreError> {
        let n = self.len()?;
        (0..n).map(|_| self.u64()).collect()
    }

    pub(crate) fn f64s(&mut self) -> Result<Vec<f64>, OutOfCoreError> {
        let n = self.len()?;
        (0..n).map(|_| self.f64()).collect()
    }

    pub(crate) fn bytes(&mut self) -> Result<&'a [u8], OutOfCoreError> {
        let n = self.len()?;
        self.take(n)
    }

    /// What [`Packer::u64s_by_steps`] wrote.
    pub(crate) fn u64s_by_steps(&mut self) -> Result<Vec<u64>, OutOfCoreError> {
        let n = self.u64()?;
        let steps = self.bytes()?;
        let bad = || Error::Internal("a member's list of steps does not fit its count".into());
        // Every value takes a byte at least.
        if n > steps.len() as u64 {
            return Err(bad().into());
        }
        let mut list = Vec::with_capacity(n as usize);
        let mut previous = 0u64;
        let mut at = 0;
        for _ in 0..n {
            let mut zigzag = 0u64;
            let mut shift = 0;
            loop {
                let byte = *steps.get(at).ok_or_else(bad)?;
                at += 1;
                // Ten bytes of seven bits hold 64; the tenth may carry only the last bit.
                if shift == 63 && byte > 1 {
                    return Err(bad().into());
                }
                zigzag |= u64::from(byte & 0x7f) << shift;
                if byte & 0x80 == 0 {
                    break;
                }
                shift += 7;
            }
            let step = (zigzag >> 1) as i64 ^ -((zigzag & 1) as i64);
            previous = previous.wrapping_add(step as u64);
            list.push(previous);
        }
        if at != steps.len() {
            return Err(bad().into());
        }
        Ok(list)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::{gather, rounds, Packer, Team, Unpacker};
    use crate::outofcore::OutOfCoreError;
    use crate::Error;
    use std::sync::{Barrier, Mutex};

    /// A team of threads in one process, for the tests: the members meet at a barrier.
    pub(crate) struct Threads {
        size: usize,
        barrier: Barrier,
        board: Mutex<Vec<Option<Vec<u8>>>>,
    }

    impl Threads {
        pub(crate) fn new(size: usize) -> Self {
            Threads {
                size,
                barrier: Barrier::new(size),
                board: Mutex::new(vec![None; size]),
            }
        }

        /// Member `rank`'s view of the team.
        pub(crate) fn member(&self, rank: usize) -> Member<'_> {
            Member { team: self, rank }
        }
    }

    pub(crate) struct Member<'a> {
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
            self.team.board.lock().unwrap()[self.rank] = Some(mine);
            self.team.barrier.wait();
            let all: Vec<Vec<u8>> = self
                .team
                .board
                .lock()
                .unwrap()
                .iter()
                .map(|m| m.clone().expect("every member wrote"))
                .collect();
            // Nobody writes the next round's message before everyone has read this one's.
            self.team.barrier.wait();
            all
        }
    }

    #[test]
    fn packed_values_read_back_and_a_short_message_is_an_error() {
        let mut p = Packer::default();
        p.u64(7);
        p.f64(-0.5);
        p.u64s(&[1, 2, 3]);
        p.f64s(&[f64::MIN_POSITIVE, 1e300]);
        p.bytes(b"abc");
        let mut u = Unpacker::new(&p.bytes);
        assert_eq!(u.u64().unwrap(), 7);
        assert_eq!(u.f64().unwrap(), -0.5);
        assert_eq!(u.u64s().unwrap(), vec![1, 2, 3]);
        assert_eq!(u.f64s().unwrap(), vec![f64::MIN_POSITIVE, 1e300]);
        assert_eq!(u.bytes().unwrap(), b"abc");
        assert!(u.u64().is_err());
        let mut short = Unpacker::new(&p.bytes[..20]);
        short.u64().unwrap();
        short.f64().unwrap();
        assert!(short.u64s().is_err());
    }

    /// Proves lists packed by their steps come back bit for bit whatever the values (the
    /// extremes, steps both ways, repeats), that sorted keys a few apart take a byte or two a
    /// value, and that steps that do not fit their count are an error, not values.
    #[test]
    fn lists_packed_by_steps_read_back_and_sorted_keys_take_few_bytes() {
        // Scrambled values: steps of every size, both ways.
        let scrambled: Vec<u64> = (1..1000u64)
            .map(|i| i.wrapping_mul(0x9e37_79b9_7f4a_7c15).rotate_left(i as u32))
            .collect();
        let sorted: Vec<u64> = (0..10_000u64).map(|i| (1 << 40) + 3 * i + i % 7).collect();
        let cases: Vec<Vec<u64>> = vec![
            Vec::new(),
            vec![0],
            vec![u64::MAX, 0, u64::MAX, 1 << 63, (1 << 63) - 1, 5, 5],
            scrambled,
            sorted.clone(),
        ];
        for list in &cases {
            let mut p = Packer::default();
            p.u64s_by_steps(list);
            p.u64(9);
            let mut u = Unpacker::new(&p.bytes);
            assert_eq!(&u.u64s_by_steps().unwrap(), list);
            assert_eq!(u.u64().unwrap(), 9, "nothing more or less read");
        }
        let mut p = Packer::default();
        p.u64s_by_steps(&sorted);
        assert!(
            p.bytes.len() < 16 + sorted.len() + 8,
            "{} bytes",
            p.bytes.len()
        );
        // More values than bytes; a value cut short; a byte left over; eleven bytes of value.
        let malformed = |count: u64, steps: &[u8]| {
            let mut p = Packer::default();
            p.u64(count);
            p.bytes(steps);
            Unpacker::new(&p.bytes).u64s_by_steps().is_err()
        };
        assert!(malformed(3, &[1, 1]));
        assert!(malformed(1, &[0x80]));
        assert!(malformed(1, &[2, 2]));
        assert!(malformed(1, &[0xff; 11]));
        assert!(malformed(
            1,
            &[0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x02]
        ));
        assert!(!malformed(
            1,
            &[0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x01]
        ));
    }

    #[test]
    fn rounds_fold_every_slab_in_order_on_every_member_and_a_failure_reaches_all() {
        for size in 1..=4 {
            let team = Threads::new(size);
            let results: Vec<(Vec<usize>, Vec<usize>)> = std::thread::scope(|s| {
                let handles: Vec<_> = (0..size)
                    .map(|rank| {
                        let member = team.member(rank);
                        s.spawn(move || {
                            let (mut worked, mut folded) = (Vec::new(), Vec::new());
                            rounds(
                                &member,
                                7,
                                |k| {
                                    worked.push(k);
                                    Ok(vec![k as u8])
                                },
                                |k, bytes| {
                                    assert_eq!(bytes, [k as u8]);
                                    folded.push(k);
                                    Ok(())
                                },
                            )
                            .unwrap();
                            (worked, folded)
                        })
                    })
                    .collect();
                handles.into_iter().map(|h| h.join().unwrap()).collect()
            });
            let mut all_worked: Vec<usize> = results.iter().flat_map(|r| r.0.clone()).collect();
            all_worked.sort_unstable();
            assert_eq!(all_worked, (0..7).collect::<Vec<_>>(), "{size} members");
            for (_, folded) in &results {
                assert_eq!(*folded, (0..7).collect::<Vec<_>>());
            }

            // Slab 5 fails on its member: every member ends with an error, the failing one
            // with its own.
            let team = Threads::new(size);
            let errors: Vec<OutOfCoreError> = std::thread::scope(|s| {
                let handles: Vec<_> = (0..size)
                    .map(|rank| {
                        let member = team.member(rank);
                        s.spawn(move || {
                            rounds(
                                &member,
                                7,
                                |k| {
                                    if k == 5 {
                                        Err(Error::Cancelled.into())
                                    } else {
                                        Ok(Vec::new())
                                    }
                                },
                                |_, _| Ok(()),
                            )
                            .unwrap_err()
                        })
                    })
                    .collect();
                handles.into_iter().map(|h| h.join().unwrap()).collect()
            });
            for (rank, e) in errors.iter().enumerate() {
                if rank == 5 % size {
                    assert!(matches!(
                        e,
                        OutOfCoreError::Reconstruction(Error::Cancelled)
                    ));
                } else {
                    assert!(
                        matches!(e, OutOfCoreError::Member { rank: r, message }
                            if *r == 5 % size && message.contains("cancel")),
                        "{e}"
                    );
                }
            }
        }
    }

    /// Proves rank 0's failure to make what it shares reaches the others with its own message.
    #[test]
    fn a_failure_of_the_first_reaches_the_others_with_its_message() {
        let team = Threads::new(3);
        let results: Vec<Result<u64, OutOfCoreError>> = std::thread::scope(|s| {
            let handles: Vec<_> = (0..3)
                .map(|rank| {
                    let member = team.member(rank);
                    s.spawn(move || {
                        super::from_first(
                            &member,
                            || Err(Error::Cancelled.into()),
                            |v: &u64, p| p.u64(*v),
                            |u| u.u64(),
                        )
                    })
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        assert!(matches!(
            results[0],
            Err(OutOfCoreError::Reconstruction(Error::Cancelled))
        ));
        for result in &results[1..] {
            match result {
                Err(OutOfCoreError::Member { rank: 0, message }) => {
                    assert_eq!(*message, Error::Cancelled.to_string());
                }
                other => panic!("{other:?}"),
            }
        }
    }

    #[test]
    fn alone_gathers_its_own() {
        let all = gather(&super::Alone, Ok(vec![1, 2])).unwrap();
        assert_eq!(all, vec![vec![1, 2]]);
    }
}
