//! Shared drawing machinery: the SVG document, a cartesian chart with our
//! axes, legends, footnotes and polyline clipping.

use plotters::chart::{ChartBuilder, ChartContext};
use plotters::coord::cartesian::Cartesian2d;
use plotters::coord::Shift;
use plotters::drawing::{DrawingArea, IntoDrawingArea};
use plotters::element::{PathElement, Text};
use plotters::prelude::SVGBackend;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{Color, IntoFont, RGBAColor, ShapeStyle, TextStyle, WHITE};

use crate::axis::{Axis, AxisSpec};
use crate::error::PlotError;
use crate::style::{finish_svg, LegendPosition, PlotSize};

pub(crate) const FONT: &str = "sans-serif";
/// Font sizes in plotters units (the SVG backend writes size/1.24 px).
pub(crate) const LABEL_SIZE: u32 = 16;
pub(crate) const DESC_SIZE: u32 = 18;
pub(crate) const TITLE_SIZE: u32 = 24;
pub(crate) type Root<'a> = DrawingArea<SVGBackend<'a>, Shift>;
pub(crate) type Chart<'a, 'b> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<Axis, Axis>>;

/// Name used for a plot in error messages.
pub(crate) fn plot_name(title: &str) -> String {
    if title.trim().is_empty() {
        "untitled".to_string()
    } else {
        title.to_string()
    }
}

/// Convert any plotters error into ours.
pub(crate) fn render_err<E: std::fmt::Debug>(plot: &str) -> impl Fn(E) -> PlotError + '_ {
    move |e| PlotError::Render {
        plot: plot.to_string(),
        message: format!("{e:?}"),
    }
}

/// Create an SVG document of `size`, let `draw` fill it, and return the text.
pub(crate) fn render_svg<F>(plot: &str, size: PlotSize, draw: F) -> Result<String, PlotError>
where
    F: FnOnce(&Root<'_>) -> Result<(), PlotError>,
{
    if size.width < 200 || size.height < 150 {
        return Err(PlotError::InvalidSize {
            plot: plot.to_string(),
            width: size.width,
            height: size.height,
        });
    }
    let mut buf = String::new();
    {
        let root = SVGBackend::with_string(&mut buf, (size.width, size.height)).into_drawing_area();
        root.fill(&WHITE).map_err(render_err(plot))?;
        draw(&root)?;
        root.present().map_err(render_err(plot))?;
    }
    Ok(finish_svg(buf))
}

/// Space reserved around the plotting area, in pixels.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Margins {
    pub left: u32,
    pub bottom: u32,
    pub right: u32,
    /// Extra space above the plotting area (to align with a titled neighbour).
    pub top: u32,
    /// Space right of everything for an outside legend ([`legend_width`]).
    pub legend: u32,
}

impl Default for Margins {
    fn default() -> Self {
        Margins {
            left: 80,
            bottom: 55,
            right: 0,
            top: 0,
            legend: 0,
        }
    }
}

/// Build a titled cartesian chart on `area` with the given axes.
pub(crate) fn chart<'a, 'b>(
    plot: &str,
    area: &'a Root<'b>,
    title: &str,
    x: &AxisSpec,
    y: &AxisSpec,
    margins: Margins,
) -> Result<Chart<'a, 'b>, PlotError> {
    let mut builder = ChartBuilder::on(area);
    if !title.is_empty() {
        builder.caption(title, (FONT, TITLE_SIZE).into_font());
    }
    builder
        .margin(12)
        .margin_top(12 + margins.top)
        .margin_right(20 + margins.legend)
        .x_label_area_size(margins.bottom)
        .y_label_area_size(margins.left);
    if margins.right > 0 {
        builder.right_y_label_area_size(margins.right);
    }
    builder
        .build_cartesian_2d(x.coord(), y.coord())
        .map_err(render_err(plot))
}

/// Grid, ticks and axis descriptions.
pub(crate) fn draw_mesh(
    plot: &str,
    chart: &mut Chart<'_, '_>,
    x: &AxisSpec,
    y: &AxisSpec,
    x_desc: &str,
    y_desc: &str,
    x_grid: bool,
) -> Result<(), PlotError> {
    let xf = |v: &f64| x.label(*v);
    let yf = |v: &f64| y.label(*v);
    let mut mesh = chart.configure_mesh();
    mesh.x_label_formatter(&xf)
        .y_label_formatter(&yf)
        .x_desc(x_desc)
        .y_desc(y_desc)
        .label_style((FONT, LABEL_SIZE))
        .axis_desc_style((FONT, DESC_SIZE))
        .bold_line_style(RGBAColor(0, 0, 0, 0.15))
        .light_line_style(RGBAColor(0, 0, 0, 0.05));
    if !x_grid {
        mesh.disable_x_mesh();
    }
    mesh.draw().map_err(render_err(plot))
}

/// Height taken by a chart title drawn with `chart` (plotters: text height
/// plus twice min(height/2, 5) padding).
pub(crate) fn title_height(root: &Root<'_>, title: &str) -> u32 {
    if title.is_empty() {
        return 0;
    }
    let style = TextStyle::from((FONT, TITLE_SIZE).into_font());
    let h = root
        .estimate_text_size(title, &style)
        .map(|(_, h)| h)
        .unwrap_or(0);
    h + 2 * (h / 2).min(5)
}

/// Plotters' legend layout: the sample's width and the box's inner margin.
const LEGEND_SAMPLE: u32 = 30;
const LEGEND_MARGIN: u32 = 10;

/// Width to reserve right of the chart for an outside legend listing `names` (0 for any
/// other position, or when there is nothing to list).
pub(crate) fn legend_width<'n>(
    root: &Root<'_>,
    names: impl IntoIterator<Item = &'n str>,
    position: LegendPosition,
) -> u32 {
    if position != LegendPosition::Outside {
        return 0;
    }
    let style = TextStyle::from((FONT, LABEL_SIZE).into_font());
    let widest = names
        .into_iter()
        .filter(|n| !n.is_empty())
        .map(|n| {
            root.estimate_text_size(n, &style)
                .map(|(w, _)| w)
                .unwrap_or(0)
        })
        .max();
    match widest {
        Some(w) => w + LEGEND_SAMPLE + LEGEND_MARGIN + crate::style::OUTSIDE_GAP,
        None => 0,
    }
}

/// The sample drawn before a legend entry's text.
#[derive(Debug, Clone)]
pub(crate) enum Glyph {
    /// A short stroke (curves, reference lines).
    Line(ShapeStyle),
    /// A filled square (bars).
    Block(RGBAColor),
    /// A filled dot (scatter points).
    Dot(RGBAColor),
    /// A coloured letter (stabilisation classes).
    Letter(&'static str, RGBAColor),
}

/// Legend entries of one figure, in drawing order.
#[derive(Debug, Clone, Default)]
pub(crate) struct Legend(pub Vec<(String, Glyph)>);

impl Legend {
    pub fn push(&mut self, name: impl Into<String>, glyph: Glyph) {
        let name = name.into();
        if !name.is_empty() {
            self.0.push((name, glyph));
        }
    }
}

/// Draw the legend collected from `.label()` calls inside the plotting area, or, for
/// [`LegendPosition::Outside`], `outside` in the space reserved right of the chart
/// (plotters clamps elements to the plotting area, so that one is drawn on the canvas).
pub(crate) fn draw_legend<'a, 'b: 'a>(
    plot: &str,
    root: &Root<'_>,
    chart: &mut Chart<'a, 'b>,
    position: LegendPosition,
    outside: &Legend,
) -> Result<(), PlotError> {
    if position == LegendPosition::Outside {
        let (_, top) = chart.plotting_area().get_base_pixel();
        let (root_w, _) = root.dim_in_pixel();
        let width = legend_width(root, outside.0.iter().map(|e| e.0.as_str()), position);
        let left = root_w as i32 - width as i32 + crate::style::OUTSIDE_GAP as i32;
        return draw_entries(plot, root, outside, (left, top));
    }
    let Some(pos) = position.to_plotters() else {
        return Ok(());
    };
    chart
        .configure_series_labels()
        .position(pos)
        .margin(LEGEND_MARGIN)
        .label_font((FONT, LABEL_SIZE))
        .background_style(RGBAColor(255, 255, 255, 0.85))
        .border_style(RGBAColor(0, 0, 0, 0.5))
        .draw()
        .map_err(render_err(plot))
}

/// One row per entry from `top_left` down: glyph, then the name.
fn draw_entries(
    plot: &str,
    root: &Root<'_>,
    legend: &Legend,
    top_left: (i32, i32),
) -> Result<(), PlotError> {
    use plotters::element::{Circle, PathElement, Rectangle};
    let text = text_style(
        LABEL_SIZE,
        RGBAColor(0, 0, 0, 1.0),
        Pos::new(HPos::Left, VPos::Center),
    );
    let row = 22;
    for (k, (name, glyph)) in legend.0.iter().enumerate() {
        let (x, y) = (top_left.0, top_left.1 + 12 + k as i32 * row);
        let drawn = match glyph {
            Glyph::Line(style) => root.draw(&PathElement::new(vec![(x, y), (x + 24, y)], *style)),
            Glyph::Block(c) => {
                root.draw(&Rectangle::new([(x + 5, y - 6), (x + 19, y + 6)], fill(*c)))
            }
            Glyph::Dot(c) => root.draw(&Circle::new((x + 12, y), 4, fill(*c))),
            Glyph::Letter(l, c) => root.draw(&Text::new(
                l.to_string(),
                (x + 12, y),
                text_style(13, *c, Pos::new(HPos::Center, VPos::Center)),
            )),
        };
        drawn.map_err(render_err(plot))?;
        root.draw(&Text::new(
            name.clone(),
            (x + LEGEND_SAMPLE as i32, y),
            text.clone(),
        ))
        .map_err(render_err(plot))?;
    }
    Ok(())
}

/// Small grey note at the bottom-left corner of the canvas, e.g. telling the
/// reader how many points could not be shown.
pub(crate) fn footnote(plot: &str, root: &Root<'_>, text: &str) -> Result<(), PlotError> {
    let (_, h) = root.dim_in_pixel();
    let style = text_style(
        12,
        RGBAColor(90, 90, 90, 1.0),
        Pos::new(HPos::Left, VPos::Bottom),
    );
    root.draw(&Text::new(text.to_string(), (6, h as i32 - 4), style))
        .map_err(render_err(plot))
}

/// Footnote text for `n` skipped points, or `None` if nothing was skipped.
pub(crate) fn skipped_note(n: usize, why: &str) -> Option<String> {
    match n {
        0 => None,
        1 => Some(format!("1 point not shown ({why})")),
        n => Some(format!("{n} points not shown ({why})")),
    }
}

/// Split a plot-space polyline (with `None` for unplottable points) into the
/// visible pieces inside `[x.lo, x.hi] × [y.lo, y.hi]`. Gaps break the line
/// rather than bridging across missing data; segments crossing the border are
/// cut at the border (Liang–Barsky), since plotters does not clip paths.
pub(crate) fn clip_polyline(
    points: &[Option<(f64, f64)>],
    x: &AxisSpec,
    y: &AxisSpec,
) -> Vec<Vec<(f64, f64)>> {
    let mut pieces: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut current: Vec<(f64, f64)> = Vec::new();
    let flush = |current: &mut Vec<(f64, f64)>, pieces: &mut Vec<Vec<(f64, f64)>>| {
        if !current.is_empty() {
            pieces.push(std::mem::take(current));
        }
    };
    let inside = |p: (f64, f64)| x.contains(p.0) && y.contains(p.1);
    let mut prev: Option<(f64, f64)> = None;
    for p in points {
        match (*p, prev) {
            (None, _) => {
                flush(&mut current, &mut pieces);
                prev = None;
            }
            (Some(q), None) => {
                if inside(q) {
                    current.push(q);
                }
                prev = Some(q);
            }
            (Some(q), Some(pq)) => {
                match clip_segment(pq, q, x, y) {
                    Some((a, b)) => {
                        if current.last() != Some(&a) {
                            flush(&mut current, &mut pieces);
                            current.push(a);
                        }
                        current.push(b);
                        if b != q {
                            flush(&mut current, &mut pieces);
                        }
                    }
                    None => flush(&mut current, &mut pieces),
                }
                prev = Some(q);
            }
        }
    }
    flush(&mut current, &mut pieces);
    pieces
}

/// The pieces of a polyline to draw on `ch`: [`clip_polyline`], each piece thinned by
/// [`decimate_to_pixels`] in the chart's own pixel columns.
pub(crate) fn drawn_pieces(
    ch: &Chart<'_, '_>,
    points: &[Option<(f64, f64)>],
    x: &AxisSpec,
    y: &AxisSpec,
) -> Vec<Vec<(f64, f64)>> {
    clip_polyline(points, x, y)
        .into_iter()
        .map(|piece| decimate_to_pixels(piece, |p| ch.backend_coord(&p).0))
        .collect()
}

/// Thins a visible polyline to what the pixel grid can show, so that a dense FRF (thousands
/// of lines in a panel a few hundred pixels wide) does not write thousands of coordinates
/// that land on the same pixel column.
///
/// `column` maps a point to its pixel column (the chart's own mapping). Of each run of
/// consecutive points in one column only the first, the one of lowest value, the one of
/// highest value and the last are kept, in their original order: a per-pixel-column
/// min/max envelope. The drawn line covers the same pixels as the full one — within a
/// column it still spans from the lowest to the highest point, and it enters and leaves
/// the column where the full line did — so peaks and notches survive; the extremes are
/// chosen by value (not by rounded pixel), so the curve's maximum and minimum points are
/// kept exactly. At most four points per column remain; a curve sparser than the pixels
/// comes back unchanged.
pub(crate) fn decimate_to_pixels(
    piece: Vec<(f64, f64)>,
    column: impl Fn((f64, f64)) -> i32,
) -> Vec<(f64, f64)> {
    let cols: Vec<i32> = piece.iter().map(|&p| column(p)).collect();
    if cols.windows(2).all(|w| w[0] != w[1]) {
        return piece;
    }
    let mut out = Vec::with_capacity(piece.len().min(4 * cols.len()));
    let mut start = 0;
    while start < piece.len() {
        let mut end = start + 1;
        while end < piece.len() && cols[end] == cols[start] {
            end += 1;
        }
        let run = start..end;
        let by_value = |a: &usize, b: &usize| piece[*a].1.total_cmp(&piece[*b].1);
        let lowest = run.clone().min_by(by_value).unwrap_or(start);
        let highest = run.clone().max_by(by_value).unwrap_or(start);
        let mut keep = [start, lowest, highest, end - 1];
        keep.sort_unstable();
        let mut last_kept = None;
        for k in keep {
            if last_kept != Some(k) {
                out.push(piece[k]);
                last_kept = Some(k);
            }
        }
        start = end;
    }
    out
}

fn clip_segment(
    a: (f64, f64),
    b: (f64, f64),
    x: &AxisSpec,
    y: &AxisSpec,
) -> Option<((f64, f64), (f64, f64))> {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-dx, a.0 - x.lo),
        (dx, x.hi - a.0),
        (-dy, a.1 - y.lo),
        (dy, y.hi - a.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    if t0 > t1 {
        return None;
    }
    let at = |t: f64| {
        if t == 0.0 {
            a
        } else if t == 1.0 {
            b
        } else {
            (a.0 + t * dx, a.1 + t * dy)
        }
    };
    Some((at(t0), at(t1)))
}

/// A label text style of `size` px in colour `c`.
pub(crate) fn text_style(size: u32, c: RGBAColor, pos: Pos) -> TextStyle<'static> {
    TextStyle {
        font: (FONT, size).into_font(),
        color: c.to_backend_color(),
        pos,
    }
}

/// An error bar in plot coordinates: the whisker from `lo` to `hi` at `x`, with caps
/// `cap` to each side (one black `<polyline>`, caps at both ends).
pub(crate) fn error_bar(x: f64, cap: f64, lo: f64, hi: f64) -> PathElement<(f64, f64)> {
    let whisker = ShapeStyle {
        color: crate::style::Rgb::BLACK.rgba(1.0),
        filled: false,
        stroke_width: 1,
    };
    PathElement::new(
        vec![
            (x - cap, lo),
            (x + cap, lo),
            (x, lo),
            (x, hi),
            (x - cap, hi),
            (x + cap, hi),
        ],
        whisker,
    )
}

/// The legend glyph of a line series: a 24-pixel stroke in the series' style.
pub(crate) fn line_glyph(style: ShapeStyle) -> impl Fn((i32, i32)) -> PathElement<(i32, i32)> {
    move |(px, py)| PathElement::new(vec![(px, py), (px + 24, py)], style)
}

/// Solid filled style.
pub(crate) fn fill(c: RGBAColor) -> ShapeStyle {
    ShapeStyle {
        color: c,
        filled: true,
        stroke_width: 0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::axis::{Fit, Scale};

    fn unit_axes() -> (AxisSpec, AxisSpec) {
        let a =
            AxisSpec::resolve("t", "x", Scale::Linear, None, Some((0.0, 1.0)), Fit::Tight).unwrap();
        (a.clone(), a)
    }

    #[test]
    fn gaps_break_the_line() {
        let (x, y) = unit_axes();
        let pts = [
            Some((0.1, 0.1)),
            Some((0.2, 0.2)),
            None,
            Some((0.4, 0.4)),
            Some((0.5, 0.5)),
        ];
        let pieces = clip_polyline(&pts, &x, &y);
        assert_eq!(
            pieces,
            vec![vec![(0.1, 0.1), (0.2, 0.2)], vec![(0.4, 0.4), (0.5, 0.5)]]
        );
    }

    #[test]
    fn excursions_are_cut_at_the_border() {
        let (x, y) = unit_axes();
        let pts = [Some((0.0, 0.5)), Some((0.5, 1.5)), Some((1.0, 0.5))];
        let pieces = clip_polyline(&pts, &x, &y);
        assert_eq!(pieces.len(), 2);
        assert_eq!(pieces[0], vec![(0.0, 0.5), (0.25, 1.0)]);
        assert_eq!(pieces[1], vec![(0.75, 1.0), (1.0, 0.5)]);
        // A segment entirely outside disappears.
        let out = [Some((2.0, 2.0)), Some((3.0, 3.0))];
        assert!(clip_polyline(&out, &x, &y).is_empty());
    }

    #[test]
    fn decimation_keeps_each_columns_entry_extremes_and_exit() {
        // Ten points per column, columns 0..3; the column's extremes are interior points.
        let piece: Vec<(f64, f64)> = (0..30)
            .map(|i| {
                (
                    i as f64 / 10.0,
                    ((i * 7) % 10) as f64 + (i / 10) as f64 * 0.5,
                )
            })
            .collect();
        let thin = decimate_to_pixels(piece.clone(), |p| p.0.floor() as i32);
        for c in 0..3 {
            let run: Vec<(f64, f64)> = piece[10 * c..10 * c + 10].to_vec();
            let kept: Vec<(f64, f64)> = thin
                .iter()
                .copied()
                .filter(|p| p.0.floor() as i32 == c as i32)
                .collect();
            let lo = run.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
            let hi = run.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
            assert!(kept.len() <= 4, "column {c}: {kept:?}");
            assert_eq!(kept.first(), run.first(), "column {c} entry");
            assert_eq!(kept.last(), run.last(), "column {c} exit");
            assert!(kept.iter().any(|p| p.1 == lo) && kept.iter().any(|p| p.1 == hi));
            // Kept points are in their original order.
            assert!(kept.windows(2).all(|w| w[0].0 < w[1].0));
        }
        // A curve sparser than the pixels is left alone.
        let sparse: Vec<(f64, f64)> = (0..5).map(|i| (i as f64, i as f64)).collect();
        assert_eq!(decimate_to_pixels(sparse.clone(), |p| p.0 as i32), sparse);
    }
}
