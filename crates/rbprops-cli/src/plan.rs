//! `rbprops plan`: reading candidates, calling `rbprops_plan`, writing the planned spec
//! and printing the predicted intervals. The numerics are in `rbprops-plan`.

use anyhow::{bail, Context, Result};
use rbprops_core::Vec3;
use rbprops_plan::{
    evaluate, plan, Candidates, Criterion, Estimator, Hit, Layout, PlanModel, PlanOptions, Sensor,
    SetupPrediction, Suggestion, PROPERTY_NAMES,
};
use rbprops_sim::spec::{ExcitationSpec, SensorKind, SensorSpec};
use rbprops_sim::CampaignSpec;
use std::fmt::Write as _;
use std::path::Path;

/// Two-sided 95 % normal quantile.
const Z95: f64 = 1.959963984540054;

/// Reads a candidates CSV: header `id,x_m,y_m,z_m,role,dx,dy,dz`; `role` is `sensor`,
/// `hit` or `both`; a hit's allowed force direction is `(dx, dy, dz)` (one row per
/// allowed direction; a sensor is triaxial along the geometry's axes). Hits go to
/// set-up `setup`.
pub fn read_candidates(path: &Path, setup: usize) -> Result<Candidates> {
    let bytes = crate::read_file(path)?;
    let name = path.display().to_string();
    let mut rdr = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(bytes.as_slice());
    let header: Vec<String> = rdr
        .headers()
        .with_context(|| name.clone())?
        .iter()
        .map(str::to_string)
        .collect();
    let want = ["id", "x_m", "y_m", "z_m", "role", "dx", "dy", "dz"];
    if header.len() < want.len() || header[..want.len()] != want {
        bail!(
            "{name}: header must be '{}' (found '{}')",
            want.join(","),
            header.join(",")
        );
    }
    let mut c = Candidates::default();
    for (k, rec) in rdr.records().enumerate() {
        let line = k + 2;
        let rec = rec.with_context(|| format!("{name}: line {line}"))?;
        let num = |i: usize| -> Result<f64> {
            let s = rec.get(i).unwrap_or("");
            let v: f64 = s.parse().with_context(|| {
                format!(
                    "{name}: line {line}: column '{}' = '{s}' is not a number",
                    want[i]
                )
            })?;
            if !v.is_finite() {
                bail!("{name}: line {line}: column '{}' is not finite", want[i]);
            }
            Ok(v)
        };
        let id = rec.get(0).unwrap_or("").to_string();
        if id.is_empty() {
            bail!("{name}: line {line}: empty id");
        }
        let p = Vec3::new(num(1)?, num(2)?, num(3)?);
        let role = rec.get(4).unwrap_or("").to_ascii_lowercase();
        let (sensor, hit) = match role.as_str() {
            "sensor" => (true, false),
            "hit" => (false, true),
            "both" => (true, true),
            other => bail!("{name}: line {line}: role '{other}' (expected sensor, hit or both)"),
        };
        if sensor && !c.sensors.iter().any(|s| s.id == id) {
            c.sensors.push(Sensor::triaxial(&id, p));
        }
        if hit {
            let d = Vec3::new(num(5)?, num(6)?, num(7)?);
            if d.norm() == 0.0 {
                bail!("{name}: line {line}: hit direction is zero");
            }
            c.hits.push(Hit {
                id: id.clone(),
                position: p,
                direction: d / d.norm(),
                setup,
            });
        }
    }
    if c.sensors.is_empty() && c.hits.is_empty() {
        bail!("{name}: no candidate");
    }
    Ok(c)
}

/// Candidates from the spec itself: every sensor and excitation point as a sensor
/// position, and a hit along each geometry axis (both senses) at every point.
pub fn spec_candidates(layout: &Layout, setup: usize) -> Candidates {
    let mut c = Candidates::default();
    let mut points: Vec<(String, Vec3)> = layout
        .sensors
        .iter()
        .map(|s| (s.id.clone(), s.position))
        .collect();
    for h in &layout.hits {
        if !points.iter().any(|(_, p)| (p - h.position).norm() == 0.0) {
            points.push((h.id.clone(), h.position));
        }
    }
    for (id, p) in &points {
        c.sensors.push(Sensor::triaxial(id, *p));
        for axis in 0..3 {
            for sign in [1.0, -1.0] {
                let mut d = Vec3::zeros();
                d[axis] = sign;
                c.hits.push(Hit {
                    id: id.clone(),
                    position: *p,
                    direction: d,
                    setup,
                });
            }
        }
    }
    c
}

/// Options of the subcommand.
pub struct PlanArgs<'a> {
    /// The spec file.
    pub spec: &'a Path,
    /// Candidates CSV.
    pub candidates: Option<&'a Path>,
    /// Sensors to place.
    pub sensors: usize,
    /// Hits to place.
    pub hits: usize,
    /// Criterion.
    pub criterion: Criterion,
    /// Estimator.
    pub estimator: Estimator,
    /// Output spec.
    pub output: Option<&'a Path>,
    /// Evaluate instead of plan.
    pub evaluate: bool,
    /// JSON output.
    pub json: bool,
    /// Least sensor spacing (m).
    pub min_spacing_m: f64,
    /// Directory of the layout figures ([`layout_figures`]).
    pub plot: Option<&'a Path>,
}

/// Runs `rbprops plan`.
pub fn run(a: &PlanArgs) -> Result<()> {
    let name = a.spec.display().to_string();
    let text = String::from_utf8(crate::read_file(a.spec)?)
        .with_context(|| format!("{name}: not UTF-8"))?;
    let spec = CampaignSpec::from_toml_str(&text).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    let model = PlanModel::from_spec(&spec).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    let input = Layout::from_spec(&spec, &model).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    let setup = input.hits.first().map(|h| h.setup).unwrap_or(0);
    let cands = match a.candidates {
        Some(p) => read_candidates(p, setup)?,
        None => spec_candidates(&input, setup),
    };
    if a.evaluate {
        if let Some(dir) = a.plot {
            let figs = layout_figures(&cands, &input, &format!("{name}: the spec's layout"))?;
            crate::write_plots(dir, &figs)?;
        }
        return evaluate_cmd(&model, &input, &cands, a);
    }
    if model.setups.len() > 1 {
        bail!(
            "{name}: the spec has {} suspension set-ups; `rbprops plan` plans one (use --evaluate for several)",
            model.setups.len()
        );
    }
    let opts = PlanOptions {
        sensors: a.sensors,
        hits: a.hits,
        criterion: a.criterion,
        estimator: a.estimator,
        min_spacing_m: a.min_spacing_m,
        ..Default::default()
    };
    let out = plan(&model, &cands, setup, &opts).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    let before = evaluate(&model, &input, a.estimator);
    let before = before
        .setups
        .into_iter()
        .find(|(id, _)| *id == model.setups[setup].id)
        .map(|(_, p)| p);
    let planned = planned_spec(&spec, &model, &out.layout, setup);
    let planned_text = planned.to_toml_string();
    // The written spec must be one frf-sim reads.
    CampaignSpec::from_toml_str(&planned_text)
        .map_err(|e| anyhow::anyhow!("the planned spec does not validate: {e}"))?;
    if let Some(dir) = a.plot {
        let figs = layout_figures(&cands, &out.layout, "planned layout")?;
        crate::write_plots(dir, &figs)?;
    }
    if let Some(p) = a.output {
        crate::write_text(p, &planned_text)?;
    }
    let report = plan_report(&model, &out.prediction, before.as_ref(), &out.layout, a);
    if a.json {
        crate::out(&(serde_json::to_string_pretty(&report.0)? + "\n"))
    } else {
        if a.output.is_none() {
            crate::out(&planned_text)?;
            eprint!("{}", report.1);
            Ok(())
        } else {
            crate::out(&report.1)
        }
    }
}

fn property_rows(model: &PlanModel, p: &SetupPrediction) -> Vec<serde_json::Value> {
    let std = p.std();
    (0..10)
        .map(|k| {
            serde_json::json!({
                "name": PROPERTY_NAMES[k],
                "value": model.truth[k],
                "std": std[k],
                "relative_std": std[k] / model.scales[k],
                "ci95": [model.truth[k] - Z95 * std[k], model.truth[k] + Z95 * std[k]],
            })
        })
        .collect()
}

fn plan_report(
    model: &PlanModel,
    planned: &SetupPrediction,
    before: Option<&Result<SetupPrediction, rbprops_plan::Unobservable>>,
    layout: &Layout,
    a: &PlanArgs,
) -> (serde_json::Value, String) {
    let std = planned.std();
    let mut t = String::new();
    let _ = writeln!(
        t,
        "plan: {} sensors, {} hits, {}-optimal for {} (predicted 95 % intervals about the spec's values)",
        layout.sensors.len(),
        layout.hits.len(),
        a.criterion.name(),
        a.estimator.name()
    );
    for s in &layout.sensors {
        let _ = writeln!(
            t,
            "  sensor {:<10} at ({:.4}, {:.4}, {:.4}) m",
            s.id, s.position.x, s.position.y, s.position.z
        );
    }
    for h in &layout.hits {
        let _ = writeln!(
            t,
            "  hit    {:<10} at ({:.4}, {:.4}, {:.4}) m along ({:.3}, {:.3}, {:.3})",
            h.id,
            h.position.x,
            h.position.y,
            h.position.z,
            h.direction.x,
            h.direction.y,
            h.direction.z
        );
    }
    let before_std = before.and_then(|b| b.as_ref().ok()).map(|p| p.std());
    let _ = writeln!(
        t,
        "{:<5} {:>12} {:>26} {:>11} {:>12}",
        "prop", "value", "95 % interval (plan)", "rel. std", "gain"
    );
    for k in 0..10 {
        let gain = before_std
            .map(|b| format!("{:.2}×", b[k] / std[k]))
            .unwrap_or_else(|| "—".into());
        let _ = writeln!(
            t,
            "{:<5} {:>12.6} ± {:<11.3e}           {:>10.2e} {:>12}",
            PROPERTY_NAMES[k],
            model.truth[k],
            Z95 * std[k],
            std[k] / model.scales[k],
            gain
        );
    }
    if let Some(l) = &planned.limit {
        let _ = writeln!(t, "limit: {l}");
    }
    let worst = |s: &[f64; 10]| (0..10).map(|k| s[k] / model.scales[k]).fold(0.0, f64::max);
    let input_json = match before {
        Some(Ok(p)) => {
            let b = p.std();
            let _ = writeln!(
                t,
                "worst relative std: input layout {:.3e}, plan {:.3e} ({:.0} % lower)",
                worst(&b),
                worst(&std),
                100.0 * (1.0 - worst(&std) / worst(&b))
            );
            serde_json::json!({"observable": true, "properties": property_rows(model, p)})
        }
        Some(Err(u)) => {
            let _ = writeln!(t, "input layout: unobservable: {}", u.reason);
            serde_json::json!({"observable": false, "reason": u.reason})
        }
        None => serde_json::json!({"observable": false, "reason": "no hit on the planned set-up"}),
    };
    let json = serde_json::json!({
        "estimator": a.estimator.name(),
        "criterion": a.criterion.name(),
        "sensors": layout.sensors.iter().map(|s| serde_json::json!({"id": s.id, "at_m": [s.position.x, s.position.y, s.position.z]})).collect::<Vec<_>>(),
        "hits": layout.hits.iter().map(|h| serde_json::json!({"id": h.id, "at_m": [h.position.x, h.position.y, h.position.z], "direction": [h.direction.x, h.direction.y, h.direction.z]})).collect::<Vec<_>>(),
        "properties": property_rows(model, planned),
        "limit": planned.limit,
        "input_layout": input_json,
    });
    (json, t)
}

/// The spec with the planned sensors and hits (everything else unchanged).
pub fn planned_spec(
    spec: &CampaignSpec,
    model: &PlanModel,
    layout: &Layout,
    setup: usize,
) -> CampaignSpec {
    let mut s = spec.clone();
    let mut used: Vec<String> = Vec::new();
    let mut unique = |base: &str| {
        let mut id = base.to_string();
        let mut n = 2;
        while used.contains(&id) {
            id = format!("{base}-{n}");
            n += 1;
        }
        used.push(id.clone());
        id
    };
    s.sensors = layout
        .sensors
        .iter()
        .map(|x| SensorSpec {
            id: unique(&x.id),
            at_m: [x.position.x, x.position.y, x.position.z],
            kind: SensorKind::Triaxial,
            axes: None,
            direction: None,
            channels: None,
        })
        .collect();
    s.excitations = layout
        .hits
        .iter()
        .map(|h| ExcitationSpec {
            id: unique(&format!("hit-{}", h.id)),
            at_m: [h.position.x, h.position.y, h.position.z],
            direction: [h.direction.x, h.direction.y, h.direction.z],
            setup: model.setups[setup].id.clone(),
            point: None,
        })
        .collect();
    s.description = format!(
        "{} (sensors and hits planned by rbprops plan)",
        spec.description
    );
    s
}

fn evaluate_cmd(
    model: &PlanModel,
    layout: &Layout,
    cands: &Candidates,
    a: &PlanArgs,
) -> Result<()> {
    let ev = evaluate(model, layout, a.estimator);
    let mut t = String::new();
    let mut setups = Vec::new();
    for (si, (id, p)) in ev.setups.iter().enumerate() {
        let setup = model.setup_index(id).unwrap_or(si);
        match p {
            Err(u) => {
                let _ = writeln!(t, "set-up '{id}': unobservable: {}", u.reason);
                setups.push(
                    serde_json::json!({"setup": id, "observable": false, "reason": u.reason}),
                );
            }
            Ok(p) => {
                let std = p.std();
                let weakest = (0..10)
                    .max_by(|&x, &y| {
                        (std[x] / model.scales[x]).total_cmp(&(std[y] / model.scales[y]))
                    })
                    .unwrap_or(0);
                let _ = writeln!(
                    t,
                    "set-up '{id}', {} (predicted 95 % intervals about the spec's values)",
                    a.estimator.name()
                );
                for k in 0..10 {
                    let _ = writeln!(
                        t,
                        "{:<5} {:>12.6} ± {:<11.3e} (relative std {:.2e})",
                        PROPERTY_NAMES[k],
                        model.truth[k],
                        Z95 * std[k],
                        std[k] / model.scales[k]
                    );
                }
                let help = rbprops_plan::select::best_addition(
                    model,
                    layout,
                    setup,
                    weakest,
                    a.estimator,
                    cands,
                );
                let suggestion = help.map(|(s, v)| match s {
                    Suggestion::Sensor(i) => {
                        let c = &cands.sensors[i];
                        (
                            format!(
                                "a triaxial sensor at '{}' ({:.4}, {:.4}, {:.4}) m",
                                c.id, c.position.x, c.position.y, c.position.z
                            ),
                            serde_json::json!({"kind": "sensor", "id": c.id, "at_m": [c.position.x, c.position.y, c.position.z], "std_after": v}),
                            v,
                        )
                    }
                    Suggestion::Hit(i) => {
                        let c = &cands.hits[i];
                        (
                            format!(
                                "a hit at '{}' ({:.4}, {:.4}, {:.4}) m along ({:.3}, {:.3}, {:.3})",
                                c.id, c.position.x, c.position.y, c.position.z, c.direction.x, c.direction.y, c.direction.z
                            ),
                            serde_json::json!({"kind": "hit", "id": c.id, "at_m": [c.position.x, c.position.y, c.position.z], "direction": [c.direction.x, c.direction.y, c.direction.z], "std_after": v}),
                            v,
                        )
                    }
                });
                if let Some(l) = &p.limit {
                    let _ = writeln!(t, "limit: {l}");
                }
                let _ = writeln!(
                    t,
                    "weakest: {} (relative std {:.2e})",
                    PROPERTY_NAMES[weakest],
                    std[weakest] / model.scales[weakest]
                );
                if let Some((words, _, v)) = &suggestion {
                    let _ = writeln!(
                        t,
                        "most help: {words}: its std {:.3e} → {:.3e}",
                        std[weakest], v
                    );
                }
                setups.push(serde_json::json!({
                    "setup": id,
                    "observable": true,
                    "properties": property_rows(model, p),
                    "weakest": PROPERTY_NAMES[weakest],
                    "limit": p.limit,
                    "suggestion": suggestion.map(|s| s.1),
                }));
            }
        }
    }
    if a.json {
        let j = serde_json::json!({"estimator": a.estimator.name(), "setups": setups});
        crate::out(&(serde_json::to_string_pretty(&j)? + "\n"))
    } else {
        crate::out(&t)
    }
}

/// The layout figures of `--plot DIR`: the candidate points, the chosen sensors (squares)
/// and hits (arrows ending at the point of impact, along the blow), inside the bounding
/// box of the candidates (the plan knows the body only through them), in three views:
/// `plan-layout-xy.svg` (from +z), `-xz` (from −y) and `-yz` (from +x). A hit along the
/// line of sight is drawn as a cross.
pub fn layout_figures(
    cands: &Candidates,
    layout: &Layout,
    title: &str,
) -> Result<Vec<(String, String)>> {
    use rbprops_plot::{line_plot, LinePlot, LineStyle, PlotSize, Rgb, Series};
    let points: Vec<Vec3> = candidate_positions(cands)
        .chain(layout.sensors.iter().map(|s| s.position))
        .chain(layout.hits.iter().map(|h| h.position))
        .collect();
    if points.is_empty() {
        bail!("no point to draw");
    }
    let lo = points.iter().fold(points[0], |a, p| a.inf(p));
    let hi = points.iter().fold(points[0], |a, p| a.sup(p));
    let span = (hi - lo).max().max(1e-3);
    let mut figures = Vec::new();
    for (name, (a, b), view) in [
        ("xy", (0, 1), "top view, from +z"),
        ("xz", (0, 2), "front view, from −y"),
        ("yz", (1, 2), "side view, from +x"),
    ] {
        let v = View {
            a,
            b,
            tick: 0.012 * span,
        };
        let axes = ["x", "y", "z"];
        let mut series = vec![Series::new(
            "bounding box of the candidates",
            vec![lo[a], hi[a], hi[a], lo[a], lo[a]],
            vec![lo[b], lo[b], hi[b], hi[b], lo[b]],
        )
        .with_color(Rgb::GREY)
        .with_style(LineStyle::Dotted)];
        series.extend(candidate_marks(&v, cands));
        series.extend(sensor_squares(&v, layout));
        series.extend(hit_arrows(&v, layout, 0.15 * span));
        let pad = 0.2 * span;
        let mid = |k: usize| 0.5 * (lo[k] + hi[k]);
        let half = 0.5 * span + pad;
        let svg = line_plot(&LinePlot {
            title: format!("{title}: {view}"),
            x_label: format!("{} [m]", axes[a]),
            y_label: format!("{} [m]", axes[b]),
            series,
            x_range: Some((mid(a) - half, mid(a) + half)),
            y_range: Some((mid(b) - half, mid(b) + half)),
            size: PlotSize {
                width: 860,
                height: 600,
            },
            ..Default::default()
        })?;
        figures.push((format!("plan-layout-{name}.svg"), svg));
    }
    Ok(figures)
}

/// One view of the layout: the two coordinates drawn (0 x, 1 y, 2 z) and the glyph unit.
struct View {
    a: usize,
    b: usize,
    tick: f64,
}

fn candidate_positions(cands: &Candidates) -> impl Iterator<Item = Vec3> + '_ {
    cands
        .sensors
        .iter()
        .map(|s| s.position)
        .chain(cands.hits.iter().map(|h| h.position))
}

/// A glyph of the layout: one polyline, labelled in the legend when `label` is not empty.
fn glyph(label: &str, x: Vec<f64>, y: Vec<f64>, color: rbprops_plot::Rgb) -> rbprops_plot::Series {
    rbprops_plot::Series::new(label, x, y)
        .with_color(color)
        .with_style(rbprops_plot::LineStyle::Solid)
}

/// Candidate points as small plus signs (one polyline each, the stroke retraced), each
/// projected position once.
fn candidate_marks(v: &View, cands: &Candidates) -> Vec<rbprops_plot::Series> {
    let tick = v.tick;
    let mut seen: Vec<(f64, f64)> = Vec::new();
    let mut out = Vec::new();
    for p in candidate_positions(cands) {
        let (x, y) = (p[v.a], p[v.b]);
        if seen
            .iter()
            .any(|q| (q.0 - x).abs() + (q.1 - y).abs() < 1e-9)
        {
            continue;
        }
        let label = if seen.is_empty() {
            "candidate points"
        } else {
            ""
        };
        seen.push((x, y));
        out.push(glyph(
            label,
            vec![x - tick, x + tick, x, x, x],
            vec![y, y, y, y + tick, y - tick],
            rbprops_plot::Rgb::GREY,
        ));
    }
    out
}

/// The chosen sensors as squares.
fn sensor_squares(v: &View, layout: &Layout) -> Vec<rbprops_plot::Series> {
    let d = 2.0 * v.tick;
    layout
        .sensors
        .iter()
        .enumerate()
        .map(|(k, s)| {
            let (x, y) = (s.position[v.a], s.position[v.b]);
            glyph(
                if k == 0 { "sensors (triaxial)" } else { "" },
                vec![x - d, x + d, x + d, x - d, x - d],
                vec![y - d, y - d, y + d, y + d, y - d],
                rbprops_plot::Rgb::palette(0),
            )
        })
        .collect()
}

/// The chosen hits as arrows ending at the point of impact, `arrow` long for a blow in
/// the view's plane; a blow along the line of sight as a cross.
fn hit_arrows(v: &View, layout: &Layout, arrow: f64) -> Vec<rbprops_plot::Series> {
    let (tick, color) = (v.tick, rbprops_plot::Rgb::palette(3));
    let mut out = Vec::new();
    for (k, h) in layout.hits.iter().enumerate() {
        let label = if k == 0 {
            "hits (arrow: the blow; ×: along the view)"
        } else {
            ""
        };
        let (x, y) = (h.position[v.a], h.position[v.b]);
        let (dx, dy) = (h.direction[v.a], h.direction[v.b]);
        let n = dx.hypot(dy);
        if n < 0.2 {
            // Along the line of sight: a cross.
            let d = 2.0 * tick;
            out.push(glyph(
                label,
                vec![x - d, x + d, x, x - d, x + d],
                vec![y - d, y + d, y, y + d, y - d],
                color,
            ));
            continue;
        }
        let (ux, uy) = (dx / n, dy / n);
        let len = arrow * n;
        // Shaft from the approach to the point, then the head's two barbs.
        let head = 3.0 * tick;
        let (c, s) = (0.9_f64, 0.45_f64);
        let (b1x, b1y) = (-(ux * c - uy * s), -(uy * c + ux * s));
        let (b2x, b2y) = (-(ux * c + uy * s), -(uy * c - ux * s));
        out.push(glyph(
            label,
            vec![x - len * ux, x, x + head * b1x, x, x + head * b2x],
            vec![y - len * uy, y, y + head * b1y, y, y + head * b2y],
            color,
        ));
    }
    out
}
