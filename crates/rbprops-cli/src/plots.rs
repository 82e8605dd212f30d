//! Figures shared by several stages (FRF overlays), built on `rbprops-plot`.

use anyhow::Result;
use rbprops_core::{FrfSet, Geometry};
use rbprops_plot::{line_plot, LinePlot, Scale, Series};

/// One figure per excitation: |FRF| of every channel (the paper's Figs. 3 and 10).
pub fn frf_magnitudes(geometry: &Geometry, frf: &FrfSet) -> Result<Vec<(String, String)>> {
    let mut out = Vec::new();
    for (e, exc) in geometry.excitations.iter().enumerate() {
        let series = geometry
            .channels
            .iter()
            .enumerate()
            .map(|(c, ch)| {
                Series::new(
                    ch.id.clone(),
                    frf.frequency_hz.clone(),
                    frf.frf(e, c).iter().map(|v| v.norm()).collect(),
                )
            })
            .collect();
        let plot = LinePlot {
            title: format!(
                "{} FRFs, excitation {} (set-up {})",
                frf.quantity.name(),
                exc.id,
                exc.setup
            ),
            x_label: "Frequency [Hz]".into(),
            y_label: format!("|H| [{}]", frf.quantity.unit()),
            y_scale: Scale::Log10,
            series,
            ..Default::default()
        };
        out.push((format!("frf_{}.svg", sanitize(&exc.id)), line_plot(&plot)?));
    }
    Ok(out)
}

/// Dynamic range shown on a dB axis below its highest value: a zero line far below the
/// curves (−300 dB and less) would otherwise flatten them into the top of the figure.
pub const NI_SPAN_DB: f64 = 80.0;

/// Lines strictly above 0 Hz (with a finite frequency).
pub fn lines_above_dc(frequency_hz: &[f64]) -> Vec<usize> {
    (0..frequency_hz.len())
        .filter(|&l| frequency_hz[l].is_finite() && frequency_hz[l] > 0.0)
        .collect()
}

/// A fixed dB range `[max − span, max]` (padded by 3 dB) when the finite values reach
/// further down than `span` below their maximum; `None` (the data extent) otherwise.
pub fn decibel_window(values: impl IntoIterator<Item = f64>, span: f64) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    (hi.is_finite() && hi - lo > span).then(|| (hi - span, hi + 3.0))
}

/// A file-name-safe version of an id.
pub fn sanitize(id: &str) -> String {
    id.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Estimates with 95 % error bars: the ten properties (mass, CoM, moments and products
/// of inertia, docs/conventions.md §3), one group per property, one bar per estimator
/// (relative to the first estimate, so scales mix).
pub fn estimates(list: &[rbprops_core::records::InertiaEstimate]) -> Result<Vec<(String, String)>> {
    use rbprops_core::InertiaProperties;
    use rbprops_plot::{bar_chart, BarChart, BarSeries};
    let names = InertiaProperties::SYMBOLS;
    let values = |e: &rbprops_core::records::InertiaEstimate| -> ([f64; 10], [f64; 10]) {
        (
            InertiaProperties::of_estimate(e).to_vector(),
            InertiaProperties::standard_errors_of(e).to_vector(),
        )
    };
    let Some(first) = list.first() else {
        return Ok(Vec::new());
    };
    let (v0, _) = values(first);
    let series = list
        .iter()
        .map(|e| {
            let (v, s) = values(e);
            let scale: Vec<f64> = v0
                .iter()
                .map(|x| if x.abs() > 0.0 { x.abs() } else { 1.0 })
                .collect();
            BarSeries::new(
                e.method.to_string(),
                (0..10).map(|i| v[i] / scale[i]).collect(),
            )
            .with_errors((0..10).map(|i| 1.96 * s[i] / scale[i]).collect())
        })
        .collect();
    let chart = BarChart {
        title: format!("Estimates relative to |{}| (95 % intervals)", first.method),
        groups: names.iter().map(|s| s.to_string()).collect(),
        series,
        y_label: "value / |reference estimate|".into(),
        ..Default::default()
    };
    Ok(vec![("estimates.svg".into(), bar_chart(&chart)?)])
}

/// NI of all excitations on one axis (Figs. 4/11), hybrid and PRF MIF (Figs. 12/13), and a
/// mode × excitation heat map of excitation strength per set-up.
pub fn indicators(out: &rbprops_ni::SelectionOutput) -> Result<Vec<(String, String)>> {
    use rbprops_plot::{heat_map, HeatMap};
    let c = &out.curves;
    let f = &c.frequency_hz;
    let mut plots = Vec::new();
    let markers: Vec<rbprops_plot::VerticalMarker> = out
        .record
        .selected
        .iter()
        .map(|s| {
            rbprops_plot::VerticalMarker::new(
                s.frequency_hz,
                format!("{} mode {}", s.setup, s.mode),
            )
        })
        .collect();
    // The 0 Hz line (NI of a receptance or accelerance is 0 or ∞ there) would stretch the
    // axis over hundreds of dB: the curves are drawn on the lines above 0 Hz only.
    let lines = lines_above_dc(f);
    let dc_note = if lines.len() < f.len() {
        "; 0 Hz line not shown"
    } else {
        ""
    };
    let pick = |v: &[f64]| lines.iter().map(|&l| v[l]).collect::<Vec<f64>>();
    let fp = pick(f);
    let ni = LinePlot {
        title: format!("Norm Indicator (Eq. 12){dc_note}"),
        x_label: "Frequency [Hz]".into(),
        y_label: format!("NI [dB re 1 {}]", c.quantity.unit()),
        series: c
            .excitations
            .iter()
            .map(|e| {
                Series::new(
                    format!("{} ({})", e.excitation, e.setup),
                    fp.clone(),
                    pick(&e.ni_db),
                )
            })
            .collect(),
        markers: markers.clone(),
        y_range: decibel_window(
            c.excitations.iter().flat_map(|e| pick(&e.ni_db)),
            NI_SPAN_DB,
        ),
        ..Default::default()
    };
    plots.push(("ni.svg".to_string(), line_plot(&ni)?));
    for (name, title, which) in [
        ("hybrid_mif", "Hybrid MIF (Rades 1994)", 0usize),
        ("prf_mif", "PRF MIF (Rades & Ewins 2000)", 1usize),
    ] {
        let p = LinePlot {
            title: format!("{title}{dc_note}"),
            x_label: "Frequency [Hz]".into(),
            y_label: "MIF [-]".into(),
            series: c
                .excitations
                .iter()
                .map(|e| {
                    let curve = if which == 0 {
                        &e.hybrid_mif
                    } else {
                        &e.prf_mif
                    };
                    Series::new(e.excitation.clone(), fp.clone(), pick(curve))
                })
                .collect(),
            markers: markers.clone(),
            ..Default::default()
        };
        plots.push((format!("{name}.svg"), line_plot(&p)?));
    }
    for m in &out.strength_db {
        let values: Vec<Vec<f64>> = m
            .measured_db
            .iter()
            .map(|row| row.iter().map(|v| v.unwrap_or(f64::NAN)).collect())
            .collect();
        let hm = HeatMap {
            title: format!("Excitation strength f_kᵀq [dB re 1/kg], set-up {}", m.setup),
            row_labels: m
                .modes
                .iter()
                .zip(&m.frequency_hz)
                .map(|(k, fr)| format!("mode {k} ({fr:.3} Hz)"))
                .collect(),
            column_labels: m.excitations.clone(),
            values,
            x_label: "excitation".into(),
            y_label: "mode".into(),
            value_label: "dB".into(),
            ..Default::default()
        };
        plots.push((
            format!("strength_{}.svg", sanitize(&m.setup)),
            heat_map(&hm)?,
        ));
    }
    Ok(plots)
}

/// Per excitation: the stabilisation diagram over Σ|H|, and measured vs synthesised FRFs.
pub fn modal_fit(
    geometry: &Geometry,
    frf: &FrfSet,
    out: &rbprops_modal::ModalFitOutput,
) -> Result<Vec<(String, String)>> {
    modal_fit_shaded(geometry, frf, out, None)
}

/// The default threshold of [`modal_fit_shaded`]'s shading: a line with γ² < 0.9 has
/// `(1 − γ²)/γ² > 0.11`, an FRF error above a third of |H| per average (so above 12 % with
/// 8 averages), which a reader should not take at face value.
pub const LOW_COHERENCE: f64 = 0.9;

/// [`modal_fit`] with the measured coherence `(grid, threshold)`: each channel's panel
/// of the measured vs synthesised FRFs shades the lines where γ² < threshold.
pub fn modal_fit_shaded(
    geometry: &Geometry,
    frf: &FrfSet,
    out: &rbprops_modal::ModalFitOutput,
    coherence: Option<(&crate::coherence::CoherenceGrid, f64)>,
) -> Result<Vec<(String, String)>> {
    use rbprops_modal::StabilityClass as S;
    use rbprops_plot::{
        stabilisation_diagram, BackgroundCurve, PoleClass, StabilisationDiagram, StabilisationPole,
        VerticalMarker,
    };
    let mut plots = Vec::new();
    for (e, d) in out.diagnostics.iter().enumerate() {
        if d.frequency_hz.is_empty() {
            continue;
        }
        let name = sanitize(&d.excitation);
        let sum: Vec<f64> = (0..frf.n_lines())
            .map(|l| (0..frf.n_channels).map(|c| frf.frf(e, c)[l].norm()).sum())
            .collect();
        let selected: Vec<VerticalMarker> = out
            .record
            .modes
            .iter()
            .filter(|m| m.excitation == d.excitation)
            .map(|m| {
                VerticalMarker::new(
                    m.frequency_hz,
                    format!("{}{}", m.mode, if m.weak { " (weak)" } else { "" }),
                )
            })
            .collect();
        let diagram = StabilisationDiagram {
            title: format!("Stabilisation diagram, excitation {}", d.excitation),
            poles: d
                .stabilisation
                .poles
                .iter()
                .map(|p| StabilisationPole {
                    frequency_hz: p.frequency_hz,
                    order: p.order,
                    class: match p.class {
                        S::Stable | S::Shape => PoleClass::Stable,
                        S::Damping => PoleClass::FrequencyDamping,
                        S::Frequency => PoleClass::Frequency,
                        _ => PoleClass::New,
                    },
                })
                .collect(),
            background: Some(BackgroundCurve {
                name: "Σ|H|".into(),
                frequency_hz: frf.frequency_hz.clone(),
                magnitude: sum,
                axis_label: format!("Σ|H| [{}]", frf.quantity.unit()),
            }),
            selected,
            x_range: Some((d.frequency_hz[0], *d.frequency_hz.last().unwrap())),
            ..Default::default()
        };
        plots.push((
            format!("stabilisation_{name}.svg"),
            stabilisation_diagram(&diagram)?,
        ));
        let band = (d.frequency_hz[0], *d.frequency_hz.last().unwrap());
        let mut panels = fit_panels(geometry, frf, e, band, &d.frequency_hz, &d.synthesised);
        if let Some((grid, threshold)) = coherence {
            shade_low_coherence(&mut panels, frf, &grid[e], band, threshold);
        }
        let overlay = rbprops_plot::FrfPanels {
            title: format!("Measured vs synthesised FRFs, excitation {}", d.excitation),
            magnitude_label: format!("|H| [{}]", frf.quantity.unit()),
            panels,
            ..Default::default()
        };
        plots.push((
            format!("fit_{name}.svg"),
            rbprops_plot::frf_panels(&overlay)?,
        ));
    }
    Ok(plots)
}

/// Gives each channel's panel its coherence inside `band` as the quality measure
/// shaded below `threshold` (channels without coherence get none).
fn shade_low_coherence(
    panels: &mut [rbprops_plot::FrfPanel],
    frf: &FrfSet,
    row: &[Option<Vec<f64>>],
    band: (f64, f64),
    threshold: f64,
) {
    let lines: Vec<usize> = (0..frf.n_lines())
        .filter(|&l| frf.frequency_hz[l] >= band.0 && frf.frequency_hz[l] <= band.1)
        .collect();
    for (panel, g) in panels.iter_mut().zip(row) {
        if let Some(g) = g {
            panel.quality = Some(rbprops_plot::LineQuality {
                frequency_hz: lines.iter().map(|&l| frf.frequency_hz[l]).collect(),
                value: lines.iter().map(|&l| g[l]).collect(),
                threshold,
                label: format!("γ² < {threshold}"),
            });
        }
    }
}

/// One panel per channel of excitation `e`: the measured FRF in `band` (solid) and the
/// synthesised one on `fit_hz` (dashed), as magnitude and phase.
fn fit_panels(
    geometry: &Geometry,
    frf: &FrfSet,
    e: usize,
    band: (f64, f64),
    fit_hz: &[f64],
    synthesised: &[Vec<rbprops_core::c64>],
) -> Vec<rbprops_plot::FrfPanel> {
    use rbprops_plot::{FrfPanel, FrfTrace, LineStyle, Rgb};
    let lines: Vec<usize> = (0..frf.n_lines())
        .filter(|&l| frf.frequency_hz[l] >= band.0 && frf.frequency_hz[l] <= band.1)
        .collect();
    let trace = |name: &str, hz: Vec<f64>, h: Vec<rbprops_core::c64>, style, color| FrfTrace {
        name: name.to_string(),
        frequency_hz: hz,
        magnitude: h.iter().map(|v| v.norm()).collect(),
        phase_deg: h.iter().map(|v| v.arg().to_degrees()).collect(),
        style,
        color: Some(color),
    };
    geometry
        .channels
        .iter()
        .enumerate()
        .map(|(c, ch)| {
            let measured = trace(
                "measured",
                lines.iter().map(|&l| frf.frequency_hz[l]).collect(),
                lines.iter().map(|&l| frf.frf(e, c)[l]).collect(),
                LineStyle::Solid,
                Rgb(40, 40, 40),
            );
            let mut traces = vec![measured];
            if let Some(s) = synthesised.get(c) {
                traces.push(trace(
                    "synthesised",
                    fit_hz.to_vec(),
                    s.clone(),
                    LineStyle::Dashed,
                    Rgb(214, 39, 40),
                ));
            }
            FrfPanel {
                title: format!("channel {}", ch.id),
                traces,
                quality: None,
            }
        })
        .collect()
}

/// Cells of the baseline residual map counted as "worst" for the overlays: those whose
/// noise-normalised residual is beyond z = 5 (the model check's own flag), strongest first.
pub const WORST_CELL_Z: f64 = 5.0;
/// At most this many (excitation, channel) pairs are overlaid.
pub const WORST_CELLS_SHOWN: usize = 6;

/// The model check's figures: residual maps before (baseline fit) and after (final
/// model) as heat maps of log10 χ²/n per channel × excitation, and the worst
/// (excitation, channel) pairs of the baseline residual as small multiples (magnitude and
/// phase per pair: measured, nominal spec, baseline fit, improved model).
pub fn model_check(
    out: &rbprops_check::CheckOutcome,
    g: &Geometry,
) -> Result<Vec<(String, String)>> {
    let mut files = Vec::new();
    if let Some(svg) = worst_channels(out, g)? {
        files.push(("check_worst_channels.svg".to_string(), svg));
    }
    for (name, svg) in residual_maps(&out.report, &out.layout)? {
        files.push((name, svg));
    }
    Ok(files)
}

/// The (excitation, channel) pairs whose baseline residual is worst (z > [`WORST_CELL_Z`],
/// strongest first, each pair once, at most [`WORST_CELLS_SHOWN`]).
pub fn worst_pairs(report: &rbprops_check::ModelCheckReport) -> Vec<(String, String)> {
    let mut cells: Vec<&rbprops_check::locate::ResidualCell> = report
        .residuals_before
        .cells
        .iter()
        .filter(|c| c.z > WORST_CELL_Z)
        .collect();
    cells.sort_by(|a, b| b.z.total_cmp(&a.z));
    let mut seen: Vec<(String, String)> = Vec::new();
    for c in cells {
        let key = (c.excitation.clone(), c.channel.clone());
        if !seen.contains(&key) && seen.len() < WORST_CELLS_SHOWN {
            seen.push(key);
        }
    }
    seen
}

/// Small multiples of the worst pairs ([`worst_pairs`]); `None` when no cell is flagged.
fn worst_channels(out: &rbprops_check::CheckOutcome, g: &Geometry) -> Result<Option<String>> {
    use rbprops_plot::{FrfPanel, FrfTrace, LineStyle, Rgb};
    let l = &out.layout;
    let nl = l.n_lines();
    let nch = l.channel_map.len();
    let pairs = worst_pairs(&out.report);
    if pairs.is_empty() {
        return Ok(None);
    }
    let mut panels = Vec::new();
    for (exc, chan) in &pairs {
        // The layout's arrays are [exc][ch][line] in the recording's order.
        let (Some(e), Some(c)) = (
            g.excitations.iter().position(|x| &x.id == exc),
            g.channels.iter().position(|x| &x.id == chan),
        ) else {
            continue;
        };
        let slice = |v: &[rbprops_core::c64]| -> Vec<rbprops_core::c64> {
            v[(e * nch + c) * nl..(e * nch + c + 1) * nl].to_vec()
        };
        let trace = |name: &str, h: Vec<rbprops_core::c64>, style, color| FrfTrace {
            name: name.to_string(),
            frequency_hz: l.frequency_hz.clone(),
            magnitude: h.iter().map(|v| v.norm()).collect(),
            phase_deg: h.iter().map(|v| v.arg().to_degrees()).collect(),
            style,
            color: Some(color),
        };
        panels.push(FrfPanel {
            title: format!("{exc} / {chan}"),
            traces: [
                ("measured", &out.measured, LineStyle::Solid, Rgb(40, 40, 40)),
                (
                    "nominal spec",
                    &out.nominal,
                    LineStyle::Dotted,
                    Rgb(31, 119, 180),
                ),
                (
                    "baseline fit",
                    &out.baseline,
                    LineStyle::Dashed,
                    Rgb(255, 127, 14),
                ),
                (
                    "improved",
                    &out.improved,
                    LineStyle::Dashed,
                    Rgb(214, 39, 40),
                ),
            ]
            .into_iter()
            .map(|(name, h, style, color)| trace(name, slice(h), style, color))
            .collect(),
            quality: None,
        });
    }
    if panels.is_empty() {
        return Ok(None);
    }
    let fig = rbprops_plot::FrfPanels {
        title: "Worst channels of the baseline fit: measured vs nominal vs improved".into(),
        magnitude_label: format!("|H| [{}]", l.quantity.unit()),
        panels,
        ..Default::default()
    };
    Ok(Some(rbprops_plot::frf_panels(&fig)?))
}

/// Residual maps before and after: χ²/n per channel (rows) × excitation (columns), as
/// log10 so that 0 is the noise level.
pub fn residual_maps(
    r: &rbprops_check::ModelCheckReport,
    l: &rbprops_check::predict::Layout,
) -> Result<Vec<(String, String)>> {
    use rbprops_plot::{heat_map, HeatMap};
    let mut files = Vec::new();
    for (name, map) in [
        ("before", &r.residuals_before),
        ("after", &r.residuals_after),
    ] {
        let rows: Vec<String> = l
            .channel_map
            .iter()
            .map(|&c| l.spec_geometry.channels[c].id.clone())
            .collect();
        let cols: Vec<String> = l
            .excitation_map
            .iter()
            .map(|&e| l.spec_geometry.excitations[e].id.clone())
            .collect();
        let values = rows
            .iter()
            .map(|ch| {
                cols.iter()
                    .map(|ex| {
                        let (mut n, mut c2) = (0usize, 0.0);
                        for c in map
                            .cells
                            .iter()
                            .filter(|c| &c.channel == ch && &c.excitation == ex)
                        {
                            n += c.n;
                            c2 += c.chi2;
                        }
                        if n > 0 {
                            (c2 / n as f64).log10()
                        } else {
                            f64::NAN
                        }
                    })
                    .collect()
            })
            .collect();
        let hm = HeatMap {
            title: format!(
                "noise-normalised residual {name} ({})",
                if name == "before" {
                    "baseline fit"
                } else {
                    "final model"
                }
            ),
            row_labels: rows,
            column_labels: cols,
            values,
            x_label: "excitation".into(),
            y_label: "channel".into(),
            value_label: "log10 χ²/n (0 = noise)".into(),
            decimals: 2,
            ..Default::default()
        };
        files.push((format!("residual_map_{name}.svg"), heat_map(&hm)?));
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dc_line_is_left_out_of_indicator_curves() {
        assert_eq!(lines_above_dc(&[0.0, 0.5, 1.0]), vec![1, 2]);
        assert_eq!(lines_above_dc(&[0.25, 0.5]), vec![0, 1]);
        assert_eq!(lines_above_dc(&[f64::NAN, 0.0, 2.0]), vec![2]);
    }

    #[test]
    fn decibel_axis_keeps_the_curves_not_the_zero_lines() {
        // A −400 dB zero line next to curves spanning 30 dB: the axis shows 80 dB.
        assert_eq!(
            decibel_window([-400.0, -20.0, 10.0, f64::NEG_INFINITY], 80.0),
            Some((-70.0, 13.0))
        );
        // Curves within the span keep the data extent.
        assert_eq!(decibel_window([-20.0, 10.0], 80.0), None);
        assert_eq!(decibel_window([f64::NAN], 80.0), None);
    }
}
