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

/// Estimates with 95 % error bars: mass, CoM and the six tensor entries, one group per
/// property, one bar per estimator (relative to the first estimate, so scales mix).
pub fn estimates(list: &[rbprops_core::records::InertiaEstimate]) -> Result<Vec<(String, String)>> {
    use rbprops_plot::{bar_chart, BarChart, BarSeries};
    let names = [
        "m", "cx", "cy", "cz", "Jxx", "Jyy", "Jzz", "Jxy", "Jxz", "Jyz",
    ];
    let values = |e: &rbprops_core::records::InertiaEstimate| -> ([f64; 10], [f64; 10]) {
        let j = &e.inertia_cm_kg_m2;
        let s = &e.inertia_cm_std_kg_m2;
        (
            [
                e.mass_kg, e.com_m[0], e.com_m[1], e.com_m[2], j[0][0], j[1][1], j[2][2], j[0][1],
                j[0][2], j[1][2],
            ],
            [
                e.mass_std_kg,
                e.com_std_m[0],
                e.com_std_m[1],
                e.com_std_m[2],
                s[0][0],
                s[1][1],
                s[2][2],
                s[0][1],
                s[0][2],
                s[1][2],
            ],
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
            BarSeries::new(e.method.clone(), (0..10).map(|i| v[i] / scale[i]).collect())
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
    let ni = LinePlot {
        title: "Norm Indicator (Eq. 12)".into(),
        x_label: "Frequency [Hz]".into(),
        y_label: format!("NI [dB re 1 {}]", c.quantity.unit()),
        series: c
            .excitations
            .iter()
            .map(|e| {
                Series::new(
                    format!("{} ({})", e.excitation, e.setup),
                    f.clone(),
                    e.ni_db.clone(),
                )
            })
            .collect(),
        markers: markers.clone(),
        ..Default::default()
    };
    plots.push(("ni.svg".to_string(), line_plot(&ni)?));
    for (name, title, pick) in [
        ("hybrid_mif", "Hybrid MIF (Rades 1994)", 0usize),
        ("prf_mif", "PRF MIF (Rades & Ewins 2000)", 1usize),
    ] {
        let p = LinePlot {
            title: title.into(),
            x_label: "Frequency [Hz]".into(),
            y_label: "MIF [-]".into(),
            series: c
                .excitations
                .iter()
                .map(|e| {
                    Series::new(
                        e.excitation.clone(),
                        f.clone(),
                        if pick == 0 {
                            e.hybrid_mif.clone()
                        } else {
                            e.prf_mif.clone()
                        },
                    )
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
        let band_lines: Vec<usize> = (0..frf.n_lines())
            .filter(|&l| {
                frf.frequency_hz[l] >= d.frequency_hz[0]
                    && frf.frequency_hz[l] <= *d.frequency_hz.last().unwrap()
            })
            .collect();
        let mut series = Vec::new();
        for (c, ch) in geometry.channels.iter().enumerate() {
            let color = rbprops_plot::Rgb::palette(c);
            series.push(
                Series::new(
                    ch.id.clone(),
                    band_lines.iter().map(|&l| frf.frequency_hz[l]).collect(),
                    band_lines
                        .iter()
                        .map(|&l| frf.frf(e, c)[l].norm())
                        .collect(),
                )
                .with_color(color),
            );
            if let Some(s) = d.synthesised.get(c) {
                series.push(
                    Series::new(
                        format!("{} fit", ch.id),
                        d.frequency_hz.clone(),
                        s.iter().map(|v| v.norm()).collect(),
                    )
                    .with_style(rbprops_plot::LineStyle::Dashed)
                    .with_color(color),
                );
            }
        }
        let overlay = LinePlot {
            title: format!(
                "Measured (solid) vs synthesised (dashed), excitation {}",
                d.excitation
            ),
            x_label: "Frequency [Hz]".into(),
            y_label: format!("|H| [{}]", frf.quantity.unit()),
            y_scale: Scale::Log10,
            series,
            ..Default::default()
        };
        plots.push((format!("fit_{name}.svg"), line_plot(&overlay)?));
    }
    Ok(plots)
}
