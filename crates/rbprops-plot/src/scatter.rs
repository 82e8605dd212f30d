//! Scatter plot of x/y points with optional y error bars, e.g. estimated vs
//! true values.

use plotters::element::{Circle, PathElement};

use crate::axis::{extent, AxisSpec, Fit, Scale};
use crate::canvas::{
    chart, draw_legend, draw_mesh, error_bar, fill, footnote, legend_width, line_glyph, plot_name,
    render_err, render_svg, skipped_note, Glyph, Legend, Margins,
};
use crate::error::PlotError;
use crate::line::check_series;
use crate::style::{stroke, LegendPosition, LineStyle, PlotSize, Rgb};

/// One named set of points.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ScatterSeries {
    /// Legend text.
    pub name: String,
    /// Abscissae, e.g. the true values.
    pub x: Vec<f64>,
    /// Ordinates, same length as `x`, e.g. the estimates.
    pub y: Vec<f64>,
    /// Optional symmetric error half-widths in y (e.g. 1.96σ), one per point.
    pub y_errors: Option<Vec<f64>>,
    /// `None`: colour `i` of [`Rgb::palette`] for the `i`-th series.
    pub color: Option<Rgb>,
}

impl ScatterSeries {
    /// A series with the palette colour and no error bars.
    pub fn new(name: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        ScatterSeries {
            name: name.into(),
            x,
            y,
            ..Default::default()
        }
    }

    /// Adds y error-bar half-widths, one per point.
    pub fn with_errors(mut self, half_widths: Vec<f64>) -> Self {
        self.y_errors = Some(half_widths);
        self
    }

    /// Fixes the colour instead of the palette's.
    pub fn with_color(mut self, color: Rgb) -> Self {
        self.color = Some(color);
        self
    }
}

/// Input of [`scatter_plot`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ScatterPlot {
    /// Printed above the plot.
    pub title: String,
    /// Printed below the x axis, with units.
    pub x_label: String,
    /// Printed beside the y axis, with units.
    pub y_label: String,
    /// Scale of the x axis.
    pub x_scale: Scale,
    /// Scale of the y axis.
    pub y_scale: Scale,
    /// The point sets, drawn in order.
    pub series: Vec<ScatterSeries>,
    /// Draw the identity line y = x (estimated vs true).
    pub identity_line: bool,
    /// Fixed x limits; default: the data extent.
    pub x_range: Option<(f64, f64)>,
    /// Fixed y limits; default: the data extent.
    pub y_range: Option<(f64, f64)>,
    /// Where the legend goes.
    pub legend: LegendPosition,
    /// Canvas size.
    pub size: PlotSize,
    /// When not empty, the x axis is categorical: a point's x is the 0-based index of its
    /// category, drawn at the category's centre and labelled with its name (recordings of
    /// a campaign, not a numeric axis).
    pub x_categories: Vec<String>,
}

/// Per point: plot-space centre and (low, high) y ends of the error bar.
type Point = ((f64, f64), Option<(f64, f64)>);

/// Each series' plottable points in plot space (a category's centre on a categorical x
/// axis), and how many were skipped (non-finite, or ≤ 0 on a log/dB axis).
fn plottable_points(plot: &str, p: &ScatterPlot) -> Result<(Vec<Vec<Point>>, usize), PlotError> {
    let categorical = !p.x_categories.is_empty();
    let mut pts: Vec<Vec<Point>> = Vec::new();
    let mut skipped = 0usize;
    for s in &p.series {
        check_series(plot, &s.name, s.x.len(), s.y.len())?;
        if let Some(e) = &s.y_errors {
            if e.len() != s.x.len() {
                return Err(PlotError::LengthMismatch {
                    plot: plot.to_string(),
                    series: s.name.clone(),
                    what: "y_errors",
                    expected: s.x.len(),
                    found: e.len(),
                });
            }
        }
        let mut v = Vec::new();
        for i in 0..s.x.len() {
            let x = if categorical {
                // Category i occupies [i, i + 1] (AxisSpec::categorical).
                (s.x[i] >= 0.0 && s.x[i] < p.x_categories.len() as f64).then(|| s.x[i] + 0.5)
            } else {
                p.x_scale.transform(s.x[i])
            };
            match (x, p.y_scale.transform(s.y[i])) {
                (Some(tx), Some(ty)) => {
                    let bar = s
                        .y_errors
                        .as_ref()
                        .map(|e| e[i])
                        .filter(|e| e.is_finite() && *e > 0.0)
                        .map(|e| {
                            // A lower end that is not plottable (log axis) runs to the axis bottom.
                            let lo = p.y_scale.transform(s.y[i] - e).unwrap_or(f64::NEG_INFINITY);
                            let hi = p.y_scale.transform(s.y[i] + e).unwrap_or(ty);
                            (lo, hi)
                        });
                    v.push(((tx, ty), bar));
                }
                _ => skipped += 1,
            }
        }
        pts.push(v);
    }
    Ok((pts, skipped))
}

/// Render a scatter plot: one filled `<circle>` per plottable point in the
/// series colour, one black `<polyline>` per error bar, and a dashed grey
/// identity line if requested (only meaningful for equal scales). Points that
/// are non-finite (or non-positive on a log/dB axis) are skipped and counted in
/// the footnote; an error bar whose ends cannot be shown is clipped.
///
/// Errors: no series, empty series, length mismatches, no plottable point,
/// invalid ranges.
pub fn scatter_plot(p: &ScatterPlot) -> Result<String, PlotError> {
    let plot = plot_name(&p.title);
    if p.series.is_empty() {
        return Err(PlotError::Empty {
            plot,
            what: "series list",
        });
    }
    let categorical = !p.x_categories.is_empty();
    let (pts, skipped) = plottable_points(&plot, p)?;
    let all = || pts.iter().flatten();
    let xe = extent(all().map(|q| q.0 .0));
    let ye = extent(
        all()
            .flat_map(|q| [Some(q.0 .1), q.1.map(|b| b.0), q.1.map(|b| b.1)])
            .flatten(),
    );
    let (Some(mut xe), Some(mut ye)) = (xe, ye) else {
        return Err(PlotError::NoPlottableData { plot, skipped });
    };
    if p.identity_line && p.x_scale == p.y_scale {
        // Same limits on both axes so the identity line is the diagonal.
        let lo = xe.0.min(ye.0);
        let hi = xe.1.max(ye.1);
        xe = (lo, hi);
        ye = (lo, hi);
    }
    let x = if categorical {
        AxisSpec::categorical(p.x_categories.clone())
    } else {
        AxisSpec::resolve(&plot, "x", p.x_scale, Some(xe), p.x_range, Fit::Nice)?
    };
    let y = AxisSpec::resolve(&plot, "y", p.y_scale, Some(ye), p.y_range, Fit::Nice)?;

    render_svg(&plot, p.size, |root| {
        let names = p.series.iter().map(|s| s.name.as_str());
        let names = names.chain(p.identity_line.then_some("y = x"));
        let margins = Margins {
            legend: legend_width(root, names, p.legend),
            ..Margins::default()
        };
        let mut ch = chart(&plot, root, &p.title, &x, &y, margins)?;
        draw_mesh(&plot, &mut ch, &x, &y, &p.x_label, &p.y_label, true)?;
        let mut legend = Legend::default();
        if p.identity_line {
            let lo = x.lo.max(y.lo);
            let hi = x.hi.min(y.hi);
            if hi > lo {
                let style = stroke(Rgb::GREY, LineStyle::Dashed, 1);
                legend.push("y = x", Glyph::Line(style));
                ch.draw_series(std::iter::once(PathElement::new(
                    vec![(lo, lo), (hi, hi)],
                    style,
                )))
                .map_err(render_err(&plot))?
                .label("y = x")
                .legend(line_glyph(style));
            }
        }
        for v in &pts {
            ch.draw_series(v.iter().filter(|q| x.contains(q.0 .0)).filter_map(|q| {
                let (lo, hi) = q.1?;
                let (lo, hi) = (lo.clamp(y.lo, y.hi), hi.clamp(y.lo, y.hi));
                Some(error_bar(q.0 .0, 0.006 * (x.hi - x.lo), lo, hi))
            }))
            .map_err(render_err(&plot))?;
        }
        for (i, (s, v)) in p.series.iter().zip(&pts).enumerate() {
            let colour = s.color.unwrap_or_else(|| Rgb::palette(i)).rgba(1.0);
            legend.push(s.name.clone(), Glyph::Dot(colour));
            ch.draw_series(
                v.iter()
                    .filter(|q| x.contains(q.0 .0) && y.contains(q.0 .1))
                    .map(|q| Circle::new(q.0, 4, fill(colour))),
            )
            .map_err(render_err(&plot))?
            .label(s.name.clone())
            .legend(move |(px, py)| Circle::new((px + 8, py), 4, fill(colour)));
        }
        draw_legend(&plot, root, &mut ch, p.legend, &legend)?;
        if let Some(note) = skipped_note(skipped, "non-finite, or ≤ 0 on a log/dB axis") {
            footnote(&plot, root, &note)?;
        }
        Ok(())
    })
}
