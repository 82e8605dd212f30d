//! Low-quality shading of FRF panels: the lines whose quality (coherence γ²) is below the
//! threshold are light spans behind the curves, where they should be.
use crate::common::*;
use rbprops_plot::*;

/// 1 … 20 Hz in 0.1 Hz steps (191 lines).
fn axis() -> Vec<f64> {
    (0..191).map(|k| 1.0 + 0.1 * k as f64).collect()
}

/// γ² low on lines 20–29 (3.0–3.9 Hz), line 100 (11.0 Hz) and 186–190 (19.6–20.0 Hz,
/// the end of the axis); exactly the threshold on line 50 and NaN on line 60 (neither
/// shaded).
fn quality() -> LineQuality {
    let mut value = vec![0.99; 191];
    for k in (20..=29).chain([100]).chain(186..=190) {
        value[k] = 0.5;
    }
    value[50] = 0.9;
    value[60] = f64::NAN;
    LineQuality {
        frequency_hz: axis(),
        value,
        threshold: 0.9,
        label: "γ² < 0.9".into(),
    }
}

#[test]
fn spans_cover_the_low_lines_to_the_half_spacing() {
    let s = low_quality_spans(&quality());
    let want = [(2.95, 3.95), (10.95, 11.05), (19.55, 20.05)];
    assert_eq!(s.len(), 3, "{s:?}");
    for (a, b) in s.iter().zip(want) {
        assert!(
            (a.0 - b.0).abs() < 1e-12 && (a.1 - b.1).abs() < 1e-12,
            "{s:?}"
        );
    }
    // A single line alone on the axis, and the first line: half the spacing either side.
    let one = LineQuality {
        frequency_hz: vec![1.0, 1.5, 2.5],
        value: vec![0.1, 1.0, 1.0],
        threshold: 0.9,
        label: String::new(),
    };
    assert_eq!(low_quality_spans(&one), vec![(0.75, 1.25)]);
}

#[test]
fn shaded_spans_sit_at_their_frequencies_in_the_svg() {
    let f = axis();
    let h: Vec<f64> = f
        .iter()
        .map(|x| 1.0 / ((25.0 - x * x).powi(2) + (0.5 * x).powi(2)).sqrt())
        .collect();
    let trace = FrfTrace {
        name: "measured".into(),
        frequency_hz: f.clone(),
        magnitude: h,
        phase_deg: f.iter().map(|x| -10.0 * x).collect(),
        ..Default::default()
    };
    let p = FrfPanels {
        title: "fit".into(),
        magnitude_label: "|H|".into(),
        panels: vec![
            FrfPanel {
                title: "channel a".into(),
                traces: vec![trace.clone()],
                quality: Some(quality()),
            },
            FrfPanel {
                title: "channel b".into(),
                traces: vec![trace],
                quality: None,
            },
        ],
        // Wide panels: about 40 px per Hz, 4 px per line.
        panel_size: PlotSize {
            width: 900,
            height: 400,
        },
        ..Default::default()
    };
    let svg = frf_panels(&p).unwrap();
    let els = parse(&svg);
    let shade = format!(
        "#{:02X}{:02X}{:02X}",
        LOW_QUALITY_SHADE.0, LOW_QUALITY_SHADE.1, LOW_QUALITY_SHADE.2
    );
    let rects = with_attr(&els, "rect", "fill", &shade);
    // Three spans in the magnitude chart, the same three in the phase chart (channel b
    // has none), and the legend's swatch.
    assert_eq!(rects.len(), 7, "{rects:?}");
    // (XML-escaped in the document.)
    assert_has_texts(&els, &["γ² &lt; 0.9"]);
    // Document order: the legend (drawn first), then the panel's magnitude and phase.
    assert!(
        rects[0].num("height") < 20.0,
        "legend swatch first: {:?}",
        rects[0]
    );
    let (mag, phase) = (&rects[1..4], &rects[4..7]);
    // Pixel = a + b·f from the two outermost edges (2.95 Hz and the axis end, 20 Hz, 17 Hz
    // apart, so the 1-px rounding of each edge moves b by < 0.1 px/Hz); every edge must
    // then be within 1.5 px (its own rounding and that of the fit).
    let edges = |r: &Element| (r.num("x"), r.num("x") + r.num("width"));
    let (l0, _) = edges(mag[0]);
    let (_, r2) = edges(mag[2]);
    let b = (r2 - l0) / (20.0 - 2.95);
    let a = l0 - b * 2.95;
    let px = |f: f64| a + b * f;
    // The last span is clipped at the axis end, 20 Hz.
    for (r, (lo, hi)) in mag
        .iter()
        .zip([(2.95, 3.95), (10.95, 11.05), (19.55, 20.0)])
    {
        let (l, rr) = edges(r);
        assert!(
            (l - px(lo)).abs() <= 1.0 && (rr - px(hi)).abs() <= 1.0,
            "{r:?}: {lo}–{hi} Hz"
        );
    }
    // 3 px per line (0.1 Hz) or more: the test tells neighbouring lines apart.
    assert!(b >= 30.0, "{b} px/Hz");
    // The phase chart shades the same frequencies, over its own full height.
    for (m, p) in mag.iter().zip(phase) {
        assert_eq!(edges(m), edges(p));
        assert!(p.num("y") > m.num("y") + m.num("height"));
    }
    // Every span covers its chart's full height (all three the same).
    for set in [mag, phase] {
        assert!(set.iter().all(|r| r.num("height") == set[0].num("height")));
        assert!(set[0].num("height") > 50.0);
    }
    // Shading is drawn before (under) the curves: the first shaded span precedes the
    // first data polyline (legend samples are two-point lines).
    let index = |pred: &dyn Fn(&Element) -> bool| els.iter().position(|e| pred(e)).unwrap();
    let shade_at =
        index(&|e| e.name == "rect" && e.attr("fill") == Some(&shade) && e.num("height") > 50.0);
    let curve_at = index(&|e| e.name == "polyline" && e.points().len() > 2);
    assert!(shade_at < curve_at, "shade {shade_at}, curve {curve_at}");
}
