//! Stabilisation diagram: pole classes per model order over frequency, with
//! the sum-of-FRFs (or NI) magnitude behind on a secondary log axis.

use plotters::element::{PathElement, Text};
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::axis::{extent, AxisSpec, Fit, Scale};
use crate::canvas::{
    chart, clip_polyline, decimate_to_pixels, draw_legend, draw_mesh, footnote, legend_width,
    line_glyph, plot_name, render_err, render_svg, skipped_note, text_style, Glyph, Legend,
    Margins, DESC_SIZE, FONT, LABEL_SIZE,
};
use crate::error::PlotError;
use crate::line::{check_series, draw_vertical_markers, VerticalMarker};
use crate::style::{stroke, LegendPosition, LineStyle, PlotSize, Rgb};

/// Stability class of a pole relative to the previous model order, drawn as
/// the letter used by commercial modal software (LMS/Simcenter PolyMAX).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PoleClass {
    /// "s": stable in frequency, damping and mode shape.
    Stable,
    /// "d": stable in frequency and damping.
    FrequencyDamping,
    /// "f": stable in frequency only.
    Frequency,
    /// "o": new or unstable pole.
    New,
}

impl PoleClass {
    /// Every class, in legend order (most to least stable).
    pub const ALL: [PoleClass; 4] = [
        PoleClass::Stable,
        PoleClass::FrequencyDamping,
        PoleClass::Frequency,
        PoleClass::New,
    ];

    /// The letter drawn for this class.
    pub fn symbol(self) -> &'static str {
        match self {
            PoleClass::Stable => "s",
            PoleClass::FrequencyDamping => "d",
            PoleClass::Frequency => "f",
            PoleClass::New => "o",
        }
    }

    /// Colour of the letter (and of its legend entry).
    pub fn color(self) -> Rgb {
        match self {
            PoleClass::Stable => Rgb(0, 128, 0),
            PoleClass::FrequencyDamping => Rgb(31, 119, 180),
            PoleClass::Frequency => Rgb(230, 120, 0),
            PoleClass::New => Rgb(200, 30, 30),
        }
    }

    fn description(self) -> &'static str {
        match self {
            PoleClass::Stable => "stable freq., damping, shape",
            PoleClass::FrequencyDamping => "stable freq., damping",
            PoleClass::Frequency => "stable freq.",
            PoleClass::New => "new / unstable",
        }
    }
}

/// One pole of one model order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StabilisationPole {
    /// Frequency of the pole in Hz (x position).
    pub frequency_hz: f64,
    /// Model order the pole was found at (y position).
    pub order: usize,
    /// How stable it is against the next lower order.
    pub class: PoleClass,
}

/// The magnitude curve drawn behind the poles (e.g. sum of FRFs, or NI).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BackgroundCurve {
    /// Legend text, e.g. "Σ|H|".
    pub name: String,
    /// Frequency of every line (Hz).
    pub frequency_hz: Vec<f64>,
    /// Positive magnitudes; drawn on a log axis at the right.
    pub magnitude: Vec<f64>,
    /// Right axis description, e.g. "Σ|H| [m/s²/N]".
    pub axis_label: String,
}

/// Input of [`stabilisation_diagram`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StabilisationDiagram {
    /// Printed above the diagram.
    pub title: String,
    /// Every pole of every model order.
    pub poles: Vec<StabilisationPole>,
    /// Magnitude curve behind the poles, on its own right axis.
    pub background: Option<BackgroundCurve>,
    /// Selected (physical) poles: solid vertical lines with labels.
    pub selected: Vec<VerticalMarker>,
    /// Fixed frequency band; default: the extent of poles and curve.
    pub x_range: Option<(f64, f64)>,
    /// Where the legend goes.
    pub legend: LegendPosition,
    /// Canvas size.
    pub size: PlotSize,
}

/// The background curve's points (frequency, log10 magnitude; None where not plottable)
/// and how many poles and curve points are skipped as not finite (or ≤ 0 on the log axis).
#[allow(clippy::type_complexity)]
fn background_points(
    plot: &str,
    d: &StabilisationDiagram,
) -> Result<(Vec<Option<(f64, f64)>>, usize), PlotError> {
    let mut skipped = d
        .poles
        .iter()
        .filter(|p| !p.frequency_hz.is_finite())
        .count();
    let mut curve_pts: Vec<Option<(f64, f64)>> = Vec::new();
    if let Some(bg) = &d.background {
        check_series(plot, &bg.name, bg.frequency_hz.len(), bg.magnitude.len())?;
        curve_pts = bg
            .frequency_hz
            .iter()
            .zip(&bg.magnitude)
            .map(
                |(&f, &m)| match (f.is_finite(), Scale::Log10.transform(m)) {
                    (true, Some(lm)) => Some((f, lm)),
                    _ => None,
                },
            )
            .collect();
        skipped += curve_pts.iter().filter(|p| p.is_none()).count();
    }
    Ok((curve_pts, skipped))
}

/// Render a stabilisation diagram: x = frequency (Hz), y = model order, one
/// coloured letter per pole (s/d/f/o, see [`PoleClass`]), selected poles as
/// dashed vertical lines, and the optional background curve on a log axis at
/// the right, drawn first so that it lies behind the letters.
///
/// Poles with non-finite frequency or outside `x_range` are skipped (counted in
/// the footnote). Errors: no poles, background length mismatch, invalid range.
pub fn stabilisation_diagram(d: &StabilisationDiagram) -> Result<String, PlotError> {
    let plot = plot_name(&d.title);
    if d.poles.is_empty() {
        return Err(PlotError::Empty {
            plot,
            what: "pole list",
        });
    }
    let (curve_pts, mut skipped) = background_points(&plot, d)?;
    let fx = extent(
        d.poles
            .iter()
            .map(|p| p.frequency_hz)
            .chain(curve_pts.iter().flatten().map(|p| p.0)),
    );
    let Some(fx) = fx else {
        return Err(PlotError::NoPlottableData { plot, skipped });
    };
    let x = AxisSpec::resolve(&plot, "x", Scale::Linear, Some(fx), d.x_range, Fit::Tight)?;
    skipped += d
        .poles
        .iter()
        .filter(|p| p.frequency_hz.is_finite() && !x.contains(p.frequency_hz))
        .count();
    let max_order = d.poles.iter().map(|p| p.order).max().unwrap_or(1);
    let y = AxisSpec::integers(0.0, max_order as f64 + 1.0);
    let y2 = AxisSpec::resolve(
        &plot,
        "secondary y",
        Scale::Log10,
        extent(curve_pts.iter().flatten().map(|p| p.1)),
        None,
        Fit::Nice,
    )?;

    render_svg(&plot, d.size, |root| {
        let names = PoleClass::ALL.iter().map(|c| c.description());
        let names = names.chain(d.background.iter().map(|b| b.name.as_str()));
        let margins = Margins {
            right: if d.background.is_some() { 80 } else { 0 },
            legend: legend_width(root, names, d.legend),
            ..Margins::default()
        };
        let ch = chart(&plot, root, &d.title, &x, &y, margins)?;
        let mut ch = ch.set_secondary_coord(x.coord(), y2.coord());
        draw_mesh(
            &plot,
            &mut ch,
            &x,
            &y,
            "Frequency [Hz]",
            "Model order",
            true,
        )?;
        let mut legend = Legend::default();
        if let Some(bg) = &d.background {
            let y2f = |v: &f64| y2.label(*v);
            ch.configure_secondary_axes()
                .y_label_formatter(&y2f)
                .y_desc(bg.axis_label.as_str())
                .label_style((FONT, LABEL_SIZE))
                .axis_desc_style((FONT, DESC_SIZE))
                .draw()
                .map_err(render_err(&plot))?;
            let style = stroke(Rgb(150, 150, 150), LineStyle::Solid, 1);
            legend.push(bg.name.clone(), Glyph::Line(style));
            let pieces = clip_polyline(&curve_pts, &x, &y2)
                .into_iter()
                .map(|piece| decimate_to_pixels(piece, |p| ch.backend_coord(&(p.0, y.lo)).0))
                .collect::<Vec<_>>();
            ch.draw_secondary_series(pieces.into_iter().map(|p| PathElement::new(p, style)))
                .map_err(render_err(&plot))?
                .label(bg.name.clone())
                .legend(line_glyph(style));
        }
        draw_vertical_markers(&plot, &mut ch, &d.selected, &x, &y)?;
        let centred = Pos::new(HPos::Center, VPos::Center);
        for class in PoleClass::ALL {
            let c = class.color();
            let style = text_style(13, c.rgba(1.0), centred);
            let legend_style = style.clone();
            legend.push(
                class.description(),
                Glyph::Letter(class.symbol(), c.rgba(1.0)),
            );
            ch.draw_series(
                d.poles
                    .iter()
                    .filter(|p| p.class == class && x.contains(p.frequency_hz))
                    .map(|p| {
                        Text::new(
                            class.symbol(),
                            (p.frequency_hz, p.order as f64),
                            style.clone(),
                        )
                    }),
            )
            .map_err(render_err(&plot))?
            .label(class.description())
            .legend(move |(px, py)| Text::new(class.symbol(), (px + 12, py), legend_style.clone()));
        }
        draw_legend(&plot, root, &mut ch, d.legend, &legend)?;
        if let Some(note) = skipped_note(
            skipped,
            "non-finite, outside the band, or ≤ 0 on the log axis",
        ) {
            footnote(&plot, root, &note)?;
        }
        Ok(())
    })
}
