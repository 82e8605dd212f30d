//! The number of averages an FRF export names for its FRFs and coherence, where it names
//! it. UFF 58 has no field for it (record 6's fields are the function type, its
//! identification and version numbers, the load case and the DOFs), so analysers write it
//! as text in the ID lines (records 1–5), e.g. `Averages: 10`, `Number of averages = 10`,
//! `10 averages`, `Avg=10`, `NAVG 10`, `10 Mittelungen`, `10 moyennes`. It is read from
//! the FRF (function type 4) and coherence (6) datasets: a keyword, then the whole number
//! right after it (`:`/`=` and `of` skipped) or right before it. Every dataset that names
//! a count must name the same one; none named, or two different ones, leave the choice
//! to the caller (`--averages`), with the reason.

use crate::error::DatasetLocation;
use crate::model::{Record, UffFile};

/// Words that name the number of averages in an ID line (lower case).
const KEYWORDS: &[&str] = &[
    "averages",
    "average",
    "averaged",
    "avgs",
    "avg",
    "avg.",
    "navg",
    "nave",
    "n_avg",
    "num_avg",
    "#avg",
    "mittelungen",
    "moyennes",
];

/// Where an export names its number of averages.
#[derive(Debug, Clone, PartialEq)]
pub struct DeclaredAverages {
    /// The number of averages.
    pub count: usize,
    /// The first dataset naming it.
    pub at: DatasetLocation,
    /// Its ID line (1–5).
    pub id_line: usize,
    /// How many FRF and coherence datasets name it.
    pub datasets: usize,
}

/// The number of averages named in one ID line (module docs), if any.
pub fn averages_in_line(line: &str) -> Option<usize> {
    let lower = line.to_ascii_lowercase();
    let tokens: Vec<&str> = lower
        .split(|c: char| c.is_whitespace() || matches!(c, ':' | '=' | ',' | ';' | '(' | ')'))
        .filter(|t| !t.is_empty())
        .collect();
    let count = |t: &str| {
        t.parse::<usize>()
            .ok()
            .filter(|&n| (1..=1_000_000).contains(&n))
    };
    for (i, t) in tokens.iter().enumerate() {
        if !KEYWORDS.contains(t) {
            continue;
        }
        let after = tokens.get(i + 1).and_then(|t| count(t));
        let after_of = (tokens.get(i + 1) == Some(&"of"))
            .then(|| tokens.get(i + 2).and_then(|t| count(t)))
            .flatten();
        let before = i.checked_sub(1).and_then(|j| count(tokens[j]));
        if let Some(n) = after.or(before).or(after_of) {
            return Some(n);
        }
    }
    None
}

/// The number of averages the FRF and coherence datasets of `uff` name (module docs):
/// `Ok(None)` when none does; `Err` with the reason when two name different counts.
pub fn declared_averages(uff: &UffFile) -> Result<Option<DeclaredAverages>, String> {
    let mut found: Option<DeclaredAverages> = None;
    for d in &uff.datasets {
        let Record::Function(f) = &d.record else {
            continue;
        };
        if !matches!(f.function_type, 4 | 6) {
            continue;
        }
        let named = f
            .id_lines
            .iter()
            .enumerate()
            .find_map(|(k, l)| averages_in_line(l).map(|n| (n, k + 1)));
        let Some((count, id_line)) = named else {
            continue;
        };
        match &mut found {
            None => {
                found = Some(DeclaredAverages {
                    count,
                    at: d.location.clone(),
                    id_line,
                    datasets: 1,
                })
            }
            Some(first) if first.count == count => first.datasets += 1,
            Some(first) => {
                return Err(format!(
                    "dataset #{} (line {}) names {} averages in ID line {}, dataset #{} (line {}) {count} in ID line {id_line}: give --averages",
                    first.at.index, first.at.line, first.count, first.id_line, d.location.index, d.location.line
                ))
            }
        }
    }
    Ok(found)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ways_analysers_write_it() {
        for (line, want) in [
            ("Averages: 10", Some(10)),
            ("Number of averages = 12", Some(12)),
            ("H1 estimate, 5 averages, Hanning", Some(5)),
            ("Avg=8", Some(8)),
            ("NAVG 20", Some(20)),
            ("Lin. Mittelung, 16 Mittelungen", Some(16)),
            ("FRF 101:+Z/1:+Z  7 avg", Some(7)),
            // Not a count: no number beside the word, or a number that is not one.
            ("Average type: linear", None),
            ("Averages: -3", None),
            ("Averages: 2.5", None),
            ("Point 12 +Z / Point 1 +Z", None),
            ("NONE", None),
        ] {
            assert_eq!(averages_in_line(line), want, "{line}");
        }
    }
}
