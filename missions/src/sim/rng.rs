//! A small, seedable, portable random number generator: xoshiro256** seeded through
//! splitmix64, with Box–Muller Gaussian samples. The same seed gives the same numbers on every
//! platform and in every build.

/// One step of splitmix64: advances `state` and returns the next output.
fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// xoshiro256** (Blackman and Vigna): fast, 256 bits of state, good statistical quality. Not
/// for cryptography.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Rng {
    s: [u64; 4],
}

impl Rng {
    /// A generator seeded with `seed`.
    pub fn new(seed: u64) -> Self {
        let mut sm = seed;
        let mut s = [0u64; 4];
        for x in &mut s {
            *x = splitmix64(&mut sm);
        }
        if s == [0; 4] {
            s[0] = 1; // the all-zero state is a fixed point; splitmix64 never yields it anyway
        }
        Rng { s }
    }

    /// An independent generator for sub-stream `stream` of `seed` (e.g. one for the sonar,
    /// one for the odometry), so drawing from one never shifts the other.
    pub fn stream(seed: u64, stream: u64) -> Self {
        let mut sm = stream.wrapping_mul(0xD1B5_4A32_D192_ED03) ^ 0x5851_F42D_4C95_7F2D;
        Rng::new(seed ^ splitmix64(&mut sm))
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        let result = self.s[1].wrapping_mul(5).rotate_left(7).wrapping_mul(9);
        let t = self.s[1] << 17;
        self.s[2] ^= self.s[0];
        self.s[3] ^= self.s[1];
        self.s[1] ^= self.s[2];
        self.s[0] ^= self.s[3];
        self.s[2] ^= t;
        self.s[3] = self.s[3].rotate_left(45);
        result
    }

    /// Uniform in [0, 1), 53 bits of precision.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Standard normal (mean 0, standard deviation 1), by Box–Muller. Each call consumes
    /// exactly two uniforms (the second Box–Muller value is discarded), which keeps streams
    /// easy to reason about.
    pub fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform(); // (0, 1]: ln is finite
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// Normal with mean 0 and standard deviation `sigma` (0 when `sigma` is not positive);
    /// always consumes the same amount of randomness.
    pub fn gaussian(&mut self, sigma: f64) -> f64 {
        let z = self.normal();
        if sigma > 0.0 && sigma.is_finite() {
            z * sigma
        } else {
            0.0
        }
    }

    /// True with probability `p` (never when `p <= 0`, always when `p >= 1`); always consumes
    /// one uniform.
    pub fn chance(&mut self, p: f64) -> bool {
        let u = self.uniform();
        u < p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_numbers_different_seed_different() {
        let a: Vec<u64> = {
            let mut r = Rng::new(42);
            (0..8).map(|_| r.next_u64()).collect()
        };
        let b: Vec<u64> = {
            let mut r = Rng::new(42);
            (0..8).map(|_| r.next_u64()).collect()
        };
        let c: Vec<u64> = {
            let mut r = Rng::new(43);
            (0..8).map(|_| r.next_u64()).collect()
        };
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert_ne!(Rng::stream(42, 0), Rng::stream(42, 1));
    }

    #[test]
    fn known_splitmix_output() {
        // splitmix64 seeded with 0: first output 0xE220A8397B1DCDAF (reference value).
        let mut s = 0u64;
        assert_eq!(splitmix64(&mut s), 0xE220_A839_7B1D_CDAF);
    }

    #[test]
    fn uniform_and_normal_moments() {
        let mut r = Rng::new(7);
        let n = 200_000;
        let (mut sum, mut sum2, mut usum) = (0.0, 0.0, 0.0);
        for _ in 0..n {
            let u = r.uniform();
            assert!((0.0..1.0).contains(&u));
            usum += u;
            let z = r.normal();
            assert!(z.is_finite());
            sum += z;
            sum2 += z * z;
        }
        let n = n as f64;
        assert!((usum / n - 0.5).abs() < 0.01);
        assert!((sum / n).abs() < 0.01);
        assert!((sum2 / n - 1.0).abs() < 0.02);
    }
}
