//! `compact_svg` on a dense recording: the figure the report inlines stays small and
//! every curve keeps its peak.

use crate::common::parse;
use rbprops_plot::{compact_svg, frf_panels, FrfPanel, FrfPanels, FrfTrace, LineStyle};

/// Absolute points of a `<path d>` written by `compact_svg` (M, then h/v/l steps with
/// implicit repeats).
fn path_points(d: &str) -> Vec<(i64, i64)> {
    let mut nums = Vec::new();
    let mut cmds = Vec::new();
    let mut cur = String::new();
    let flush = |cur: &mut String, nums: &mut Vec<i64>| {
        if !cur.is_empty() {
            nums.push(cur.parse().unwrap());
            cur.clear();
        }
    };
    for c in d.chars() {
        match c {
            'M' | 'h' | 'v' | 'l' => {
                flush(&mut cur, &mut nums);
                cmds.push((c, nums.len()));
            }
            '-' => {
                flush(&mut cur, &mut nums);
                cur.push(c);
            }
            ' ' => flush(&mut cur, &mut nums),
            _ => cur.push(c),
        }
    }
    flush(&mut cur, &mut nums);
    let mut pts = vec![(nums[0], nums[1])];
    for (k, &(c, start)) in cmds.iter().enumerate().skip(1) {
        let end = cmds.get(k + 1).map_or(nums.len(), |n| n.1);
        let args = &nums[start..end];
        let step = if c == 'l' { 2 } else { 1 };
        for a in args.chunks(step) {
            let (x, y) = *pts.last().unwrap();
            pts.push(match c {
                'h' => (x + a[0], y),
                'v' => (x, y + a[0]),
                _ => (x + a[0], y + a[1]),
            });
        }
    }
    pts
}

/// Nine channels of 20,000 lines each (two lightly damped modes, 0.5 % ripple that
/// makes every line differ), measured and synthesised: the dense case of a long record.
fn dense_figure() -> String {
    let n = 20_000;
    let f: Vec<f64> = (0..n).map(|i| 0.01 + 25.0 * i as f64 / n as f64).collect();
    let panels = (0..9)
        .map(|c| {
            let h = |k: usize, ripple: f64| {
                let (w, z) = (f[k], 0.01 + 0.002 * c as f64);
                let mode = |fr: f64| {
                    let r = w / fr;
                    1.0 / (((1.0 - r * r).powi(2) + (2.0 * z * r).powi(2)).sqrt())
                };
                (mode(4.0 + c as f64) + 0.5 * mode(17.0)) * (1.0 + ripple * (k as f64).sin())
            };
            let trace = |name: &str, ripple: f64, style| FrfTrace {
                name: name.into(),
                frequency_hz: f.clone(),
                magnitude: (0..n).map(|k| h(k, ripple)).collect(),
                phase_deg: (0..n)
                    .map(|k| -180.0 * f[k] / 25.0 + 90.0 * ripple)
                    .collect(),
                style,
                color: None,
            };
            FrfPanel {
                title: format!("channel {c}"),
                traces: vec![
                    trace("measured", 0.005, LineStyle::Solid),
                    trace("synthesised", 0.0, LineStyle::Dashed),
                ],
                quality: None,
            }
        })
        .collect();
    frf_panels(&FrfPanels {
        title: "dense".into(),
        magnitude_label: "|H|".into(),
        panels,
        ..Default::default()
    })
    .unwrap()
}

#[test]
fn a_dense_recording_compacts_under_its_bound_and_keeps_every_peak() {
    let full = dense_figure();
    let small = compact_svg(&full);
    // 18 curves of 20,000 lines in 9 panels: the figure's text, thinned to the pixels
    // (at most a few points per pixel column of a 420-pixel panel) and compacted, stays
    // under 120 kB — the page of the 24-recording campaign holds 72 such figures.
    assert!(small.len() < 120_000, "{} bytes", small.len());
    assert!(
        small.len() * 3 < full.len(),
        "{} of {}",
        small.len(),
        full.len()
    );
    // Magnitude curves in document order, before (polylines) and after (paths with a
    // stroke of width 2; grid, ticks and phase are 1 px wide).
    let before: Vec<Vec<(i64, i64)>> = parse(&full)
        .iter()
        .filter(|e| e.name == "polyline" && e.attr("stroke-width") == Some("2"))
        .map(|e| {
            e.points()
                .iter()
                .map(|&(x, y)| (x as i64, y as i64))
                .collect()
        })
        .filter(|p: &Vec<(i64, i64)>| p.len() > 2)
        .collect();
    let after: Vec<Vec<(i64, i64)>> = parse(&small)
        .iter()
        .filter(|e| e.name == "path" && e.attr("stroke-width") == Some("2"))
        .map(|e| e.attr("d").unwrap())
        // Curves (one `M`, relative steps), not merged segments (legend samples).
        .filter(|d| !d.contains(['m', 'H', 'V', 'L']))
        .map(path_points)
        .filter(|p| p.len() > 2)
        .collect();
    assert_eq!(before.len(), after.len());
    // The magnitude curves (phase is drawn 1 px wide): 9 panels × measured, synthesised.
    assert_eq!(before.len(), 18);
    for (b, a) in before.iter().zip(&after) {
        // The peak (smallest y: the largest |H| on the page) and the lowest point stay.
        let top = |p: &[(i64, i64)]| p.iter().map(|q| q.1).min().unwrap();
        let bottom = |p: &[(i64, i64)]| p.iter().map(|q| q.1).max().unwrap();
        assert_eq!(top(b), top(a));
        assert_eq!(bottom(b), bottom(a));
        assert_eq!(b.first(), a.first());
        assert_eq!(b.last(), a.last());
    }
}
