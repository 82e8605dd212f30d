//! Small multiples of FRFs: one panel per channel, magnitude over phase, so that a fit
//! can be read against its data channel by channel instead of under 17 other curves.

use plotters::element::{PathElement, Rectangle, Text};
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::RGBAColor;

use crate::axis::{extent, AxisSpec, Fit, Scale};
use crate::canvas::{
    chart, draw_mesh, drawn_pieces, fill, footnote, plot_name, render_err, render_svg,
    skipped_note, text_style, Margins, Root, TITLE_SIZE,
};
use crate::error::PlotError;
use crate::line::check_series;
use crate::style::{stroke, LineStyle, PlotSize, Rgb};

/// One curve of a panel: a complex FRF given as magnitude and phase.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FrfTrace {
    /// Legend text (shared by every panel: the first panel's names are listed once).
    pub name: String,
    /// Frequency of every line (Hz).
    pub frequency_hz: Vec<f64>,
    /// |H|, drawn on a log axis (values ≤ 0 are not drawn).
    pub magnitude: Vec<f64>,
    /// Phase in degrees, drawn in [−180, 180].
    pub phase_deg: Vec<f64>,
    /// Solid, dashed or dotted.
    pub style: LineStyle,
    /// `None`: colour `i` of [`Rgb::palette`] for the `i`-th trace of the panel.
    pub color: Option<Rgb>,
}

/// One channel's panel.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FrfPanel {
    /// E.g. the channel id.
    pub title: String,
    /// The curves, drawn in order (later ones on top).
    pub traces: Vec<FrfTrace>,
    /// A per-line quality measure (the measured coherence γ²): the lines where it is
    /// below its threshold are shaded behind the curves.
    pub quality: Option<LineQuality>,
}

/// A per-line quality measure of a panel and the level below which a line is shaded
/// (see [`low_quality_spans`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LineQuality {
    /// Frequency of every line (Hz), as `value`.
    pub frequency_hz: Vec<f64>,
    /// The measure per line (e.g. γ² in [0, 1]); NaN lines are not shaded.
    pub value: Vec<f64>,
    /// Lines with `value < threshold` are shaded (0.9 for coherence by default).
    pub threshold: f64,
    /// Legend text of the shading, e.g. "γ² < 0.9".
    pub label: String,
}

/// Colour of the low-quality shading: a light amber, behind every curve.
pub const LOW_QUALITY_SHADE: Rgb = Rgb(255, 226, 180);

/// The frequency spans `[lo, hi]` to shade: each run of consecutive lines with
/// `value < threshold` covers its lines out to halfway to the neighbouring lines (each
/// line stands for the band around it; at the ends of the axis, half the spacing to the
/// one neighbour). Runs come in ascending frequency; a single line's span is its own
/// half-spacings.
pub fn low_quality_spans(q: &LineQuality) -> Vec<(f64, f64)> {
    let f = &q.frequency_hz;
    let n = f.len().min(q.value.len());
    let half_below = |k: usize| match (k > 0, k + 1 < n) {
        (true, _) => 0.5 * (f[k] - f[k - 1]),
        (false, true) => 0.5 * (f[k + 1] - f[k]),
        _ => 0.0,
    };
    let half_above = |k: usize| match (k + 1 < n, k > 0) {
        (true, _) => 0.5 * (f[k + 1] - f[k]),
        (false, true) => 0.5 * (f[k] - f[k - 1]),
        _ => 0.0,
    };
    let low = |k: usize| q.value[k] < q.threshold;
    let mut spans = Vec::new();
    let mut k = 0;
    while k < n {
        if !low(k) {
            k += 1;
            continue;
        }
        let start = k;
        while k + 1 < n && low(k + 1) {
            k += 1;
        }
        spans.push((f[start] - half_below(start), f[k] + half_above(k)));
        k += 1;
    }
    spans
}

/// Input of [`frf_panels`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FrfPanels {
    /// Printed above the panels.
    pub title: String,
    /// Magnitude axis description, e.g. "|H| [m/s²/N]".
    pub magnitude_label: String,
    /// One panel per channel, filled row by row.
    pub panels: Vec<FrfPanel>,
    /// Panels per row; 0 chooses 3 (or fewer when there are fewer panels).
    pub columns: usize,
    /// Size of one panel (magnitude and phase together) in pixels; the canvas grows
    /// with the number of panels.
    pub panel_size: PlotSize,
}

const LEGEND_ROW: u32 = 34;
/// Share of a panel's height given to the magnitude.
const MAGNITUDE_SHARE: f64 = 0.64;

/// Render [`FrfPanels`]: a title, one legend row shared by all panels, then a grid of
/// panels, each a log-magnitude chart over a phase chart on the same frequency axis.
///
/// Every panel has its own magnitude range (channels differ by decades); phases share
/// [−180°, 180°]. Unplottable points are counted in one footnote. Errors: no panel, a
/// panel without traces, a trace whose lengths differ, nothing plottable in a panel.
pub fn frf_panels(p: &FrfPanels) -> Result<String, PlotError> {
    let plot = plot_name(&p.title);
    if p.panels.is_empty() {
        return Err(PlotError::Empty {
            plot,
            what: "panel list",
        });
    }
    let columns = match p.columns {
        0 => p.panels.len().min(3),
        c => c.min(p.panels.len()),
    };
    let rows = p.panels.len().div_ceil(columns);
    let cell = if p.panel_size == PlotSize::default() {
        PlotSize {
            width: 420,
            height: 330,
        }
    } else {
        p.panel_size
    };
    let header = 44 + LEGEND_ROW;
    let size = PlotSize {
        width: cell.width * columns as u32,
        height: cell.height * rows as u32 + header + 22,
    };
    let prepared = p
        .panels
        .iter()
        .map(|panel| prepare(&plot, panel))
        .collect::<Result<Vec<_>, _>>()?;
    let skipped: usize = prepared.iter().map(|q| q.skipped).sum();

    render_svg(&plot, size, |root| {
        let title_style = text_style(TITLE_SIZE, RGBAColor(0, 0, 0, 1.0), centred_top());
        root.draw(&Text::new(
            p.title.clone(),
            (size.width as i32 / 2, 10),
            title_style,
        ))
        .map_err(render_err(&plot))?;
        draw_shared_legend(&plot, root, &p.panels, 44)?;
        let (_, grid) = root.split_vertically(header);
        let (grid, _) = grid.split_vertically(cell.height * rows as u32);
        let cells = grid.split_evenly((rows, columns));
        for ((panel, prep), area) in p.panels.iter().zip(&prepared).zip(&cells) {
            draw_panel(&plot, area, panel, prep, &p.magnitude_label)?;
        }
        if let Some(note) = skipped_note(skipped, "non-finite, or ≤ 0 on the log axis") {
            footnote(&plot, root, &note)?;
        }
        Ok(())
    })
}

fn centred_top() -> Pos {
    Pos::new(HPos::Center, VPos::Top)
}

/// A panel's traces in plot space and its resolved axes.
struct Prepared {
    magnitude: Vec<Vec<Option<(f64, f64)>>>,
    phase: Vec<Vec<Option<(f64, f64)>>>,
    x: AxisSpec,
    y_mag: AxisSpec,
    y_phase: AxisSpec,
    skipped: usize,
    /// Low-quality spans to shade ([`low_quality_spans`]).
    spans: Vec<(f64, f64)>,
}

fn prepare(plot: &str, panel: &FrfPanel) -> Result<Prepared, PlotError> {
    if panel.traces.is_empty() {
        return Err(PlotError::Empty {
            plot: format!("{plot}, panel {}", panel.title),
            what: "trace list",
        });
    }
    let mut magnitude = Vec::with_capacity(panel.traces.len());
    let mut phase = Vec::with_capacity(panel.traces.len());
    let mut skipped = 0;
    for t in &panel.traces {
        check_series(plot, &t.name, t.frequency_hz.len(), t.magnitude.len())?;
        check_series(plot, &t.name, t.frequency_hz.len(), t.phase_deg.len())?;
        let m: Vec<_> = t
            .frequency_hz
            .iter()
            .zip(&t.magnitude)
            .map(
                |(&f, &v)| match (f.is_finite(), Scale::Log10.transform(v)) {
                    (true, Some(tv)) => Some((f, tv)),
                    _ => None,
                },
            )
            .collect();
        let ph: Vec<_> = t
            .frequency_hz
            .iter()
            .zip(&t.phase_deg)
            .map(|(&f, &v)| (f.is_finite() && v.is_finite()).then_some((f, wrap_deg(v))))
            .collect();
        skipped += m.iter().filter(|q| q.is_none()).count();
        magnitude.push(m);
        phase.push(ph);
    }
    let all_m = || magnitude.iter().flatten().flatten();
    let (Some(xe), Some(ye)) = (extent(all_m().map(|q| q.0)), extent(all_m().map(|q| q.1))) else {
        return Err(PlotError::NoPlottableData {
            plot: format!("{plot}, panel {}", panel.title),
            skipped,
        });
    };
    Ok(Prepared {
        x: AxisSpec::resolve(plot, "x", Scale::Linear, Some(xe), None, Fit::Tight)?,
        y_mag: AxisSpec::resolve(plot, "y", Scale::Log10, Some(ye), None, Fit::Nice)?,
        y_phase: phase_axis(plot)?,
        magnitude,
        phase,
        skipped,
        spans: match &panel.quality {
            Some(q) => {
                check_series(plot, &q.label, q.frequency_hz.len(), q.value.len())?;
                low_quality_spans(q)
            }
            None => Vec::new(),
        },
    })
}

/// [−200°, 200°] with ticks every 90°: the wrap at ±180° stays off the frame.
fn phase_axis(plot: &str) -> Result<AxisSpec, PlotError> {
    let mut a = AxisSpec::resolve(
        plot,
        "phase",
        Scale::Linear,
        None,
        Some((-200.0, 200.0)),
        Fit::Tight,
    )?;
    a.bold = vec![-180.0, -90.0, 0.0, 90.0, 180.0];
    a.light.clear();
    Ok(a)
}

/// Phase folded into (−180°, 180°].
fn wrap_deg(v: f64) -> f64 {
    let w = v.rem_euclid(360.0);
    if w > 180.0 {
        w - 360.0
    } else {
        w
    }
}

fn draw_panel(
    plot: &str,
    area: &Root<'_>,
    panel: &FrfPanel,
    prep: &Prepared,
    magnitude_label: &str,
) -> Result<(), PlotError> {
    let (_, h) = area.dim_in_pixel();
    let (top, bottom) = area.split_vertically((h as f64 * MAGNITUDE_SHARE) as u32);
    let narrow = Margins {
        left: 70,
        bottom: 24,
        ..Margins::default()
    };
    let mut ch = chart(plot, &top, &panel.title, &prep.x, &prep.y_mag, narrow)?;
    draw_mesh(
        plot,
        &mut ch,
        &prep.x,
        &prep.y_mag,
        "",
        magnitude_label,
        true,
    )?;
    shade(plot, &mut ch, &prep.spans, &prep.x, &prep.y_mag)?;
    for (i, (t, pts)) in panel.traces.iter().zip(&prep.magnitude).enumerate() {
        let style = stroke(t.color.unwrap_or_else(|| Rgb::palette(i)), t.style, 2);
        let pieces = drawn_pieces(&ch, pts, &prep.x, &prep.y_mag);
        ch.draw_series(pieces.into_iter().map(|q| PathElement::new(q, style)))
            .map_err(render_err(plot))?;
    }
    let lower = Margins {
        left: 70,
        bottom: 44,
        ..Margins::default()
    };
    let mut ch = chart(plot, &bottom, "", &prep.x, &prep.y_phase, lower)?;
    draw_mesh(
        plot,
        &mut ch,
        &prep.x,
        &prep.y_phase,
        "Frequency [Hz]",
        "Phase [°]",
        true,
    )?;
    shade(plot, &mut ch, &prep.spans, &prep.x, &prep.y_phase)?;
    for (i, (t, pts)) in panel.traces.iter().zip(&prep.phase).enumerate() {
        let style = stroke(t.color.unwrap_or_else(|| Rgb::palette(i)), t.style, 1);
        // Phase wraps at ±180°: a jump of more than 180° between lines is a wrap, not
        // a change, and is drawn as a break.
        let broken = break_wraps(pts);
        let pieces = drawn_pieces(&ch, &broken, &prep.x, &prep.y_phase);
        ch.draw_series(pieces.into_iter().map(|q| PathElement::new(q, style)))
            .map_err(render_err(plot))?;
    }
    Ok(())
}

/// The low-quality spans as light rectangles over the whole height of the chart, clipped
/// to its frequency axis.
fn shade(
    plot: &str,
    ch: &mut crate::canvas::Chart<'_, '_>,
    spans: &[(f64, f64)],
    x: &AxisSpec,
    y: &AxisSpec,
) -> Result<(), PlotError> {
    // The frequency axis is linear: plot space is Hz.
    let (x0, x1) = (x.lo, x.hi);
    let (y0, y1) = (y.lo, y.hi);
    let colour = RGBAColor(
        LOW_QUALITY_SHADE.0,
        LOW_QUALITY_SHADE.1,
        LOW_QUALITY_SHADE.2,
        1.0,
    );
    let rects = spans
        .iter()
        .map(|&(a, b)| (a.max(x0), b.min(x1)))
        .filter(|(a, b)| b > a)
        .map(|(a, b)| Rectangle::new([(a, y1), (b, y0)], fill(colour)));
    ch.draw_series(rects).map_err(render_err(plot))?;
    Ok(())
}

fn break_wraps(pts: &[Option<(f64, f64)>]) -> Vec<Option<(f64, f64)>> {
    let mut out = Vec::with_capacity(pts.len() + 8);
    let mut prev: Option<(f64, f64)> = None;
    for &p in pts {
        if let (Some(a), Some(b)) = (prev, p) {
            if (b.1 - a.1).abs() > 180.0 {
                out.push(None);
            }
        }
        out.push(p);
        prev = p;
    }
    out
}

/// The first panel's trace names with their line samples, in one row under the title.
fn draw_shared_legend(
    plot: &str,
    root: &Root<'_>,
    panels: &[FrfPanel],
    y: i32,
) -> Result<(), PlotError> {
    let panel = &panels[0];
    let label = text_style(
        14,
        RGBAColor(0, 0, 0, 1.0),
        Pos::new(HPos::Left, VPos::Center),
    );
    let mut x = 20;
    let mid = y + LEGEND_ROW as i32 / 2;
    for (i, t) in panel.traces.iter().enumerate() {
        let style = stroke(t.color.unwrap_or_else(|| Rgb::palette(i)), t.style, 2);
        root.draw(&PathElement::new(vec![(x, mid), (x + 28, mid)], style))
            .map_err(render_err(plot))?;
        root.draw(&Text::new(t.name.clone(), (x + 34, mid), label.clone()))
            .map_err(render_err(plot))?;
        let w = root
            .estimate_text_size(&t.name, &label)
            .map(|(w, _)| w as i32)
            .unwrap_or(8 * t.name.len() as i32);
        x += 34 + w + 24;
    }
    // The shading's legend entry, when any panel has a quality measure.
    if let Some(q) = panels.iter().find_map(|p| p.quality.as_ref()) {
        let colour = RGBAColor(
            LOW_QUALITY_SHADE.0,
            LOW_QUALITY_SHADE.1,
            LOW_QUALITY_SHADE.2,
            1.0,
        );
        root.draw(&Rectangle::new(
            [(x, mid - 7), (x + 28, mid + 7)],
            fill(colour),
        ))
        .map_err(render_err(plot))?;
        root.draw(&Text::new(q.label.clone(), (x + 34, mid), label))
            .map_err(render_err(plot))?;
    }
    Ok(())
}
