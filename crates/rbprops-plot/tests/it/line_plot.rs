use crate::common::*;
use rbprops_plot::*;

fn grid(n: usize, lo: f64, hi: f64) -> Vec<f64> {
    (0..n)
        .map(|i| lo + (hi - lo) * i as f64 / (n - 1) as f64)
        .collect()
}

const RED: Rgb = Rgb(200, 0, 0);
const BLUE: Rgb = Rgb(0, 0, 200);
const GREEN: Rgb = Rgb(0, 150, 0);

fn overlay() -> LinePlot {
    let f = grid(200, 1.0, 100.0);
    let h = |s: f64| {
        f.iter()
            .map(|&f| s / (1.0 + (f - 40.0).powi(2)))
            .collect::<Vec<_>>()
    };
    LinePlot {
        title: "FRF overlay F1".into(),
        x_label: "Frequency [Hz]".into(),
        y_label: "|H| [m/N]".into(),
        y_scale: Scale::Log10,
        series: vec![
            Series::new("measured x1", f.clone(), h(1.0)).with_color(RED),
            Series::new("synthesised x1", f.clone(), h(1.1))
                .with_color(BLUE)
                .with_style(LineStyle::Dashed),
            Series::new("measured x2", f.clone(), h(0.5)).with_color(GREEN),
        ],
        markers: vec![
            VerticalMarker::new(40.0, "40.0 Hz"),
            VerticalMarker::new(70.0, ""),
            VerticalMarker::new(500.0, "outside"),
        ],
        ..Default::default()
    }
}

#[test]
fn overlay_has_title_legend_one_polyline_per_series_and_markers() {
    let p = overlay();
    let svg = line_plot(&p).unwrap();
    let els = parse(&svg);
    assert_has_texts(
        &els,
        &[
            "FRF overlay F1",
            "measured x1",
            "synthesised x1",
            "measured x2",
            "Frequency [Hz]",
            "|H| [m/N]",
            "40.0 Hz",
        ],
    );
    // One data polyline plus one legend sample per series.
    for c in [RED, BLUE, GREEN] {
        let lines = with_attr(&els, "polyline", "stroke", &c.hex());
        assert_eq!(lines.len(), 2, "colour {}", c.hex());
        assert_eq!(lines[0].points().len(), 200);
        let dashed = lines[0].attr("stroke-dasharray").is_some();
        assert_eq!(dashed, c == BLUE, "only the synthesised series is dashed");
    }
    // Two in-range markers drawn, the one at 500 Hz is outside the data range.
    assert_eq!(
        with_attr(&els, "polyline", "stroke-dasharray", "5 4").len(),
        2
    );
    assert!(!texts(&els).iter().any(|t| t == "outside"));
    // Decade labels on a log axis.
    assert!(texts(&els).iter().any(|t| t == "10⁻¹"), "{:?}", texts(&els));
    // Nothing skipped: no footnote.
    assert!(!svg.contains("not shown"));
}

#[test]
fn output_is_deterministic() {
    let a = line_plot(&overlay()).unwrap();
    let b = line_plot(&overlay().clone()).unwrap();
    assert_eq!(a, b);
}

/// A straight line in axis units must be drawn as collinear pixels: this checks
/// the log10 and dB transforms and the coordinate mapping end to end.
#[test]
fn scales_map_exponentials_to_straight_lines() {
    let x = grid(50, 0.0, 10.0);
    for (scale, y) in [
        (
            Scale::Linear,
            x.iter().map(|&x| 3.0 * x - 7.0).collect::<Vec<_>>(),
        ),
        (
            Scale::Log10,
            x.iter().map(|&x| 10f64.powf(-0.4 * x)).collect(),
        ),
        (
            Scale::Decibel,
            x.iter().map(|&x| 10f64.powf(x / 20.0 * 3.0)).collect(),
        ),
    ] {
        let p = LinePlot {
            title: format!("{scale:?}"),
            y_scale: scale,
            series: vec![Series::new("s", x.clone(), y).with_color(RED)],
            ..Default::default()
        };
        let els = parse(&line_plot(&p).unwrap());
        let pts = with_attr(&els, "polyline", "stroke", &RED.hex())[0].points();
        assert_eq!(pts.len(), 50);
        let (a, b) = (pts[0], pts[49]);
        for &(px, py) in &pts {
            let t = (px - a.0) as f64 / (b.0 - a.0) as f64;
            let expect = a.1 as f64 + t * (b.1 - a.1) as f64;
            assert!(
                (py as f64 - expect).abs() <= 1.5,
                "{scale:?}: ({px},{py}) off line by {}",
                py as f64 - expect
            );
        }
        // x strictly increasing; y decreasing in pixels when the value rises.
        assert!(pts.windows(2).all(|w| w[1].0 >= w[0].0));
        assert!(b.0 - a.0 > 700, "curve spans the plot width");
    }
}

#[test]
fn nan_breaks_the_curve_and_is_counted() {
    let x = grid(20, 0.0, 19.0);
    let mut y: Vec<f64> = x.iter().map(|v| v + 1.0).collect();
    y[5] = f64::NAN;
    y[12] = f64::INFINITY;
    let p = LinePlot {
        title: "gaps".into(),
        series: vec![Series::new("s", x, y).with_color(RED)],
        ..Default::default()
    };
    let svg = line_plot(&p).unwrap();
    let els = parse(&svg);
    let lines = with_attr(&els, "polyline", "stroke", &RED.hex());
    // pieces [0..5), [6..12), [13..20) plus the legend sample
    let lens: Vec<usize> = lines.iter().map(|l| l.points().len()).collect();
    assert_eq!(lens, vec![5, 6, 7, 2]);
    assert!(svg.contains("2 points not shown"), "footnote");
}

#[test]
fn log_axis_skips_non_positive_values() {
    let x = grid(10, 1.0, 10.0);
    let y = vec![1.0, 0.0, -2.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0];
    for scale in [Scale::Log10, Scale::Decibel] {
        let p = LinePlot {
            title: "log".into(),
            y_scale: scale,
            series: vec![Series::new("s", x.clone(), y.clone()).with_color(RED)],
            ..Default::default()
        };
        let svg = line_plot(&p).unwrap();
        let els = parse(&svg);
        let lens: Vec<usize> = with_attr(&els, "polyline", "stroke", &RED.hex())
            .iter()
            .map(|l| l.points().len())
            .collect();
        assert_eq!(lens, vec![1, 7, 2], "{scale:?}");
        assert!(svg.contains("2 points not shown"));
    }
}

#[test]
fn fixed_ranges_clip_inside_the_plot_area() {
    let x = grid(101, 0.0, 100.0);
    let y: Vec<f64> = x.iter().map(|v| (v * 0.2).sin() * 10.0).collect();
    let wide = LinePlot {
        title: "clip".into(),
        series: vec![Series::new("s", x.clone(), y.clone()).with_color(RED)],
        ..Default::default()
    };
    let clipped = LinePlot {
        x_range: Some((20.0, 80.0)),
        y_range: Some((-5.0, 5.0)),
        ..wide.clone()
    };
    let els_w = parse(&line_plot(&wide).unwrap());
    let els_c = parse(&line_plot(&clipped).unwrap());
    let all_w = with_attr(&els_w, "polyline", "stroke", &RED.hex());
    let pieces = with_attr(&els_c, "polyline", "stroke", &RED.hex());
    assert_eq!(all_w.len(), 2);
    // |10 sin(0.2x)| <= 5 near the zeros x = 5kπ, k = 2..5, inside 20..80 Hz:
    // exactly four visible pieces (+ the legend sample).
    assert_eq!(pieces.len(), 5);
    let starts: Vec<i32> = pieces[..4].iter().map(|p| p.points()[0].0).collect();
    assert!(starts.windows(2).all(|w| w[1] > w[0]));
    let ys: Vec<i32> = pieces[..pieces.len() - 1]
        .iter()
        .flat_map(|p| p.points())
        .map(|p| p.1)
        .collect();
    let (lo, hi) = (ys.iter().min().unwrap(), ys.iter().max().unwrap());
    // Pieces end on the clip borders: 3 times at -5 (bottom), 4 times at +5 (top).
    assert_eq!(ys.iter().filter(|y| *y == hi).count(), 3);
    assert_eq!(ys.iter().filter(|y| *y == lo).count(), 4);
}

#[test]
fn errors_name_the_plot_and_series() {
    let base = LinePlot {
        title: "bad".into(),
        ..Default::default()
    };
    assert!(matches!(line_plot(&base), Err(PlotError::Empty { .. })));
    let e = line_plot(&LinePlot {
        series: vec![Series::new("empty one", vec![], vec![])],
        ..base.clone()
    })
    .unwrap_err();
    assert_eq!(
        e,
        PlotError::EmptySeries {
            plot: "bad".into(),
            series: "empty one".into()
        }
    );
    let e = line_plot(&LinePlot {
        series: vec![Series::new("short", vec![1.0, 2.0], vec![1.0])],
        ..base.clone()
    })
    .unwrap_err();
    assert!(
        e.to_string().contains("'short'") && e.to_string().contains("expected 2"),
        "{e}"
    );
    let e = line_plot(&LinePlot {
        series: vec![Series::new("nan", vec![1.0, 2.0], vec![f64::NAN, f64::NAN])],
        ..base.clone()
    })
    .unwrap_err();
    assert_eq!(
        e,
        PlotError::NoPlottableData {
            plot: "bad".into(),
            skipped: 2
        }
    );
    let e = line_plot(&LinePlot {
        y_scale: Scale::Log10,
        y_range: Some((-1.0, 1.0)),
        series: vec![Series::new("s", vec![1.0, 2.0], vec![1.0, 2.0])],
        ..base.clone()
    })
    .unwrap_err();
    assert!(matches!(e, PlotError::InvalidRange { axis: "y", .. }));
    let e = line_plot(&LinePlot {
        size: PlotSize {
            width: 50,
            height: 50,
        },
        series: vec![Series::new("s", vec![1.0, 2.0], vec![1.0, 2.0])],
        ..base
    })
    .unwrap_err();
    assert!(matches!(e, PlotError::InvalidSize { .. }));
}

#[test]
fn text_is_escaped_and_default_palette_used() {
    let p = LinePlot {
        title: "a <b> & c".into(),
        series: vec![
            Series::new("one", vec![0.0, 1.0], vec![0.0, 1.0]),
            Series::new("two", vec![0.0, 1.0], vec![1.0, 0.0]),
        ],
        ..Default::default()
    };
    let svg = line_plot(&p).unwrap();
    let els = parse(&svg);
    assert_has_texts(&els, &["a &lt;b&gt; &amp; c"]);
    assert_eq!(
        with_attr(&els, "polyline", "stroke", &Rgb::palette(0).hex()).len(),
        2
    );
    assert_eq!(
        with_attr(&els, "polyline", "stroke", &Rgb::palette(1).hex()).len(),
        2
    );
    // Text needs no font files: plotters' SVG backend only writes the family name.
    assert!(with_name(&els, "text")
        .iter()
        .all(|t| t.attr("font-family") == Some("sans-serif")));
}
