//! Keys that weld points: the bit patterns of their index coordinates
//! (`+0.0` and `-0.0` as one), and the hash map they go into.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use glam::DVec3;

/// A small multiplicative hasher for point keys (no DoS concern: keys are
/// our own coordinates).
#[derive(Default)]
pub(crate) struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        // Keys arrive as one slice of 24 bytes: mix them a word at a time.
        let mut words = bytes.chunks_exact(8);
        for w in &mut words {
            self.write_u64(u64::from_le_bytes(w.try_into().unwrap()));
        }
        for b in words.remainder() {
            self.write_u64(*b as u64);
        }
    }
    fn write_u64(&mut self, n: u64) {
        self.0 = (self.0.rotate_left(5) ^ n).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

pub(crate) type KeyMap<V> = HashMap<[u64; 3], V, BuildHasherDefault<KeyHasher>>;

/// The float next to the finite `x` towards +infinity (`up`) or
/// -infinity (`f64::next_up` / `next_down`, newer than the crate's
/// minimum Rust). (Towards the infinity it is, an infinite `x` gives NaN.)
pub(crate) fn next_float(x: f64, up: bool) -> f64 {
    if x == 0.0 {
        let tiny = f64::from_bits(1);
        return if up { tiny } else { -tiny };
    }
    let bits = x.to_bits();
    f64::from_bits(if (x > 0.0) == up { bits + 1 } else { bits - 1 })
}

#[inline]
pub(crate) fn key(p: DVec3) -> [u64; 3] {
    // +0.0 and -0.0 weld together.
    [
        (p.x + 0.0).to_bits(),
        (p.y + 0.0).to_bits(),
        (p.z + 0.0).to_bits(),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn next_float_steps_one_float() {
        for x in [
            0.0,
            -0.0,
            1.0,
            -1.0,
            7.0,
            -7.0,
            1e300,
            -3.5e-310,
            2f64.powi(52),
        ] {
            let (up, down) = (next_float(x, true), next_float(x, false));
            assert!(up > x && down < x, "{x}");
            // Nothing between: the midpoint rounds to one of the ends.
            for (a, b) in [(x, up), (down, x)] {
                let m = a / 2.0 + b / 2.0;
                assert!(m == a || m == b, "{a} {b}");
            }
        }
        assert_eq!(next_float(1.0, true), 1.0 + f64::EPSILON);
        assert_eq!(next_float(1.0, false), 1.0 - f64::EPSILON / 2.0);
    }
}
