//! The workspace's one source of deterministic randomness: a SplitMix64 stream (synthetic scans,
//! the report's colour samples, the packers' shuffles, the `random` scorer), a xorshift stream for
//! test and bench fixtures, stateless hashes for per-element randomness (so parallel loops draw
//! the same numbers in any order), and seeded smooth value noise for shape displacement and camera
//! preferences. Nothing here depends on the platform, so seeded runs give the same bytes anywhere.

/// The SplitMix64 finalizer: a bijective 64-bit mix with good avalanche.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A hash of a seed and two integers, for stateless per-element random numbers.
#[inline]
pub fn hash3(seed: u64, a: u64, b: u64) -> u64 {
    mix64(
        seed ^ mix64(
            a.wrapping_add(0x9E37_79B9_7F4A_7C15) ^ mix64(b.wrapping_mul(0xD6E8_FEB8_6659_FD93)),
        ),
    )
}

/// Maps a hash to a uniform `f64` in `[0, 1)` (53 random bits).
#[inline]
pub fn unit_f64(h: u64) -> f64 {
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// Maps a hash to a uniform `f64` in `[-1, 1)`.
#[inline]
pub fn signed_f64(h: u64) -> f64 {
    2.0 * unit_f64(h) - 1.0
}

/// A SplitMix64 stream: tiny, fast and good enough for placing cameras and jittering meshes.
#[derive(Clone, Debug)]
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    /// A stream starting from `seed`; every seed, zero included, is valid.
    pub fn new(seed: u64) -> Self {
        Self { state: seed }
    }

    /// The next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        mix64(self.state)
    }

    /// Uniform in `[0, 1)`.
    #[inline]
    pub fn unit(&mut self) -> f64 {
        unit_f64(self.next_u64())
    }

    /// Uniform in `[lo, hi)`.
    #[inline]
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// A number in `0..n` (n > 0). The modulo bias is negligible for the small `n` of shuffles
    /// and fixtures, and, unlike rejection sampling, the count of draws stays fixed.
    #[inline]
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// Fisher–Yates shuffle of `v`.
    pub fn shuffle<T>(&mut self, v: &mut [T]) {
        for i in (1..v.len()).rev() {
            let j = self.below(i + 1);
            v.swap(i, j);
        }
    }
}

/// A xorshift64 stream: the generator the tests and benches use for their fixtures (one shared
/// definition, so their sequences stay fixed). The state must not be zero.
#[derive(Clone, Debug)]
pub struct XorShift64(pub u64);

impl XorShift64 {
    /// The next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    /// Uniform in `[0, 1)`.
    #[inline]
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `[-1, 1)`.
    #[inline]
    pub fn signed(&mut self) -> f64 {
        self.unit() * 2.0 - 1.0
    }
}

/// The quintic smoothstep of Perlin's improved noise: C2, so displaced surfaces have continuous
/// curvature and no visible lattice creases.
#[inline]
fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// Hash of an integer lattice point to `[-1, 1)`.
#[inline]
fn lattice(seed: u64, x: i64, y: i64, z: i64) -> f64 {
    let h = hash3(seed, (x as u64).wrapping_mul(0x8CB9_2BA7_2F3D_8DD7) ^ (y as u64), z as u64);
    signed_f64(h)
}

/// Seeded 3D value noise in `[-1, 1]`, smooth (C2) with features about one unit wide.
pub fn value_noise(seed: u64, p: [f64; 3]) -> f64 {
    let f = [p[0].floor(), p[1].floor(), p[2].floor()];
    let (x, y, z) = (f[0] as i64, f[1] as i64, f[2] as i64);
    let t = [fade(p[0] - f[0]), fade(p[1] - f[1]), fade(p[2] - f[2])];
    let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
    let mut acc = [0.0; 4];
    for (k, slot) in acc.iter_mut().enumerate() {
        let dy = (k & 1) as i64;
        let dz = (k >> 1) as i64;
        *slot = lerp(lattice(seed, x, y + dy, z + dz), lattice(seed, x + 1, y + dy, z + dz), t[0]);
    }
    lerp(lerp(acc[0], acc[1], t[1]), lerp(acc[2], acc[3], t[1]), t[2])
}

/// Fractal sum of `octaves` value-noise octaves (frequency ×2, amplitude ×½ each), normalized to
/// about `[-1, 1]`.
pub fn fbm(seed: u64, p: [f64; 3], octaves: u32) -> f64 {
    let (mut sum, mut amp, mut norm, mut freq) = (0.0, 1.0, 0.0, 1.0);
    for o in 0..octaves {
        sum += amp * value_noise(seed.wrapping_add(o as u64 * 0x1000_0001), p.map(|c| c * freq));
        norm += amp;
        amp *= 0.5;
        freq *= 2.0;
    }
    sum / norm
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_and_hashes_are_deterministic_and_in_range() {
        let mut a = SplitMix64::new(7);
        let mut b = SplitMix64::new(7);
        let mut c = SplitMix64::new(8);
        let va: Vec<u64> = (0..16).map(|_| a.next_u64()).collect();
        let vb: Vec<u64> = (0..16).map(|_| b.next_u64()).collect();
        let vc: Vec<u64> = (0..16).map(|_| c.next_u64()).collect();
        assert_eq!(va, vb);
        assert_ne!(va, vc);
        for i in 0..1000 {
            let u = unit_f64(hash3(1, i, 2));
            assert!((0.0..1.0).contains(&u));
        }
        assert_ne!(hash3(1, 2, 3), hash3(1, 3, 2));
    }

    #[test]
    fn value_noise_is_bounded_continuous_and_seeded() {
        let mut max_step: f64 = 0.0;
        let mut prev = value_noise(3, [0.0, 0.3, 0.7]);
        for i in 1..2000 {
            let x = i as f64 * 0.005;
            let v = value_noise(3, [x, 0.3, 0.7]);
            assert!((-1.0..=1.0).contains(&v));
            max_step = max_step.max((v - prev).abs());
            prev = v;
        }
        assert!(max_step < 0.05, "continuous: step {max_step}");
        assert_ne!(value_noise(3, [0.5, 0.5, 0.5]), value_noise(4, [0.5, 0.5, 0.5]));
    }
}
