//! A small seeded random number generator (xoshiro256++ seeded by SplitMix64) with Gaussian
//! samples. Written here rather than taken from a crate so that a seed gives the same run on every
//! platform and with every dependency version, for ever.

use armor_model::random::SplitMix64;

/// A deterministic stream of random numbers.
#[derive(Clone, Debug)]
pub struct Rng {
    state: [u64; 4],
    /// The second value of the last Box–Muller pair, not yet used.
    spare: Option<f64>,
}

impl Rng {
    /// A stream determined entirely by `seed` (and `stream`, to give independent streams for
    /// different noise sources from one seed).
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut mix = SplitMix64(seed ^ stream.wrapping_mul(0xD1B5_4A32_D192_ED03));
        Self {
            state: [
                mix.next_u64(),
                mix.next_u64(),
                mix.next_u64(),
                mix.next_u64(),
            ],
            spare: None,
        }
    }

    pub fn next_u64(&mut self) -> u64 {
        let s = &mut self.state;
        let result = s[0].wrapping_add(s[3]).rotate_left(23).wrapping_add(s[0]);
        let t = s[1] << 17;
        s[2] ^= s[0];
        s[3] ^= s[1];
        s[1] ^= s[2];
        s[0] ^= s[3];
        s[2] ^= t;
        s[3] = s[3].rotate_left(45);
        result
    }

    /// Uniform in (0, 1]: never 0, so its logarithm is finite.
    pub fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) + 1) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// A sample of the standard normal distribution (Box–Muller).
    pub fn standard_normal(&mut self) -> f64 {
        if let Some(spare) = self.spare.take() {
            return spare;
        }
        let radius = (-2.0 * self.uniform().ln()).sqrt();
        let angle = std::f64::consts::TAU * self.uniform();
        self.spare = Some(radius * angle.sin());
        radius * angle.cos()
    }

    /// A sample of a normal distribution of mean 0 and standard deviation `std_dev`.
    pub fn normal(&mut self, std_dev: f64) -> f64 {
        self.standard_normal() * std_dev
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_stream_and_plausible_statistics() {
        let mut a = Rng::new(7, 0);
        let mut b = Rng::new(7, 0);
        let mut c = Rng::new(8, 0);
        let mut d = Rng::new(7, 1);
        let xs: Vec<f64> = (0..10_000).map(|_| a.standard_normal()).collect();
        let ys: Vec<f64> = (0..10_000).map(|_| b.standard_normal()).collect();
        assert_eq!(xs, ys);
        assert_ne!(xs[0], c.standard_normal());
        assert_ne!(xs[0], d.standard_normal());
        let mean = xs.iter().sum::<f64>() / xs.len() as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / xs.len() as f64;
        assert!(mean.abs() < 0.05, "{mean}");
        assert!((var - 1.0).abs() < 0.05, "{var}");
        assert!((0..1000).map(|_| a.uniform()).all(|u| u > 0.0 && u <= 1.0));
    }
}
