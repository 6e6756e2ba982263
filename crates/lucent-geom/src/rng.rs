//! A small deterministic random number generator (PCG32) and a hash for
//! deriving independent streams from (pixel, sample, seed) keys.

/// PCG-XSH-RR 32-bit generator (O'Neill 2014): 64-bit state, 2^63 streams.
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

const MULT: u64 = 6_364_136_223_846_793_005;

impl Pcg32 {
    /// A generator for `seed` on stream `stream`; different streams give
    /// independent sequences for the same seed.
    #[inline]
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = Self {
            state: 0,
            inc: (stream << 1) | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(seed);
        rng.next_u32();
        rng
    }

    /// The generator's state and stream increment, for code that steps
    /// many generators side by side ([`Pcg32::from_parts`] gives it back).
    #[inline]
    pub fn to_parts(&self) -> (u64, u64) {
        (self.state, self.inc)
    }

    /// The generator with `state` and stream increment `inc`, as
    /// [`Pcg32::to_parts`] gave them.
    #[inline]
    pub fn from_parts(state: u64, inc: u64) -> Self {
        Self { state, inc }
    }

    /// Next uniformly distributed 32-bit value.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(MULT).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Moves on past `n` values, as `n` calls of [`Pcg32::next_u32`] would,
    /// without making them: for a draw whose value would go unused, so the
    /// draws after it are the ones they always were.
    ///
    /// ```
    /// use lucent_geom::Pcg32;
    /// let (mut a, mut b) = (Pcg32::new(3, 0), Pcg32::new(3, 0));
    /// a.skip(2);
    /// b.next_u32();
    /// b.next_u32();
    /// assert_eq!(a.next_u32(), b.next_u32());
    /// ```
    #[inline]
    pub fn skip(&mut self, n: u32) {
        for _ in 0..n {
            self.state = self.state.wrapping_mul(MULT).wrapping_add(self.inc);
        }
    }

    /// Uniform float in `[0, 1)` (24 random bits, so never exactly 1).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }
}

/// Mixes a list of integers into one well-distributed 64-bit value
/// (splitmix64 finaliser applied after each word). Used to key per-pixel RNG
/// streams so that results do not depend on thread scheduling.
pub fn hash_u64(words: &[u64]) -> u64 {
    hash_u64_from(0x9E37_79B9_7F4A_7C15, words)
}

/// [`hash_u64`] carried on from `h`, the hash of the words before `words`:
/// `hash_u64_from(hash_u64(a), b)` is `hash_u64` of `a` followed by `b`. A
/// key's fixed leading words (a render's seed, a pixel) are then hashed
/// once, not once per key.
///
/// ```
/// use lucent_geom::{hash_u64, hash_u64_from};
/// assert_eq!(hash_u64_from(hash_u64(&[7, 8]), &[9]), hash_u64(&[7, 8, 9]));
/// ```
#[inline]
pub fn hash_u64_from(mut h: u64, words: &[u64]) -> u64 {
    for &w in words {
        h ^= w;
        h = h.wrapping_add(0x9E37_79B9_7F4A_7C15);
        h = (h ^ (h >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h = (h ^ (h >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        h ^= h >> 31;
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_sequence_other_stream_differs() {
        let a: Vec<u32> = (0..8).scan(Pcg32::new(42, 7), |r, _| Some(r.next_u32())).collect();
        let b: Vec<u32> = (0..8).scan(Pcg32::new(42, 7), |r, _| Some(r.next_u32())).collect();
        let c: Vec<u32> = (0..8).scan(Pcg32::new(42, 8), |r, _| Some(r.next_u32())).collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
    }

    #[test]
    fn floats_are_uniform_in_unit_interval() {
        let mut rng = Pcg32::new(1, 1);
        let n = 100_000;
        let mut buckets = [0u32; 10];
        for _ in 0..n {
            let x = rng.next_f32();
            assert!((0.0..1.0).contains(&x));
            buckets[(x * 10.0) as usize] += 1;
        }
        // Each bucket expects 10_000 with std dev ~95; allow 5 sigma.
        for b in buckets {
            assert!((b as i32 - 10_000).abs() < 475, "{buckets:?}");
        }
    }

    #[test]
    fn hash_separates_neighbouring_keys() {
        assert_ne!(hash_u64(&[1, 2, 3]), hash_u64(&[1, 2, 4]));
        assert_ne!(hash_u64(&[1, 2]), hash_u64(&[2, 1]));
        assert_eq!(hash_u64(&[5, 6]), hash_u64(&[5, 6]));
        assert_eq!(hash_u64_from(hash_u64(&[]), &[5, 6]), hash_u64(&[5, 6]));
        assert_eq!(hash_u64_from(hash_u64(&[5]), &[6]), hash_u64(&[5, 6]));
        assert_eq!(hash_u64_from(hash_u64(&[5, 6]), &[]), hash_u64(&[5, 6]));
    }
}
