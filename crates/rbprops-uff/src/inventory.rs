//! What a universal file holds, in a few lines a user can read: datasets by type,
//! functions by type with counts, nodes, units and frequency axes
//! (`rbprops convert --list`, and the error of a file without FRFs).

use crate::model::{Function, Record, UffFile};
use std::collections::BTreeMap;
use std::fmt::Write;

/// The name of a dataset 58 function type (record 6 field 1).
pub fn function_type_name(code: i64) -> &'static str {
    match code {
        0 => "general",
        1 => "time response",
        2 => "auto spectrum",
        3 => "cross spectrum",
        4 => "FRF",
        5 => "transmissibility",
        6 => "coherence",
        7 => "auto correlation",
        8 => "cross correlation",
        9 => "PSD",
        10 => "ESD",
        11 => "probability density",
        12 => "spectrum",
        13 => "cumulative frequency distribution",
        14 => "peaks valley",
        15 => "stress/cycles",
        16 => "strain/cycles",
        17 => "orbit",
        18 => "mode indicator function",
        19 => "force pattern",
        20 => "partial power",
        21 => "partial coherence",
        22 => "eigenvalue",
        23 => "eigenvector",
        24 => "shock response spectrum",
        25 => "finite impulse response",
        26 => "multiple coherence",
        27 => "order function",
        _ => "unknown",
    }
}

fn dataset_name(number: i64) -> &'static str {
    match number {
        15 => "nodes (single precision)",
        18 => "coordinate systems",
        55 => "data at nodes (mode shapes, …)",
        58 => "functions at nodal DOFs",
        82 => "trace lines",
        151 => "header",
        164 => "units",
        2411 => "nodes (double precision)",
        2412 => "elements",
        2420 => "coordinate systems",
        _ => "",
    }
}

fn abscissa_kind(code: i64) -> &'static str {
    match code {
        0 => "unknown",
        1 => "general",
        17 => "time",
        18 => "frequency",
        19 => "order",
        _ => "other",
    }
}

/// Compact list of integers: `1-4, 7, 9-12` (at most `max` runs, then `…`).
fn ranges(mut v: Vec<i64>, max: usize) -> String {
    v.sort_unstable();
    v.dedup();
    let mut runs: Vec<(i64, i64)> = Vec::new();
    for x in v {
        match runs.last_mut() {
            Some((_, b)) if *b + 1 == x => *b = x,
            _ => runs.push((x, x)),
        }
    }
    let mut parts: Vec<String> = runs
        .iter()
        .take(max)
        .map(|&(a, b)| {
            if a == b {
                a.to_string()
            } else {
                format!("{a}-{b}")
            }
        })
        .collect();
    if runs.len() > max {
        parts.push("…".into());
    }
    parts.join(", ")
}

fn label_or(l: &str) -> &str {
    if crate::units::is_unset(l) {
        "(no label)"
    } else {
        l
    }
}

/// A multi-line description of what `uff` holds.
pub fn inventory(uff: &UffFile) -> String {
    let mut out = String::new();
    let mut by_number: BTreeMap<i64, usize> = BTreeMap::new();
    let mut functions: BTreeMap<i64, usize> = BTreeMap::new();
    let mut binary = 0usize;
    let mut node_labels: Vec<i64> = Vec::new();
    let mut referenced: Vec<i64> = Vec::new();
    let mut units: Vec<String> = Vec::new();
    let mut ordinate_units: BTreeMap<String, usize> = BTreeMap::new();
    let mut axes: BTreeMap<String, usize> = BTreeMap::new();
    for d in &uff.datasets {
        let number = match &d.record {
            Record::Unknown { number, .. } => *number,
            _ => d.location.number,
        };
        *by_number.entry(number).or_default() += 1;
        match &d.record {
            Record::Nodes(set) => node_labels.extend(set.nodes.iter().map(|n| n.label)),
            Record::Units(u) => units.push(format!(
                "code {} {} (length factor {}, force factor {})",
                u.code,
                if u.description.is_empty() {
                    "".to_string()
                } else {
                    format!("'{}'", u.description)
                },
                u.length_factor,
                u.force_factor
            )),
            Record::Function(f) => {
                *functions.entry(f.function_type).or_default() += 1;
                binary += f.binary.is_some() as usize;
                referenced.extend([f.response_node, f.reference_node]);
                *ordinate_units.entry(ordinate_units_text(f)).or_default() += 1;
                *axes.entry(axis_text(f)).or_default() += 1;
            }
            _ => {}
        }
    }
    let _ = writeln!(out, "{} datasets:", uff.datasets.len());
    for (n, c) in &by_number {
        let name = dataset_name(*n);
        let extra = if *n == 58 && binary > 0 {
            format!(" ({binary} binary)")
        } else {
            String::new()
        };
        let _ = writeln!(
            out,
            "  dataset {n}{}: {c}{extra}",
            if name.is_empty() {
                String::new()
            } else {
                format!(" {name}")
            }
        );
    }
    if !functions.is_empty() {
        let _ = writeln!(out, "functions (dataset 58) by type:");
        for (t, c) in &functions {
            let _ = writeln!(out, "  {} (type {t}): {c}", function_type_name(*t));
        }
        let _ = writeln!(out, "ordinate units (record 9 / record 10 type and label):");
        for (u, c) in &ordinate_units {
            let _ = writeln!(out, "  {u}: {c}");
        }
        let _ = writeln!(out, "abscissae:");
        for (a, c) in &axes {
            let _ = writeln!(out, "  {a}: {c}");
        }
    }
    let _ = writeln!(
        out,
        "nodes: {} defined{}",
        {
            let mut v = node_labels.clone();
            v.sort_unstable();
            v.dedup();
            v.len()
        },
        if node_labels.is_empty() {
            String::new()
        } else {
            format!(" ({})", ranges(node_labels.clone(), 8))
        }
    );
    if !referenced.is_empty() {
        let _ = writeln!(
            out,
            "nodes named in record 6 of the functions: {}",
            ranges(referenced, 8)
        );
    }
    if units.is_empty() {
        let _ = writeln!(out, "units: no dataset 164 (SI assumed)");
    } else {
        for u in units {
            let _ = writeln!(out, "units: dataset 164 {u}");
        }
    }
    if let Some(t) = crate::timehist::describe(uff) {
        let _ = writeln!(out, "{t}");
    }
    out.trim_end().to_string()
}

fn ordinate_units_text(f: &Function) -> String {
    format!(
        "{} {} (type {}) / {} (type {})",
        function_type_name(f.function_type),
        label_or(&f.numerator.units_label),
        f.numerator.data_type,
        label_or(&f.denominator.units_label),
        f.denominator.data_type
    )
}

fn axis_text(f: &Function) -> String {
    let (a, b) = if f.is_empty() {
        (0.0, 0.0)
    } else {
        (f.abscissa_at(0), f.abscissa_at(f.len() - 1))
    };
    format!(
        "{} {} lines {}…{} {} ({} spacing)",
        abscissa_kind(f.abscissa_axis.data_type),
        f.len(),
        a,
        b,
        label_or(&f.abscissa_axis.units_label),
        if f.even { "even" } else { "uneven" }
    )
}

#[cfg(test)]
mod tests {
    #[test]
    fn ranges_compress_runs() {
        assert_eq!(super::ranges(vec![4, 1, 2, 3, 7, 9, 10], 8), "1-4, 7, 9-10");
        assert_eq!(super::ranges(vec![1, 3, 5], 2), "1, 3, …");
        assert_eq!(super::ranges(vec![], 2), "");
    }
}
