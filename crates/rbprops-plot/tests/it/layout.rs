//! Layout a reader relies on: legends never cover data, and small multiples give every
//! channel its own magnitude and phase axes.
use crate::common::*;
use rbprops_plot::*;

fn grid(n: usize, lo: f64, hi: f64) -> Vec<f64> {
    (0..n)
        .map(|i| lo + (hi - lo) * i as f64 / (n - 1) as f64)
        .collect()
}

/// Rightmost pixel of any data polyline (legend samples are short two-point lines).
fn data_right_edge(els: &[Element]) -> i32 {
    with_name(els, "polyline")
        .iter()
        .map(|p| p.points())
        .filter(|pts| pts.len() > 2)
        .flat_map(|pts| pts.into_iter().map(|q| q.0))
        .max()
        .expect("data polylines")
}

fn text_x(els: &[Element], text: &str) -> f64 {
    els.iter()
        .find(|e| e.name == "text" && e.text == text)
        .unwrap_or_else(|| panic!("no text {text}"))
        .num("x")
}

#[test]
fn default_legend_sits_right_of_the_data() {
    let f = grid(300, 1.0, 50.0);
    // Curves that fill the whole width, up to the top right corner, where an inside
    // legend would sit on them.
    let series = (0..18)
        .map(|k| {
            let y = f.iter().map(|x| (x * (k + 1) as f64).ln()).collect();
            Series::new(format!("channel {k} with a long name"), f.clone(), y)
        })
        .collect();
    let svg = line_plot(&LinePlot {
        title: "eighteen curves".into(),
        series,
        ..Default::default()
    })
    .unwrap();
    let els = parse(&svg);
    let right = data_right_edge(&els);
    let width: f64 = svg[..200]
        .split("width=\"")
        .nth(1)
        .and_then(|s| s.split('"').next())
        .unwrap()
        .parse()
        .unwrap();
    for k in 0..18 {
        let x = text_x(&els, &format!("channel {k} with a long name"));
        assert!(
            x > right as f64,
            "legend entry {k} at x = {x}, data reach {right}"
        );
        assert!(
            x < width,
            "legend entry {k} at x = {x} beyond the canvas ({width})"
        );
    }
}

#[test]
fn inside_legend_is_still_available() {
    let f = grid(50, 1.0, 50.0);
    let svg = line_plot(&LinePlot {
        series: vec![Series::new("a", f.clone(), f.clone())],
        legend: LegendPosition::UpperLeft,
        ..Default::default()
    })
    .unwrap();
    let els = parse(&svg);
    assert!(text_x(&els, "a") < data_right_edge(&els) as f64);
}

#[test]
fn stabilisation_legend_clears_the_secondary_axis() {
    let f = grid(100, 0.5, 10.0);
    let svg = stabilisation_diagram(&StabilisationDiagram {
        title: "st".into(),
        poles: (1..20)
            .map(|o| StabilisationPole {
                frequency_hz: 9.9,
                order: o,
                class: PoleClass::Stable,
            })
            .collect(),
        background: Some(BackgroundCurve {
            name: "sum".into(),
            frequency_hz: f.clone(),
            magnitude: f.iter().map(|x| 1.0 / x).collect(),
            axis_label: "right axis".into(),
        }),
        ..Default::default()
    })
    .unwrap();
    let els = parse(&svg);
    // The secondary axis' tick labels are the rightmost texts before the legend.
    let axis_label = text_x(&els, "right axis");
    for entry in [
        "stable freq., damping, shape",
        "stable freq., damping",
        "stable freq.",
        "new / unstable",
    ] {
        assert!(
            text_x(&els, entry) > axis_label,
            "{entry}: legend over the right axis"
        );
    }
    assert!(text_x(&els, "sum") > axis_label);
}

fn panels(n: usize) -> FrfPanels {
    let f = grid(400, 0.5, 20.0);
    let h = |k: usize, s: f64| -> (Vec<f64>, Vec<f64>) {
        let fr = 3.0 + k as f64;
        f.iter()
            .map(|&x| {
                let re = fr * fr - x * x;
                let im = 0.1 * fr * x;
                let d = re * re + im * im;
                (
                    s * (re * re + im * im).sqrt() / d,
                    (-im).atan2(re).to_degrees(),
                )
            })
            .unzip()
    };
    FrfPanels {
        title: "fit".into(),
        magnitude_label: "|H|".into(),
        panels: (0..n)
            .map(|k| {
                let (m, p) = h(k, 1.0);
                let (mf, pf) = h(k, 1.05);
                FrfPanel {
                    title: format!("channel {k}"),
                    traces: vec![
                        FrfTrace {
                            name: "measured".into(),
                            frequency_hz: f.clone(),
                            magnitude: m,
                            phase_deg: p,
                            ..Default::default()
                        },
                        FrfTrace {
                            name: "synthesised".into(),
                            frequency_hz: f.clone(),
                            magnitude: mf,
                            phase_deg: pf,
                            style: LineStyle::Dashed,
                            ..Default::default()
                        },
                    ],
                    ..Default::default()
                }
            })
            .collect(),
        ..Default::default()
    }
}

#[test]
fn small_multiples_give_each_channel_magnitude_and_phase() {
    let p = panels(7);
    let svg = frf_panels(&p).unwrap();
    let els = parse(&svg);
    // Seven panel titles, one shared legend entry per trace (not one per channel).
    for k in 0..7 {
        assert_eq!(
            els.iter()
                .filter(|e| e.name == "text" && e.text == format!("channel {k}"))
                .count(),
            1
        );
    }
    assert_eq!(
        els.iter()
            .filter(|e| e.name == "text" && e.text == "measured")
            .count(),
        1
    );
    assert_eq!(
        els.iter()
            .filter(|e| e.name == "text" && e.text == "Phase [°]")
            .count(),
        7
    );
    // 3 columns: 3 rows of panels on a canvas 3 panels wide.
    assert!(
        svg.starts_with("<svg width=\"1260\" height=\"1090\""),
        "{}",
        &svg[..60]
    );
    // Every panel has a dashed fit curve, and the phase charts label ±180° and 0°.
    let dashed = with_attr(&els, "polyline", "stroke-dasharray", "9 5");
    assert!(dashed.len() >= 14, "{} dashed pieces", dashed.len());
    for t in ["-180", "0", "180"] {
        assert_eq!(
            els.iter()
                .filter(|e| e.name == "text" && e.text == t)
                .count(),
            7,
            "{t}"
        );
    }
    // Same input, same bytes.
    assert_eq!(svg, frf_panels(&p).unwrap());
}

#[test]
fn small_multiples_report_bad_input() {
    let mut p = panels(2);
    p.panels[1].traces[0].phase_deg.pop();
    let e = frf_panels(&p).unwrap_err().to_string();
    assert!(e.contains("measured"), "{e}");
    let e = frf_panels(&FrfPanels::default()).unwrap_err().to_string();
    assert!(e.contains("panel"), "{e}");
}
