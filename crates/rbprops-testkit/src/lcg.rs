//! A reproducible stream of uniforms for tests that need arbitrary but fixed numbers
//! (matrices of mixed sign, pseudo-random polynomials) and no statistics: Knuth's MMIX
//! linear congruential generator, `s ← 6364136223846793005 s + 1442695040888963407`
//! (mod 2⁶⁴), its top 53 bits as the uniform. Several unit tests wrote this loop by hand;
//! they draw the same bits from [`Lcg`] (the state is advanced before each draw, as
//! they did). Tests that need statistics use `rand_chacha`.

/// The MMIX LCG (see the module documentation).
#[derive(Debug, Clone)]
pub struct Lcg {
    state: u64,
}

impl Lcg {
    /// The stream whose first draw advances `seed` once.
    pub fn new(seed: u64) -> Self {
        Lcg { state: seed }
    }

    /// The next uniform on [0, 1): the advanced state's top 53 bits over 2⁵³.
    pub fn unit(&mut self) -> f64 {
        self.state = self
            .state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.state >> 11) as f64 / (1u64 << 53) as f64
    }

    /// The next uniform on [−½, ½): [`Lcg::unit`] − ½.
    pub fn centred(&mut self) -> f64 {
        self.unit() - 0.5
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stream is the recurrence itself: the first states from seed 0 are the
    /// increment c and then a·c + c (mod 2⁶⁴), exactly; the draws are their top 53 bits.
    #[test]
    fn draws_are_the_mmix_recurrence() {
        let (a, c) = (6364136223846793005u64, 1442695040888963407u64);
        let mut rng = Lcg::new(0);
        let s1 = c;
        let s2 = a.wrapping_mul(c).wrapping_add(c);
        assert_eq!(rng.unit(), (s1 >> 11) as f64 / 9007199254740992.0);
        assert_eq!(rng.centred(), (s2 >> 11) as f64 / 9007199254740992.0 - 0.5);
        assert_eq!(s1 >> 11, 704440937934064);
        // Every draw in range, and the mean of 10⁵ draws within 5σ of ½ (σ = 1/√(12·10⁵)).
        let mut rng = Lcg::new(7);
        let n = 100_000;
        let mut sum = 0.0;
        for _ in 0..n {
            let u = rng.unit();
            assert!((0.0..1.0).contains(&u));
            sum += u;
        }
        let sigma = (1.0 / (12.0 * n as f64)).sqrt();
        assert!((sum / n as f64 - 0.5).abs() < 5.0 * sigma);
    }
}
