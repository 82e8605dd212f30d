//! Deterministic SVG plots for the rbprops pipeline stages (`--plot DIR`).
//!
//! Every function takes a plain-data description and returns the complete SVG
//! document as a `String` (no file I/O, no fonts needed: plotters' SVG backend
//! writes `<text>` elements and estimates text extents itself). The same input
//! always gives byte-identical output.
//!
//! | function | typical use |
//! |---|---|
//! | [`line_plot`] | FRF magnitude overlays (measured solid, synthesised dashed), NI curves, MIFs |
//!
//! Unplottable points (NaN/Inf, or ≤ 0 on a log/dB axis) are skipped, break
//! the curve, and are counted in a footnote printed on the figure.

mod axis;
mod bar;
mod canvas;
mod error;
mod heatmap;
mod line;
mod scatter;
mod stabilisation;
mod style;

pub use axis::Scale;
pub use bar::{bar_chart, BarChart, BarSeries, ReferenceLine};
pub use error::PlotError;
pub use heatmap::{heat_map, viridis, HeatMap};
pub use line::{line_plot, LinePlot, Series, VerticalMarker};
pub use scatter::{scatter_plot, ScatterPlot, ScatterSeries};
pub use stabilisation::{
    stabilisation_diagram, BackgroundCurve, PoleClass, StabilisationDiagram, StabilisationPole,
};
pub use style::{LegendPosition, LineStyle, PlotSize, Rgb};
