//! The precision a recording's numbers were stored with, and the quantisation noise
//! floor it implies.
//!
//! A value stored with a rounding step `Δ` (round to nearest) carries an error uniform on
//! `[−Δ/2, Δ/2]`, of variance `Δ²/12`. For a complex FRF value the two parts are rounded
//! independently, so the quantisation adds
//!
//! ```text
//!   q(Y) = E|δ|² = Δ(Re Y)²/12 + Δ(Im Y)²/12
//! ```
//!
//! to `E|ε|²`, where `Δ(x)` is the step at `x`:
//! - double precision: one unit in the last place, `Δ = 2^(e−52)` for `2^e ≤ |x| < 2^(e+1)`
//!   (relative ≈ 1.1e-16 … 2.2e-16);
//! - single precision (UFF 58 records with single-precision ordinates): `Δ = 2^(e−23)`
//!   (relative ≈ 6e-8 … 1.2e-7), `2^−149` for subnormals;
//! - `d` significant decimal digits (ASCII files): `Δ = 10^(⌊log₁₀|x|⌋ − d + 1)`.
//!
//! [`DataPrecision::detect`] reads the precision from the values alone:
//! - *single*: every value is exactly representable in single precision
//!   (`x as f32 as f64 == x` for both parts). A double-precision value passes with
//!   probability 2⁻²⁹ (its 29 low mantissa bits all zero), so with 64 or more non-zero
//!   parts a double-precision recording is never taken for single precision.
//! - *decimal digits*: the shortest decimal string that reads back as exactly `x` has at
//!   most `d ≤ 15` significant digits for every part (the largest `d` over the parts is
//!   taken). A value computed in double precision needs 16–17 digits except by chance
//!   (roughly one value in five or fewer needs ≤ 15), so 64 parts rule that out. For
//!   single-precision values (an ASCII file read through `f32`) the shortest
//!   single-precision decimal is used, with `d ≤ 7` (a computed single needs 8–9).
//!
//! When both hold (an ASCII file of single-precision numbers read through `f32`), each
//! value gets the larger of the two variances. Exact zeros carry no information about
//! the format and are left out of the detection; they get `q = 0`.

use crate::c64;
use serde::{Deserialize, Serialize};

/// Fewest non-zero parts from which the format is read (module docs).
pub const MIN_PARTS: usize = 64;

/// Largest number of significant decimal digits taken as a decimal format: below the
/// 15.95 digits of double precision.
pub const MAX_DECIMAL_DIGITS: u32 = 15;

/// The same for values exactly representable in single precision, whose shortest
/// single-precision decimal has 6–9 digits: at most 7 (below its 7.2 digits; about one
/// single-precision value in eight needs ≤ 7 by chance, so 64 parts rule chance out).
pub const MAX_DECIMAL_DIGITS_F32: u32 = 7;

/// The storage precision of a set of values (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct DataPrecision {
    /// Every value is exactly representable in single precision.
    pub single: bool,
    /// Every value has at most this many significant decimal digits (≤ 15).
    pub decimal_digits: Option<u32>,
}

impl DataPrecision {
    /// Double precision, no coarser format detected.
    pub const DOUBLE: DataPrecision = DataPrecision {
        single: false,
        decimal_digits: None,
    };

    /// Reads the precision from the values (module docs). Fewer than [`MIN_PARTS`]
    /// non-zero finite parts: double precision is assumed.
    pub fn detect(values: &[c64]) -> DataPrecision {
        let parts = || {
            values
                .iter()
                .flat_map(|v| [v.re, v.im])
                .filter(|x| *x != 0.0 && x.is_finite())
        };
        if parts().count() < MIN_PARTS {
            return DataPrecision::DOUBLE;
        }
        let single = parts().all(|x| x as f32 as f64 == x);
        // Decimal digits of the format the values went through: as single-precision
        // numbers when they are (an ASCII file read through `f32`), else as doubles.
        let (digits_of, max_digits): (fn(f64) -> u32, u32) = if single {
            (|x| shortest_digits_f32(x as f32), MAX_DECIMAL_DIGITS_F32)
        } else {
            (shortest_digits, MAX_DECIMAL_DIGITS)
        };
        let mut digits = 0;
        for x in parts() {
            digits = digits.max(digits_of(x));
            if digits > max_digits {
                break;
            }
        }
        DataPrecision {
            single,
            decimal_digits: (digits <= max_digits).then_some(digits),
        }
    }

    /// A short description for reports ("single precision", "6 significant digits", …).
    pub fn describe(&self) -> String {
        match (self.single, self.decimal_digits) {
            (false, None) => "double precision".into(),
            (true, None) => "single precision".into(),
            (false, Some(d)) => format!("{d} significant decimal digits"),
            (true, Some(d)) => format!("single precision, {d} significant decimal digits"),
        }
    }

    /// The rounding step at `x` (0 at x = 0): the largest of the steps of the formats
    /// that hold.
    pub fn step(&self, x: f64) -> f64 {
        if x == 0.0 || !x.is_finite() {
            return 0.0;
        }
        let mut s = ulp_f64(x);
        if self.single {
            s = s.max(ulp_f32(x));
        }
        if let Some(d) = self.decimal_digits {
            s = s.max(decimal_step(x, d));
        }
        s
    }

    /// Quantisation variance `q(Y) = E|δ|² = (Δ(Re Y)² + Δ(Im Y)²)/12` of one stored
    /// complex value.
    pub fn variance(&self, y: c64) -> f64 {
        let (a, b) = (self.step(y.re), self.step(y.im));
        (a * a + b * b) / 12.0
    }
}

/// Unit in the last place of a double: `2^(e−52)`, `2^−1074` for subnormals.
pub fn ulp_f64(x: f64) -> f64 {
    let e = ((x.abs().to_bits() >> 52) & 0x7ff) as i32;
    if e == 0 {
        f64::from_bits(1)
    } else {
        2f64.powi(e - 1023 - 52)
    }
}

/// Unit in the last place of `x` stored in single precision: `2^(e−23)`, `2^−149` for
/// subnormals (`x` rounded to single first, so the binade is the stored value's).
pub fn ulp_f32(x: f64) -> f64 {
    let e = (((x.abs() as f32).to_bits() >> 23) & 0xff) as i32;
    if e == 0 {
        2f64.powi(-149)
    } else {
        2f64.powi(e - 127 - 23)
    }
}

/// Step of `d` significant decimal digits at `x`: `10^(⌊log₁₀|x|⌋ − d + 1)`.
pub fn decimal_step(x: f64, d: u32) -> f64 {
    // The exponent from the shortest representation, not log10 (which can land on the
    // wrong side of a power of ten by one ulp).
    let s = format!("{:e}", x.abs());
    let e: i32 = s
        .split_once('e')
        .and_then(|(_, e)| e.parse().ok())
        .unwrap_or(0);
    10f64.powi(e - d as i32 + 1)
}

/// Significant digits of the shortest decimal string that reads back as exactly `x`.
pub fn shortest_digits(x: f64) -> u32 {
    mantissa_digits(&format!("{:e}", x.abs()))
}

/// Significant digits of the shortest decimal string that reads back (as a single) as
/// exactly `x`.
pub fn shortest_digits_f32(x: f32) -> u32 {
    mantissa_digits(&format!("{:e}", x.abs()))
}

fn mantissa_digits(s: &str) -> u32 {
    let mantissa = s.split_once('e').map_or(s, |(m, _)| m);
    mantissa.bytes().filter(u8::is_ascii_digit).count() as u32
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_values(n: usize, seed: u64) -> Vec<c64> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                let m = 10f64.powf(rng.random::<f64>() * 8.0 - 6.0);
                c64::from_polar(m, std::f64::consts::TAU * rng.random::<f64>())
            })
            .collect()
    }

    #[test]
    fn steps_match_their_definitions() {
        assert_eq!(ulp_f64(1.0), f64::EPSILON);
        assert_eq!(ulp_f64(1.5), f64::EPSILON);
        assert_eq!(ulp_f64(-3.0), 2.0 * f64::EPSILON);
        assert_eq!(ulp_f32(1.0), f32::EPSILON as f64);
        assert_eq!(ulp_f32(0.75), f32::EPSILON as f64 / 2.0);
        assert_eq!(ulp_f32(1e-40), 2f64.powi(-149));
        assert_eq!(decimal_step(1.23456e-3, 6), 1e-8);
        assert_eq!(decimal_step(-9.99999e2, 6), 1e-3);
        assert_eq!(decimal_step(1e5, 3), 1e3);
        assert_eq!(shortest_digits(1.23456e-3), 6);
        assert_eq!(shortest_digits(0.1), 1);
        assert_eq!(shortest_digits(0.1f32 as f64), 17);
    }

    #[test]
    fn detects_the_storage_format() {
        let v = random_values(500, 1);
        assert_eq!(DataPrecision::detect(&v), DataPrecision::DOUBLE);
        let single: Vec<c64> = v
            .iter()
            .map(|z| c64::new(z.re as f32 as f64, z.im as f32 as f64))
            .collect();
        assert_eq!(
            DataPrecision::detect(&single),
            DataPrecision {
                single: true,
                decimal_digits: None
            }
        );
        // An ASCII file with 6 significant digits (UFF's E13.5), read as double …
        let ascii = |x: f64| format!("{x:.5e}").parse::<f64>().unwrap();
        let six: Vec<c64> = v
            .iter()
            .map(|z| c64::new(ascii(z.re), ascii(z.im)))
            .collect();
        assert_eq!(
            DataPrecision::detect(&six),
            DataPrecision {
                single: false,
                decimal_digits: Some(6)
            }
        );
        // … or through single precision: both hold, the decimal step is the larger.
        let six32: Vec<c64> = six
            .iter()
            .map(|z| c64::new(z.re as f32 as f64, z.im as f32 as f64))
            .collect();
        let p = DataPrecision::detect(&six32);
        assert!(p.single && p.decimal_digits.is_some(), "{p:?}");
        assert_eq!(p.step(six32[3].re), decimal_step(six32[3].re, 6));
        // Too few parts to tell: double.
        assert_eq!(DataPrecision::detect(&single[..20]), DataPrecision::DOUBLE);
    }

    /// The variance q(Y) is that of the actual rounding error: over many values the mean
    /// of |δ|²/q is 1. With U uniform on [−½, ½], 12U² has mean 1 and variance 0.8, so
    /// |δ|²/q (a weighted mean of two such terms) has sd between 0.63 (equal steps) and
    /// 0.89 (one step dominant); the mean of 20 000 has sd below 0.0063, and 0.04 is over
    /// 6 sd.
    #[test]
    fn variance_is_that_of_the_rounding_error() {
        let v = random_values(20_000, 2);
        let single = DataPrecision {
            single: true,
            decimal_digits: None,
        };
        let six = DataPrecision {
            single: false,
            decimal_digits: Some(6),
        };
        let ascii = |x: f64| format!("{x:.5e}").parse::<f64>().unwrap();
        for (p, round) in [
            (single, &(|x: f64| x as f32 as f64) as &dyn Fn(f64) -> f64),
            (six, &ascii),
        ] {
            let mut s = 0.0;
            for z in &v {
                let y = c64::new(round(z.re), round(z.im));
                s += (y - z).norm_sqr() / p.variance(y);
            }
            let m = s / v.len() as f64;
            assert!((m - 1.0).abs() < 0.04, "{p:?}: mean |δ|²/q = {m}");
        }
    }
}
