//! The one-page HTML report: a self-contained document (CSS in a `<style>` element, every
//! figure an inline `<svg>`, no script, no external file) with the estimates and their
//! intervals, the figures, the warnings grouped by stage and explained, and the model
//! check's verdict. [`html`] only formats: it takes the data already read
//! ([`ReportData`], see `report::load`) and returns the page as a `String`.

use crate::summary::SummaryRow;
use crate::warnings::{grouped_by_kind, severity_label, shown_by_default, Diagnostic};
use anyhow::{bail, Result};
use rbprops_core::records::InertiaEstimate;
use std::fmt::Write;

/// One run of the report: a single recording's or campaign item's outputs.
#[derive(Debug, Clone, Default)]
pub struct RunSection {
    /// The campaign label (path relative to the campaign directory) or the run's name.
    pub label: String,
    /// The run's inertia estimates.
    pub estimates: Vec<InertiaEstimate>,
    /// Its model check, when one ran.
    pub check: Option<rbprops_check::ModelCheckReport>,
    /// Every stage's diagnostics.
    pub warnings: Vec<Diagnostic>,
    /// `frf-est`'s verdict on every hit (the processing topic's `frf_estimation.hits`).
    pub hits: Vec<rbprops_core::records::HitRecord>,
    /// (file name, SVG document), in the order they are shown.
    pub figures: Vec<(String, String)>,
}

/// Everything the page shows.
#[derive(Debug, Clone, Default)]
pub struct ReportData {
    /// Page title.
    pub title: String,
    /// The summary table (a campaign's), one row per recording and estimator.
    pub rows: Vec<SummaryRow>,
    /// Figures of the whole campaign (estimates across recordings, error figures).
    pub figures: Vec<(String, String)>,
    /// One section per run, in order.
    pub runs: Vec<RunSection>,
}

/// Escapes text for HTML element content and attribute values.
pub fn escape(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&#39;"),
            c => o.push(c),
        }
    }
    o
}

/// An SVG document as an inline element: the XML declaration and doctype dropped, the
/// rest checked to be one `<svg>…</svg>` element without script (the page runs none),
/// and rewritten by [`rbprops_plot::compact_svg`] (the same picture in about a third of
/// the bytes: a campaign's page inlines hundreds of figures).
pub fn inline_svg(name: &str, svg: &str) -> Result<String> {
    let mut body = svg.trim();
    while body.starts_with("<?") || body.starts_with("<!") {
        match body.find('>') {
            Some(k) => body = body[k + 1..].trim_start(),
            None => break,
        }
    }
    if !body.starts_with("<svg") || !body.ends_with("</svg>") {
        bail!("figure {name}: not an SVG document (expected one <svg>…</svg> element)");
    }
    let lower = body.to_ascii_lowercase();
    if lower.contains("<script") || lower.contains("<foreignobject") {
        bail!("figure {name}: SVG with script or foreign content is not inlined");
    }
    Ok(rbprops_plot::compact_svg(body).trim_end().to_string())
}

const STYLE: &str = "body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;margin:1.5em auto;max-width:1400px;padding:0 1em;color:#222}\
h1{font-size:1.6em}h2{font-size:1.3em;border-bottom:1px solid #ccc;margin-top:2em}h3{font-size:1.1em}\
table{border-collapse:collapse;font-size:.85em;margin:.5em 0}th,td{border:1px solid #ccc;padding:.2em .5em;text-align:right}\
th{background:#f2f2f2}td.t,th.t{text-align:left}tr.rejected td{background:#fdecea}\
figure{margin:1em 0;overflow-x:auto}figure svg{max-width:100%;height:auto}figcaption{font-size:.8em;color:#555}\
.verdict{padding:.4em .8em;border-left:4px solid #888;background:#f7f7f7}.ok{border-color:#2a7}.bad{border-color:#c33}\
.changes{color:#b00}.note{color:#555}p.expl{margin:.1em 0 .6em 1.5em;font-size:.85em;color:#444}";

/// The report page.
pub fn html(d: &ReportData) -> Result<String> {
    let mut h = String::new();
    let t = escape(&d.title);
    write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{t}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n<h1>{t}</h1>\n"
    )?;
    h += "<p>Mass m, centre of mass c and the inertia tensor J about the centre of mass, with 95 % intervals: \
          <em>noise</em> is ±1.96 standard errors of the measurement noise; <em>systematic</em> adds the \
          leave-one-sensor/excitation-out spread. Products of inertia are J<sub>xy</sub> = ∫xy dm (the tensor's \
          off-diagonal entries are their negatives). Conventions: docs/conventions.md.</p>\n";
    if !d.rows.is_empty() {
        summary_table(&mut h, &d.rows)?;
    }
    unseen(&mut h, &d.runs)?;
    for (name, svg) in &d.figures {
        figure(&mut h, name, svg)?;
    }
    for r in &d.runs {
        run_section(&mut h, r, d.runs.len() > 1)?;
    }
    h += "</body>\n</html>\n";
    Ok(h)
}

/// What the model checks cannot see (an effect the free parameters absorb), said once for
/// the whole report with the recordings it concerns, not in every row.
fn unseen(h: &mut String, runs: &[RunSection]) -> Result<()> {
    let mut seen: Vec<(&rbprops_check::report::NotObservable, Vec<&str>)> = Vec::new();
    for r in runs {
        for n in r.check.iter().flat_map(|c| &c.not_observable) {
            match seen
                .iter_mut()
                .find(|(m, _)| m.id == n.id && m.reason == n.reason)
            {
                Some((_, labels)) => labels.push(&r.label),
                None => seen.push((n, vec![&r.label])),
            }
        }
    }
    if seen.is_empty() {
        return Ok(());
    }
    h.push_str("<h3>What these tests cannot see</h3>\n<ul>\n");
    for (n, labels) in seen {
        let which = if labels.len() == runs.len() {
            "every recording".to_string()
        } else {
            labels.join(", ")
        };
        write!(
            h,
            "<li><b>{}</b> [{}]: {}; would need {} ({})</li>\n",
            escape(&n.title),
            escape(&n.id),
            escape(&n.reason),
            escape(&n.would_reveal),
            escape(&which)
        )?;
    }
    h.push_str("</ul>\n");
    Ok(())
}

fn summary_table(h: &mut String, rows: &[SummaryRow]) -> Result<()> {
    let checked = rows
        .iter()
        .any(|r| !r.check_verdict.is_empty() || !r.check_effects.is_empty());
    h.push_str("<h2>Summary</h2>\n<table>\n<tr><th class=\"t\">recording</th><th class=\"t\">method</th><th>m [kg]</th><th>±95 % [kg]</th><th>c [mm]</th><th>J<sub>xx</sub> J<sub>yy</sub> J<sub>zz</sub> [kg m²]</th><th>J<sub>xy</sub> J<sub>xz</sub> J<sub>yz</sub> [kg m²]</th>");
    if checked {
        h.push_str("<th class=\"t\">model check: effects</th><th>χ²/ν before → after</th><th class=\"t\">verdict</th>");
    }
    h.push_str("</tr>\n");
    for r in rows {
        write!(
            h,
            "<tr><td class=\"t\">{}</td><td class=\"t\">{}</td>",
            escape(&r.campaign),
            escape(&r.method)
        )?;
        if r.method == "error" {
            write!(
                h,
                "<td class=\"t changes\" colspan=\"{}\">{}</td></tr>\n",
                if checked { 8 } else { 5 },
                escape(&r.warnings)
            )?;
            continue;
        }
        let c = r.property_cells();
        write!(
            h,
            "<td>{}</td><td>{:.4}</td><td>{}</td><td>{}</td><td>{}</td>",
            c.mass,
            1.96 * r.mass_std_kg,
            c.com_mm,
            c.moments,
            c.products
        )?;
        if checked {
            let chi = match (r.check_chi2_nu_before, r.check_chi2_nu_after) {
                (Some(a), Some(b)) => format!("{a:.3} → {b:.3}"),
                _ => "–".into(),
            };
            write!(
                h,
                "<td class=\"t\">{}</td><td>{}</td><td class=\"t\">{}</td>",
                escape(&r.check_effects),
                escape(&chi),
                // The short label; the full verdict is in the recording's section (an
                // older summary without labels shows the verdict).
                escape(if r.check_label.is_empty() {
                    &r.check_verdict
                } else {
                    &r.check_label
                })
            )?;
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n");
    Ok(())
}

/// `value ± h` with `h` = 1.96 σ, or the value alone when σ is not positive.
fn pm(v: f64, std: f64, prec: usize) -> String {
    if std > 0.0 && std.is_finite() {
        format!("{v:.prec$} ± {:.prec$}", 1.96 * std)
    } else {
        format!("{v:.prec$}")
    }
}

fn interval(iv: [f64; 2], prec: usize) -> String {
    format!("[{:.prec$}, {:.prec$}]", iv[0], iv[1])
}

fn estimates_table(h: &mut String, list: &[InertiaEstimate]) -> Result<()> {
    h.push_str("<table>\n<tr><th class=\"t\">method</th><th class=\"t\">set-up</th><th class=\"t\">quantity</th><th>value ± 95 % (noise)</th><th>95 % (noise + systematic)</th></tr>\n");
    for e in list {
        let j = &e.inertia_cm_kg_m2;
        let sj = &e.inertia_cm_std_kg_m2;
        let sys = e.systematic.as_ref();
        let mut lines: Vec<(String, String, String)> = vec![(
            "m [kg]".into(),
            pm(e.mass_kg, e.mass_std_kg, 4),
            sys.map(|s| interval(s.mass_95_kg, 4)).unwrap_or_default(),
        )];
        for (i, axis) in ["x", "y", "z"].iter().enumerate() {
            lines.push((
                format!("c<sub>{axis}</sub> [mm]"),
                pm(1e3 * e.com_m[i], 1e3 * e.com_std_m[i], 2),
                sys.map(|s| interval([1e3 * s.com_95_m[i][0], 1e3 * s.com_95_m[i][1]], 2))
                    .unwrap_or_default(),
            ));
        }
        for (r, c, name) in [
            (0, 0, "J<sub>xx</sub>"),
            (1, 1, "J<sub>yy</sub>"),
            (2, 2, "J<sub>zz</sub>"),
            (0, 1, "tensor J<sub>xy</sub>"),
            (0, 2, "tensor J<sub>xz</sub>"),
            (1, 2, "tensor J<sub>yz</sub>"),
        ] {
            lines.push((
                format!("{name} [kg m²]"),
                pm(j[r][c], sj[r][c], 5),
                sys.map(|s| interval(s.inertia_cm_95_kg_m2[r][c], 5))
                    .unwrap_or_default(),
            ));
        }
        let n = lines.len();
        for (k, (q, v, s)) in lines.into_iter().enumerate() {
            h.push_str("<tr>");
            if k == 0 {
                write!(
                    h,
                    "<td class=\"t\" rowspan=\"{n}\">{}{}</td><td class=\"t\" rowspan=\"{n}\">{}</td>",
                    escape(e.method.as_str()),
                    if e.physically_consistent {
                        ""
                    } else {
                        " <span class=\"changes\">(not physical)</span>"
                    },
                    escape(&e.setup)
                )?;
            }
            // `q` is our own markup (sub-scripts), the numbers are formatted floats.
            write!(h, "<td class=\"t\">{q}</td><td>{v}</td><td>{s}</td></tr>\n")?;
        }
    }
    h.push_str("</table>\n");
    Ok(())
}

fn verdict(h: &mut String, c: &rbprops_check::ModelCheckReport) -> Result<()> {
    let cls = if c.noise_floor_reached { "ok" } else { "bad" };
    write!(
        h,
        "<h3>Model check</h3>\n<p class=\"verdict {cls}\">{}</p>\n<table>\n<tr><th class=\"t\">quantity</th><th>value</th></tr>\n",
        escape(&c.verdict)
    )?;
    let accepted: Vec<&str> = c.accepted.iter().map(|a| a.id.as_str()).collect();
    let ambiguous: Vec<String> = c.ambiguous.iter().map(|f| f.ids.join("/")).collect();
    for (q, v) in [
        ("effects named".to_string(), accepted.join(", ")),
        ("ambiguous families".to_string(), ambiguous.join(", ")),
        (
            "χ²/ν nominal spec".to_string(),
            format!("{:.3}", c.chi2_nu_nominal),
        ),
        (
            "χ²/ν baseline fit".to_string(),
            format!("{:.3}", c.chi2_nu_before),
        ),
        (
            "χ²/ν final model".to_string(),
            format!("{:.3}", c.chi2_nu_after),
        ),
        (
            "noise band of χ²/ν".to_string(),
            format!("[{:.3}, {:.3}]", c.noise_band[0], c.noise_band[1]),
        ),
        (
            "residual reached the noise".to_string(),
            if c.noise_floor_reached { "yes" } else { "no" }.to_string(),
        ),
    ] {
        write!(
            h,
            "<tr><td class=\"t\">{}</td><td>{}</td></tr>\n",
            escape(&q),
            escape(&v)
        )?;
    }
    h.push_str("</table>\n");
    Ok(())
}

/// The diagnostics, by stage and within a stage by kind: each kind's sentence once, then
/// its diagnostics (severity, subject, message), the ones that may change the answer
/// marked.
fn warnings(h: &mut String, list: &[Diagnostic]) -> Result<()> {
    if list.is_empty() {
        h.push_str("<h3>Warnings</h3>\n<p>None.</p>\n");
        return Ok(());
    }
    h.push_str("<h3>Warnings</h3>\n");
    let mut stages: Vec<&str> = Vec::new();
    for w in list {
        if !stages.contains(&w.stage.as_str()) {
            stages.push(&w.stage);
        }
    }
    for s in stages {
        let of = grouped_by_kind(list.iter().filter(|w| w.stage == s));
        let notes = of.iter().filter(|d| !shown_by_default(d)).count();
        let (n_w, n_n) = (of.len() - notes, notes);
        write!(
            h,
            "<h4>{} ({n_w} warning{}, {n_n} note{})</h4>\n<ul>\n",
            escape(s),
            if n_w == 1 { "" } else { "s" },
            if n_n == 1 { "" } else { "s" },
        )?;
        let mut kind = None;
        for d in of {
            if kind != Some(d.kind) {
                if kind.is_some() {
                    h.push_str("</ul></li>\n");
                }
                kind = Some(d.kind);
                write!(
                    h,
                    "<li class=\"kind\"><b>{}</b><p class=\"expl\">{}</p><ul>\n",
                    escape(&d.kind.as_str().replace('_', " ")),
                    escape(d.kind.sentence())
                )?;
            }
            let cls = if shown_by_default(d) {
                "changes"
            } else {
                "note"
            };
            write!(
                h,
                "<li><span class=\"{cls}\">[{}]</span> {}</li>\n",
                severity_label(d.severity),
                escape(&d.line())
            )?;
        }
        h.push_str("</ul></li>\n</ul>\n");
    }
    Ok(())
}

fn figure(h: &mut String, name: &str, svg: &str) -> Result<()> {
    write!(
        h,
        "<figure>\n{}\n<figcaption>{}</figcaption>\n</figure>\n",
        inline_svg(name, svg)?,
        escape(name)
    )?;
    Ok(())
}

/// `frf-est`'s per-hit table ([`crate::report::HIT_TABLE_HEADER`] and
/// [`crate::report::hit_cells`]).
fn hit_table(h: &mut String, hits: &[rbprops_core::records::HitRecord]) -> Result<()> {
    if hits.is_empty() {
        return Ok(());
    }
    h.push_str("<h3>Hits (frf-est)</h3>\n<table>\n<tr>");
    for (k, name) in crate::report::HIT_TABLE_HEADER.iter().enumerate() {
        let class = if k < 4 { " class=\"t\"" } else { "" };
        write!(h, "<th{class}>{}</th>", escape(name))?;
    }
    h.push_str("</tr>\n");
    for hit in hits {
        h.push_str(if hit.accepted {
            "<tr>"
        } else {
            "<tr class=\"rejected\">"
        });
        for (k, cell) in crate::report::hit_cells(hit).iter().enumerate() {
            let class = if k < 4 { " class=\"t\"" } else { "" };
            write!(h, "<td{class}>{}</td>", escape(cell))?;
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n");
    Ok(())
}

fn run_section(h: &mut String, r: &RunSection, several: bool) -> Result<()> {
    write!(
        h,
        "<h2>{}{}</h2>\n",
        if several { "Recording " } else { "" },
        escape(&r.label)
    )?;
    if !r.estimates.is_empty() {
        h.push_str("<h3>Estimates</h3>\n");
        estimates_table(h, &r.estimates)?;
    }
    if let Some(c) = &r.check {
        verdict(h, c)?;
    }
    hit_table(h, &r.hits)?;
    warnings(h, &r.warnings)?;
    if !r.figures.is_empty() {
        h.push_str("<h3>Figures</h3>\n");
        for (name, svg) in &r.figures {
            figure(h, name, svg)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::warnings::DiagnosticKind;

    #[test]
    fn text_is_escaped_and_figures_inlined() {
        assert_eq!(
            escape("<a href=\"x\">&'</a>"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&#39;&lt;/a&gt;"
        );
        let svg = "<?xml version=\"1.0\"?>\n<svg width=\"10\" height=\"10\"><rect/></svg>\n";
        assert_eq!(
            inline_svg("a.svg", svg).unwrap(),
            "<svg width=\"10\" height=\"10\"><rect/></svg>"
        );
        assert!(inline_svg("b.svg", "<html></html>").is_err());
        assert!(inline_svg("c.svg", "<svg><script>x()</script></svg>").is_err());
        let d = ReportData {
            title: "<b>campaign</b>".into(),
            runs: vec![RunSection {
                label: "run & <1>".into(),
                warnings: vec![Diagnostic::new(
                    "rb-solve",
                    DiagnosticKind::IllConditioned,
                    crate::warnings::Severity::Warning,
                    Default::default(),
                    "Φ0 is poorly conditioned (cond = <1e9>)",
                )],
                figures: vec![("f.svg".into(), svg.into())],
                ..Default::default()
            }],
            ..Default::default()
        };
        let page = html(&d).unwrap();
        assert!(page.contains("<h1>&lt;b&gt;campaign&lt;/b&gt;</h1>"));
        assert!(page.contains("run &amp; &lt;1&gt;"));
        assert!(page.contains("(cond = &lt;1e9&gt;)"));
        assert!(page.contains("[warning]"));
        assert!(page.contains(DiagnosticKind::IllConditioned.sentence()));
        assert_eq!(page.matches("<svg").count(), 1);
        assert!(!page.contains("<script"));
        assert!(!page.contains("<?xml"));
    }
}
