//! Units: the dataset 164 unit systems and the axis units labels of dataset 58.
//!
//! A physical unit here is a factor to SI times a dimension `L^a F^b T^c` (length,
//! force, time). Dataset 164 gives the file's length and force units (its factors
//! convert SI to file units); an axis units label such as `m/s^2`, `g`, `mm/s`, `lbf`
//! or `(m/s^2)/N`, when present, takes precedence for that axis.

/// A unit: `value_SI = value × factor`, dimension `L^length F^force T^time`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Unit {
    pub factor: f64,
    pub length: i32,
    pub force: i32,
    pub time: i32,
}

impl Unit {
    pub const ONE: Unit = Unit {
        factor: 1.0,
        length: 0,
        force: 0,
        time: 0,
    };
    const fn base(factor: f64, length: i32, force: i32, time: i32) -> Unit {
        Unit {
            factor,
            length,
            force,
            time,
        }
    }
    pub fn powi(self, k: i32) -> Unit {
        Unit {
            factor: self.factor.powi(k),
            length: self.length * k,
            force: self.force * k,
            time: self.time * k,
        }
    }
    pub fn times(self, o: Unit) -> Unit {
        Unit {
            factor: self.factor * o.factor,
            length: self.length + o.length,
            force: self.force + o.force,
            time: self.time + o.time,
        }
    }
    pub fn same_dimension(&self, o: &Unit) -> bool {
        (self.length, self.force, self.time) == (o.length, o.force, o.time)
    }
    /// "L^1 F^0 T^-2"-style description of the dimension.
    pub fn dimension(&self) -> String {
        format!(
            "length^{} force^{} time^{}",
            self.length, self.force, self.time
        )
    }
}

const G0: f64 = 9.80665;
const LBF: f64 = 4.448_221_615_260_5;
const INCH: f64 = 0.0254;
const FOOT: f64 = 0.3048;

/// The symbols the label parser knows.
fn symbol(s: &str) -> Option<Unit> {
    Some(match s {
        "m" => Unit::base(1.0, 1, 0, 0),
        "mm" => Unit::base(1e-3, 1, 0, 0),
        "cm" => Unit::base(1e-2, 1, 0, 0),
        "um" | "µm" | "μm" => Unit::base(1e-6, 1, 0, 0),
        "in" | "inch" => Unit::base(INCH, 1, 0, 0),
        "ft" => Unit::base(FOOT, 1, 0, 0),
        "N" => Unit::base(1.0, 0, 1, 0),
        "mN" => Unit::base(1e-3, 0, 1, 0),
        "kN" => Unit::base(1e3, 0, 1, 0),
        "lbf" | "lb" => Unit::base(LBF, 0, 1, 0),
        "kgf" => Unit::base(G0, 0, 1, 0),
        "s" | "sec" => Unit::base(1.0, 0, 0, 1),
        "ms" => Unit::base(1e-3, 0, 0, 1),
        "Hz" | "hz" | "HZ" => Unit::base(1.0, 0, 0, -1),
        "g" | "G" | "g0" => Unit::base(G0, 1, 0, -2),
        // An angle in radians is dimensionless; per radian of phase, 1 rad/s = 1/(2π) Hz.
        "rad" => Unit::base(1.0 / (2.0 * std::f64::consts::PI), 0, 0, 0),
        _ => return None,
    })
}

/// A factor like `s^2`, `s2`, `s**2`, `s²`.
fn factor(tok: &str) -> Option<Unit> {
    let tok = tok.trim();
    if tok == "1" {
        return Some(Unit::ONE);
    }
    let (base, exp) = if let Some(b) = tok.strip_suffix('²') {
        (b, 2)
    } else if let Some(b) = tok.strip_suffix('³') {
        (b, 3)
    } else if let Some((b, e)) = tok.split_once("**").or_else(|| tok.split_once('^')) {
        (b, e.trim().parse::<i32>().ok()?)
    } else {
        let digits = tok.trim_end_matches(|c: char| c.is_ascii_digit());
        if digits.len() < tok.len() && !digits.is_empty() {
            (digits, tok[digits.len()..].parse::<i32>().ok()?)
        } else {
            (tok, 1)
        }
    };
    if !(-4..=4).contains(&exp) {
        return None;
    }
    Some(symbol(base.trim())?.powi(exp))
}

/// A product of factors separated by `*`, `.` or blanks.
fn product(s: &str) -> Option<Unit> {
    let mut u = Unit::ONE;
    let mut any = false;
    for tok in s.split(['*', ' ', '·']).filter(|t| !t.is_empty()) {
        // "**" splits into empty pieces around it; rejoin handled by factor() on "s**2"
        u = u.times(factor(tok)?);
        any = true;
    }
    any.then_some(u)
}

/// Parses a units label: `a/b/c` = a·b⁻¹·c⁻¹, each part a product; one pair of
/// parentheses around a part is allowed (`(m/s^2)/N`). Returns None if any symbol is unknown.
pub fn parse_label(label: &str) -> Option<Unit> {
    let s = label.trim().replace("**", "^");
    if s.is_empty() {
        return None;
    }
    // Expand one level of parentheses: "(m/s^2)/N" → parts of the group keep their sign.
    let mut parts: Vec<(String, bool)> = Vec::new(); // (text, in denominator)
    let mut rest = s.as_str();
    let mut denominator = false;
    loop {
        rest = rest.trim_start();
        if let Some(inner) = rest.strip_prefix('(') {
            let close = inner.find(')')?;
            for (k, p) in inner[..close].split('/').enumerate() {
                parts.push((p.to_string(), denominator ^ (k > 0)));
            }
            rest = &inner[close + 1..];
        } else {
            let end = rest.find('/').unwrap_or(rest.len());
            parts.push((rest[..end].to_string(), denominator));
            rest = &rest[end..];
        }
        rest = rest.trim_start();
        if rest.is_empty() {
            break;
        }
        rest = rest.strip_prefix('/')?;
        denominator = true;
    }
    let mut u = Unit::ONE;
    for (p, den) in parts {
        let f = product(&p)?;
        u = u.times(if den { f.powi(-1) } else { f });
    }
    Some(u)
}

/// Whether a label means "no label".
pub fn is_unset(label: &str) -> bool {
    let t = label.trim();
    t.is_empty() || t.eq_ignore_ascii_case("none")
}

/// The length and force units of a dataset 164 unit system, checked against its code.
/// Returns SI per file unit for (length, force).
pub fn system_units(
    code: i64,
    length_factor: f64,
    force_factor: f64,
) -> Result<(f64, f64), String> {
    // File units per SI unit, by code (SDRC table).
    let table: Option<(f64, f64, &str)> = match code {
        1 => Some((1.0, 1.0, "SI: meter, newton")),
        2 => Some((1.0 / FOOT, 1.0 / LBF, "BG: foot, pound force")),
        3 => Some((1.0, 1.0 / G0, "MG: meter, kilogram force")),
        4 => Some((
            1.0 / FOOT,
            1.0 / (LBF / 32.174_048_556_430_45),
            "BA: foot, poundal",
        )),
        5 => Some((1e3, 1e3, "MM: millimeter, millinewton")),
        6 => Some((1e2, 1e2, "CM: centimeter, centinewton")),
        7 => Some((1.0 / INCH, 1.0 / LBF, "IN: inch, pound force")),
        8 => Some((1e3, 1.0 / G0, "GM: millimeter, kilogram force")),
        9 => None,
        c => return Err(format!("unknown units code {c}")),
    };
    for (v, name) in [(length_factor, "length"), (force_factor, "force")] {
        if !(v.is_finite() && v > 0.0) {
            return Err(format!("{name} factor {v} is not a positive number"));
        }
    }
    if let Some((l, f, name)) = table {
        let close = |a: f64, b: f64| ((a - b) / b).abs() < 1e-4;
        if !close(length_factor, l) || !close(force_factor, f) {
            return Err(format!(
                "units code {code} ({name}) expects length and force factors {l:.9} and {f:.9}, the record gives {length_factor} and {force_factor}"
            ));
        }
    }
    Ok((1.0 / length_factor, 1.0 / force_factor))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * b.abs()
    }

    #[test]
    fn labels_parse_to_si_factor_and_dimension() {
        let acc = parse_label("m/s^2").unwrap();
        assert_eq!((acc.length, acc.force, acc.time), (1, 0, -2));
        assert!(close(acc.factor, 1.0));
        for l in ["m/s2", "m/s**2", "m/s²", "m s^-2"] {
            let u = parse_label(l).unwrap();
            assert!(u.same_dimension(&acc) && close(u.factor, 1.0), "{l}");
        }
        let g = parse_label("g").unwrap();
        assert!(g.same_dimension(&acc) && close(g.factor, 9.80665));
        let mms = parse_label("mm/s").unwrap();
        assert_eq!((mms.length, mms.time), (1, -1));
        assert!(close(mms.factor, 1e-3));
        let frf = parse_label("(m/s^2)/N").unwrap();
        assert_eq!((frf.length, frf.force, frf.time), (1, -1, -2));
        let frf2 = parse_label("g/lbf").unwrap();
        assert!(close(frf2.factor, 9.80665 / 4.4482216152605));
        assert_eq!(parse_label("in").unwrap().factor, 0.0254);
        assert!(parse_label("furlong").is_none());
        assert!(parse_label("(m/s").is_none());
        assert!(parse_label("").is_none());
    }

    #[test]
    fn unit_systems_check_their_factors() {
        assert_eq!(system_units(1, 1.0, 1.0).unwrap(), (1.0, 1.0));
        let (l, f) = system_units(5, 1000.0, 1000.0).unwrap();
        assert!(close(l, 1e-3) && close(f, 1e-3));
        let (l, f) = system_units(7, 39.37007874015748, 0.2248089430997105).unwrap();
        assert!(close(l, 0.0254) && close(f, 4.4482216152605));
        assert!(system_units(5, 1.0, 1.0).unwrap_err().contains("MM"));
        assert!(system_units(10, 1.0, 1.0).is_err());
        assert!(system_units(9, 0.0, 1.0).is_err());
        assert_eq!(system_units(9, 2.0, 4.0).unwrap(), (0.5, 0.25));
    }
}
