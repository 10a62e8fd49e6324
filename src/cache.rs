//! A cache hint for loops that know which memory they will read a little later: the table
//! look-ups of the extraction (`crate::key_table`) and the window gathers of the system
//! (`crate::system`), both of which would otherwise wait on memory one access at a time.

/// Hints the processor to bring the cache line holding `at` into the cache. No effect on any
/// value, and none at all where the target has no such hint here (only x86-64 does).
#[inline]
pub(crate) fn prefetch<T>(at: &T) {
    let at: *const T = at;
    #[cfg(target_arch = "x86_64")]
    // SAFETY: `_mm_prefetch` needs SSE, which every x86-64 processor has; a prefetch only
    // hints the cache and never faults, and `at` comes from a reference anyway.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(at.cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = at;
}
