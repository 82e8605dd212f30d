//! One-page Markdown report: the summary table and the paper-style error figures.

use crate::summary::SummaryRow;
use anyhow::{bail, Context, Result};
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

/// Writes the Markdown report `md_name` (e.g. `report.md`), `summary.csv` and the error
/// figures into `dir`, with `frf-est`'s per-hit table of each run in `hits`.
pub fn write(
    dir: &Path,
    md_name: &str,
    title: &str,
    rows: &[SummaryRow],
    extra_figures: &[PathBuf],
    hits: &[(String, Vec<rbprops_core::records::HitRecord>)],
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
        let c = r.property_cells();
        writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.campaign,
            r.set,
            r.origin,
            r.method,
            c.mass,
            c.com_mm,
            c.moments,
            c.products,
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
    md.push_str(&hit_tables_markdown(hits));
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
    crate::write_text(&dir.join(md_name), &md)
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

/// Order of the figure kinds on the page: the data and the fit first, then the mode
/// selection, the estimates and the model check.
const FIGURE_ORDER: [&str; 9] = [
    "fit_",
    "stabilisation_",
    "frf_",
    "ni",
    "hybrid_mif",
    "prf_mif",
    "strength_",
    "estimates",
    "residual_map_",
];

fn figure_rank(name: &str) -> usize {
    if name.starts_with("check_") {
        return FIGURE_ORDER.len() + 1;
    }
    FIGURE_ORDER
        .iter()
        .position(|p| name.starts_with(p))
        .unwrap_or(FIGURE_ORDER.len())
}

/// The SVG files of a directory (not recursive), in page order (kind, then name).
pub fn read_figures(dir: &Path) -> Result<Vec<(String, String)>> {
    let mut figs = Vec::new();
    for e in std::fs::read_dir(dir).with_context(|| dir.display().to_string())? {
        let p = e?.path();
        if p.is_file() && p.extension().is_some_and(|x| x == "svg") {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            let text = crate::read_text(&p)?;
            figs.push((name, text));
        }
    }
    figs.sort_by(|a, b| {
        figure_rank(&a.0)
            .cmp(&figure_rank(&b.0))
            .then_with(|| a.0.cmp(&b.0))
    });
    Ok(figs)
}

/// Columns of the per-hit table of `frf-est`'s processing (Markdown and HTML).
pub const HIT_TABLE_HEADER: [&str; 8] = [
    "excitation",
    "hit",
    "verdict",
    "reasons",
    "peak force [N]",
    "clipped samples per channel (force first)",
    "double-hit delay [ms]",
    "double-hit ratio",
];

/// The cells of one hit's row under [`HIT_TABLE_HEADER`]; "–" where nothing was found.
pub fn hit_cells(h: &rbprops_core::records::HitRecord) -> [String; 8] {
    [
        h.excitation.clone(),
        h.hit.to_string(),
        if h.accepted { "accepted" } else { "rejected" }.into(),
        if h.reasons.is_empty() {
            "–".into()
        } else {
            h.reasons.join("; ")
        },
        format!("{:.4}", h.peak_force_n),
        h.clipped_samples
            .iter()
            .map(|c| c.to_string())
            .collect::<Vec<_>>()
            .join(" "),
        h.double_hit_delay_s
            .map_or("–".into(), |d| format!("{:.1}", 1e3 * d)),
        h.double_hit_ratio
            .map_or("–".into(), |r| format!("{:.1} %", 100.0 * r)),
    ]
}

/// `frf-est`'s hit verdicts in a run (the processing topic's `frf_estimation.hits`);
/// empty when its FRFs were not estimated from time histories.
pub fn hits_of(
    record: &rbprops_formats::RunRecord,
) -> Result<Vec<rbprops_core::records::HitRecord>> {
    use rbprops_core::records::{ProcessingRecord, PROCESSING_TOPIC};
    let p: Option<ProcessingRecord> = record.get_one(PROCESSING_TOPIC)?;
    Ok(p.and_then(|p| p.frf_estimation)
        .map(|e| e.hits)
        .unwrap_or_default())
}

/// The per-hit tables of runs in Markdown, one per run with hits, under `## Hits`.
pub fn hit_tables_markdown(runs: &[(String, Vec<rbprops_core::records::HitRecord>)]) -> String {
    let mut md = String::new();
    let runs: Vec<_> = runs.iter().filter(|(_, h)| !h.is_empty()).collect();
    if runs.is_empty() {
        return md;
    }
    md.push_str("\n## Hits (frf-est)\n");
    let cell = |s: &str| s.replace('|', "\\|");
    for (label, hits) in runs {
        md.push_str(&format!("\n### {}\n\n", cell(label)));
        md.push_str(&format!("| {} |\n", HIT_TABLE_HEADER.join(" | ")));
        md.push_str(&format!("|{}\n", "---|".repeat(HIT_TABLE_HEADER.len())));
        for h in hits {
            let cells: Vec<String> = hit_cells(h).iter().map(|c| cell(c)).collect();
            md.push_str(&format!("| {} |\n", cells.join(" | ")));
        }
    }
    md
}

/// One run's section from its record (estimates, model check report, warnings) and the
/// figures in `figures_dir`.
pub fn run_section(
    label: &str,
    record: &rbprops_formats::RunRecord,
    figures_dir: Option<&Path>,
) -> Result<crate::html::RunSection> {
    use rbprops_formats::topics;
    let mut warnings = crate::warnings::from_record(record)?;
    // A report with a non-finite statistic (null in JSON) does not decode: the section
    // says so instead of failing the whole page (the summary table keeps the verdict).
    let check = record
        .get_one(topics::MODEL_CHECK)
        .unwrap_or_else(|e| {
            warnings.push(crate::warnings::Diagnostic::new(
                "report",
                crate::warnings::DiagnosticKind::Text,
                crate::warnings::Severity::Warning,
                Default::default(),
                format!("the model check's report could not be read ({e:#}); its verdict is in the summary table"),
            ));
            None
        });
    Ok(crate::html::RunSection {
        label: label.to_string(),
        estimates: record.get(topics::ESTIMATES)?,
        check,
        warnings,
        hits: hits_of(record)?,
        figures: match figures_dir {
            Some(d) => read_figures(d)?,
            None => Vec::new(),
        },
    })
}

/// What `rbprops report` reads, from one input path:
///
/// - a summary CSV (`campaign -o`, `summary`): its rows;
/// - a campaign output directory holding `summary.csv` and, from `campaign --runs
///   DIR/runs`, one directory per recording under `runs/` (`run.mcap` and its SVG
///   figures): the rows, plus a section per recording;
/// - a run directory holding `run.mcap` (or one `*.mcap`) and the SVG figures the stages
///   wrote with `--plot`: one section;
/// - a run file (MCAP) or CSV run directory with an estimates topic: one section.
pub fn load(input: &Path, title: &str) -> Result<crate::html::ReportData> {
    let name = input.display().to_string();
    let mut d = crate::html::ReportData {
        title: title.to_string(),
        ..Default::default()
    };
    let read_rows = |p: &Path| -> Result<Vec<SummaryRow>> {
        let text = crate::read_text(p)?;
        crate::summary::from_csv(&text).with_context(|| p.display().to_string())
    };
    if input.is_file() && input.extension().is_some_and(|e| e == "csv") {
        d.rows = read_rows(input)?;
    } else if input.is_dir() && input.join("summary.csv").is_file() {
        d.rows = read_rows(&input.join("summary.csv"))?;
        let runs = input.join("runs");
        if runs.is_dir() {
            let mut dirs: Vec<PathBuf> = std::fs::read_dir(&runs)
                .with_context(|| runs.display().to_string())?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.join(crate::campaign::RUN_FILE).is_file())
                .collect();
            dirs.sort();
            // Label each section with the campaign label of its rows (the directory name
            // is that label made file-name safe).
            let mut labels: Vec<&str> = d.rows.iter().map(|r| r.campaign.as_str()).collect();
            labels.dedup();
            for dir in dirs {
                let stem = dir.file_name().unwrap().to_string_lossy().into_owned();
                let label = labels
                    .iter()
                    .find(|l| crate::plots::sanitize(l) == stem)
                    .map(|l| l.to_string())
                    .unwrap_or(stem);
                let rec = crate::read_input(Some(&dir.join(crate::campaign::RUN_FILE)))?.record;
                d.runs.push(run_section(&label, &rec, Some(&dir))?);
            }
        }
        d.figures = campaign_figures(&d.rows)?;
    } else if input.is_dir() && !input.join("manifest.csv").exists() {
        let mut mcaps: Vec<PathBuf> = std::fs::read_dir(input)
            .with_context(|| name.clone())?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
            .collect();
        mcaps.sort();
        let run = input.join(crate::campaign::RUN_FILE);
        let file = if run.is_file() {
            run
        } else if mcaps.len() == 1 {
            mcaps.remove(0)
        } else {
            bail!("{name}: not a report input: expected summary.csv (a campaign's output), run.mcap or one *.mcap (a run's), found {} MCAP files", mcaps.len());
        };
        let rec = crate::read_input(Some(&file))?.record;
        let label = input
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        d.rows = crate::summary::rows(&rec, &label, "ni", "geometry")?;
        d.runs.push(run_section(&label, &rec, Some(input))?);
    } else {
        let rec = crate::read_input(Some(input))?.record;
        let label = input
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        d.rows = crate::summary::rows(&rec, &label, "ni", "geometry")?;
        d.runs.push(run_section(&label, &rec, None)?);
    }
    if d.rows.is_empty()
        && d.runs
            .iter()
            .all(|r| r.estimates.is_empty() && r.hits.is_empty())
    {
        bail!("{name}: no estimates or hit verdicts to report (run frf-est, rb-solve or rbprops campaign first)");
    }
    Ok(d)
}

/// Figures of a whole campaign: the error figures when the rows have reference values,
/// and the mass per recording with its 95 % noise interval, one series per estimator.
pub fn campaign_figures(rows: &[SummaryRow]) -> Result<Vec<(String, String)>> {
    use rbprops_plot::{scatter_plot, ScatterPlot, ScatterSeries};
    let mut figs = error_figures(rows)?;
    let ok: Vec<&SummaryRow> = rows.iter().filter(|r| r.method != "error").collect();
    let mut labels: Vec<&str> = ok.iter().map(|r| r.campaign.as_str()).collect();
    labels.dedup();
    if labels.len() < 2 {
        return Ok(figs);
    }
    let mut methods: Vec<&str> = ok.iter().map(|r| r.method.as_str()).collect();
    methods.sort();
    methods.dedup();
    let series = methods
        .iter()
        .map(|m| {
            let sel: Vec<&&SummaryRow> = ok.iter().filter(|r| r.method == *m).collect();
            let x = sel
                .iter()
                .map(|r| labels.iter().position(|l| *l == r.campaign).unwrap() as f64)
                .collect();
            ScatterSeries::new(*m, x, sel.iter().map(|r| r.mass_kg).collect())
                .with_errors(sel.iter().map(|r| 1.96 * r.mass_std_kg).collect())
        })
        .collect();
    let plot = ScatterPlot {
        title: "Mass per recording (95 % noise intervals)".into(),
        x_label: "recording (in table order)".into(),
        x_categories: labels.iter().map(|l| l.to_string()).collect(),
        y_label: "m [kg]".into(),
        series,
        ..Default::default()
    };
    figs.push(("campaign_mass.svg".into(), scatter_plot(&plot)?));
    Ok(figs)
}

/// Writes the HTML report of `data` to `path` (atomically: a temporary file renamed).
pub fn write_html(path: &Path, data: &crate::html::ReportData) -> Result<()> {
    crate::write_text(path, &crate::html::html(data)?)
}
