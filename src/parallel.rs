//! Parallel primitives shared by the stages: fixed chunking, so that results never depend on
//! the number of threads, the disjoint writes the stages make from several threads at once,
//! and [`watched`] jobs, whose progress the calling thread reports while they run and which
//! it can cancel (every stage of the pipeline runs as one).
//!
//! This file and `system/simd.rs` hold the crate's `unsafe` code outside the C API. Here it is
//! one pointer, [`SharedSlice`], written through at indices that a safe wrapper has proved
//! distinct: by a [`DistinctIndices`] list (checked strictly increasing when it is made), or by
//! handing out the element of one index at a time per task. Callers never write `unsafe`.

use crate::error::{Error, Result};
use rayon::prelude::*;
use std::cell::RefCell;
use std::ops::Deref;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{mpsc, Arc};
use std::time::Duration;

/// Elements per parallel task in the per-node loops: fixed, so that every reduction adds the
/// same partial sums in the same order whatever the thread count.
pub(crate) const CHUNK: usize = 4096;

/// Indices in strictly increasing order, hence distinct: what makes writes at them from
/// several threads at once race-free. Checked once, when made.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub(crate) struct DistinctIndices(Vec<u32>);

impl DistinctIndices {
    /// Wraps `indices`.
    ///
    /// # Panics
    /// If they are not strictly increasing (a bug in the caller: the writes would alias).
    pub(crate) fn new(indices: Vec<u32>) -> Self {
        assert!(
            indices.windows(2).all(|w| w[0] < w[1]),
            "DistinctIndices::new: indices are not strictly increasing"
        );
        DistinctIndices(indices)
    }
}

impl Deref for DistinctIndices {
    type Target = [u32];

    fn deref(&self) -> &[u32] {
        &self.0
    }
}

impl<'a> IntoIterator for &'a DistinctIndices {
    type Item = &'a u32;
    type IntoIter = std::slice::Iter<'a, u32>;

    fn into_iter(self) -> Self::IntoIter {
        self.0.iter()
    }
}

/// The elements at one chunk's indices of N output slices, handed out one index at a time (the
/// `&mut self` borrow keeps any two from being live together).
pub(crate) struct ChunkWriter<'s, 'a, const N: usize> {
    indices: &'s [u32],
    outputs: &'s [SharedSlice<'a, f64>; N],
}

impl<'s, const N: usize> ChunkWriter<'s, '_, N> {
    /// This chunk's indices.
    #[inline]
    pub(crate) fn indices(&self) -> &'s [u32] {
        self.indices
    }

    /// The elements of the N outputs at this chunk's `k`-th index.
    #[inline]
    pub(crate) fn at(&mut self, k: usize) -> [&mut f64; N] {
        let i = self.indices[k] as usize;
        // SAFETY: `i` belongs to this chunk alone (the indices are distinct and the chunks
        // partition them), each output is a different slice, and `&mut self` ends the previous
        // call's borrows before this one's start.
        self.outputs.each_ref().map(|o| unsafe { o.get_mut(i) })
    }
}

/// Runs `task(chunk number, writer, aligned chunk)` for every chunk of [`CHUNK`] consecutive
/// entries of `indices`, in parallel, and returns the tasks' results in chunk order. The writer
/// gives the elements of `scattered` at the chunk's indices; `aligned` (the same length as
/// `indices`, or empty) is cut into the matching chunks of positions.
///
/// # Panics
/// If `aligned` is neither empty nor as long as `indices`, or an index lies beyond an output.
pub(crate) fn scatter_by_chunk<const N: usize, R: Send>(
    indices: &DistinctIndices,
    scattered: [&mut [f64]; N],
    aligned: &mut [f64],
    task: impl Fn(usize, &mut ChunkWriter<'_, '_, N>, &mut [f64]) -> R + Sync,
) -> Vec<R> {
    assert!(aligned.is_empty() || aligned.len() == indices.len());
    let outputs = scattered.map(SharedSlice::new);
    let run = |c: usize, aligned: &mut [f64]| {
        let start = c * CHUNK;
        let end = indices.len().min(start + CHUNK);
        let mut writer = ChunkWriter {
            indices: &indices[start..end],
            outputs: &outputs,
        };
        task(c, &mut writer, aligned)
    };
    let chunks = indices.len().div_ceil(CHUNK);
    if aligned.is_empty() {
        (0..chunks)
            .into_par_iter()
            .map(|c| run(c, &mut []))
            .collect()
    } else {
        aligned
            .par_chunks_mut(CHUNK)
            .enumerate()
            .map(|(c, aligned)| run(c, aligned))
            .collect()
    }
}

/// `f(position, &mut x[indices[position]])` for every position, in parallel chunks.
pub(crate) fn for_each_indexed(
    indices: &DistinctIndices,
    x: &mut [f64],
    f: impl Fn(usize, &mut f64) + Sync,
) {
    scatter_by_chunk(indices, [x], &mut [], |c, writer, _| {
        for k in 0..writer.indices().len() {
            let [v] = writer.at(k);
            f(c * CHUNK + k, v);
        }
    });
}

/// `slice` cut into the parts `ranges` gives (ascending and disjoint; gaps between them are
/// left out), for tasks that each own one part.
///
/// # Panics
/// If the ranges are not ascending and disjoint, or reach beyond `slice`.
pub(crate) fn split_parts<T>(
    slice: &mut [T],
    ranges: impl IntoIterator<Item = std::ops::Range<usize>>,
) -> Vec<&mut [T]> {
    let mut parts = Vec::new();
    let mut rest = slice;
    let mut at = 0;
    for range in ranges {
        assert!(
            range.start >= at && range.start <= range.end,
            "parts overlap"
        );
        let (_, tail) = std::mem::take(&mut rest).split_at_mut(range.start - at);
        let (part, tail) = tail.split_at_mut(range.end - range.start);
        parts.push(part);
        rest = tail;
        at = range.end;
    }
    parts
}

/// The longest the calling thread of [`watched`] waits between two calls of its report: with a
/// job that checks its [`Watch`] at least every ~0.1 s, a "stop" returns within 0.2 s.
pub(crate) const SLICE: Duration = Duration::from_millis(20);

/// What a job run by [`watched`] shares with the thread waiting for it: the fraction of the job
/// done (set by the job, read by the waiting thread) and the cancel flag (raised by the waiting
/// thread, checked by the job between its pieces of work, and by the innermost loops through
/// [`stop_requested`]). Both are atomics, so the job may set and check them from any of its
/// threads; neither changes what the job computes.
#[derive(Debug, Default)]
pub(crate) struct Watch {
    /// The f32 bits of the fraction done, only ever raised (non-negative floats order as their
    /// bits), so the fractions reported never go back.
    fraction: AtomicU32,
    cancelled: Arc<AtomicBool>,
}

impl Watch {
    /// A watch nobody reads or cancels (for jobs run outside [`watched`], e.g. in unit tests).
    pub(crate) fn new() -> Watch {
        Watch::default()
    }

    /// Records that `fraction` (clamped to 0..=1) of the job is done, unless more already is.
    pub(crate) fn set(&self, fraction: f32) {
        let f = if fraction.is_nan() {
            0.0
        } else {
            fraction.clamp(0.0, 1.0)
        };
        self.fraction.fetch_max(f.to_bits(), Ordering::Relaxed);
    }

    /// The fraction done so far.
    pub(crate) fn fraction(&self) -> f32 {
        f32::from_bits(self.fraction.load(Ordering::Relaxed))
    }

    /// Whether the waiting thread asked the job to stop.
    pub(crate) fn is_cancelled(&self) -> bool {
        self.cancelled.load(Ordering::Relaxed)
    }

    /// `Err(Error::Cancelled)` once the waiting thread asked the job to stop: a cancel point.
    pub(crate) fn check(&self) -> Result<()> {
        if self.is_cancelled() {
            Err(Error::Cancelled)
        } else {
            Ok(())
        }
    }

    /// [`Watch::set`] to `from + (to − from)·done/total`, then [`Watch::check`]: the usual
    /// cancel point between the pieces of a step that spans `from..to` of the job.
    pub(crate) fn step(&self, done: usize, total: usize, from: f32, to: f32) -> Result<()> {
        let part = if total == 0 {
            1.0
        } else {
            (done as f64 / total as f64) as f32
        };
        self.set(from + (to - from) * part);
        self.check()
    }

    fn cancel(&self) {
        self.cancelled.store(true, Ordering::Relaxed);
    }
}

thread_local! {
    /// On each worker thread of a pool running a [`watched`] job: that job's cancel flag (for
    /// [`stop_requested`]). Set on every thread of the pool when the job starts and cleared
    /// when it ends; a reconstruction's pool runs nothing but its own jobs, one at a time.
    static JOB_CANCELLED: RefCell<Option<Arc<AtomicBool>>> = const { RefCell::new(None) };
}

/// Whether the [`watched`] job this thread is working for was cancelled: the cancel point of
/// the innermost parallel loops (a brick's passes, a chunk of a splat), which the job's
/// [`Watch`] does not reach. Such a loop skips its remaining items when this is true; its
/// output is then incomplete, which is harmless because the job stops at its next
/// [`Watch::check`] (in the same step) and nothing reads it. False outside a watched job (unit
/// tests, the calling thread, other pools).
pub(crate) fn stop_requested() -> bool {
    JOB_CANCELLED.with(|flag| {
        flag.borrow()
            .as_ref()
            .is_some_and(|f| f.load(Ordering::Relaxed))
    })
}

/// Publishes `flag` as the cancel flag of the job on every thread of `pool` (None: no job), for
/// [`stop_requested`].
fn publish_cancel_flag(pool: &rayon::ThreadPool, flag: Option<&Arc<AtomicBool>>) {
    pool.broadcast(|_| JOB_CANCELLED.with(|slot| *slot.borrow_mut() = flag.cloned()));
}

/// Clears the published cancel flag when a watched job ends, whether it returns or unwinds.
struct PublishedCancelFlag<'p>(&'p rayon::ThreadPool);

impl Drop for PublishedCancelFlag<'_> {
    fn drop(&mut self) {
        publish_cancel_flag(self.0, None);
    }
}

/// Runs `job` on `pool` while the calling thread waits for it in slices of at most [`SLICE`],
/// calling `report(fraction done)` after each slice on the calling thread (so the caller's
/// callback is never called from a worker, nor concurrently). When `report` returns false the
/// [`Watch`] is cancelled, `report` is not called again, and once the job has returned (at its
/// next cancel point, or having finished) the result is `Err(Error::Cancelled)`. A panic in the
/// job reaches the caller, as from [`rayon::ThreadPool::install`].
///
/// The job computes the same result as it would under `pool.install`: only the waiting and the
/// reports differ, so the output does not depend on when, or whether, a report happens.
pub(crate) fn watched<R: Send>(
    pool: &rayon::ThreadPool,
    report: &mut dyn FnMut(f32) -> bool,
    job: impl FnOnce(&Watch) -> Result<R> + Send,
) -> Result<R> {
    let watch = Watch::new();
    publish_cancel_flag(pool, Some(&watch.cancelled));
    let _published = PublishedCancelFlag(pool);
    let (done, finished) = mpsc::sync_channel::<Result<R>>(1);
    pool.in_place_scope(|scope| {
        let watch = &watch;
        scope.spawn(move |_| {
            // The receiver waits until this sends or the job unwinds (then the scope re-raises
            // the panic), so a failed send cannot happen; there is nothing to do if it did.
            let _ = done.send(job(watch));
        });
        let mut stopped = false;
        loop {
            let wait = if stopped {
                finished
                    .recv()
                    .map_err(|_| mpsc::RecvTimeoutError::Disconnected)
            } else {
                finished.recv_timeout(SLICE)
            };
            match wait {
                Ok(result) => {
                    return if stopped {
                        Err(Error::Cancelled)
                    } else {
                        result
                    }
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    if !report(watch.fraction().min(1.0)) {
                        stopped = true;
                        watch.cancel();
                    }
                }
                // The job panicked: the scope re-raises the panic when this closure returns.
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    return Err(Error::Internal(
                        "a watched job ended without a result".into(),
                    ))
                }
            }
        }
    })
}

/// Items per block of [`map_in_blocks`]: a few milliseconds of work per block for the costliest
/// maps (χ at a point), so cancel points come often, and enough items that the pause between
/// blocks costs nothing.
pub(crate) const BLOCK: usize = 1 << 14;

/// `items.par_iter().map(f).collect()` one block of [`BLOCK`] items after another, with a
/// [`Watch::step`] from `from` to `to` after each: the same values in the same order, with
/// cancel points.
pub(crate) fn map_in_blocks<T: Sync, R: Send>(
    items: &[T],
    f: impl Fn(&T) -> R + Sync,
    watch: &Watch,
    from: f32,
    to: f32,
) -> Result<Vec<R>> {
    let mut out = Vec::with_capacity(items.len());
    for block in items.chunks(BLOCK) {
        out.par_extend(block.par_iter().map(&f));
        watch.step(out.len(), items.len(), from, to)?;
    }
    Ok(out)
}

/// A slice written from several threads at indices known to be disjoint between threads. Only
/// the safe wrappers of this module reach its elements.
struct SharedSlice<'a, T> {
    start: *mut T,
    len: usize,
    _slice: std::marker::PhantomData<&'a mut [T]>,
}

// SAFETY: elements are only reached through `get_mut`, whose callers (this module's wrappers)
// guarantee that no two threads use the same index at the same time; T: Send lets the elements
// be written from other threads.
unsafe impl<T: Send> Sync for SharedSlice<'_, T> {}

impl<'a, T> SharedSlice<'a, T> {
    fn new(slice: &'a mut [T]) -> Self {
        SharedSlice {
            start: slice.as_mut_ptr(),
            len: slice.len(),
            _slice: std::marker::PhantomData,
        }
    }

    /// Element `i` (bounds-checked).
    ///
    /// # Safety
    /// No other reference to element `i` may be live while the returned one is.
    #[inline]
    #[allow(clippy::mut_from_ref)]
    unsafe fn get_mut(&self, i: usize) -> &mut T {
        assert!(i < self.len, "index {i} beyond a slice of {}", self.len);
        // SAFETY: `i` is in bounds (checked above) and the caller guarantees exclusive access.
        unsafe { &mut *self.start.add(i) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pool() -> rayon::ThreadPool {
        rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap()
    }

    /// Proves: while a watched job runs, its fractions reach the report on the calling thread,
    /// never going back, and the job's result is returned.
    #[test]
    fn a_watched_job_reports_on_the_calling_thread() {
        let caller = std::thread::current().id();
        let mut seen = Vec::new();
        let result = watched(
            &pool(),
            &mut |f| {
                assert_eq!(std::thread::current().id(), caller);
                seen.push(f);
                true
            },
            |watch| {
                assert_ne!(std::thread::current().id(), caller);
                for k in 1..=10 {
                    std::thread::sleep(SLICE);
                    watch.step(k, 10, 0.0, 1.0)?;
                }
                Ok(42)
            },
        );
        assert_eq!(result, Ok(42));
        assert!(seen.iter().any(|&f| f > 0.0 && f < 1.0), "{seen:?}");
        assert!(seen.windows(2).all(|w| w[0] <= w[1]), "{seen:?}");
    }

    /// Proves: a report that says stop cancels a job that would otherwise never end, at its
    /// next cancel point, with `Error::Cancelled`, and is not called again.
    #[test]
    fn a_stop_cancels_a_watched_job_at_its_next_cancel_point() {
        let mut calls = 0;
        let result: Result<()> = watched(
            &pool(),
            &mut |_| {
                calls += 1;
                false
            },
            |watch| loop {
                watch.check()?;
                std::thread::sleep(Duration::from_millis(1));
            },
        );
        assert_eq!(result, Err(Error::Cancelled));
        assert_eq!(calls, 1);
    }

    /// Proves: a stop that comes as the job finishes still gives `Error::Cancelled` (the
    /// caller said stop: no result), and a job's own error comes through unchanged.
    #[test]
    fn a_stop_wins_over_a_finished_job_and_errors_pass_through() {
        let result = watched(&pool(), &mut |_| false, |_| {
            std::thread::sleep(3 * SLICE);
            Ok(1)
        });
        assert_eq!(result, Err(Error::Cancelled));
        let failed: Result<()> = watched(&pool(), &mut |_| true, |_| Err(Error::EmptyInput));
        assert_eq!(failed, Err(Error::EmptyInput));
    }

    /// Proves: the innermost loops of a watched job see its stop through `stop_requested` on
    /// every worker thread (so a loop that never reaches the job's `Watch` still ends early),
    /// and nothing outside a job, or after it, sees a stop.
    #[test]
    fn inner_loops_see_the_stop_of_their_job_only() {
        let pool = pool();
        let result: Result<usize> = watched(&pool, &mut |_| false, |watch| {
            // 10^7 items of 1 ms (hours were every item done); a stopped item takes no time.
            let done: usize = pool.install(|| {
                (0..10_000_000usize)
                    .into_par_iter()
                    .with_max_len(1)
                    .map(|_| {
                        if stop_requested() {
                            0
                        } else {
                            std::thread::sleep(Duration::from_millis(1));
                            1
                        }
                    })
                    .sum()
            });
            watch.check()?;
            Ok(done)
        });
        assert_eq!(result, Err(Error::Cancelled));
        assert!(!stop_requested());
        let after: Vec<bool> = pool.broadcast(|_| stop_requested());
        assert_eq!(after, vec![false, false]);
        let unstopped = watched(&pool, &mut |_| true, |_| {
            Ok(pool.broadcast(|_| stop_requested()))
        });
        assert_eq!(unstopped, Ok(vec![false, false]));
    }

    #[test]
    #[should_panic(expected = "not strictly increasing")]
    fn repeated_indices_are_refused() {
        DistinctIndices::new(vec![1, 4, 4, 7]);
    }

    #[test]
    fn scattered_writes_reach_every_index_once_and_results_keep_chunk_order() {
        let indices = DistinctIndices::new((0..10_000).map(|i| 3 * i + 1).collect());
        let mut a = vec![0.0; 30_001];
        let mut b = vec![0.0; 30_001];
        let mut aligned: Vec<f64> = (0..10_000).map(|i| i as f64).collect();
        let sums = scatter_by_chunk(&indices, [&mut a, &mut b], &mut aligned, |c, w, al| {
            for (k, v) in al.iter_mut().enumerate() {
                let [x, y] = w.at(k);
                *x += 1.0;
                *y = *v;
                *v = -*v;
            }
            c
        });
        assert_eq!(sums, vec![0, 1, 2]);
        for i in 0..10_000 {
            assert_eq!(a[3 * i + 1], 1.0);
            assert_eq!(b[3 * i + 1], i as f64);
            assert_eq!(aligned[i], -(i as f64));
        }
        assert_eq!(a.iter().sum::<f64>(), 10_000.0);
    }

    #[test]
    fn parts_are_the_ranges_asked_for() {
        let mut v: Vec<u32> = (0..10).collect();
        let parts = split_parts(&mut v, [1..3, 3..3, 5..9]);
        assert_eq!(parts.len(), 3);
        assert_eq!(&*parts[0], &[1, 2]);
        assert!(parts[1].is_empty());
        assert_eq!(&*parts[2], &[5, 6, 7, 8]);
    }

    #[test]
    #[should_panic(expected = "parts overlap")]
    fn overlapping_parts_are_refused() {
        let mut v = [0u8; 10];
        split_parts(&mut v, [2..5, 4..6]);
    }
}
