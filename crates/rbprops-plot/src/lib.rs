//! Deterministic SVG plots for the rbprops pipeline stages (`--plot DIR`).
//!
//! Every function takes a plain-data description and returns the complete SVG
//! document as a `String` (no file I/O, no fonts needed: plotters' SVG backend
//! writes `<text>` elements and estimates text extents itself). The same input
//! always gives byte-identical output.
//!
//! | function | input | typical use |
//! |---|---|---|
//! | [`line_plot`] | [`LinePlot`] | FRF magnitude overlays (measured solid, synthesised dashed), NI curves, hybrid/PRF MIF, measured vs nominal vs improved |
//! | [`frf_panels`] | [`FrfPanels`] | small multiples: one panel per channel, magnitude over phase, measured vs fitted |
//! | [`stabilisation_diagram`] | [`StabilisationDiagram`] | pole stability letters s/d/f/o per model order over the Σ-FRF or NI curve |
//! | [`heat_map`] | [`HeatMap`] | mode × excitation strength \[dB\], any labelled table |
//! | [`bar_chart`] | [`BarChart`] | property value / relative error per data set and origin or method, ±1.96σ, true value |
//! | [`scatter_plot`] | [`ScatterPlot`] | estimated vs true with error bars and the identity line |
//!
//! [`compact_svg`] rewrites any of these documents in fewer bytes for a page that inlines
//! many of them (the same picture: grid lines and ticks merged into paths, defaults
//! dropped, curves thinned to half a pixel).
//!
//! All input structs implement `Default`; fill in what you need:
//!
//! ```
//! use rbprops_plot::{line_plot, LinePlot, LineStyle, Scale, Series, VerticalMarker};
//! let f: Vec<f64> = (1..=400).map(|i| i as f64 * 0.5).collect();
//! let h: Vec<f64> = f.iter().map(|f| 1e-3 / (1.0 + (f - 80.0).powi(2))).collect();
//! let svg = line_plot(&LinePlot {
//!     title: "FRF x1/F1".into(),
//!     x_label: "Frequency [Hz]".into(),
//!     y_label: "|H| [m/N]".into(),
//!     y_scale: Scale::Log10,
//!     series: vec![
//!         Series::new("measured", f.clone(), h.clone()),
//!         Series::new("synthesised", f, h).with_style(LineStyle::Dashed),
//!     ],
//!     markers: vec![VerticalMarker::new(80.0, "80.0 Hz")],
//!     ..Default::default()
//! })?;
//! assert!(svg.starts_with("<svg"));
//! # Ok::<(), rbprops_plot::PlotError>(())
//! ```
//!
//! Bad data never panics: unplottable points (NaN/Inf, or ≤ 0 on a log/dB
//! axis) are skipped, break the curve, and are counted in a footnote printed
//! on the figure ("3 points not shown (…)"); a plot with nothing at all to
//! draw, empty series and length mismatches are [`PlotError`]s naming the
//! plot and series. Series colours default to [`Rgb::palette`] by index.

#![warn(missing_docs)]

mod axis;
mod bar;
mod canvas;
mod compact;
mod error;
mod heatmap;
mod line;
mod panels;
mod scatter;
mod stabilisation;
mod style;

pub use axis::Scale;
pub use bar::{bar_chart, BarChart, BarSeries, ReferenceLine};
pub use compact::{compact_svg, CURVE_TOLERANCE_PX};
pub use error::PlotError;
pub use heatmap::{heat_map, viridis, HeatMap};
pub use line::{line_plot, LinePlot, Series, VerticalMarker};
pub use panels::{
    frf_panels, low_quality_spans, FrfPanel, FrfPanels, FrfTrace, LineQuality, LOW_QUALITY_SHADE,
};
pub use scatter::{scatter_plot, ScatterPlot, ScatterSeries};
pub use stabilisation::{
    stabilisation_diagram, BackgroundCurve, PoleClass, StabilisationDiagram, StabilisationPole,
};
pub use style::{LegendPosition, LineStyle, PlotSize, Rgb};
