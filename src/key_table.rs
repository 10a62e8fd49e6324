//! A hash table from `u64` keys (all but `u64::MAX`) to small values whose look-ups can be
//! announced ahead ([`KeyTable::prefetch`]), for loops that look up millions of keys in a known
//! order.
//!
//! The extraction numbers each crossed edge's vertex the first time a leaf meets it and marks
//! each leaf it finds as visited, both in tables of a million or more entries, far larger than
//! the caches: nearly every look-up is a cache miss. With `std`'s map, the step that makes
//! them took 0.95 of the extraction's 3.4 s (the Happy Buddha at depth 10, one thread), waiting
//! on memory one key at a time. Here the loop announces the key it will look up some steps
//! later, so that its bucket's cache line is on its way while the current key is handled: the
//! step takes 0.57 s.
//!
//! Open addressing with linear probing: buckets of (key, value) in one array (a look-up reads
//! one cache line, rarely two), the key `u64::MAX` marking an empty bucket, at most 3/4 full
//! (doubled beyond). No removal. Keys are spread by a multiplicative (Fibonacci) hash; the
//! table's order of buckets is never observed (no iteration), so results do not depend on it.

/// The key marking an empty bucket: no key may equal it (the extraction's keys use at most 62
/// bits).
const EMPTY: u64 = u64::MAX;

/// The buckets a new table starts with.
const INITIAL_BUCKETS: usize = 1 << 10;

/// A map from keys (any `u64` but `u64::MAX`) to `V`, see the module documentation.
pub(crate) struct KeyTable<V: Copy + Default> {
    buckets: Vec<(u64, V)>,
    /// log2 of `buckets.len()`.
    bits: u32,
    len: usize,
}

impl<V: Copy + Default> KeyTable<V> {
    /// An empty table that holds `keys` keys before it grows.
    pub(crate) fn with_capacity(keys: usize) -> Self {
        let buckets = (keys.saturating_mul(4) / 3 + 1)
            .next_power_of_two()
            .max(INITIAL_BUCKETS);
        KeyTable {
            buckets: vec![(EMPTY, V::default()); buckets],
            bits: buckets.trailing_zeros(),
            len: 0,
        }
    }

    /// The number of keys in the table.
    pub(crate) fn len(&self) -> usize {
        self.len
    }

    /// The bucket where the probe for `key` starts.
    #[inline]
    fn home(&self, key: u64) -> usize {
        (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> (64 - self.bits)) as usize
    }

    /// Hints the processor to bring `key`'s first bucket into the cache: the look-up of `key`
    /// that follows a little later then finds it there. No effect on the table's contents.
    #[inline]
    pub(crate) fn prefetch(&self, key: u64) {
        crate::cache::prefetch(&self.buckets[self.home(key)]);
    }

    /// The value of `key`, inserting `value` first when `key` is absent; and whether it was
    /// inserted.
    ///
    /// # Panics
    /// When `key` is `u64::MAX`, which marks empty buckets.
    #[inline]
    pub(crate) fn get_or_insert(&mut self, key: u64, value: V) -> (V, bool) {
        assert_ne!(key, EMPTY, "u64::MAX is not a key of a KeyTable");
        let mask = self.buckets.len() - 1;
        let mut at = self.home(key);
        loop {
            let (k, v) = self.buckets[at];
            if k == key {
                return (v, false);
            }
            if k == EMPTY {
                break;
            }
            at = (at + 1) & mask;
        }
        self.buckets[at] = (key, value);
        self.len += 1;
        if 4 * self.len > 3 * self.buckets.len() {
            self.grow();
        }
        (value, true)
    }

    /// Inserts `key` with `value` when it is absent: whether it was.
    #[inline]
    pub(crate) fn insert_new(&mut self, key: u64, value: V) -> bool {
        self.get_or_insert(key, value).1
    }

    /// Doubles the buckets and places every key again.
    fn grow(&mut self) {
        let doubled = vec![(EMPTY, V::default()); 2 * self.buckets.len()];
        let old = std::mem::replace(&mut self.buckets, doubled);
        self.bits += 1;
        let mask = self.buckets.len() - 1;
        for (key, value) in old.into_iter().filter(|&(k, _)| k != EMPTY) {
            let mut at = self.home(key);
            while self.buckets[at].0 != EMPTY {
                at = (at + 1) & mask;
            }
            self.buckets[at] = (key, value);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    #[test]
    fn matches_a_hash_map_through_growth_and_colliding_keys() {
        let mut table: KeyTable<u32> = KeyTable::with_capacity(0);
        let mut want: HashMap<u64, u32> = HashMap::new();
        // Pseudo-random keys and runs of keys a multiple of 2^k apart (which a multiplicative
        // hash sends to nearby buckets), each looked up several times.
        let mut state = 0x1234_5678_9ABC_DEF0u64;
        for i in 0..200_000u64 {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            let key = match i % 3 {
                0 => state >> 2,
                1 => (i % 5_000) << 40,
                _ => (state >> 40) % 10_000,
            };
            table.prefetch(key);
            let next = want.len() as u32;
            let absent = !want.contains_key(&key);
            let expected = *want.entry(key).or_insert(next);
            assert_eq!(
                table.get_or_insert(key, next),
                (expected, absent),
                "key {key:#x}"
            );
            assert_eq!(table.len(), want.len());
        }
        assert!(table.buckets.len() >= 4 * table.len() / 3);
        for (&key, &value) in &want {
            assert_eq!(table.get_or_insert(key, u32::MAX), (value, false));
        }
    }

    #[test]
    fn a_reserved_table_holds_its_keys_without_growing() {
        for keys in [0, 1, 767, 768, 769, 10_000] {
            let mut table: KeyTable<u32> = KeyTable::with_capacity(keys);
            let buckets = table.buckets.len();
            for key in 0..keys as u64 {
                table.get_or_insert(key * 7, key as u32);
            }
            assert_eq!(table.buckets.len(), buckets, "{keys} keys");
            assert_eq!(table.len(), keys);
        }
    }

    #[test]
    fn insert_new_says_whether_the_key_was_absent() {
        let mut set: KeyTable<()> = KeyTable::with_capacity(0);
        assert!(set.insert_new(0, ()));
        assert!(!set.insert_new(0, ()));
        assert!(set.insert_new(EMPTY - 1, ()));
        assert_eq!(set.len(), 2);
    }

    #[test]
    #[should_panic(expected = "not a key")]
    fn the_empty_marker_is_refused_as_a_key() {
        let mut set: KeyTable<()> = KeyTable::with_capacity(0);
        set.insert_new(EMPTY, ());
    }
}
