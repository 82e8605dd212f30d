//! Writes one SVG of each plot kind into the directory given as the first
//! argument (default: the current directory), for visual inspection:
//! `cargo run -p rbprops-plot --example gallery -- /tmp/gallery`.

use rbprops_plot::*;

/// Receptance magnitude of a 2-DOF-like sum of modes plus a mass line.
fn frf(f: f64, scale: f64) -> f64 {
    let modes = [(35.0, 0.02, 1.0), (82.0, 0.015, 0.6), (140.0, 0.03, 0.3)];
    let w = 2.0 * std::f64::consts::PI * f;
    let (mut re, mut im) = (-scale / (w * w).max(1e-9), 0.0);
    for (fr, z, a) in modes {
        let wr = 2.0 * std::f64::consts::PI * fr;
        let (dr, di) = (wr * wr - w * w, 2.0 * z * wr * w);
        let d2 = dr * dr + di * di;
        re += a * dr / d2;
        im -= a * di / d2;
    }
    (re * re + im * im).sqrt()
}

fn main() {
    let dir = std::path::PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| ".".into()));
    std::fs::create_dir_all(&dir).expect("create output directory");
    let write = |name: &str, svg: Result<String, PlotError>| {
        let svg = svg.unwrap_or_else(|e| panic!("{name}: {e}"));
        std::fs::write(dir.join(name), svg).expect("write svg");
    };

    let f: Vec<f64> = (0..=1000).map(|i| 2.0 + i as f64 * 0.198).collect();
    let meas: Vec<f64> = f
        .iter()
        .map(|&f| frf(f, 0.5) * (1.0 + 0.05 * (f * 0.7).sin()))
        .collect();
    let synth: Vec<f64> = f.iter().map(|&f| frf(f, 0.5)).collect();
    let mut meas2 = f.iter().map(|&f| frf(f, 0.8) * 0.7).collect::<Vec<_>>();
    meas2[500] = f64::NAN;
    let c0 = Rgb::palette(0);
    let c1 = Rgb::palette(1);
    write(
        "line_log.svg",
        line_plot(&LinePlot {
            title: "FRF magnitude, force F1".into(),
            x_label: "Frequency [Hz]".into(),
            y_label: "|H| [m/N]".into(),
            y_scale: Scale::Log10,
            series: vec![
                Series::new("x1 measured", f.clone(), meas.clone()).with_color(c0),
                Series::new("x1 synthesised", f.clone(), synth.clone())
                    .with_color(c0)
                    .with_style(LineStyle::Dashed),
                Series::new("x2 measured", f.clone(), meas2.clone()).with_color(c1),
            ],
            markers: vec![
                VerticalMarker::new(35.0, "35.0 Hz"),
                VerticalMarker::new(82.0, "82.0 Hz"),
                VerticalMarker::new(140.0, "140.0 Hz"),
            ],
            ..Default::default()
        }),
    );
    write(
        "line_db.svg",
        line_plot(&LinePlot {
            title: "FRF magnitude (dB)".into(),
            x_label: "Frequency [Hz]".into(),
            y_label: "|H| [dB re 1 m/N]".into(),
            y_scale: Scale::Decibel,
            series: vec![Series::new("x1", f.clone(), meas.clone())],
            legend: LegendPosition::LowerLeft,
            ..Default::default()
        }),
    );

    let mut poles = Vec::new();
    for order in 2..=30usize {
        for (k, fr) in [35.0, 82.0, 140.0].iter().enumerate() {
            if order < 4 + 4 * k {
                continue;
            }
            let class = match order - (4 + 4 * k) {
                0 => PoleClass::New,
                1 => PoleClass::Frequency,
                2 => PoleClass::FrequencyDamping,
                _ => PoleClass::Stable,
            };
            poles.push(StabilisationPole {
                frequency_hz: fr + 0.3 * ((order * 7 + k) as f64).sin(),
                order,
                class,
            });
        }
        poles.push(StabilisationPole {
            frequency_hz: 10.0 + ((order * 37) % 190) as f64,
            order,
            class: PoleClass::New,
        });
    }
    write(
        "stabilisation.svg",
        stabilisation_diagram(&StabilisationDiagram {
            title: "PolyMAX stabilisation".into(),
            poles,
            background: Some(BackgroundCurve {
                name: "Σ|H|".into(),
                frequency_hz: f.clone(),
                magnitude: synth.clone(),
                axis_label: "Σ|H| [m/N]".into(),
            }),
            selected: vec![
                VerticalMarker::new(35.0, "mode 1"),
                VerticalMarker::new(82.0, "mode 2"),
                VerticalMarker::new(140.0, "mode 3"),
            ],
            ..Default::default()
        }),
    );

    write(
        "heat_map.svg",
        heat_map(&HeatMap {
            title: "Excitation strength per mode".into(),
            row_labels: (1..=6).map(|m| format!("mode {m}")).collect(),
            column_labels: (1..=8).map(|e| format!("F{e}")).collect(),
            values: (0..6)
                .map(|r| {
                    (0..8)
                        .map(|c| {
                            if r == 2 && c == 5 {
                                f64::NAN
                            } else {
                                -40.0 + 5.0 * ((r * 3 + c * 5) % 9) as f64
                            }
                        })
                        .collect()
                })
                .collect(),
            x_label: "Excitation".into(),
            y_label: "Mode".into(),
            value_label: "Strength [dB]".into(),
            decimals: 1,
            ..Default::default()
        }),
    );

    let sets: Vec<String> = ["I", "II", "III", "IV", "V"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    write(
        "bar_chart.svg",
        bar_chart(&BarChart {
            title: "Mass estimate per data set".into(),
            groups: sets.clone(),
            series: (0..3)
                .map(|o| {
                    BarSeries::new(
                        format!("origin {}", ["I", "II", "III"][o]),
                        (0..5)
                            .map(|g| 12.0 + 0.3 * ((g * 3 + o) as f64).sin())
                            .collect(),
                    )
                    .with_errors((0..5).map(|g| 0.1 + 0.05 * g as f64).collect())
                })
                .collect(),
            x_label: "Data set".into(),
            y_label: "m [kg]".into(),
            references: vec![ReferenceLine {
                y: 12.1,
                label: "true value".into(),
            }],
            y_range: Some((11.0, 13.0)),
            legend: LegendPosition::LowerRight,
            ..Default::default()
        }),
    );
    write(
        "scatter.svg",
        scatter_plot(&ScatterPlot {
            title: "Estimated vs true inertia".into(),
            x_label: "true [kg m²]".into(),
            y_label: "estimated [kg m²]".into(),
            series: vec![
                ScatterSeries::new("Ixx, Iyy, Izz", vec![0.5, 0.8, 1.1], vec![0.52, 0.77, 1.13])
                    .with_errors(vec![0.03, 0.04, 0.05]),
                ScatterSeries::new("products", vec![-0.05, 0.02, 0.1], vec![-0.04, 0.03, 0.08]),
            ],
            identity_line: true,
            legend: LegendPosition::UpperLeft,
            ..Default::default()
        }),
    );
}
