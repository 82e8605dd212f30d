//! Units: the dataset 164 unit systems and the axis units labels of dataset 58.
//!
//! A physical unit here is a factor to SI times a dimension `L^a F^b T^c` (length,
//! force, time). Dataset 164 gives the file's length and force units (its factors
//! convert SI to file units); an axis units label such as `m/s^2`, `g`, `mm/s`, `lbf`
//! or `(m/s^2)/N`, when present, takes precedence for that axis.

/// A unit: `value_SI = value × factor`, dimension `L^length F^force T^time`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Unit {
    /// Multiply a value in this unit by it to get SI.
    pub factor: f64,
    /// Length exponent.
    pub length: i32,
    /// Force exponent.
    pub force: i32,
    /// Time exponent.
    pub time: i32,
}

impl Unit {
    /// Dimensionless, factor 1.
    pub const ONE: Unit = Unit {
        factor: 1.0,
        length: 0,
        force: 0,
        time: 0,
    };
    /// A unit of this factor to SI and dimension.
    pub const fn base(factor: f64, length: i32, force: i32, time: i32) -> Unit {
        Unit {
            factor,
            length,
            force,
            time,
        }
    }
    /// This unit to the power `k`.
    pub fn powi(self, k: i32) -> Unit {
        Unit {
            factor: self.factor.powi(k),
            length: self.length * k,
            force: self.force * k,
            time: self.time * k,
        }
    }
    /// The product of two units.
    pub fn times(self, o: Unit) -> Unit {
        Unit {
            factor: self.factor * o.factor,
            length: self.length + o.length,
            force: self.force + o.force,
            time: self.time + o.time,
        }
    }
    /// Whether the dimensions agree (factors may differ).
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

/// Why a units label was not understood.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LabelError(pub String);

impl std::fmt::Display for LabelError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// The unit symbols the label parser knows, in their canonical spelling.
const SYMBOLS: &[(&str, Unit)] = &[
    ("m", Unit::base(1.0, 1, 0, 0)),
    ("mm", Unit::base(1e-3, 1, 0, 0)),
    ("cm", Unit::base(1e-2, 1, 0, 0)),
    ("um", Unit::base(1e-6, 1, 0, 0)),
    ("µm", Unit::base(1e-6, 1, 0, 0)),
    ("μm", Unit::base(1e-6, 1, 0, 0)),
    ("in", Unit::base(INCH, 1, 0, 0)),
    ("inch", Unit::base(INCH, 1, 0, 0)),
    ("ft", Unit::base(FOOT, 1, 0, 0)),
    ("N", Unit::base(1.0, 0, 1, 0)),
    ("mN", Unit::base(1e-3, 0, 1, 0)),
    ("kN", Unit::base(1e3, 0, 1, 0)),
    ("lbf", Unit::base(LBF, 0, 1, 0)),
    ("lb", Unit::base(LBF, 0, 1, 0)),
    ("kgf", Unit::base(G0, 0, 1, 0)),
    // kg = N·s²/m: apparent-mass and inertance labels.
    ("kg", Unit::base(1.0, -1, 1, 2)),
    ("s", Unit::base(1.0, 0, 0, 1)),
    ("sec", Unit::base(1.0, 0, 0, 1)),
    ("ms", Unit::base(1e-3, 0, 0, 1)),
    ("Hz", Unit::base(1.0, 0, 0, -1)),
    ("cpm", Unit::base(1.0 / 60.0, 0, 0, -1)),
    ("rpm", Unit::base(1.0 / 60.0, 0, 0, -1)),
    // Standard gravity (not the gram: a gram is never an FRF or axis unit).
    ("g", Unit::base(G0, 1, 0, -2)),
    ("g0", Unit::base(G0, 1, 0, -2)),
    ("gn", Unit::base(G0, 1, 0, -2)),
    // An angle in radians is dimensionless; per radian of phase, 1 rad/s = 1/(2π) Hz.
    (
        "rad",
        Unit::base(1.0 / (2.0 * std::f64::consts::PI), 0, 0, 0),
    ),
];

/// Symbols whose case is significant: their upper-case forms read as a mega prefix
/// (`MN` meganewton, `MS` megasecond) and are not folded to milli.
const CASE_SENSITIVE: &[&str] = &["mN", "ms"];

/// Looks a symbol up: exact spelling first, then ignoring case when exactly one
/// case-foldable symbol matches (`LBF`, `IN`, `G`, `HZ`, `Sec`, …).
fn symbol(s: &str) -> Option<Unit> {
    if let Some((_, u)) = SYMBOLS.iter().find(|(n, _)| *n == s) {
        return Some(*u);
    }
    let lower = s.to_lowercase();
    let mut hits = SYMBOLS
        .iter()
        .filter(|(n, _)| !CASE_SENSITIVE.contains(n) && n.to_lowercase() == lower);
    let first = hits.next()?;
    // Two symbols equal up to case but of different value would be ambiguous.
    if hits.any(|(_, u)| u != &first.1) {
        return None;
    }
    Some(first.1)
}

/// Tokens of a units label.
#[derive(Debug, Clone, PartialEq)]
enum Tok {
    /// A unit symbol.
    Name(String),
    /// An integer (`1` in `1/N`, or an exponent).
    Int(i32),
    /// `*`, `.`, `·`, `×` or blanks between two factors.
    Times,
    Slash,
    /// `^` or `**`.
    Caret,
    Minus,
    Plus,
    Open,
    Close,
    /// A superscript exponent (`²`, `³`, `⁻²`).
    Sup(i32),
}

fn superscript_digit(c: char) -> Option<i32> {
    Some(match c {
        '⁰' => 0,
        '¹' => 1,
        '²' => 2,
        '³' => 3,
        '⁴' => 4,
        '⁵' => 5,
        '⁶' => 6,
        '⁷' => 7,
        '⁸' => 8,
        '⁹' => 9,
        _ => return None,
    })
}

fn is_letter(c: char) -> bool {
    c.is_alphabetic() || c == 'µ' || c == 'μ'
}

fn tokenize(label: &str) -> Result<Vec<Tok>, LabelError> {
    let chars: Vec<char> = label.chars().collect();
    let mut out: Vec<Tok> = Vec::new();
    let mut i = 0;
    // A blank between a token that ends an operand (symbol, number, ')', exponent) and one
    // that starts an operand (symbol, number, '(') means multiplication (`N s`, `m s-2`);
    // elsewhere blanks are padding.
    let mut blank = false;
    let ends_operand = |t: Option<&Tok>| {
        matches!(
            t,
            Some(Tok::Name(_) | Tok::Int(_) | Tok::Close | Tok::Sup(_))
        )
    };
    while i < chars.len() {
        let c = chars[i];
        if c == ' ' || c == '\t' {
            blank = true;
            i += 1;
            continue;
        }
        let starts_operand = is_letter(c) || c.is_ascii_digit() || c == '(' || c == '[';
        // Juxtaposed groups multiply too: `(1/N)(m/s^2)`, `(m/s^2)N`.
        let after_group =
            matches!(out.last(), Some(Tok::Close)) && (c == '(' || c == '[' || is_letter(c));
        if (blank && starts_operand && ends_operand(out.last())) || after_group {
            out.push(Tok::Times);
        }
        blank = false;
        let (tok, len) = match c {
            '*' if chars.get(i + 1) == Some(&'*') => (Tok::Caret, 2),
            '*' | '.' | '·' | '×' => (Tok::Times, 1),
            '/' => (Tok::Slash, 1),
            '^' => (Tok::Caret, 1),
            '-' | '−' => (Tok::Minus, 1),
            '+' => (Tok::Plus, 1),
            '(' | '[' => (Tok::Open, 1),
            ')' | ']' => (Tok::Close, 1),
            '⁻' | '⁰'..='⁹' | '¹' | '²' | '³' => {
                let negative = c == '⁻';
                let start = if negative { i + 1 } else { i };
                let mut j = start;
                let mut v: i32 = 0;
                while let Some(d) = chars.get(j).and_then(|&c| superscript_digit(c)) {
                    v = v * 10 + d;
                    j += 1;
                }
                if j == start {
                    return Err(LabelError(format!("unexpected character '{c}'")));
                }
                (Tok::Sup(if negative { -v } else { v }), j - i)
            }
            d if d.is_ascii_digit() => {
                let mut j = i;
                let mut v: i32 = 0;
                while let Some(d) = chars.get(j).and_then(|c| c.to_digit(10)) {
                    v = v.saturating_mul(10).saturating_add(d as i32);
                    j += 1;
                }
                (Tok::Int(v), j - i)
            }
            a if is_letter(a) => {
                let mut j = i;
                while chars.get(j).is_some_and(|&c| is_letter(c)) {
                    j += 1;
                }
                // `g0` is one symbol (standard gravity), not g to the power 0.
                let mut name: String = chars[i..j].iter().collect();
                if name.eq_ignore_ascii_case("g") && chars.get(j) == Some(&'0') {
                    name.push('0');
                    j += 1;
                }
                (Tok::Name(name), j - i)
            }
            other => return Err(LabelError(format!("unexpected character '{other}'"))),
        };
        out.push(tok);
        i += len;
    }
    Ok(out)
}

/// Recursive-descent parser over the tokens:
/// `expr := term (('*' | '/') term)*`, left-associative (`a/b/c` = a·b⁻¹·c⁻¹);
/// `term := atom power?`; `atom := symbol | '1' | '(' expr ')'`;
/// `power := ('^' | '**') ['-'|'+'] int | superscript | int glued to a symbol (`s2`)
/// | '-' int glued to a symbol (`s-2`)`.
struct Parser {
    toks: Vec<Tok>,
    pos: usize,
}

impl Parser {
    fn peek(&self) -> Option<&Tok> {
        self.toks.get(self.pos)
    }
    fn bump(&mut self) -> Option<Tok> {
        let t = self.toks.get(self.pos).cloned();
        self.pos += 1;
        t
    }
    fn expr(&mut self, depth: usize) -> Result<Unit, LabelError> {
        if depth > 16 {
            return Err(LabelError("parentheses nested too deeply".into()));
        }
        let mut u = self.term(depth)?;
        loop {
            match self.peek() {
                Some(Tok::Times) => {
                    self.pos += 1;
                    u = u.times(self.term(depth)?);
                }
                Some(Tok::Slash) => {
                    self.pos += 1;
                    u = u.times(self.term(depth)?.powi(-1));
                }
                _ => return Ok(u),
            }
        }
    }
    fn term(&mut self, depth: usize) -> Result<Unit, LabelError> {
        let (base, is_symbol) = match self.bump() {
            Some(Tok::Name(n)) => {
                if n.eq_ignore_ascii_case("db") {
                    return Err(LabelError(
                        "decibels are a logarithmic level, not a unit the values can be scaled from"
                            .into(),
                    ));
                }
                let u = symbol(&n).ok_or_else(|| LabelError(format!("unknown unit '{n}'")))?;
                (u, true)
            }
            Some(Tok::Int(1)) => (Unit::ONE, false),
            Some(Tok::Open) => {
                let u = self.expr(depth + 1)?;
                match self.bump() {
                    Some(Tok::Close) => (u, false),
                    _ => return Err(LabelError("unbalanced parenthesis".into())),
                }
            }
            Some(t) => return Err(LabelError(format!("unexpected {}", describe(&t)))),
            None => return Err(LabelError("label ends where a unit was expected".into())),
        };
        let exp = match self.peek() {
            Some(Tok::Caret) => {
                self.pos += 1;
                Some(self.signed_int()?)
            }
            Some(Tok::Sup(e)) => {
                let e = *e;
                self.pos += 1;
                Some(e)
            }
            // Trailing digits glued to a symbol: `s2`, `m3`; with a sign: `s-2`.
            Some(Tok::Int(e)) if is_symbol => {
                let e = *e;
                self.pos += 1;
                Some(e)
            }
            Some(Tok::Minus) if is_symbol => Some(self.signed_int()?),
            _ => None,
        };
        match exp {
            None => Ok(base),
            Some(e) if (-4..=4).contains(&e) => Ok(base.powi(e)),
            Some(e) => Err(LabelError(format!("exponent {e} is out of range"))),
        }
    }
    fn signed_int(&mut self) -> Result<i32, LabelError> {
        let mut sign = 1;
        match self.peek() {
            Some(Tok::Minus) => {
                sign = -1;
                self.pos += 1;
            }
            Some(Tok::Plus) => self.pos += 1,
            _ => {}
        }
        // `^(-2)` is written too.
        if self.peek() == Some(&Tok::Open) {
            self.pos += 1;
            let e = self.signed_int()?;
            return match self.bump() {
                Some(Tok::Close) => Ok(sign * e),
                _ => Err(LabelError("unbalanced parenthesis in an exponent".into())),
            };
        }
        match self.bump() {
            Some(Tok::Int(e)) => Ok(sign * e),
            Some(Tok::Sup(e)) => Ok(sign * e),
            _ => Err(LabelError("an exponent needs an integer".into())),
        }
    }
}

fn describe(t: &Tok) -> String {
    match t {
        Tok::Name(n) => format!("'{n}'"),
        Tok::Int(i) => format!("number {i} (only 1 may stand alone, as in 1/N)"),
        Tok::Times => "multiplication sign".into(),
        Tok::Slash => "'/'".into(),
        Tok::Caret => "'^'".into(),
        Tok::Minus => "'-'".into(),
        Tok::Plus => "'+'".into(),
        Tok::Open => "'('".into(),
        Tok::Close => "')'".into(),
        Tok::Sup(e) => format!("superscript {e}"),
    }
}

/// Parses a units label into an SI factor and a dimension.
///
/// Grammar (case-insensitive symbols where unambiguous, see `symbol`):
/// products with `*`, `.`, `·`, `×` or a blank; quotients with `/`, left-associative
/// (`m/s^2/N` = m·s⁻²·N⁻¹); nested and multiplied parenthesised groups
/// (`(1/N)*(m/s²)`); powers with `^`, `**`, superscripts (`²`, `³`, `⁻²`) or digits
/// glued to a symbol (`s2`, `s-2`). `dB` is refused with its reason.
pub fn parse_label(label: &str) -> Result<Unit, LabelError> {
    let s = label.trim();
    if s.is_empty() {
        return Err(LabelError("empty label".into()));
    }
    let toks = tokenize(s)?;
    let mut p = Parser { toks, pos: 0 };
    let u = p.expr(0)?;
    if let Some(t) = p.peek() {
        return Err(LabelError(format!(
            "unexpected {} after a complete unit",
            describe(t)
        )));
    }
    Ok(u)
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

    fn dims(u: Unit) -> (i32, i32, i32) {
        (u.length, u.force, u.time)
    }

    /// Every label form analysers write, with its exact SI factor: the factor is the
    /// product of the exact definitions (lbf = 4.4482216152605 N, in = 0.0254 m,
    /// g = 9.80665 m/s²), so it must agree to rounding (1e-15 relative).
    #[test]
    fn labels_parse_to_exact_si_factor_and_dimension() {
        let (acc, acc_per_n, vel_per_n) = ((1, 0, -2), (1, -1, -2), (1, -1, -1));
        let cases: &[(&str, f64, (i32, i32, i32))] = &[
            ("m/s^2", 1.0, acc),
            ("m/s2", 1.0, acc),
            ("m/s**2", 1.0, acc),
            ("m/s²", 1.0, acc),
            ("m s^-2", 1.0, acc),
            ("m s-2", 1.0, acc),
            ("m.s-2", 1.0, acc),
            ("m·s⁻²", 1.0, acc),
            ("m/s^(-1)/s^(+3)", 1.0, acc),
            ("g", G0, acc),
            ("G", G0, acc),
            ("g0", G0, acc),
            ("mm/s", 1e-3, (1, 0, -1)),
            ("m/s^2/N", 1.0, acc_per_n),
            ("mm/s²/N", 1e-3, acc_per_n),
            ("in/s^2/lbf", INCH / LBF, acc_per_n),
            ("IN/S^2/LBF", INCH / LBF, acc_per_n),
            ("g/N", G0, acc_per_n),
            ("G/LBF", G0 / LBF, acc_per_n),
            ("g/lbf", G0 / LBF, acc_per_n),
            ("(m/s2)/N", 1.0, acc_per_n),
            ("(m/s^2)/N", 1.0, acc_per_n),
            ("(1/N)*(m/s²)", 1.0, acc_per_n),
            ("(1/N)*(m/s^2)", 1.0, acc_per_n),
            ("(1/N)(m/s^2)", 1.0, acc_per_n),
            ("(m/s)/N", 1.0, vel_per_n),
            ("((m/s)/(N))", 1.0, vel_per_n),
            ("m/(N*s)", 1.0, vel_per_n),
            ("m/(N s)", 1.0, vel_per_n),
            ("m / N / s", 1.0, vel_per_n),
            ("(mm/s) / (kN)", 1e-6, vel_per_n),
            ("m/N", 1.0, (1, -1, 0)),
            ("µm/N", 1e-6, (1, -1, 0)),
            ("N", 1.0, (0, 1, 0)),
            ("lbf", LBF, (0, 1, 0)),
            ("LBF", LBF, (0, 1, 0)),
            ("kgf", G0, (0, 1, 0)),
            ("in", INCH, (1, 0, 0)),
            ("IN", INCH, (1, 0, 0)),
            ("Hz", 1.0, (0, 0, -1)),
            ("HZ", 1.0, (0, 0, -1)),
            ("hz", 1.0, (0, 0, -1)),
            ("1/s", 1.0, (0, 0, -1)),
            ("kg", 1.0, (-1, 1, 2)),
            ("1/kg", 1.0, (1, -1, -2)),
            ("[m/s^2]/[N]", 1.0, acc_per_n),
        ];
        for &(label, factor, dim) in cases {
            let u = parse_label(label).unwrap_or_else(|e| panic!("{label}: {e}"));
            assert_eq!(dims(u), dim, "{label}");
            assert!(
                (u.factor - factor).abs() <= 1e-15 * factor,
                "{label}: {} vs {factor}",
                u.factor
            );
        }
        // The exact constants themselves.
        assert_eq!(parse_label("lbf").unwrap().factor, 4.4482216152605);
        assert_eq!(parse_label("in").unwrap().factor, 0.0254);
        assert_eq!(parse_label("g").unwrap().factor, 9.80665);
        let rad = parse_label("rad/s").unwrap();
        assert_eq!(dims(rad), (0, 0, -1));
        assert!((rad.factor * 2.0 * std::f64::consts::PI - 1.0).abs() < 1e-15);
    }

    #[test]
    fn labels_refused_say_why() {
        let db = parse_label("dB").unwrap_err();
        assert!(db.0.contains("logarithmic"), "{db}");
        assert!(parse_label("dB re 1 m/s^2")
            .unwrap_err()
            .0
            .contains("logarithmic"));
        for (label, why) in [
            ("furlong", "unknown unit 'furlong'"),
            ("(m/s", "unbalanced"),
            ("m/s)", "unexpected ')'"),
            ("", "empty"),
            ("m/s^", "exponent"),
            ("m^9", "out of range"),
            ("2/N", "only 1 may stand alone"),
            ("V/N", "unknown unit 'V'"),
            ("m/s?", "unexpected character '?'"),
            // MN and MS would be mega-units: case is not folded for mN and ms.
            ("MN", "unknown unit 'MN'"),
            ("MS", "unknown unit 'MS'"),
        ] {
            let e = parse_label(label).unwrap_err();
            assert!(e.0.contains(why), "{label}: {e}");
        }
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
