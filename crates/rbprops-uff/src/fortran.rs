//! Fixed-width (Fortran-style) fields: reading `I`, `E`/`D` and `A` fields out of a
//! record, and writing `E`-style fields with as many digits as the width allows.
//!
//! Reading is strict: a field is the columns the format gives it, a required field must
//! not be blank, and a record must not carry non-blank characters beyond its fields
//! (that is how a file written with the wrong field widths shows up).

/// Parses a Fortran real: `1.5E+00`, `1.5D+00`, `1.5e-3`, `-2.`, and the exponent
/// form without a letter that `E13.5` produces for |exponent| ≥ 100 (`1.00000-100`).
/// Rejects `nan`/`inf` and anything not finite.
pub fn parse_real(s: &str) -> Result<f64, String> {
    let t = s.trim();
    if t.is_empty() {
        return Err("blank field".into());
    }
    let mut norm = String::with_capacity(t.len() + 1);
    let bytes = t.as_bytes();
    for (i, &b) in bytes.iter().enumerate() {
        match b {
            b'0'..=b'9' | b'.' => norm.push(b as char),
            b'e' | b'E' | b'd' | b'D' | b'q' | b'Q' => norm.push('E'),
            b'+' | b'-' => {
                // A sign after a digit or '.' without an exponent letter starts the exponent.
                if i > 0 && (bytes[i - 1].is_ascii_digit() || bytes[i - 1] == b'.') {
                    norm.push('E');
                }
                norm.push(b as char);
            }
            _ => return Err(format!("'{t}' is not a number")),
        }
    }
    let v: f64 = norm.parse().map_err(|_| format!("'{t}' is not a number"))?;
    if !v.is_finite() {
        return Err(format!("'{t}' is not a finite number"));
    }
    Ok(v)
}

/// Parses a Fortran integer field (blank → error).
pub fn parse_int(s: &str) -> Result<i64, String> {
    let t = s.trim();
    if t.is_empty() {
        return Err("blank field".into());
    }
    t.parse::<i64>()
        .map_err(|_| format!("'{t}' is not an integer"))
}

/// The text of columns `[start, start + width)` of a record (fewer if the line is short).
pub fn column(line: &str, start: usize, width: usize) -> &str {
    let b = line.as_bytes();
    let s = start.min(b.len());
    let e = (start + width).min(b.len());
    // Records are checked to be ASCII before fields are cut, so this cannot split a char.
    &line[s..e]
}

/// Checks that nothing but blanks follows column `end`.
pub fn check_tail(line: &str, end: usize) -> Result<(), String> {
    let tail = column(line, end, usize::MAX / 2);
    if tail.trim().is_empty() {
        Ok(())
    } else {
        Err(format!(
            "unexpected characters '{}' after column {end} (wrong field widths?)",
            tail.trim()
        ))
    }
}

/// Formats `v` in `E` notation right-aligned in `width` columns, keeping at least one
/// leading blank so that whitespace-splitting readers also work, with the largest number
/// of significant digits (at most `max_digits`) that fits. Exponents have at least two digits.
pub fn fmt_e(v: f64, width: usize, max_digits: usize) -> String {
    let mut digits = max_digits.max(1);
    loop {
        let s = e_notation(v, digits - 1);
        if s.len() < width || digits == 1 {
            return format!("{s:>width$}");
        }
        digits -= 1;
    }
}

fn e_notation(v: f64, decimals: usize) -> String {
    let s = format!("{v:.decimals$E}");
    let (mant, exp) = s.split_once('E').expect("E format has an exponent");
    let exp: i32 = exp.parse().expect("integer exponent");
    let sign = if exp < 0 { '-' } else { '+' };
    format!("{mant}E{sign}{:02}", exp.abs())
}

/// Formats `v` for a real field of `width` columns as exactly as the width allows:
/// the shortest representation that reads back to the same `f64` if it fits (with a
/// leading blank), else [`fmt_e`] with as many digits as fit.
pub fn fmt_exactish(v: f64, width: usize) -> String {
    let plain = format!("{v:?}");
    let sci = e_shortest(v);
    let best = if plain.len() <= sci.len() { plain } else { sci };
    if best.len() < width {
        return format!("{best:>width$}");
    }
    // Otherwise the closer of E notation and plain decimals, both filling the field.
    let e = fmt_e(v, width, 17);
    let mut candidates = vec![e];
    let int_len = format!("{:.0}", v).len();
    if int_len + 2 < width {
        let decimals = width - 2 - int_len;
        candidates.push(format!("{:>width$}", format!("{v:.decimals$}")));
    }
    candidates
        .into_iter()
        .filter(|c| c.len() == width)
        .min_by(|a, b| {
            let err = |c: &str| parse_real(c).map_or(f64::INFINITY, |x| (x - v).abs());
            err(a).total_cmp(&err(b))
        })
        .unwrap_or_else(|| fmt_e(v, width, 17))
}

fn e_shortest(v: f64) -> String {
    let s = format!("{v:E}");
    match s.split_once('E') {
        Some((m, e)) => {
            let exp: i32 = e.parse().unwrap_or(0);
            let m = if m.contains('.') {
                m.to_string()
            } else {
                format!("{m}.")
            };
            if exp == 0 {
                m
            } else {
                format!("{m}E{exp}")
            }
        }
        None => s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_fortran_reals() {
        assert_eq!(parse_real(" 1.50000E+00").unwrap(), 1.5);
        assert_eq!(parse_real("-2.5D-03").unwrap(), -2.5e-3);
        assert_eq!(parse_real(" 1.00000-100").unwrap(), 1e-100);
        assert_eq!(parse_real("3.").unwrap(), 3.0);
        assert!(parse_real("nan").is_err());
        assert!(parse_real("inf").is_err());
        assert!(parse_real("1e999").is_err());
        assert!(parse_real("   ").is_err());
        assert!(parse_real("1.0x").is_err());
    }

    #[test]
    fn e_fields_keep_a_blank_and_maximal_digits() {
        assert_eq!(
            fmt_e(-1.234_567_890_123_456, 20, 17),
            " -1.234567890123E+00"
        );
        assert_eq!(fmt_e(1.5, 13, 6), "  1.50000E+00");
        assert_eq!(fmt_e(-1.5e-100, 13, 17), " -1.5000E-100");
        for v in [0.0, 1e-300, -7.25e123, 3.3333333333333335] {
            let s = fmt_e(v, 20, 17);
            assert_eq!(s.len(), 20);
            assert!(s.starts_with(' '));
            let back = parse_real(&s).unwrap();
            assert!((back - v).abs() <= 1e-12 * v.abs());
        }
    }

    #[test]
    fn exactish_round_trips_short_values() {
        for v in [0.0125, 0.0, 12.5, 1e-7, 400.0, 0.00025, 2.44140625] {
            let s = fmt_exactish(v, 13);
            assert_eq!(s.len(), 13, "{s}");
            assert_eq!(parse_real(&s).unwrap(), v, "{s}");
        }
        let long = 0.01220703125; // 13 characters: does not fit with a leading blank
        let s = fmt_exactish(long, 13);
        assert!((parse_real(&s).unwrap() - long).abs() < 5e-8 * long, "{s}");
        assert_eq!(s, " 0.0122070312");
        let third = 1.0 / 3.0;
        let s = fmt_exactish(third, 13);
        assert_eq!(s.len(), 13);
        assert!((parse_real(&s).unwrap() - third).abs() < 1e-7 * third);
    }
}
