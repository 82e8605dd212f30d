//! Grouped bar chart with optional symmetric error bars and reference lines,
//! e.g. a property estimate per data set (groups) and origin/method (bars).

use plotters::element::{PathElement, Rectangle};

use crate::axis::{extent, AxisSpec, Fit, Scale};
use crate::canvas::{
    chart, draw_legend, draw_mesh, error_bar, fill, footnote, legend_width, line_glyph, plot_name,
    render_err, render_svg, skipped_note, Glyph, Legend, Margins,
};
use crate::error::PlotError;
use crate::style::{stroke, LegendPosition, LineStyle, PlotSize, Rgb};

/// One bar per group, all in one colour and one legend entry.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BarSeries {
    /// Legend text.
    pub name: String,
    /// One value per group; non-finite values leave the slot empty.
    pub values: Vec<f64>,
    /// Optional error-bar half-widths (e.g. 1.96σ), one per group; a
    /// non-finite or negative entry draws no error bar for that bar.
    pub errors: Option<Vec<f64>>,
    /// `None`: colour `i` of [`Rgb::palette`] for the `i`-th series.
    pub color: Option<Rgb>,
}

impl BarSeries {
    /// A series with the palette colour and no error bars.
    pub fn new(name: impl Into<String>, values: Vec<f64>) -> Self {
        BarSeries {
            name: name.into(),
            values,
            ..Default::default()
        }
    }

    /// Adds error-bar half-widths, one per group.
    pub fn with_errors(mut self, half_widths: Vec<f64>) -> Self {
        self.errors = Some(half_widths);
        self
    }

    /// Fixes the colour instead of the palette's.
    pub fn with_color(mut self, color: Rgb) -> Self {
        self.color = Some(color);
        self
    }
}

/// A horizontal line across the chart, e.g. the true value.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ReferenceLine {
    /// Height of the line, in the chart's y units.
    pub y: f64,
    /// Legend text, e.g. "true value".
    pub label: String,
}

/// Input of [`bar_chart`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BarChart {
    /// Printed above the chart.
    pub title: String,
    /// Group names along x, e.g. data sets "I" … "V".
    pub groups: Vec<String>,
    /// Bars within each group, e.g. origins I–III or methods.
    pub series: Vec<BarSeries>,
    /// Printed below the groups.
    pub x_label: String,
    /// With units, e.g. "m \[kg\]" or "relative error [%]".
    pub y_label: String,
    /// Horizontal lines across the chart, each with a legend entry.
    pub references: Vec<ReferenceLine>,
    /// Fixed y limits; default: zero, all bar ends ± errors and references.
    pub y_range: Option<(f64, f64)>,
    /// Where the legend goes.
    pub legend: LegendPosition,
    /// Canvas size.
    pub size: PlotSize,
}

/// Render a grouped bar chart. Bars grow from zero; each bar is one filled
/// `<rect>` in its series colour; each error bar is one `<polyline>` (whisker
/// with caps, black); reference lines are black dashed lines with a legend
/// entry. Skipped (non-finite) bars are counted in the footnote.
///
/// Errors: no groups or series, value/error counts not matching the groups,
/// no finite value, invalid range.
pub fn bar_chart(b: &BarChart) -> Result<String, PlotError> {
    let plot = plot_name(&b.title);
    check_bar_shapes(&plot, b)?;
    let skipped = b
        .series
        .iter()
        .flat_map(|s| &s.values)
        .filter(|v| !v.is_finite())
        .count();
    let error_of = |s: &BarSeries, g: usize| {
        s.errors
            .as_ref()
            .map(|e| e[g])
            .filter(|e| e.is_finite() && *e >= 0.0)
    };
    let mut ends: Vec<f64> = Vec::new();
    for s in &b.series {
        for (g, &v) in s.values.iter().enumerate() {
            if v.is_finite() {
                let e = error_of(s, g).unwrap_or(0.0);
                ends.extend([v - e, v + e]);
            }
        }
    }
    if ends.is_empty() {
        return Err(PlotError::NoPlottableData { plot, skipped });
    }
    let refs: Vec<&ReferenceLine> = b.references.iter().filter(|r| r.y.is_finite()).collect();
    let ye = extent(
        ends.iter()
            .copied()
            .chain(refs.iter().map(|r| r.y))
            .chain([0.0]),
    );
    let y = AxisSpec::resolve(&plot, "y", Scale::Linear, ye, b.y_range, Fit::Nice)?;
    let x = AxisSpec::categorical(b.groups.clone());
    let clamp = |v: f64| v.clamp(y.lo, y.hi);
    let base = clamp(0.0);

    // Bars fill 80 % of a group; each bar leaves 10 % of its slot as a gap.
    let ns = b.series.len();
    let slot = 0.8 / ns as f64;
    let bar_span = |g: usize, i: usize| {
        let left = g as f64 + 0.1 + i as f64 * slot;
        (left + 0.05 * slot, left + 0.95 * slot)
    };

    render_svg(&plot, b.size, |root| {
        let names = b.series.iter().map(|s| s.name.as_str());
        let names = names.chain(refs.iter().map(|r| r.label.as_str()));
        let margins = Margins {
            legend: legend_width(root, names, b.legend),
            ..Margins::default()
        };
        let mut ch = chart(&plot, root, &b.title, &x, &y, margins)?;
        draw_mesh(&plot, &mut ch, &x, &y, &b.x_label, &b.y_label, false)?;
        let mut legend = Legend::default();
        for (i, s) in b.series.iter().enumerate() {
            let colour = s.color.unwrap_or_else(|| Rgb::palette(i)).rgba(1.0);
            legend.push(s.name.clone(), Glyph::Block(colour));
            ch.draw_series(
                s.values
                    .iter()
                    .enumerate()
                    .filter(|(_, v)| v.is_finite())
                    .map(|(g, &v)| {
                        let (l, r) = bar_span(g, i);
                        Rectangle::new([(l, base), (r, clamp(v))], fill(colour))
                    }),
            )
            .map_err(render_err(&plot))?
            .label(s.name.clone())
            .legend(move |(px, py)| {
                Rectangle::new([(px, py - 6), (px + 14, py + 6)], fill(colour))
            });
        }
        // Error bars on top of all bars so neighbours never hide them.
        for (i, s) in b.series.iter().enumerate() {
            ch.draw_series(s.values.iter().enumerate().filter_map(|(g, &v)| {
                let e = error_of(s, g)?;
                if !v.is_finite() {
                    return None;
                }
                let (l, r) = bar_span(g, i);
                Some(error_bar(
                    0.5 * (l + r),
                    0.2 * (r - l),
                    clamp(v - e),
                    clamp(v + e),
                ))
            }))
            .map_err(render_err(&plot))?;
        }
        for (k, r) in refs.iter().enumerate() {
            if !y.contains(r.y) {
                continue;
            }
            let style = stroke(reference_colour(k), LineStyle::Dashed, 2);
            legend.push(r.label.clone(), Glyph::Line(style));
            ch.draw_series(std::iter::once(PathElement::new(
                vec![(x.lo, r.y), (x.hi, r.y)],
                style,
            )))
            .map_err(render_err(&plot))?
            .label(r.label.clone())
            .legend(line_glyph(style));
        }
        draw_legend(&plot, root, &mut ch, b.legend, &legend)?;
        if let Some(note) = skipped_note(skipped, "non-finite values") {
            footnote(&plot, root, &note)?;
        }
        Ok(())
    })
}

/// The series fit the groups: values (and errors, when given) one per group.
fn check_bar_shapes(plot: &str, b: &BarChart) -> Result<(), PlotError> {
    if b.groups.is_empty() {
        return Err(PlotError::Empty {
            plot: plot.to_string(),
            what: "group list",
        });
    }
    if b.series.is_empty() {
        return Err(PlotError::Empty {
            plot: plot.to_string(),
            what: "series list",
        });
    }
    let ng = b.groups.len();
    for s in &b.series {
        let mismatch = |what: &'static str, found: usize| PlotError::LengthMismatch {
            plot: plot.to_string(),
            series: s.name.clone(),
            what,
            expected: ng,
            found,
        };
        if s.values.len() != ng {
            return Err(mismatch("values", s.values.len()));
        }
        if let Some(e) = &s.errors {
            if e.len() != ng {
                return Err(mismatch("errors", e.len()));
            }
        }
    }
    Ok(())
}

/// Reference lines: black first, then dark greys, so they never look like a series.
fn reference_colour(k: usize) -> Rgb {
    [Rgb::BLACK, Rgb(90, 90, 90), Rgb(150, 150, 150)][k % 3]
}
