//! Several named curves on one frequency axis: FRF overlays, NI curves, MIFs.

use plotters::element::{PathElement, Text};
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{FontTransform, RGBAColor};

use crate::axis::{extent, AxisSpec, Fit, Scale};
use crate::canvas::{
    chart, draw_legend, draw_mesh, drawn_pieces, footnote, legend_width, plot_name, render_err,
    render_svg, skipped_note, text_style, Chart, Glyph, Legend, Margins,
};
use crate::error::PlotError;
use crate::style::{marker_stroke, stroke, LegendPosition, LineStyle, PlotSize, Rgb};

/// One named curve.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// Abscissa of every point, e.g. frequency (Hz).
    pub x: Vec<f64>,
    /// Same length as `x`. Non-finite values (and non-positive ones on log/dB
    /// axes) are not drawn; the curve is broken there.
    pub y: Vec<f64>,
    /// Solid, dashed or dotted.
    pub style: LineStyle,
    /// `None`: colour `i` of [`Rgb::palette`] for the `i`-th series.
    pub color: Option<Rgb>,
}

impl Series {
    /// A solid series with the palette colour.
    pub fn new(name: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Series {
            name: name.into(),
            x,
            y,
            ..Default::default()
        }
    }

    /// Sets the dash pattern.
    pub fn with_style(mut self, style: LineStyle) -> Self {
        self.style = style;
        self
    }

    /// Fixes the colour instead of the palette's.
    pub fn with_color(mut self, color: Rgb) -> Self {
        self.color = Some(color);
        self
    }
}

/// A labelled vertical line, e.g. an identified natural frequency.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct VerticalMarker {
    /// Position on the x axis, in its data units.
    pub x: f64,
    /// Printed vertically beside the line at the top; may be empty.
    pub label: String,
}

impl VerticalMarker {
    /// A marker at `x` with this label.
    pub fn new(x: f64, label: impl Into<String>) -> Self {
        VerticalMarker {
            x,
            label: label.into(),
        }
    }
}

/// Input of [`line_plot`]. Start from `LinePlot::default()` and fill in.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LinePlot {
    /// Printed above the plot.
    pub title: String,
    /// E.g. "Frequency \[Hz\]".
    pub x_label: String,
    /// E.g. "|H| [m/s²/N]".
    pub y_label: String,
    /// Linear, log10 or dB (`20 log10`) y axis.
    pub y_scale: Scale,
    /// The curves, drawn in order (later ones on top).
    pub series: Vec<Series>,
    /// Vertical lines drawn over the curves.
    pub markers: Vec<VerticalMarker>,
    /// Fixed x limits; default: the data extent.
    pub x_range: Option<(f64, f64)>,
    /// Fixed y limits in axis units (dB for [`Scale::Decibel`]); default: the
    /// data extent, on whole decades for [`Scale::Log10`].
    pub y_range: Option<(f64, f64)>,
    /// Where the legend goes.
    pub legend: LegendPosition,
    /// Canvas size.
    pub size: PlotSize,
}

/// Render a [`LinePlot`] as an SVG document.
///
/// Each series becomes one `<polyline>` per contiguous run of plottable
/// points (so a clean series is exactly one polyline), in its palette colour;
/// dashed/dotted series carry `stroke-dasharray`. Points that cannot be shown
/// are counted in a footnote at the bottom of the figure.
///
/// Errors: no series, a series with no points, `x`/`y` length mismatch, no
/// plottable point at all, invalid fixed ranges, canvas too small.
pub fn line_plot(p: &LinePlot) -> Result<String, PlotError> {
    let plot = plot_name(&p.title);
    if p.series.is_empty() {
        return Err(PlotError::Empty {
            plot,
            what: "series list",
        });
    }
    let mut transformed: Vec<Vec<Option<(f64, f64)>>> = Vec::with_capacity(p.series.len());
    let mut skipped = 0usize;
    for s in &p.series {
        check_series(&plot, &s.name, s.x.len(), s.y.len())?;
        let pts: Vec<Option<(f64, f64)>> =
            s.x.iter()
                .zip(&s.y)
                .map(|(&x, &y)| match (x.is_finite(), p.y_scale.transform(y)) {
                    (true, Some(ty)) => Some((x, ty)),
                    _ => None,
                })
                .collect();
        skipped += pts.iter().filter(|q| q.is_none()).count();
        transformed.push(pts);
    }
    let all = || transformed.iter().flatten().flatten();
    let (Some(xe), Some(ye)) = (extent(all().map(|q| q.0)), extent(all().map(|q| q.1))) else {
        return Err(PlotError::NoPlottableData { plot, skipped });
    };
    let x = AxisSpec::resolve(&plot, "x", Scale::Linear, Some(xe), p.x_range, Fit::Tight)?;
    let y = AxisSpec::resolve(&plot, "y", p.y_scale, Some(ye), p.y_range, Fit::Nice)?;

    render_svg(&plot, p.size, |root| {
        let margins = Margins {
            legend: legend_width(root, p.series.iter().map(|s| s.name.as_str()), p.legend),
            ..Margins::default()
        };
        let mut ch = chart(&plot, root, &p.title, &x, &y, margins)?;
        draw_mesh(&plot, &mut ch, &x, &y, &p.x_label, &p.y_label, true)?;
        draw_vertical_markers(&plot, &mut ch, &p.markers, &x, &y)?;
        let mut legend = Legend::default();
        for (i, (s, pts)) in p.series.iter().zip(&transformed).enumerate() {
            let colour = s.color.unwrap_or_else(|| Rgb::palette(i));
            let style = stroke(colour, s.style, 2);
            legend.push(s.name.clone(), Glyph::Line(style));
            let pieces = drawn_pieces(&ch, pts, &x, &y);
            ch.draw_series(
                pieces
                    .into_iter()
                    .map(|piece| PathElement::new(piece, style)),
            )
            .map_err(render_err(&plot))?
            .label(s.name.clone())
            .legend(move |(px, py)| PathElement::new(vec![(px, py), (px + 24, py)], style));
        }
        draw_legend(&plot, root, &mut ch, p.legend, &legend)?;
        if let Some(note) = skipped_note(skipped, "non-finite, or ≤ 0 on a log/dB axis") {
            footnote(&plot, root, &note)?;
        }
        Ok(())
    })
}

pub(crate) fn check_series(
    plot: &str,
    name: &str,
    x_len: usize,
    y_len: usize,
) -> Result<(), PlotError> {
    if x_len == 0 {
        return Err(PlotError::EmptySeries {
            plot: plot.to_string(),
            series: name.to_string(),
        });
    }
    if y_len != x_len {
        return Err(PlotError::LengthMismatch {
            plot: plot.to_string(),
            series: name.to_string(),
            what: "y",
            expected: x_len,
            found: y_len,
        });
    }
    Ok(())
}

/// Dashed grey vertical lines over the full height with rotated labels at the
/// top; markers outside the x range (or non-finite) are not drawn.
pub(crate) fn draw_vertical_markers(
    plot: &str,
    ch: &mut Chart<'_, '_>,
    markers: &[VerticalMarker],
    x: &AxisSpec,
    y: &AxisSpec,
) -> Result<(), PlotError> {
    let visible: Vec<&VerticalMarker> = markers
        .iter()
        .filter(|m| m.x.is_finite() && x.contains(m.x))
        .collect();
    let line = marker_stroke(Rgb::GREY);
    ch.draw_series(
        visible
            .iter()
            .map(|m| PathElement::new(vec![(m.x, y.lo), (m.x, y.hi)], line)),
    )
    .map_err(render_err(plot))?;
    // Rotated 270° the text reads bottom-to-top; anchoring its start at the
    // top edge makes it run downwards from there, just right of the line.
    let label_style = text_style(
        12,
        RGBAColor(60, 60, 60, 1.0),
        Pos::new(HPos::Right, VPos::Top),
    )
    .transform(FontTransform::Rotate270);
    ch.draw_series(
        visible
            .iter()
            .filter(|m| !m.label.is_empty())
            .map(|m| Text::new(m.label.clone(), (m.x, y.hi), label_style.clone())),
    )
    .map_err(render_err(plot))?;
    Ok(())
}
