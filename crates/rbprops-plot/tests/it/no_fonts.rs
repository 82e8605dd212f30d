//! The SVG backend must not need any font file: plotters is built without its
//! `ttf` and `ab_glyph` features and estimates text extents itself. Three tests, the
//! first two able to fail on any machine:
//! - the resolved `plotters` (Cargo.lock) depends on no font engine (font-kit,
//!   ttf-parser, ab_glyph): enabling one fails here, whoever does it;
//! - every plot kind renders in a child process whose font lookup finds nothing: a
//!   fontconfig file naming one empty directory, and `HOME` / XDG directories empty
//!   (`fc-list` under that environment, where installed, shows it lists no font);
//! - the same in a mount namespace that hides the font directories themselves (Linux,
//!   root and `unshare`; otherwise it reports that it was skipped).

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

/// The `dependencies` of the `[[package]]` named `name` in a Cargo.lock text.
fn locked_dependencies(lock: &str, name: &str) -> Option<Vec<String>> {
    let block = lock
        .split("[[package]]")
        .find(|b| b.lines().any(|l| l.trim() == format!("name = \"{name}\"")))?;
    let deps = block.split_once("dependencies = [")?.1.split_once(']')?.0;
    Some(
        deps.split(',')
            .map(|d| d.trim().trim_matches('"'))
            .filter(|d| !d.is_empty())
            .map(|d| d.split(' ').next().unwrap_or(d).to_string())
            .collect(),
    )
}

#[test]
fn plotters_is_built_without_a_font_engine() {
    let lock_path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../Cargo.lock");
    let lock = std::fs::read_to_string(&lock_path).expect("the workspace's Cargo.lock");
    let deps = locked_dependencies(&lock, "plotters").expect("plotters is in Cargo.lock");
    // The parse is right: the SVG backend is there.
    assert!(deps.iter().any(|d| d == "plotters-svg"), "{deps:?}");
    for engine in ["font-kit", "ttf-parser", "ab_glyph"] {
        assert!(
            !deps.iter().any(|d| d == engine),
            "plotters is built with {engine}: its text would need font files ({deps:?})"
        );
    }
    // And the check itself rejects a lock that has one.
    let with_ttf = "[[package]]\nname = \"plotters\"\ndependencies = [\n \"font-kit\",\n \"plotters-svg\",\n]\n";
    let d = locked_dependencies(with_ttf, "plotters").unwrap();
    assert!(d.contains(&"font-kit".to_string()));
}

const EMPTY_CONFIG_CHILD: &str = "RBPROPS_PLOT_EMPTY_FONT_CONFIG_CHILD";

#[test]
fn renders_with_an_empty_font_configuration() {
    if std::env::var_os(EMPTY_CONFIG_CHILD).is_some() {
        for (svg, title) in render_everything()
            .iter()
            .zip(["line", "stab", "heat", "bars", "scatter"])
        {
            assert!(svg.starts_with("<svg") && svg.contains(&format!("\n{title}\n")));
        }
        return;
    }
    let root = std::env::temp_dir().join(format!("rbprops-plot-no-fonts-{}", std::process::id()));
    let empty = root.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let conf = root.join("fonts.conf");
    std::fs::write(
        &conf,
        format!(
            "<?xml version=\"1.0\"?>\n<fontconfig><dir>{0}</dir><cachedir>{1}</cachedir></fontconfig>\n",
            empty.display(),
            root.join("cache").display()
        ),
    )
    .unwrap();
    let fontless = |c: &mut std::process::Command| {
        c.env("FONTCONFIG_FILE", &conf)
            .env_remove("FONTCONFIG_PATH")
            .env("HOME", &empty)
            .env("XDG_DATA_HOME", &empty)
            .env("XDG_DATA_DIRS", &empty)
            .env("XDG_CONFIG_HOME", &empty);
    };
    // Where fontconfig is installed, show that this environment hides every font.
    let mut fc = std::process::Command::new("fc-list");
    fontless(&mut fc);
    match fc.output() {
        Ok(o) => assert!(
            o.stdout.is_empty(),
            "fc-list still finds fonts: {}",
            String::from_utf8_lossy(&o.stdout)
        ),
        Err(e) => eprintln!("fc-list not available ({e}): the empty configuration is not shown"),
    }
    let (_, module) = module_path!().split_once("::").unwrap();
    let mut child = std::process::Command::new(std::env::current_exe().unwrap());
    child
        .args([
            "--exact",
            &format!("{module}::renders_with_an_empty_font_configuration"),
            "--test-threads",
            "1",
        ])
        .env(EMPTY_CONFIG_CHILD, "1");
    fontless(&mut child);
    let out = child.output().unwrap();
    let _ = std::fs::remove_dir_all(&root);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && stdout.contains("1 passed"),
        "rendering with no font found failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
