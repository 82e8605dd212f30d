use crate::common::*;
use rbprops_plot::*;

fn diagram() -> StabilisationDiagram {
    let mut poles = Vec::new();
    for order in 1..=20usize {
        poles.push(StabilisationPole {
            frequency_hz: 30.0,
            order,
            class: if order < 3 {
                PoleClass::New
            } else {
                PoleClass::Stable
            },
        });
        poles.push(StabilisationPole {
            frequency_hz: 60.0 + order as f64,
            order,
            class: PoleClass::Frequency,
        });
        if order % 4 == 0 {
            poles.push(StabilisationPole {
                frequency_hz: 90.0,
                order,
                class: PoleClass::FrequencyDamping,
            });
        }
    }
    let f: Vec<f64> = (0..200).map(|i| 1.0 + i as f64 * 0.5).collect();
    StabilisationDiagram {
        title: "Stabilisation".into(),
        poles,
        background: Some(BackgroundCurve {
            name: "sum of FRFs".into(),
            magnitude: f
                .iter()
                .map(|&f| 1e-3 / (1.0 + (f - 30.0).powi(2)))
                .collect(),
            frequency_hz: f,
            axis_label: "Σ|H| [m/N]".into(),
        }),
        selected: vec![VerticalMarker::new(30.0, "mode 1")],
        ..Default::default()
    }
}

#[test]
fn stabilisation_letters_per_class_background_and_selection() {
    let d = diagram();
    let svg = stabilisation_diagram(&d).unwrap();
    let els = parse(&svg);
    assert_has_texts(
        &els,
        &[
            "Stabilisation",
            "sum of FRFs",
            "Σ|H| [m/N]",
            "mode 1",
            "Model order",
            "Frequency [Hz]",
        ],
    );
    for class in PoleClass::ALL {
        let n = d.poles.iter().filter(|p| p.class == class).count();
        let drawn = with_attr(&els, "text", "fill", &class.color().hex())
            .into_iter()
            .filter(|t| t.text == class.symbol())
            .count();
        // One letter per pole plus the legend key.
        assert_eq!(drawn, n + 1, "{class:?}");
    }
    // Background curve (one polyline + legend sample), one selected-pole line.
    assert_eq!(with_attr(&els, "polyline", "stroke", "#969696").len(), 2);
    assert_eq!(
        with_attr(&els, "polyline", "stroke-dasharray", "5 4").len(),
        1
    );
    // The background is drawn before (behind) the pole letters.
    let first_curve = svg.find("stroke=\"#969696\"").unwrap();
    let first_letter = svg
        .find(&format!("fill=\"{}\"", PoleClass::Stable.color().hex()))
        .unwrap();
    assert!(first_curve < first_letter);
    // Letters at the same frequency share a pixel column; higher order is higher up.
    let stable: Vec<&Element> = with_attr(&els, "text", "fill", &PoleClass::Stable.color().hex())
        .into_iter()
        .filter(|t| t.text == "s")
        .collect();
    let xs: Vec<f64> = stable[..18].iter().map(|t| t.num("x")).collect();
    assert!(xs.iter().all(|&x| x == xs[0]));
    assert!(stable[..18]
        .windows(2)
        .all(|w| w[1].num("y") < w[0].num("y")));
    assert_eq!(svg, stabilisation_diagram(&d).unwrap(), "deterministic");
}

#[test]
fn stabilisation_bad_data() {
    let mut d = diagram();
    d.poles[1].frequency_hz = f64::NAN;
    d.x_range = Some((0.0, 80.0)); // drops the 90 Hz "d" poles (5) and 60+order > 80 (0)
    let svg = stabilisation_diagram(&d).unwrap();
    parse(&svg);
    assert!(
        svg.contains("6 points not shown"),
        "NaN pole + five 90 Hz poles"
    );
    d.poles.clear();
    assert!(matches!(
        stabilisation_diagram(&d),
        Err(PlotError::Empty { .. })
    ));
    let mut d = diagram();
    d.background.as_mut().unwrap().magnitude.pop();
    assert!(matches!(
        stabilisation_diagram(&d),
        Err(PlotError::LengthMismatch { .. })
    ));
    // Without a background curve there is no right axis.
    let mut d = diagram();
    d.background = None;
    let els = parse(&stabilisation_diagram(&d).unwrap());
    assert!(!texts(&els).iter().any(|t| t.contains("Σ|H|")));
}

fn heat() -> HeatMap {
    HeatMap {
        title: "Strength".into(),
        row_labels: vec!["mode 1".into(), "mode 2".into()],
        column_labels: vec!["F1".into(), "F2".into(), "F3".into()],
        values: vec![vec![-10.0, -20.5, 0.0], vec![-30.0, f64::NAN, -5.25]],
        value_label: "strength [dB]".into(),
        decimals: 1,
        ..Default::default()
    }
}

#[test]
fn heat_map_cells_values_colours_and_scale() {
    let h = heat();
    let svg = heat_map(&h).unwrap();
    let els = parse(&svg);
    assert_has_texts(
        &els,
        &[
            "Strength",
            "mode 1",
            "mode 2",
            "F1",
            "F3",
            "strength [dB]",
            "-10.0",
            "-20.5",
            "0.0",
            "-30.0",
            "n/a",
            "-5.2",
        ],
    );
    // Extremes take the ends of the colour map; NaN is grey.
    let fills = |c: Rgb| with_attr(&els, "rect", "fill", &c.hex()).len();
    assert!(fills(viridis(1.0)) >= 1, "max cell");
    assert!(fills(viridis(0.0)) >= 1, "min cell");
    assert_eq!(fills(Rgb(200, 200, 200)), 1, "NaN cell");
    // Cells: 6 value rects + 64 colour-bar bands + background.
    assert_eq!(with_name(&els, "rect").len(), 6 + 64 + 1);
    // Row 0 is on top: "-10.0" (row 0) above "-30.0" (row 1).
    let y_of = |s: &str| {
        with_name(&els, "text")
            .into_iter()
            .find(|t| t.text == s)
            .unwrap()
            .num("y")
    };
    assert!(y_of("-10.0") < y_of("-30.0"));
    assert!(y_of("mode 1") < y_of("mode 2"));
    assert!(svg.contains("1 cell has no finite value"));
    assert_eq!(svg, heat_map(&h).unwrap());
}

#[test]
fn heat_map_shape_errors() {
    let mut h = heat();
    h.values[1].pop();
    let e = heat_map(&h).unwrap_err();
    assert!(e.to_string().contains("row 1 ('mode 2')"), "{e}");
    let mut h = heat();
    h.values.pop();
    assert!(matches!(
        heat_map(&h),
        Err(PlotError::LengthMismatch { what: "rows", .. })
    ));
    let mut h = heat();
    h.column_labels.clear();
    assert!(matches!(heat_map(&h), Err(PlotError::Empty { .. })));
    let mut h = heat();
    h.values = vec![vec![f64::NAN; 3]; 2];
    assert!(matches!(
        heat_map(&h),
        Err(PlotError::NoPlottableData { skipped: 6, .. })
    ));
}

const C: [Rgb; 3] = [Rgb(10, 20, 30), Rgb(40, 50, 60), Rgb(70, 80, 90)];

fn bars() -> BarChart {
    BarChart {
        title: "Mass per set".into(),
        groups: vec!["I".into(), "II".into(), "III".into(), "IV".into()],
        series: (0..3)
            .map(|o| {
                BarSeries::new(format!("origin {o}"), vec![10.0, 11.0, -2.0, 12.0])
                    .with_errors(vec![0.5, f64::NAN, 0.2, 0.1])
                    .with_color(C[o])
            })
            .collect(),
        x_label: "Data set".into(),
        y_label: "m [kg]".into(),
        references: vec![ReferenceLine {
            y: 10.5,
            label: "true value".into(),
        }],
        ..Default::default()
    }
}

#[test]
fn bar_chart_bars_error_bars_reference_and_labels() {
    let b = bars();
    let svg = bar_chart(&b).unwrap();
    let els = parse(&svg);
    assert_has_texts(
        &els,
        &[
            "Mass per set",
            "I",
            "II",
            "III",
            "IV",
            "origin 0",
            "origin 2",
            "true value",
            "m [kg]",
            "Data set",
        ],
    );
    for c in C {
        // four bars + legend swatch
        assert_eq!(with_attr(&els, "rect", "fill", &c.hex()).len(), 5);
    }
    // Error bars: 3 finite per series (the NaN one is dropped), black whiskers.
    let whiskers = with_attr(&els, "polyline", "stroke", "#000000")
        .into_iter()
        .filter(|p| p.points().len() == 6)
        .count();
    assert_eq!(whiskers, 9);
    // Reference line dashed, plus legend sample.
    assert_eq!(
        with_attr(&els, "polyline", "stroke-dasharray", "9 5").len(),
        2
    );
    // Bars grow from zero: the negative bar hangs below the positive ones' base.
    let r = with_attr(&els, "rect", "fill", &C[0].hex());
    let base_pos = r[0].num("y") + r[0].num("height");
    assert_eq!(
        r[2].num("y"),
        base_pos,
        "negative bar starts at the zero line"
    );
    // Bar heights proportional to values: 10 vs 12 (same series).
    let h = |e: &Element| e.num("height");
    assert!(
        (h(r[3]) / h(r[0]) - 1.2).abs() < 0.02,
        "{} {}",
        h(r[3]),
        h(r[0])
    );
    assert_eq!(svg, bar_chart(&b).unwrap());
}

#[test]
fn bar_chart_bad_data() {
    let mut b = bars();
    b.series[1].values[3] = f64::NAN;
    let svg = bar_chart(&b).unwrap();
    let els = parse(&svg);
    assert_eq!(with_attr(&els, "rect", "fill", &C[1].hex()).len(), 4);
    assert!(svg.contains("1 point not shown"));
    let mut b = bars();
    b.series[2].errors = Some(vec![1.0]);
    let e = bar_chart(&b).unwrap_err();
    assert!(
        e.to_string()
            .contains("'origin 2': errors has 1 entries, expected 4"),
        "{e}"
    );
    let mut b = bars();
    b.groups.clear();
    assert!(matches!(
        bar_chart(&b),
        Err(PlotError::Empty {
            what: "group list",
            ..
        })
    ));
}

#[test]
fn scatter_points_error_bars_identity() {
    let p = ScatterPlot {
        title: "est vs true".into(),
        x_label: "true".into(),
        y_label: "estimated".into(),
        series: vec![
            ScatterSeries::new("a", vec![1.0, 2.0, 3.0, f64::NAN], vec![1.1, 1.9, 3.2, 1.0])
                .with_errors(vec![0.1, 0.2, 0.0, 0.1])
                .with_color(C[0]),
            ScatterSeries::new("b", vec![0.5], vec![0.4]).with_color(C[1]),
        ],
        identity_line: true,
        ..Default::default()
    };
    let svg = scatter_plot(&p).unwrap();
    let els = parse(&svg);
    assert_has_texts(&els, &["est vs true", "a", "b", "y = x"]);
    assert_eq!(with_attr(&els, "circle", "fill", &C[0].hex()).len(), 3 + 1);
    assert_eq!(with_attr(&els, "circle", "fill", &C[1].hex()).len(), 1 + 1);
    // zero-width error is not drawn
    assert_eq!(
        with_attr(&els, "polyline", "stroke", "#000000")
            .iter()
            .filter(|p| p.points().len() == 6)
            .count(),
        2
    );
    assert!(svg.contains("1 point not shown"));
    // Identity line passes through the points (1,1)... check it is a diagonal:
    let id = &with_attr(&els, "polyline", "stroke-dasharray", "9 5")[0].points();
    let (a, b) = (id[0], id[1]);
    // Equal axis ranges, so the pixel slope equals -(plot height / plot width).
    assert!(b.0 > a.0 && b.1 < a.1);
    // A point on y = x sits on the identity line.
    let q = ScatterPlot {
        series: vec![
            ScatterSeries::new("on", vec![1.0, 2.0, 3.0], vec![1.0, 2.0, 3.0]).with_color(C[2]),
        ],
        ..p.clone()
    };
    let els = parse(&scatter_plot(&q).unwrap());
    let line = with_attr(&els, "polyline", "stroke-dasharray", "9 5")[0].points();
    let (a, b) = (line[0], line[1]);
    for c in with_attr(&els, "circle", "fill", &C[2].hex())
        .iter()
        .take(3)
    {
        let (cx, cy) = (c.num("cx"), c.num("cy"));
        let t = (cx - a.0 as f64) / (b.0 - a.0) as f64;
        let expect = a.1 as f64 + t * (b.1 - a.1) as f64;
        assert!(
            (cy - expect).abs() <= 1.5,
            "point off the diagonal by {}",
            cy - expect
        );
    }
    assert_eq!(svg, scatter_plot(&p).unwrap());
    let e = scatter_plot(&ScatterPlot {
        series: vec![ScatterSeries::new("x", vec![1.0], vec![1.0]).with_errors(vec![])],
        ..Default::default()
    })
    .unwrap_err();
    assert!(matches!(
        e,
        PlotError::LengthMismatch {
            what: "y_errors",
            ..
        }
    ));
}

/// A categorical x axis (a campaign's recordings): one labelled category per name, the
/// points at their category's centre, evenly spaced, whatever numbers the names hold.
#[test]
fn scatter_on_categories() {
    let names = ["run-01.uff", "run-02.uff", "run-10.uff"];
    let p = ScatterPlot {
        title: "mass per recording".into(),
        x_label: "recording".into(),
        y_label: "m [kg]".into(),
        series: vec![
            ScatterSeries::new("a", vec![0.0, 1.0, 2.0], vec![1.0, 1.1, 0.9]).with_color(C[0]),
        ],
        x_categories: names.iter().map(|s| s.to_string()).collect(),
        ..Default::default()
    };
    let els = parse(&scatter_plot(&p).unwrap());
    assert_has_texts(&els, &names);
    // The three points, then the legend's glyph.
    let cx: Vec<f64> = with_attr(&els, "circle", "fill", &C[0].hex())
        .iter()
        .take(3)
        .map(|c| c.num("cx"))
        .collect();
    let (d1, d2) = (cx[1] - cx[0], cx[2] - cx[1]);
    assert!(d1 > 10.0 && (d1 - d2).abs() <= 1.0, "{cx:?}");
    // No numeric tick labels on x: the only labels there are the names.
    assert!(!texts(&els).iter().any(|t| t == "0.5" || t == "1.5"));
}
