//! The SVG backend must not need any font file: plotters is built without its
//! `ttf` feature and estimates text extents itself. This test re-runs the
//! rendering of every plot kind in a child process whose mount namespace hides
//! all system font directories (Linux, root, `unshare` available; otherwise it
//! reports that it was skipped).

use rbprops_plot::*;

const SYSTEM_FONT_DIRS: [&str; 2] = ["/usr/share/fonts", "/usr/local/share/fonts"];

/// The system font directories and the user's own (`$HOME/.fonts`).
fn font_dirs() -> Vec<String> {
    let mut dirs: Vec<String> = SYSTEM_FONT_DIRS.iter().map(|d| d.to_string()).collect();
    if let Some(home) = std::env::var_os("HOME") {
        dirs.push(format!("{}/.fonts", home.to_string_lossy()));
    }
    dirs
}
const CHILD_ENV: &str = "RBPROPS_PLOT_FONTLESS_CHILD";

fn render_everything() -> Vec<String> {
    let x = vec![1.0, 2.0, 3.0];
    let y = vec![1e-3, 2e-3, 1e-4];
    vec![
        line_plot(&LinePlot {
            title: "line".into(),
            y_scale: Scale::Log10,
            series: vec![Series::new("s", x.clone(), y.clone())],
            markers: vec![VerticalMarker::new(2.0, "m")],
            ..Default::default()
        })
        .unwrap(),
        stabilisation_diagram(&StabilisationDiagram {
            title: "stab".into(),
            poles: vec![StabilisationPole {
                frequency_hz: 2.0,
                order: 4,
                class: PoleClass::Stable,
            }],
            background: Some(BackgroundCurve {
                name: "sum".into(),
                frequency_hz: x.clone(),
                magnitude: y.clone(),
                axis_label: "|H|".into(),
            }),
            ..Default::default()
        })
        .unwrap(),
        heat_map(&HeatMap {
            title: "heat".into(),
            row_labels: vec!["r".into()],
            column_labels: vec!["c1".into(), "c2".into()],
            values: vec![vec![1.0, 2.0]],
            ..Default::default()
        })
        .unwrap(),
        bar_chart(&BarChart {
            title: "bars".into(),
            groups: vec!["I".into()],
            series: vec![BarSeries::new("b", vec![1.0])],
            ..Default::default()
        })
        .unwrap(),
        scatter_plot(&ScatterPlot {
            title: "scatter".into(),
            series: vec![ScatterSeries::new("p", x, y)],
            ..Default::default()
        })
        .unwrap(),
    ]
}

#[test]
fn renders_with_no_fonts_installed() {
    if std::env::var_os(CHILD_ENV).is_some() {
        // Inside the namespace: prove the fonts are really gone, then render.
        for d in font_dirs() {
            if let Ok(mut entries) = std::fs::read_dir(&d) {
                assert!(entries.next().is_none(), "{d} is still visible");
            }
        }
        for (svg, title) in render_everything()
            .iter()
            .zip(["line", "stab", "heat", "bars", "scatter"])
        {
            assert!(svg.starts_with("<svg") && svg.contains(&format!("\n{title}\n")));
        }
        return;
    }
    let exe = std::env::current_exe().unwrap();
    let mounts: Vec<String> = font_dirs()
        .iter()
        .filter(|d| std::path::Path::new(d).is_dir())
        .map(|d| format!("mount -t tmpfs none {d} && "))
        .collect();
    // This test's name in the test binary: its module path without the crate.
    let (_, module) = module_path!().split_once("::").unwrap();
    let script = format!(
        "{}exec \"$0\" --exact {module}::renders_with_no_fonts_installed --test-threads 1",
        mounts.concat()
    );
    let out = std::process::Command::new("unshare")
        .args(["-m", "sh", "-c", &script])
        .arg(&exe)
        .env(CHILD_ENV, "1")
        .output();
    match out {
        Ok(o) if o.status.success() => {
            let stdout = String::from_utf8_lossy(&o.stdout);
            assert!(stdout.contains("1 passed"), "child did not run: {stdout}");
        }
        Ok(o)
            if String::from_utf8_lossy(&o.stderr).contains("unshare failed")
                || String::from_utf8_lossy(&o.stderr).contains("Operation not permitted") =>
        {
            eprintln!(
                "skipped: cannot create a mount namespace here; rendering without the namespace"
            );
            assert_eq!(render_everything().len(), 5);
        }
        Ok(o) => panic!(
            "fontless child failed:\n{}\n{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        ),
        Err(e) => {
            eprintln!("skipped: `unshare` not available ({e}); rendering without the namespace");
            assert_eq!(render_everything().len(), 5);
        }
    }
}
