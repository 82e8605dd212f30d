//! One-page Markdown report: the summary table and the paper-style error figures.

use crate::summary::SummaryRow;
use anyhow::Result;
use rbprops_plot::{bar_chart, BarChart, BarSeries};
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// Error figures per method: groups = mode sets, bars = origins (the paper's Figs. 14–17
/// layout; Figs. 5–8 when there is one origin).
pub fn error_figures(rows: &[SummaryRow]) -> Result<Vec<(String, String)>> {
    let mut methods: Vec<&str> = rows.iter().map(|r| r.method.as_str()).collect();
    methods.dedup();
    methods.sort();
    methods.dedup();
    let mut out = Vec::new();
    for m in methods {
        let sel: Vec<&SummaryRow> = rows
            .iter()
            .filter(|r| r.method == m && r.err_sum.is_some())
            .collect();
        if sel.is_empty() {
            continue;
        }
        let mut sets: Vec<String> = Vec::new();
        let mut origins: Vec<String> = Vec::new();
        for r in &sel {
            let s = format!("{} {}", r.campaign, r.set);
            if !sets.contains(&s) {
                sets.push(s);
            }
            if !origins.contains(&r.origin) {
                origins.push(r.origin.clone());
            }
        }
        for (what, get) in [
            (
                "mass",
                (|r: &SummaryRow| r.err_mass) as fn(&SummaryRow) -> Option<f64>,
            ),
            ("com", |r: &SummaryRow| r.err_com),
            ("inertia", |r: &SummaryRow| r.err_inertia),
            ("sum", |r: &SummaryRow| r.err_sum),
        ] {
            let series = origins
                .iter()
                .map(|o| {
                    let vals = sets
                        .iter()
                        .map(|s| {
                            sel.iter()
                                .find(|r| {
                                    &r.origin == o && &format!("{} {}", r.campaign, r.set) == s
                                })
                                .and_then(|r| get(r))
                                .map(|v| 100.0 * v)
                                .unwrap_or(f64::NAN)
                        })
                        .collect();
                    BarSeries::new(format!("origin {o}"), vals)
                })
                .collect();
            let chart = BarChart {
                title: format!("{m}: relative error of {what} per set and origin"),
                groups: sets.clone(),
                series,
                y_label: "relative error [%]".into(),
                ..Default::default()
            };
            out.push((
                format!("error_{what}_{}.svg", crate::plots::sanitize(m)),
                bar_chart(&chart)?,
            ));
        }
    }
    Ok(out)
}

/// Writes `report.md`, `summary.csv` and the error figures into `dir`.
pub fn write(
    dir: &Path,
    title: &str,
    rows: &[SummaryRow],
    extra_figures: &[PathBuf],
) -> Result<()> {
    let figs = error_figures(rows)?;
    crate::write_plots(dir, &figs)?;
    crate::write_text(&dir.join("summary.csv"), &crate::summary::to_csv(rows)?)?;
    let mut md = String::new();
    writeln!(md, "# {title}\n")?;
    writeln!(md, "Products of inertia are `J_xy = ∫xy dm` (the tensor's off-diagonals are their negatives). Errors are the paper's relative measures (mass; CoM vector; the 6-vector {{Jxx Jxy Jxz Jyy Jyz Jzz}}).\n")?;
    writeln!(md, "| campaign | set | origin | method | m [kg] | c [mm] | Jxx Jyy Jzz [kg m²] | Jxy Jxz Jyz [kg m²] | err m | err c | err J | Σ err |")?;
    writeln!(md, "|---|---|---|---|---|---|---|---|---|---|---|---|")?;
    let pct = |v: Option<f64>| {
        v.map(|x| format!("{:.3} %", 100.0 * x))
            .unwrap_or_else(|| "–".into())
    };
    for r in rows {
        writeln!(
            md,
            "| {} | {} | {} | {} | {:.4} | {:.2}, {:.2}, {:.2} | {:.5} {:.5} {:.5} | {:.5} {:.5} {:.5} | {} | {} | {} | {} |",
            r.campaign,
            r.set,
            r.origin,
            r.method,
            r.mass_kg,
            1e3 * r.com_x_m,
            1e3 * r.com_y_m,
            1e3 * r.com_z_m,
            r.jxx,
            r.jyy,
            r.jzz,
            r.jxy,
            r.jxz,
            r.jyz,
            pct(r.err_mass),
            pct(r.err_com),
            pct(r.err_inertia),
            pct(r.err_sum)
        )?;
    }
    let warned: Vec<&SummaryRow> = rows.iter().filter(|r| !r.warnings.is_empty()).collect();
    if !warned.is_empty() {
        writeln!(md, "\n## Warnings\n")?;
        for r in warned {
            writeln!(
                md,
                "- {} {} {} {}: {}",
                r.campaign, r.set, r.origin, r.method, r.warnings
            )?;
        }
    }
    writeln!(md, "\n## Figures\n")?;
    for (name, _) in &figs {
        writeln!(md, "![{name}]({name})\n")?;
    }
    for f in extra_figures {
        let rel = pathdiff(f, dir);
        writeln!(
            md,
            "![{}]({})\n",
            f.file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            rel
        )?;
    }
    crate::write_text(&dir.join("report.md"), &md)
}

fn pathdiff(target: &Path, base: &Path) -> String {
    match (std::fs::canonicalize(target), std::fs::canonicalize(base)) {
        (Ok(t), Ok(b)) => {
            let tc: Vec<_> = t.components().collect();
            let bc: Vec<_> = b.components().collect();
            let common = tc.iter().zip(&bc).take_while(|(a, b)| a == b).count();
            let mut p = PathBuf::new();
            for _ in common..bc.len() {
                p.push("..");
            }
            for c in &tc[common..] {
                p.push(c);
            }
            p.display().to_string()
        }
        _ => target.display().to_string(),
    }
}
