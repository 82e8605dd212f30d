//! Small multiples of FRFs: one panel per channel, magnitude over phase, so that a fit
//! can be read against its data channel by channel instead of under 17 other curves.

use plotters::element::{PathElement, Text};
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::RGBAColor;

use crate::axis::{extent, AxisSpec, Fit, Scale};
use crate::canvas::{
    chart, clip_polyline, draw_mesh, footnote, plot_name, render_err, render_svg, skipped_note,
    text_style, Margins, Root, TITLE_SIZE,
};
use crate::error::PlotError;
use crate::line::check_series;
use crate::style::{stroke, LineStyle, PlotSize, Rgb};

/// One curve of a panel: a complex FRF given as magnitude and phase.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FrfTrace {
    /// Legend text (shared by every panel: the first panel's names are listed once).
    pub name: String,
    pub frequency_hz: Vec<f64>,
    /// |H|, drawn on a log axis (values ≤ 0 are not drawn).
    pub magnitude: Vec<f64>,
    /// Phase in degrees, drawn in [−180, 180].
    pub phase_deg: Vec<f64>,
    pub style: LineStyle,
    /// `None`: colour `i` of [`Rgb::palette`] for the `i`-th trace of the panel.
    pub color: Option<Rgb>,
}

/// One channel's panel.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FrfPanel {
    /// E.g. the channel id.
    pub title: String,
    pub traces: Vec<FrfTrace>,
}

/// Input of [`frf_panels`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FrfPanels {
    pub title: String,
    /// Magnitude axis description, e.g. "|H| [m/s²/N]".
    pub magnitude_label: String,
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
        draw_shared_legend(&plot, root, &p.panels[0], 44)?;
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
    for (i, (t, pts)) in panel.traces.iter().zip(&prep.magnitude).enumerate() {
        let style = stroke(t.color.unwrap_or_else(|| Rgb::palette(i)), t.style, 2);
        let pieces = clip_polyline(pts, &prep.x, &prep.y_mag);
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
    for (i, (t, pts)) in panel.traces.iter().zip(&prep.phase).enumerate() {
        let style = stroke(t.color.unwrap_or_else(|| Rgb::palette(i)), t.style, 1);
        // Phase wraps at ±180°: a jump of more than 180° between lines is a wrap, not
        // a change, and is drawn as a break.
        let broken = break_wraps(pts);
        let pieces = clip_polyline(&broken, &prep.x, &prep.y_phase);
        ch.draw_series(pieces.into_iter().map(|q| PathElement::new(q, style)))
            .map_err(render_err(plot))?;
    }
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
    panel: &FrfPanel,
    y: i32,
) -> Result<(), PlotError> {
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
    Ok(())
}
