//! A small open-addressing hash map from `u64` keys to `Copy` values, for
//! the per-cell bookkeeping of refinement (edge decisions, the soundness
//! check of a refined patch).
//!
//! These maps are filled and emptied once per cell, millions of times per
//! extraction, so clearing must not cost the table's size: every slot
//! carries the generation it was written in, and [`FlatMap::clear`] only
//! starts a new generation. Keys are vertex-id pairs packed into a word,
//! hashed by one multiplication (Fibonacci hashing).

/// Map from `u64` keys to `V`, cleared in O(1).
#[derive(Debug, Clone)]
pub(crate) struct FlatMap<V: Copy> {
    /// `(generation, key, value)` per slot; a slot is empty unless its
    /// generation is the current one.
    slots: Vec<(u32, u64, V)>,
    generation: u32,
    len: usize,
    /// `64 - log2(slots.len())`: the hash's top bits index the table.
    shift: u32,
}

impl<V: Copy + Default> Default for FlatMap<V> {
    fn default() -> Self {
        Self::with_log2_capacity(6)
    }
}

impl<V: Copy + Default> FlatMap<V> {
    fn with_log2_capacity(bits: u32) -> Self {
        FlatMap {
            slots: vec![(0, 0, V::default()); 1 << bits],
            generation: 1,
            len: 0,
            shift: 64 - bits,
        }
    }

    /// Empties the map (O(1) but once every 2^32 calls).
    pub fn clear(&mut self) {
        self.len = 0;
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.slots.fill((0, 0, V::default()));
            self.generation = 1;
        }
    }

    #[inline(always)]
    fn home(&self, key: u64) -> usize {
        (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> self.shift) as usize
    }

    /// The slot holding `key` and `true`, or the empty slot where it would
    /// go and `false`.
    #[inline]
    fn probe(&self, key: u64) -> (usize, bool) {
        let mask = self.slots.len() - 1;
        let mut i = self.home(key);
        loop {
            let (g, k, _) = self.slots[i];
            if g != self.generation {
                return (i, false);
            }
            if k == key {
                return (i, true);
            }
            i = (i + 1) & mask;
        }
    }

    /// The value stored under `key`.
    #[inline]
    pub fn get(&self, key: u64) -> Option<V> {
        let (i, found) = self.probe(key);
        found.then(|| self.slots[i].2)
    }

    /// Stores `value` under `key` unless the key is present; returns the
    /// value already stored, if any (which is then kept).
    #[inline]
    pub fn insert_new(&mut self, key: u64, value: V) -> Option<V> {
        if 2 * (self.len + 1) > self.slots.len() {
            self.grow();
        }
        let (i, found) = self.probe(key);
        if found {
            return Some(self.slots[i].2);
        }
        self.slots[i] = (self.generation, key, value);
        self.len += 1;
        None
    }

    /// [`FlatMap::insert_new`], growing the table fallibly: `Err(bytes)`,
    /// the map unchanged, when the larger table cannot be allocated (a
    /// cell refined to a high level fills millions of entries).
    #[inline]
    pub fn try_insert_new(&mut self, key: u64, value: V) -> Result<Option<V>, usize> {
        if 2 * (self.len + 1) > self.slots.len() {
            self.try_grow()?;
        }
        Ok(self.insert_new(key, value))
    }

    /// Makes room for `extra` more entries without growing: until then
    /// the slots [`FlatMap::find`] returns stay where they are.
    /// `Err(bytes)`, the map unchanged, when the larger table cannot be
    /// allocated.
    #[inline]
    pub fn try_reserve(&mut self, extra: usize) -> Result<(), usize> {
        while 2 * (self.len + extra) > self.slots.len() {
            self.try_grow()?;
        }
        Ok(())
    }

    /// The slot of `key`, and whether it holds it (else the empty slot
    /// where [`FlatMap::fill`] puts it). One probe where a look-up, an
    /// insertion and a second look-up took three (refinement's edges).
    /// Valid until the table grows (see [`FlatMap::try_reserve`]).
    #[inline]
    pub fn find(&self, key: u64) -> (usize, bool) {
        self.probe(key)
    }

    /// The value in slot `i`, which [`FlatMap::find`] found holding a key.
    #[inline]
    pub fn value(&self, i: usize) -> V {
        self.slots[i].2
    }

    /// The value in slot `i` (found or filled), to change in place.
    #[inline]
    pub fn value_mut(&mut self, i: usize) -> &mut V {
        &mut self.slots[i].2
    }

    /// Puts `key` and `value` in the empty slot `i` that [`FlatMap::find`]
    /// returned for `key`, with room reserved and nothing inserted since.
    #[inline]
    pub fn fill(&mut self, i: usize, key: u64, value: V) {
        debug_assert!(self.slots[i].0 != self.generation && 2 * (self.len + 1) <= self.slots.len());
        self.slots[i] = (self.generation, key, value);
        self.len += 1;
    }

    /// Doubles the table, keeping the entries; `Err(bytes)` when the new
    /// table cannot be allocated.
    #[cold]
    fn try_grow(&mut self) -> Result<(), usize> {
        let n = 1usize << (64 - self.shift + 1);
        let bytes = n.saturating_mul(std::mem::size_of::<(u32, u64, V)>());
        let mut slots = Vec::new();
        slots.try_reserve_exact(n).map_err(|_| bytes)?;
        slots.resize(n, (0, 0, V::default()));
        let fresh = FlatMap {
            slots,
            generation: 1,
            len: 0,
            shift: self.shift - 1,
        };
        // (The same table as `with_log2_capacity` makes, allocated fallibly.)
        let old = std::mem::replace(self, fresh);
        for (g, k, v) in old.slots {
            if g == old.generation {
                self.insert_new(k, v);
            }
        }
        Ok(())
    }

    /// Doubles the table, keeping the entries; a failed allocation ends
    /// the process, as a `Vec`'s does.
    #[cold]
    fn grow(&mut self) {
        if self.try_grow().is_err() {
            let n = 1usize << (64 - self.shift + 1);
            std::alloc::handle_alloc_error(
                std::alloc::Layout::array::<(u32, u64, V)>(n)
                    .unwrap_or_else(|_| std::alloc::Layout::new::<(u32, u64, V)>()),
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fallible_insertion_grows_like_insertion() {
        let (mut a, mut b) = (FlatMap::<u32>::default(), FlatMap::<u32>::default());
        for k in 0..10_000u64 {
            let key = k.wrapping_mul(0x2545_F491_4F6C_DD1D);
            assert_eq!(
                a.try_insert_new(key, k as u32),
                Ok(b.insert_new(key, k as u32))
            );
            assert_eq!(a.try_insert_new(key, 7), Ok(Some(k as u32)));
        }
        assert_eq!((a.len, a.slots.len()), (b.len, b.slots.len()));
        assert!(
            (0..10_000u64).all(|k| a.get(k.wrapping_mul(0x2545_F491_4F6C_DD1D)) == Some(k as u32))
        );
    }

    #[test]
    fn behaves_like_a_hash_map_across_clears_and_growth() {
        let mut ours = FlatMap::<u32>::default();
        let mut reference = std::collections::HashMap::new();
        let mut x = 12345u64;
        for round in 0..50 {
            ours.clear();
            reference.clear();
            // Rounds of very different sizes exercise growth and reuse.
            let n = (round * 37) % 300;
            for _ in 0..n {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let key = (x >> 40) % 512;
                let value = (x >> 20) as u32;
                let expected = reference.get(&key).copied();
                if x & (1 << 60) == 0 {
                    assert_eq!(ours.insert_new(key, value), expected);
                } else {
                    // The slot interface: room first, one probe, then
                    // the value found or the key filled in.
                    ours.try_reserve(1).unwrap();
                    let (i, found) = ours.find(key);
                    assert_eq!(found.then(|| ours.value(i)), expected);
                    if !found {
                        ours.fill(i, key, value);
                    }
                }
                reference.entry(key).or_insert(value);
            }
            for key in 0..512u64 {
                assert_eq!(ours.get(key), reference.get(&key).copied());
                // Changes in place land in the map.
                let (i, found) = ours.find(key);
                assert_eq!(found, reference.contains_key(&key));
                if let (true, Some(r)) = (found, reference.get_mut(&key)) {
                    *ours.value_mut(i) ^= 0x5a5a;
                    *r ^= 0x5a5a;
                }
                assert_eq!(ours.get(key), reference.get(&key).copied());
            }
        }
    }
}
