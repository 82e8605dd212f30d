//! Heat map: a rows × columns table of values as coloured cells with the
//! value printed in each, plus a colour bar.

use plotters::element::{PathElement, Rectangle, Text};
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{RGBAColor, ShapeStyle};

use crate::axis::{extent, format_number, AxisSpec, Fit, Scale};
use crate::canvas::{
    chart, draw_mesh, fill, footnote, plot_name, render_err, render_svg, text_style, title_height,
    Margins, Root, DESC_SIZE, FONT, LABEL_SIZE,
};
use crate::error::PlotError;
use crate::style::{PlotSize, Rgb};

/// Input of [`heat_map`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct HeatMap {
    /// Printed above the map.
    pub title: String,
    /// One label per row (top to bottom), e.g. "mode 1".
    pub row_labels: Vec<String>,
    /// One label per column (left to right), e.g. "F1".
    pub column_labels: Vec<String>,
    /// `values[row][column]`; non-finite cells are drawn grey with "n/a".
    pub values: Vec<Vec<f64>>,
    /// Printed below the columns.
    pub x_label: String,
    /// Printed beside the rows.
    pub y_label: String,
    /// Colour-bar description with units, e.g. "excitation strength \[dB\]".
    pub value_label: String,
    /// Decimal places of the printed cell values.
    pub decimals: usize,
    /// Fixed colour scale limits; default: the finite data extent.
    pub value_range: Option<(f64, f64)>,
    /// Canvas size.
    pub size: PlotSize,
}

/// Viridis colour map sampled at 9 equidistant points (matplotlib `_viridis_data`).
const VIRIDIS: [Rgb; 9] = Rgb::table([
    0x440154, 0x472c7a, 0x3b518b, 0x2c718e, 0x21908d, 0x27ad81, 0x5cc863, 0xaadc32, 0xfde725,
]);

/// Viridis colour at `t ∈ [0, 1]` (clamped), linearly interpolated.
pub fn viridis(t: f64) -> Rgb {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let s = t * (VIRIDIS.len() - 1) as f64;
    let i = (s.floor() as usize).min(VIRIDIS.len() - 2);
    let f = s - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    let mix = |p: u8, q: u8| (p as f64 + f * (q as f64 - p as f64)).round() as u8;
    Rgb(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

const NAN_CELL: Rgb = Rgb(200, 200, 200);

/// Render a heat map. Row 0 is at the top. Each cell is one `<rect>` filled
/// with the viridis colour of its value and carries the value as text (black
/// or white for contrast); a colour bar with the value scale is at the right.
///
/// Errors: no rows/columns, label counts or row lengths that do not match,
/// no finite value, invalid fixed range.
pub fn heat_map(h: &HeatMap) -> Result<String, PlotError> {
    let plot = plot_name(&h.title);
    let (nr, nc) = (h.row_labels.len(), h.column_labels.len());
    check_heat_map_shape(&plot, h)?;
    let skipped = h.values.iter().flatten().filter(|v| !v.is_finite()).count();
    let Some(data) = extent(h.values.iter().flatten().copied()) else {
        return Err(PlotError::NoPlottableData { plot, skipped });
    };
    let scale = AxisSpec::resolve(
        &plot,
        "value",
        Scale::Linear,
        Some(data),
        h.value_range,
        Fit::Tight,
    )?;
    let t_of = |v: f64| (v - scale.lo) / (scale.hi - scale.lo);

    // Cell (r, c) occupies [c, c+1] × [nr-1-r, nr-r] so that row 0 is on top.
    let x = AxisSpec::categorical(h.column_labels.clone());
    // Row 0 at the top: the axis lists rows bottom-up.
    let y = AxisSpec::categorical(h.row_labels.iter().rev().cloned().collect());
    let longest_row = h
        .row_labels
        .iter()
        .map(|l| l.chars().count())
        .max()
        .unwrap_or(1);
    let margins = Margins {
        left: (longest_row as u32 * 8 + 40).clamp(60, 300),
        ..Margins::default()
    };

    render_svg(&plot, h.size, |root| {
        let (w, _) = root.dim_in_pixel();
        let (main, bar) = root.split_horizontally(w.saturating_sub(150));
        let mut ch = chart(&plot, &main, &h.title, &x, &y, margins)?;
        ch.configure_mesh()
            .disable_mesh()
            .x_label_formatter(&|v: &f64| x.label(*v))
            .y_label_formatter(&|v: &f64| y.label(*v))
            .x_desc(h.x_label.as_str())
            .y_desc(h.y_label.as_str())
            .label_style((FONT, LABEL_SIZE))
            .axis_desc_style((FONT, DESC_SIZE))
            .draw()
            .map_err(render_err(&plot))?;
        let cells: Vec<(usize, usize, f64)> = h
            .values
            .iter()
            .enumerate()
            .flat_map(|(r, row)| row.iter().enumerate().map(move |(c, &v)| (r, c, v)))
            .collect();
        let colour = |v: f64| {
            if v.is_finite() {
                viridis(t_of(v))
            } else {
                NAN_CELL
            }
        };
        let top = |r: usize| (nr - r) as f64;
        ch.draw_series(cells.iter().map(|&(r, c, v)| {
            Rectangle::new(
                [(c as f64, top(r)), (c as f64 + 1.0, top(r) - 1.0)],
                fill(colour(v).rgba(1.0)),
            )
        }))
        .map_err(render_err(&plot))?;
        // Thin white grid between cells.
        let grid = ShapeStyle {
            color: RGBAColor(255, 255, 255, 1.0),
            filled: false,
            stroke_width: 1,
        };
        ch.draw_series(
            (1..nc)
                .map(|c| vec![(c as f64, 0.0), (c as f64, nr as f64)])
                .chain((1..nr).map(|r| vec![(0.0, r as f64), (nc as f64, r as f64)]))
                .map(|p| PathElement::new(p, grid)),
        )
        .map_err(render_err(&plot))?;
        let centred = Pos::new(HPos::Center, VPos::Center);
        let font = cell_font(h.size, nr, nc);
        ch.draw_series(cells.iter().map(|&(r, c, v)| {
            let (text, ink) = cell_text(v, colour(v), h.decimals);
            Text::new(
                text,
                (c as f64 + 0.5, top(r) - 0.5),
                text_style(font, ink, centred),
            )
        }))
        .map_err(render_err(&plot))?;

        let bar_margins = Margins {
            left: 0,
            bottom: margins.bottom,
            right: 90,
            top: title_height(root, &h.title),
            legend: 0,
        };
        draw_colour_bar(
            &plot,
            &bar,
            bar_margins,
            (scale.lo, scale.hi),
            &h.value_label,
        )?;
        if skipped > 0 {
            let note = match skipped {
                1 => "1 cell has no finite value (shown as n/a)".to_string(),
                n => format!("{n} cells have no finite value (shown as n/a)"),
            };
            footnote(&plot, root, &note)?;
        }
        Ok(())
    })
}

/// One label per row and column, and every row as long as the column labels.
fn check_heat_map_shape(plot: &str, h: &HeatMap) -> Result<(), PlotError> {
    let (nr, nc) = (h.row_labels.len(), h.column_labels.len());
    if nr == 0 || nc == 0 {
        return Err(PlotError::Empty {
            plot: plot.to_string(),
            what: if nr == 0 {
                "row label list"
            } else {
                "column label list"
            },
        });
    }
    if h.values.len() != nr {
        return Err(PlotError::LengthMismatch {
            plot: plot.to_string(),
            series: "values".into(),
            what: "rows",
            expected: nr,
            found: h.values.len(),
        });
    }
    if let Some((r, row)) = h.values.iter().enumerate().find(|(_, r)| r.len() != nc) {
        return Err(PlotError::LengthMismatch {
            plot: plot.to_string(),
            series: format!("row {r} ('{}')", h.row_labels[r]),
            what: "columns",
            expected: nc,
            found: row.len(),
        });
    }
    Ok(())
}

/// The colour bar beside the map: 64 bands of the viridis scale over `(lo, hi)`.
fn draw_colour_bar(
    plot: &str,
    area: &Root<'_>,
    margins: Margins,
    (lo, hi): (f64, f64),
    value_label: &str,
) -> Result<(), PlotError> {
    let unit = AxisSpec::categorical(vec![]);
    let bar_axis = AxisSpec::resolve(
        plot,
        "value",
        Scale::Linear,
        None,
        Some((lo, hi)),
        Fit::Tight,
    )?;
    let mut cb = chart(plot, area, "", &unit, &bar_axis, margins)?;
    draw_mesh(plot, &mut cb, &unit, &bar_axis, "", value_label, false)?;
    const BANDS: usize = 64;
    let span = hi - lo;
    cb.draw_series((0..BANDS).map(|k| {
        let a = lo + span * k as f64 / BANDS as f64;
        let b = lo + span * (k + 1) as f64 / BANDS as f64;
        Rectangle::new(
            [(0.0, a), (1.0, b)],
            fill(viridis((k as f64 + 0.5) / BANDS as f64).rgba(1.0)),
        )
    }))
    .map_err(render_err(plot))?;
    Ok(())
}

/// The value printed in a cell and its ink: white on a dark cell, black on a light one,
/// grey "n/a" where the value is not finite.
fn cell_text(v: f64, cell: Rgb, decimals: usize) -> (String, RGBAColor) {
    if !v.is_finite() {
        return ("n/a".to_string(), RGBAColor(60, 60, 60, 1.0));
    }
    let ink = if cell.luminance() < 0.5 {
        RGBAColor(255, 255, 255, 1.0)
    } else {
        RGBAColor(0, 0, 0, 1.0)
    };
    (format_number(v, Some(decimals)), ink)
}

/// Font size that fits a printed value in a cell.
fn cell_font(size: PlotSize, nr: usize, nc: usize) -> u32 {
    let cell_w = size.width.saturating_sub(300) / nc.max(1) as u32;
    let cell_h = size.height.saturating_sub(120) / nr.max(1) as u32;
    (cell_w / 5).min(cell_h / 2).clamp(8, 16)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn viridis_endpoints_and_clamping() {
        assert_eq!(viridis(0.0), Rgb(68, 1, 84));
        assert_eq!(viridis(1.0), Rgb(253, 231, 37));
        assert_eq!(viridis(-3.0), viridis(0.0));
        assert_eq!(viridis(7.0), viridis(1.0));
        assert_eq!(viridis(0.5), Rgb(33, 144, 141));
    }
}
