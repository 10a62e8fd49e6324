//! The programs' allocator: every large block (1 MiB and up) in pages of its own, so that a
//! freed one never leaves a resident hole below live blocks in a heap (what glibc's malloc
//! gives with a fixed mmap threshold), but a freed block's pages kept for the next large block
//! instead of given back to the kernel at once.
//!
//! psr's stages allocate and free vectors of megabytes to hundreds of megabytes one after
//! another (the octree's levels, the splatted field, the system's diagonals, the extraction's
//! batches). Given back at once, each of their pages is faulted in and cleared again by the
//! next vector: 700,000 page faults and 1.5 s of kernel time in the Buddha at depth 10 (9.7 s
//! in all, one thread). Here freed pages are kept, up to a share of the live ones, and handed
//! to the next large block: the front of a kept range long enough, or the longest kept ranges
//! moved side by side into a new mapping by `mremap` (which moves page tables, not data). A
//! zeroed block made of kept pages is cleared by writing its resident pages and dropping the
//! others, so pages never written stay unbacked, as with `calloc`.
//!
//! Small blocks, and large ones with an alignment above a page, are the system allocator's.
//! This is the programs' allocator only: the library leaves its host's allocator alone.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// Blocks from this size up get pages of their own.
const LARGE: usize = 1 << 20;
/// How many freed ranges of pages are kept at most.
const SLOTS: usize = 64;
/// Freed ranges shorter than this are given back at once (not worth a system call to reuse).
const MIN_KEPT: usize = 64 << 10;
/// Freed pages are kept up to a quarter of the live large blocks' (or 64 MiB, if more), so the
/// peak resident memory grows by at most a quarter (or 64 MiB). Measured (Buddha, depth 10, one thread):
/// 9.6 → 8.8 s, peak 620 → 655 MiB; keeping everything, 8.6 s and 953 MiB; 64 MiB at most,
/// 8.9 s and 651 MiB.
const LIVE_PER_KEPT: usize = 4;
const KEPT_FLOOR: usize = 64 << 20;

/// The allocator of the programs `psr` and `psr-mpi` (their `#[global_allocator]`).
pub struct ReusingAllocator;

/// The bytes of freed pages kept for reuse at most: [`keep_at_most`].
static KEEP_LIMIT: AtomicUsize = AtomicUsize::new(usize::MAX);
/// The bytes of live large blocks' pages.
static LIVE: AtomicUsize = AtomicUsize::new(0);

/// Freed pages waiting for a large block, as page-aligned ranges (address, length in bytes),
/// oldest first.
struct Kept {
    ranges: [(usize, usize); SLOTS],
    count: usize,
    bytes: usize,
}

static KEPT: Mutex<Kept> = Mutex::new(Kept {
    ranges: [(0, 0); SLOTS],
    count: 0,
    bytes: 0,
});

/// Keeps at most `bytes` of freed large blocks' pages for reuse from now on (0: gives every
/// freed large block back to the kernel at once), and gives back what is kept beyond it. A run
/// under a memory budget sets it so that kept pages never count against the budget unseen.
pub fn keep_at_most(bytes: usize) {
    KEEP_LIMIT.store(bytes, Ordering::Relaxed);
    let mut kept = lock();
    while kept.bytes > bytes {
        let (address, length) = kept.remove(0);
        unmap(address, length);
    }
}

fn lock() -> std::sync::MutexGuard<'static, Kept> {
    // Nothing panics while the lock is held; a poisoned lock still holds consistent data.
    KEPT.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

impl Kept {
    fn remove(&mut self, slot: usize) -> (usize, usize) {
        let range = self.ranges[slot];
        self.ranges.copy_within(slot + 1..self.count, slot);
        self.count -= 1;
        self.bytes -= range.1;
        range
    }

    /// Keeps the freed range (address, length), giving back the oldest ranges for room, or
    /// gives it back when it is too short to be worth a system call or beyond the limit.
    fn keep(&mut self, address: usize, length: usize) {
        let share = LIVE.load(Ordering::Relaxed) / LIVE_PER_KEPT;
        let limit = KEEP_LIMIT
            .load(Ordering::Relaxed)
            .min(share.max(KEPT_FLOOR));
        if length < MIN_KEPT || length > limit {
            unmap(address, length);
            return;
        }
        while self.count == SLOTS || self.bytes + length > limit {
            let (old_address, old_length) = self.remove(0);
            unmap(old_address, old_length);
        }
        self.ranges[self.count] = (address, length);
        self.count += 1;
        self.bytes += length;
    }

    /// The shortest kept range of at least `length` bytes.
    fn shortest_fitting(&self, length: usize) -> Option<usize> {
        let ranges = &self.ranges[..self.count];
        (0..ranges.len())
            .filter(|&k| ranges[k].1 >= length)
            .min_by_key(|&k| ranges[k].1)
    }

    /// The longest kept range.
    fn longest(&self) -> Option<usize> {
        let ranges = &self.ranges[..self.count];
        (0..ranges.len()).max_by_key(|&k| ranges[k].1)
    }
}

fn page_size() -> usize {
    static PAGE: AtomicUsize = AtomicUsize::new(0);
    match PAGE.load(Ordering::Relaxed) {
        0 => {
            // SAFETY: sysconf only reads a system constant.
            let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
            let page = usize::try_from(page)
                .ok()
                .filter(|p| p.is_power_of_two())
                .unwrap_or(4096);
            PAGE.store(page, Ordering::Relaxed);
            page
        }
        page => page,
    }
}

/// Whether `layout` gets pages of its own, and their length if so.
fn mapped_length(layout: Layout) -> Option<usize> {
    let page = page_size();
    (layout.size() >= LARGE && layout.align() <= page)
        .then(|| layout.size().checked_next_multiple_of(page))
        .flatten()
}

fn unmap(address: usize, length: usize) {
    // SAFETY: (address, length) are whole pages this allocator mapped and nothing refers to.
    unsafe {
        libc::munmap(address as *mut libc::c_void, length);
    }
}

/// `length` bytes of pages for a large block, and how many of its first bytes hold old data
/// (the rest is zero). From the kept pages when they can: the shortest kept range long enough
/// for the whole block, or else the longest ranges one after another, the front of each taken
/// and the rest kept. One range is the block itself; several are moved side by side into a new
/// mapping (`mremap` moves page tables, not data; the kernel fills what they do not cover with
/// zeros).
fn map(length: usize) -> Option<(*mut u8, usize)> {
    let mut pieces = [(0usize, 0usize); SLOTS];
    let mut count = 0;
    let mut gathered = 0;
    {
        let mut kept = lock();
        while gathered < length {
            let wanted = length - gathered;
            let whole = if count == 0 {
                kept.shortest_fitting(length)
            } else {
                None
            };
            let Some(slot) = whole.or_else(|| kept.longest()) else {
                break;
            };
            let (address, had) = kept.remove(slot);
            let used = had.min(wanted);
            if used < had {
                kept.keep(address + used, had - used);
            }
            pieces[count] = (address, used);
            count += 1;
            gathered += used;
        }
    }
    if count == 1 && gathered == length {
        return Some((pieces[0].0 as *mut u8, length));
    }
    // SAFETY: an anonymous private mapping at an address of the kernel's choice.
    let fresh = unsafe {
        libc::mmap(
            std::ptr::null_mut(),
            length,
            libc::PROT_READ | libc::PROT_WRITE,
            libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
            -1,
            0,
        )
    };
    if fresh == libc::MAP_FAILED {
        pieces[..count]
            .iter()
            .for_each(|&(address, used)| unmap(address, used));
        return None;
    }
    let mut placed = 0;
    for &(address, used) in &pieces[..count] {
        // SAFETY: the piece is whole pages no one refers to; its destination lies in the new
        // mapping, past the pieces already placed. A piece the kernel cannot move (one that
        // spans two mappings, made by an earlier move) is given back and its place stays zero.
        let moved = unsafe {
            libc::mremap(
                address as *mut libc::c_void,
                used,
                used,
                libc::MREMAP_MAYMOVE | libc::MREMAP_FIXED,
                fresh.cast::<u8>().add(placed),
            )
        };
        if moved == libc::MAP_FAILED {
            unmap(address, used);
        } else {
            placed += used;
        }
    }
    Some((fresh.cast(), placed))
}

/// Zeroes the first `length` bytes of a reused mapping at `block` without faulting in pages
/// that are not resident: resident pages are written with zeros (cheaper than a fault and a
/// clear by the kernel), the others dropped (a later touch then maps a zero page; a page
/// swapped out is not resident and is dropped too, so it never comes back with old data).
/// A zeroed block that is only partly written thus stays partly unbacked, as with `calloc`.
fn clear(block: *mut u8, length: usize) {
    let page = page_size();
    const CHUNK: usize = 1024;
    let mut resident = [0u8; CHUNK];
    let pages = length / page;
    let mut first = 0;
    while first < pages {
        let count = CHUNK.min(pages - first);
        // SAFETY: the range lies in the block's mapping; `resident` has room for its pages.
        let asked = unsafe {
            libc::mincore(
                block.add(first * page).cast(),
                count * page,
                resident.as_mut_ptr(),
            )
        };
        // Where mincore fails, every page counts as resident (written, so zero either way).
        let is_resident = |j: usize| asked != 0 || resident[j] & 1 != 0;
        let mut k = 0;
        while k < count {
            let run = (k..count)
                .take_while(|&j| is_resident(j) == is_resident(k))
                .count();
            // SAFETY: the run's pages lie in the block, which no one else refers to.
            unsafe {
                let start = block.add((first + k) * page);
                if is_resident(k) {
                    std::ptr::write_bytes(start, 0, run * page);
                } else {
                    libc::madvise(start.cast(), run * page, libc::MADV_DONTNEED);
                }
            }
            k += run;
        }
        first += count;
    }
}

// SAFETY: a large block is a page-aligned range of private anonymous pages of at least its
// size, owned by one block at a time (a kept range is in `KEPT` and nowhere else, and ranges
// never overlap); the rest is `System`'s.
unsafe impl GlobalAlloc for ReusingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        match mapped_length(layout) {
            Some(length) => map(length).map_or(std::ptr::null_mut(), |(block, _)| {
                LIVE.fetch_add(length, Ordering::Relaxed);
                block
            }),
            // SAFETY: the caller's contract, passed on.
            None => unsafe { System.alloc(layout) },
        }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        match mapped_length(layout) {
            Some(length) => map(length).map_or(std::ptr::null_mut(), |(block, old)| {
                LIVE.fetch_add(length, Ordering::Relaxed);
                clear(block, old);
                block
            }),
            // SAFETY: the caller's contract, passed on.
            None => unsafe { System.alloc_zeroed(layout) },
        }
    }

    unsafe fn dealloc(&self, block: *mut u8, layout: Layout) {
        match mapped_length(layout) {
            Some(length) => {
                LIVE.fetch_sub(length, Ordering::Relaxed);
                lock().keep(block as usize, length);
            }
            // SAFETY: the caller's contract, passed on.
            None => unsafe { System.dealloc(block, layout) },
        }
    }

    unsafe fn realloc(&self, block: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: the caller guarantees that new_size, rounded up to the alignment, fits isize.
        let new_layout = unsafe { Layout::from_size_align_unchecked(new_size, layout.align()) };
        match (mapped_length(layout), mapped_length(new_layout)) {
            (Some(old_length), Some(new_length)) => {
                if new_length <= old_length {
                    if new_length < old_length {
                        LIVE.fetch_sub(old_length - new_length, Ordering::Relaxed);
                        lock().keep(block as usize + new_length, old_length - new_length);
                    }
                    return block;
                }
                // SAFETY: (block, old_length) are the block's pages; the kernel moves them
                // (contents kept) when it cannot grow them in place.
                let moved = unsafe {
                    libc::mremap(block.cast(), old_length, new_length, libc::MREMAP_MAYMOVE)
                };
                if moved != libc::MAP_FAILED {
                    LIVE.fetch_add(new_length - old_length, Ordering::Relaxed);
                    return moved.cast();
                }
                // A block whose pages span two mappings (made of kept pieces) cannot be
                // remapped whole: copied instead.
                // SAFETY: the caller's contract, passed on.
                unsafe { self.copied(block, layout, new_layout) }
            }
            // SAFETY: the caller's contract, passed on.
            (None, None) => unsafe { System.realloc(block, layout, new_size) },
            // SAFETY: the caller's contract, passed on.
            _ => unsafe { self.copied(block, layout, new_layout) },
        }
    }
}

impl ReusingAllocator {
    /// `realloc` by a new block, the contents copied and the old block freed.
    ///
    /// # Safety
    /// As `GlobalAlloc::realloc`, with `new_layout` its new size and the old alignment.
    unsafe fn copied(&self, block: *mut u8, layout: Layout, new_layout: Layout) -> *mut u8 {
        // SAFETY: new_layout is non-zero in size and valid (the caller's contract).
        let moved = unsafe { self.alloc(new_layout) };
        if !moved.is_null() {
            // SAFETY: both blocks hold at least the smaller size and do not overlap; the old
            // block is the caller's to free.
            unsafe {
                let size = layout.size().min(new_layout.size());
                std::ptr::copy_nonoverlapping(block, moved, size);
                self.dealloc(block, layout);
            }
        }
        moved
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MIB: usize = 1 << 20;

    fn layout(bytes: usize) -> Layout {
        Layout::from_size_align(bytes, 8).unwrap()
    }

    /// Writes `byte` over the first `length` bytes of `block`.
    fn fill(block: *mut u8, length: usize, byte: u8) {
        // SAFETY: the tests' blocks hold at least `length` bytes.
        unsafe { std::ptr::write_bytes(block, byte, length) };
    }

    /// Whether the first `length` bytes of `block` are all `byte`.
    fn all(block: *mut u8, length: usize, byte: u8) -> bool {
        // SAFETY: the tests' blocks hold at least `length` initialised bytes.
        unsafe { std::slice::from_raw_parts(block, length) }
            .iter()
            .all(|&b| b == byte)
    }

    fn kept_bytes() -> usize {
        lock().bytes
    }

    /// One test, not several, because the kept pages are the process's: tests running side by
    /// side would take each other's.
    #[test]
    fn large_blocks_reuse_freed_pages_zeroed_when_asked_and_keep_their_contents_when_resized() {
        let a = ReusingAllocator;
        unsafe {
            // A freed block's pages serve the next block of the same length: its old bytes are
            // there unless zeroing is asked, resident pages written and the others (never
            // touched: the second half) dropped.
            let first = a.alloc(layout(4 * MIB));
            fill(first, 2 * MIB, 0xAB);
            a.dealloc(first, layout(4 * MIB));
            assert!(kept_bytes() >= 4 * MIB, "the freed pages are kept");
            let again = a.alloc_zeroed(layout(4 * MIB));
            assert_eq!(again, first, "the kept range is reused");
            assert!(
                all(again, 4 * MIB, 0),
                "a zeroed block made of kept pages is zero"
            );
            fill(again, 4 * MIB, 0xCD);

            // A shorter block takes the front of a kept range; the rest stays kept.
            a.dealloc(again, layout(4 * MIB));
            let front = a.alloc(layout(3 * MIB));
            assert_eq!(front, first);
            assert!(
                all(front, 3 * MIB, 0xCD),
                "a block not zeroed keeps the old bytes"
            );
            let rest = a.alloc_zeroed(layout(MIB));
            assert_eq!(
                rest as usize,
                first as usize + 3 * MIB,
                "the tail serves the next"
            );
            assert!(all(rest, MIB, 0));

            // A block longer than every kept range is made of several moved side by side,
            // zeroed where asked, and stays usable when resized (it spans two mappings, so
            // growing it copies).
            a.dealloc(front, layout(3 * MIB));
            a.dealloc(rest, layout(MIB));
            let joined = a.alloc_zeroed(layout(6 * MIB + 100));
            assert!(
                all(joined, 6 * MIB + 100, 0),
                "kept pieces and new pages are zero"
            );
            for k in 0..6 {
                fill(joined.add(k * MIB), MIB, k as u8 + 1);
            }
            let grown = a.realloc(joined, layout(6 * MIB + 100), 9 * MIB);
            assert!(!grown.is_null());
            for k in 0..6 {
                assert!(
                    all(grown.add(k * MIB), MIB, k as u8 + 1),
                    "MiB {k} kept its bytes"
                );
            }
            fill(grown.add(6 * MIB), 3 * MIB, 7);
            let shrunk = a.realloc(grown, layout(9 * MIB), 2 * MIB);
            assert_eq!(shrunk, grown, "shrinking stays in place");
            assert!(all(shrunk, MIB, 1) && all(shrunk.add(MIB), MIB, 2));
            let small = a.realloc(shrunk, layout(2 * MIB), 1000);
            assert!(
                all(small, 1000, 1),
                "across the threshold the bytes are copied"
            );
            a.dealloc(small, layout(1000));

            // Without a limit to keep, freed pages go back at once.
            keep_at_most(0);
            assert_eq!(kept_bytes(), 0);
            let block = a.alloc(layout(2 * MIB));
            a.dealloc(block, layout(2 * MIB));
            assert_eq!(kept_bytes(), 0);
            keep_at_most(usize::MAX);

            // Threads allocating, filling, checking and freeing at once never share a block.
            std::thread::scope(|scope| {
                for t in 0..4u8 {
                    scope.spawn(move || {
                        let a = ReusingAllocator;
                        for round in 0..40usize {
                            let bytes = MIB + ((round * 7 + t as usize * 3) % 5) * MIB / 2;
                            let block = a.alloc(layout(bytes));
                            fill(block, bytes, t + 1);
                            std::thread::yield_now();
                            assert!(all(block, bytes, t + 1), "thread {t}'s block was shared");
                            a.dealloc(block, layout(bytes));
                        }
                    });
                }
            });
        }
    }
}
