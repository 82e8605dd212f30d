//! Degrees of freedom of datasets 58 whose record 6 does not give them (node 0 or
//! direction 0): the naming patterns analysers write in entity names and ID lines, and
//! the channel map a user fills in when no pattern applies.
//!
//! # Patterns (first match wins)
//! 1. **Entity names** (record 6 fields 5 and 8), each one DOF: `Point3:+Z`, `12:-x`,
//!    `BASE12+Y`, `7Z-` (see the token forms below).
//! 2. **ID lines 1–5**, in order: the first line holding two DOF tokens gives the
//!    response (first) and the reference (second), e.g. `Point3:+Z / Point1:+Z`.
//!
//! A DOF token is a node number followed by a signed axis letter, in one of three forms
//! (letters before the number are a name and are ignored; the sign defaults to `+`):
//! - `<name><node>:<sign><axis>`: `Point3:+Z`, `pt12 : -y`, `3:X`;
//! - `<node><sign><axis>`: `12+X`, `12-z`;
//! - `<node><axis><sign>`: `12X+`, `4Y-`.
//!
//! The axis letter must not be followed by another letter or digit (`12+Xa` is no DOF).
//! Tokens such as `#  2` (a channel number, as in `H1 : #  2 / #  1`) carry no
//! direction and give no DOF: such files need a channel map.

use crate::model::Function;

/// A translational DOF: node label and direction code ±1..±3.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct NodeDof {
    /// Node label as in the file.
    pub node: i64,
    /// Direction code: +1..+3 along x, y, z of the node's displacement system, negative for −x..−z.
    pub direction: i64,
}

fn axis_code(c: char) -> Option<i64> {
    match c.to_ascii_lowercase() {
        'x' => Some(1),
        'y' => Some(2),
        'z' => Some(3),
        _ => None,
    }
}

/// Every DOF token in `text`, in order (see the module documentation for the forms).
pub fn dof_tokens(text: &str) -> Vec<NodeDof> {
    let c: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < c.len() {
        if !c[i].is_ascii_digit() || (i > 0 && c[i - 1].is_ascii_digit()) {
            i += 1;
            continue;
        }
        let start = i;
        while i < c.len() && c[i].is_ascii_digit() {
            i += 1;
        }
        let Ok(node) = c[start..i].iter().collect::<String>().parse::<i64>() else {
            continue;
        };
        // The character after the axis letter must end the token.
        let ends = |k: usize| c.get(k).is_none_or(|ch| !ch.is_alphanumeric());
        let mut j = i;
        let skip_blanks = |mut k: usize| {
            while k < c.len() && c[k] == ' ' {
                k += 1;
            }
            k
        };
        let sign_of = |ch: char| match ch {
            '+' => Some(1),
            '-' | '−' => Some(-1),
            _ => None,
        };
        // Form 1: node ':' [sign] axis.
        let k = skip_blanks(j);
        if c.get(k) == Some(&':') {
            j = skip_blanks(k + 1);
            let mut sign = 1;
            if let Some(s) = c.get(j).and_then(|&ch| sign_of(ch)) {
                sign = s;
                j = skip_blanks(j + 1);
            }
            if let Some(a) = c.get(j).and_then(|&ch| axis_code(ch)) {
                if ends(j + 1) {
                    out.push(NodeDof {
                        node,
                        direction: sign * a,
                    });
                    i = j + 1;
                }
            }
            continue;
        }
        // Form 2: node sign axis.
        if let Some(s) = c.get(j).and_then(|&ch| sign_of(ch)) {
            if let Some(a) = c.get(j + 1).and_then(|&ch| axis_code(ch)) {
                if ends(j + 2) {
                    out.push(NodeDof {
                        node,
                        direction: s * a,
                    });
                    i = j + 2;
                }
            }
            continue;
        }
        // Form 3: node axis sign.
        if let Some(a) = c.get(j).and_then(|&ch| axis_code(ch)) {
            if let Some(s) = c.get(j + 1).and_then(|&ch| sign_of(ch)) {
                if ends(j + 2) {
                    out.push(NodeDof {
                        node,
                        direction: s * a,
                    });
                    j += 2;
                    i = j;
                }
            }
        }
    }
    out
}

/// How a dataset's DOF was determined.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DofSource {
    /// Record 6 of the dataset (node and direction fields).
    Record6,
    /// The response or reference entity name of record 6, e.g. `12X+`.
    EntityName,
    /// The ID line with this 1-based number.
    IdLine(usize),
    /// A row of the caller's channel map.
    ChannelMap,
}

/// The (response, reference) DOFs the names of a dataset 58 give, with where they came
/// from; `None` for a side no pattern gives.
pub fn dofs_from_names(f: &Function) -> [Option<(NodeDof, DofSource)>; 2] {
    let mut out: [Option<(NodeDof, DofSource)>; 2] = [None, None];
    for (k, name) in [&f.response_entity, &f.reference_entity].iter().enumerate() {
        if let [one] = dof_tokens(name).as_slice() {
            out[k] = Some((*one, DofSource::EntityName));
        }
    }
    if out.iter().all(Option::is_some) {
        return out;
    }
    for (line_no, line) in f.id_lines.iter().enumerate() {
        let toks = dof_tokens(line);
        if toks.len() >= 2 {
            for k in 0..2 {
                if out[k].is_none() {
                    out[k] = Some((toks[k], DofSource::IdLine(line_no + 1)));
                }
            }
            break;
        }
    }
    out
}

/// One row of a channel map: the DOFs of the dataset(s) it matches.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelMapRow {
    /// 1-based dataset index in the file (as `rbprops convert --list` numbers them).
    pub dataset: Option<usize>,
    /// ID line 1 text (blanks collapsed), used when `dataset` is blank.
    pub id_text: String,
    /// Response DOF the row assigns, if any.
    pub response: Option<NodeDof>,
    /// Reference (excitation) DOF the row assigns, if any.
    pub reference: Option<NodeDof>,
    /// 1-based line of the map file.
    pub line: usize,
}

/// A channel map (`--channels map.csv`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ChannelMap {
    /// The map file's name, for messages.
    pub name: String,
    /// Rows in file order.
    pub rows: Vec<ChannelMapRow>,
}

/// The header of a channel map file.
pub const CHANNEL_MAP_HEADER: &str =
    "dataset,id_line_1,function,response_point,response_direction,reference_point,reference_direction";

fn collapse_blanks(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Parses a direction: `+x`, `-Z`, `y`, or a code `1`, `-3`.
pub fn parse_direction(s: &str) -> Option<i64> {
    let t = s.trim();
    if let Ok(code) = t.parse::<i64>() {
        return (1..=3).contains(&code.abs()).then_some(code);
    }
    let (sign, rest) = match t.chars().next()? {
        '+' => (1, &t[1..]),
        '-' => (-1, &t[1..]),
        _ => (1, t),
    };
    let mut ch = rest.trim().chars();
    let a = axis_code(ch.next()?)?;
    ch.next().is_none().then_some(sign * a)
}

fn format_direction(d: i64) -> String {
    let letter = ['x', 'y', 'z'][(d.unsigned_abs() as usize).clamp(1, 3) - 1];
    format!("{}{letter}", if d < 0 { '-' } else { '+' })
}

/// Splits one CSV line (double quotes around a field allowed, `""` inside quotes).
fn csv_fields(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                cur.push('"');
                chars.next();
            }
            ('"', _) => quoted = !quoted,
            (',', false) => out.push(std::mem::take(&mut cur)),
            (c, _) => cur.push(c),
        }
    }
    out.push(cur);
    out
}

fn csv_quote(s: &str) -> String {
    if s.contains([',', '"']) || s.starts_with(' ') || s.ends_with(' ') {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

impl ChannelMap {
    /// Parses a channel map (see [`CHANNEL_MAP_HEADER`]; `#` starts a comment line).
    /// `name` is used in error messages.
    pub fn parse(text: &str, name: &str) -> Result<ChannelMap, String> {
        let mut rows = Vec::new();
        let mut header_seen = false;
        for (k, raw) in text.lines().enumerate() {
            let line_no = k + 1;
            let line = raw.trim_end_matches('\r');
            if line.trim().is_empty() || line.trim_start().starts_with('#') {
                continue;
            }
            let f = csv_fields(line);
            if !header_seen {
                let got = f.iter().map(|s| s.trim()).collect::<Vec<_>>().join(",");
                if got != CHANNEL_MAP_HEADER {
                    return Err(format!(
                        "{name}: line {line_no}: header '{got}' is not '{CHANNEL_MAP_HEADER}'"
                    ));
                }
                header_seen = true;
                continue;
            }
            if f.len() != 7 {
                return Err(format!(
                    "{name}: line {line_no}: {} fields, expected 7 ({CHANNEL_MAP_HEADER})",
                    f.len()
                ));
            }
            let dataset = match f[0].trim() {
                "" => None,
                s => Some(s.parse::<usize>().ok().filter(|&d| d > 0).ok_or_else(|| {
                    format!("{name}: line {line_no}: dataset '{s}' is not a positive integer")
                })?),
            };
            let id_text = collapse_blanks(&f[1]);
            if dataset.is_none() && id_text.is_empty() {
                return Err(format!(
                    "{name}: line {line_no}: neither a dataset index nor an ID text"
                ));
            }
            let dof = |p: &str, d: &str, what: &str| -> Result<Option<NodeDof>, String> {
                match (p.trim(), d.trim()) {
                    ("", "") => Ok(None),
                    (p, d) => {
                        let node = p.parse::<i64>().map_err(|_| {
                            format!(
                                "{name}: line {line_no}: {what} point '{p}' is not a node number"
                            )
                        })?;
                        let direction = parse_direction(d).ok_or_else(|| {
                            format!(
                                "{name}: line {line_no}: {what} direction '{d}' is not one of +x -x +y -y +z -z (or 1..3, -1..-3)"
                            )
                        })?;
                        Ok(Some(NodeDof { node, direction }))
                    }
                }
            };
            rows.push(ChannelMapRow {
                dataset,
                id_text,
                response: dof(&f[3], &f[4], "response")?,
                reference: dof(&f[5], &f[6], "reference")?,
                line: line_no,
            });
        }
        if !header_seen {
            return Err(format!("{name}: empty channel map (no header line)"));
        }
        Ok(ChannelMap {
            name: name.to_string(),
            rows,
        })
    }

    /// The row for dataset `index` (1-based) with ID line 1 `id_line`: by index first,
    /// then by ID text.
    pub fn row_for(&self, index: usize, id_line: &str) -> Option<&ChannelMapRow> {
        self.rows
            .iter()
            .find(|r| r.dataset == Some(index))
            .or_else(|| {
                let id = collapse_blanks(id_line);
                self.rows
                    .iter()
                    .find(|r| r.dataset.is_none() && r.id_text == id)
            })
    }
}

/// Writes a channel map template: one row per dataset 58 of the file, with the DOFs
/// record 6 or a naming pattern gives already filled in and the others blank, for the
/// user to complete.
pub fn channel_map_template(uff: &crate::UffFile) -> String {
    let mut out = String::from(
        "# rbprops channel map: one row per dataset 58. Fill in the blank points (node numbers)\n\
         # and directions (+x -x +y -y +z -z). Rows match by dataset index, or by ID line 1\n\
         # when the dataset column is blank.\n",
    );
    out.push_str(CHANNEL_MAP_HEADER);
    out.push('\n');
    for d in &uff.datasets {
        let crate::Record::Function(f) = &d.record else {
            continue;
        };
        let named = dofs_from_names(f);
        let side = |node: i64, dir: i64, k: usize| -> (String, String) {
            if node != 0 && dir != 0 {
                (node.to_string(), format_direction(dir))
            } else if let Some((n, _)) = &named[k] {
                (n.node.to_string(), format_direction(n.direction))
            } else {
                (String::new(), String::new())
            }
        };
        let (rp, rd) = side(f.response_node, f.response_direction, 0);
        let (ep, ed) = side(f.reference_node, f.reference_direction, 1);
        out.push_str(&format!(
            "{},{},{},{rp},{rd},{ep},{ed}\n",
            d.location.index,
            csv_quote(&collapse_blanks(&f.id_lines[0])),
            crate::inventory::function_type_name(f.function_type),
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn d(node: i64, direction: i64) -> NodeDof {
        NodeDof { node, direction }
    }

    #[test]
    fn tokens_of_every_documented_form() {
        assert_eq!(dof_tokens("Point3:+Z"), vec![d(3, 3)]);
        assert_eq!(dof_tokens("pt12 : -y"), vec![d(12, -2)]);
        assert_eq!(dof_tokens("3:X"), vec![d(3, 1)]);
        assert_eq!(dof_tokens("12+X"), vec![d(12, 1)]);
        assert_eq!(dof_tokens("12-z"), vec![d(12, -3)]);
        assert_eq!(dof_tokens("12X+"), vec![d(12, 1)]);
        assert_eq!(dof_tokens("4Y-"), vec![d(4, -2)]);
        assert_eq!(
            dof_tokens("FRF Point3:+Z / Point1:-X"),
            vec![d(3, 3), d(1, -1)]
        );
        assert_eq!(dof_tokens("BASE12+Y/7Z-"), vec![d(12, 2), d(7, -3)]);
    }

    #[test]
    fn non_dofs_are_not_tokens() {
        assert!(dof_tokens("H1 : #  2 / #  1").is_empty());
        assert!(dof_tokens("NONE").is_empty());
        assert!(dof_tokens("12+Xa").is_empty());
        assert!(dof_tokens("Record 3 of 12").is_empty());
        assert!(dof_tokens("setup=A 2 kg").is_empty());
        assert!(dof_tokens("10:30 run").is_empty());
    }

    #[test]
    fn channel_map_parses_and_matches() {
        let text = format!(
            "# comment\n{CHANNEL_MAP_HEADER}\n3,\"H1 : #  2 / #  1\",FRF,12,+z,1,-x\n,\"H1 : #  3 / #  1\",FRF,13,y,1,-1\n"
        );
        let m = ChannelMap::parse(&text, "map.csv").unwrap();
        assert_eq!(m.rows.len(), 2);
        assert_eq!(m.row_for(3, "anything").unwrap().response, Some(d(12, 3)));
        let r = m.row_for(9, "H1 :  #  3 /  #  1").unwrap();
        assert_eq!((r.response, r.reference), (Some(d(13, 2)), Some(d(1, -1))));
        assert!(m.row_for(9, "H1 : #  4 / #  1").is_none());
        let bad = ChannelMap::parse(
            &format!("{CHANNEL_MAP_HEADER}\n1,,FRF,12,+w,1,z\n"),
            "m.csv",
        )
        .unwrap_err();
        assert!(
            bad.contains("m.csv: line 2") && bad.contains("'+w'"),
            "{bad}"
        );
        assert!(ChannelMap::parse("a,b\n", "m.csv")
            .unwrap_err()
            .contains("header"));
    }
}
