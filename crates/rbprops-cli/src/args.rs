//! Validation of the numeric and named command-line options, in one place for every
//! executable: clap `value_parser` functions (a bad value is a command-line error, exit
//! status 2, with the accepted range in the message) and the checks that need the data
//! (a band against the data's band).

use anyhow::{bail, Result};

fn number(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a number"))?;
    if !v.is_finite() {
        return Err(format!("'{s}' is not a finite number"));
    }
    Ok(v)
}

fn in_range(s: &str, lo: f64, hi: f64, unit: &str) -> Result<f64, String> {
    let v = number(s)?;
    if !(lo..=hi).contains(&v) {
        return Err(format!("{} is outside [{lo:e}, {hi:e}]{unit}", s.trim()));
    }
    Ok(v)
}

fn count(s: &str, lo: usize, hi: usize) -> Result<usize, String> {
    let v: usize = s
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a whole number"))?;
    if !(lo..=hi).contains(&v) {
        return Err(format!("{v} is outside {lo}..={hi}"));
    }
    Ok(v)
}

/// A mass in kg: 1 g to 1000 t (a weighed or known mass of a test article).
pub fn mass_kg(s: &str) -> Result<f64, String> {
    in_range(s, 1e-3, 1e6, " kg")
}

/// A false-positive rate α: 0 < α ≤ 0.5.
pub fn alpha(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if !(v > 0.0 && v <= 0.5) {
        return Err(format!("{} is outside 0 < α ≤ 0.5", s.trim()));
    }
    Ok(v)
}

/// A fraction in [0, 1] (a MAC, a coherence).
pub fn fraction(s: &str) -> Result<f64, String> {
    in_range(s, 0.0, 1.0, "")
}

/// A non-negative finite number (a noise level).
pub fn non_negative(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v < 0.0 {
        return Err(format!("{} is negative (need ≥ 0)", s.trim()));
    }
    Ok(v)
}

/// A time constant in s: (0, 1e6].
pub fn seconds(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if !(v > 0.0 && v <= 1e6) {
        return Err(format!("{} is outside 0 < τ ≤ 1e6 s", s.trim()));
    }
    Ok(v)
}

/// A duration in s: (0, 1e6] (a record length, a pretrigger).
pub fn duration(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if !(v > 0.0 && v <= 1e6) {
        return Err(format!("{} is outside 0 < t ≤ 1e6 s", s.trim()));
    }
    Ok(v)
}

/// A positive finite number (an ADC range).
pub fn positive(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v <= 0.0 {
        return Err(format!("{} is not positive (need > 0)", s.trim()));
    }
    Ok(v)
}

/// A trigger level as a fraction of the largest |force|: 0 < level < 1.
pub fn trigger_fraction(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if !(v > 0.0 && v < 1.0) {
        return Err(format!(
            "{} is outside 0 < level < 1 (a fraction of the largest |force|)",
            s.trim()
        ));
    }
    Ok(v)
}

/// Fewest accepted hits per excitation: 2..=100000 (a variance needs two).
pub fn min_hits(s: &str) -> Result<usize, String> {
    count(s, 2, 100_000)
}

/// The response window of `frf-est`: `auto`, `none`, or τ in seconds ([`seconds`]).
pub fn response_window(s: &str) -> Result<crate::frf_est::WindowChoice, String> {
    use crate::frf_est::WindowChoice;
    match s.trim() {
        "auto" => Ok(WindowChoice::Auto),
        "none" => Ok(WindowChoice::None),
        t => seconds(t)
            .map(WindowChoice::Exponential)
            .map_err(|e| format!("{e} (or auto, none)")),
    }
}

/// A force window `PRE:POST` (s before the trigger, s after the pulse's end), or none.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceWindowSpan(pub Option<(f64, f64)>);

/// A force window `PRE:POST` in s, each ≥ 0 and finite, or `none`.
pub fn force_window(s: &str) -> Result<ForceWindowSpan, String> {
    if s.trim() == "none" {
        return Ok(ForceWindowSpan(None));
    }
    let (pre, post) = s
        .split_once(':')
        .ok_or_else(|| format!("'{s}' is not PRE:POST in seconds, or none"))?;
    Ok(ForceWindowSpan(Some((
        non_negative(pre)?,
        non_negative(post)?,
    ))))
}

/// A DOF `NODE:DIR`, DIR one of ±X/±Y/±Z or ±1..±3: `(node, ±1..±3)`.
pub fn dof(s: &str) -> Result<(i64, i64), String> {
    let (node, dir) = s
        .split_once(':')
        .ok_or_else(|| format!("'{s}' is not NODE:DIR, e.g. 201:-X"))?;
    let node: i64 = node
        .trim()
        .parse()
        .map_err(|_| format!("node '{}' is not an integer", node.trim()))?;
    let d = dir.trim().to_ascii_uppercase();
    let (sign, axis) = match d.strip_prefix('-') {
        Some(rest) => (-1, rest),
        None => (1, d.trim_start_matches('+')),
    };
    let a = match axis {
        "X" | "1" => 1,
        "Y" | "2" => 2,
        "Z" | "3" => 3,
        _ => {
            return Err(format!(
                "direction '{}' is not ±X, ±Y, ±Z or ±1..±3",
                dir.trim()
            ))
        }
    };
    Ok((node, sign * a))
}

/// The number of averages behind an FRF export: 3..=1000000 (fewer leave no degrees of
/// freedom for the variance).
pub fn averages(s: &str) -> Result<usize, String> {
    count(s, 3, 1_000_000)
}

/// Number of modes in a band: 1..=100.
pub fn modes(s: &str) -> Result<usize, String> {
    count(s, 1, 100)
}

/// Highest model order of a stabilisation diagram: 2..=400.
pub fn model_order(s: &str) -> Result<usize, String> {
    count(s, 2, 400)
}

/// Bootstrap replicates: 2..=100000.
pub fn replicates(s: &str) -> Result<usize, String> {
    count(s, 2, 100_000)
}

/// Monte Carlo draws: 0 (none) or 2..=1000000.
pub fn draws(s: &str) -> Result<usize, String> {
    let v = count(s, 0, 1_000_000)?;
    if v == 1 {
        return Err("1 draw gives no spread (0 for none, or 2..=1000000)".into());
    }
    Ok(v)
}

/// A cap on selection steps: 1..=100.
pub fn steps(s: &str) -> Result<usize, String> {
    count(s, 1, 100)
}

/// A band `FMIN:FMAX` in Hz (0 ≤ FMIN < FMAX, finite).
pub fn band(s: &str) -> Result<(f64, f64), String> {
    crate::parse_band(s).map_err(|e| format!("{e:#}"))
}

/// Fewest lines of the data a band must hold.
pub const MIN_BAND_LINES: usize = 8;

/// Checks that the band `what` ([`band`]) holds at least [`MIN_BAND_LINES`] lines of the
/// data's frequency axis; the error names the data's band.
pub fn check_band(what: &str, (lo, hi): (f64, f64), axis: &[f64]) -> Result<()> {
    let (Some(first), Some(last)) = (axis.first(), axis.last()) else {
        bail!("{what} {lo}:{hi} Hz: the data have no frequency lines");
    };
    let n = axis.iter().filter(|f| (lo..=hi).contains(*f)).count();
    if n < MIN_BAND_LINES {
        bail!(
            "{what} {lo}:{hi} Hz holds {n} of the data's lines (the data span {first}–{last} Hz, {} lines); a band needs at least {MIN_BAND_LINES}",
            axis.len()
        );
    }
    Ok(())
}

/// Checks effect ids (`--only`) against the catalogue; a further instance of an effect
/// (`elastic_mode_2`) counts as its effect. The error lists the valid ids.
pub fn check_effect_ids(ids: &[String]) -> Result<()> {
    let known = &*rbprops_sim::effects::KNOWN_EFFECTS;
    for id in ids {
        let base = id
            .rsplit_once('_')
            .filter(|(_, n)| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
            .map_or(id.as_str(), |(b, _)| b);
        if !known.contains(&id.as_str()) && !known.contains(&base) {
            bail!(
                "--only: unknown effect id '{id}' (valid ids: {})",
                known.join(", ")
            );
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nonsense_is_refused_with_the_range() {
        assert!(alpha("nan").is_err());
        assert!(alpha("0").unwrap_err().contains("0 < α ≤ 0.5"));
        assert!(alpha("2").is_err());
        assert_eq!(alpha("0.01"), Ok(0.01));
        assert!(mass_kg("1e-300").unwrap_err().contains("kg"));
        assert!(mass_kg("inf").is_err());
        assert_eq!(mass_kg("12.5"), Ok(12.5));
        assert!(modes("1000000").unwrap_err().contains("1..=100"));
        assert!(replicates("0").is_err());
        assert!(draws("1").is_err());
        assert_eq!(draws("0"), Ok(0));
        assert!(band("2:1").is_err());
        assert!(trigger_fraction("1").is_err() && trigger_fraction("0").is_err());
        assert_eq!(trigger_fraction("0.1"), Ok(0.1));
        assert!(force_window("0.01").is_err() && force_window("-1:2").is_err());
        assert_eq!(force_window("none"), Ok(ForceWindowSpan(None)));
        assert_eq!(
            force_window("0.01:0.05"),
            Ok(ForceWindowSpan(Some((0.01, 0.05))))
        );
        assert_eq!(dof("201:-X"), Ok((201, -1)));
        assert_eq!(dof("7:+3"), Ok((7, 3)));
        assert!(dof("7:W").is_err() && dof("x:1").is_err());
        assert!(response_window("-3").is_err());
        assert!(min_hits("1").is_err());
    }

    #[test]
    fn a_band_must_hold_lines_of_the_data() {
        let axis: Vec<f64> = (1..=100).map(|k| k as f64 * 0.125).collect();
        let e = check_band("--band", (100.0, 200.0), &axis)
            .unwrap_err()
            .to_string();
        assert!(e.contains("0.125–12.5 Hz"), "{e}");
        assert!(check_band("--band", (2.0, 2.0001), &axis).is_err());
        assert!(check_band("--band", (1.0, 4.0), &axis).is_ok());
    }

    #[test]
    fn effect_ids_are_checked() {
        let e = check_effect_ids(&["warp_drive".into()])
            .unwrap_err()
            .to_string();
        assert!(e.contains("warp_drive") && e.contains("valid ids"), "{e}");
        let first = rbprops_sim::effects::KNOWN_EFFECTS[0].to_string();
        assert!(check_effect_ids(&[first.clone(), format!("{first}_2")]).is_ok());
    }
}
