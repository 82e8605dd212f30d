//! Typed errors. Every variant names the plot (its title) and, where relevant,
//! the series so that a CLI can tell the user exactly which input was bad.

/// Why a plot could not be drawn.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlotError {
    /// The plot has nothing to draw (no series, no poles, no cells, no bars).
    #[error("plot '{plot}': nothing to draw ({what} is empty)")]
    Empty { plot: String, what: &'static str },
    /// A series has zero points.
    #[error("plot '{plot}': series '{series}' has no points")]
    EmptySeries { plot: String, series: String },
    /// Paired vectors of a series differ in length.
    #[error("plot '{plot}': series '{series}': {what} has {found} entries, expected {expected}")]
    LengthMismatch {
        plot: String,
        series: String,
        what: &'static str,
        expected: usize,
        found: usize,
    },
    /// Every point of the plot was unplottable (non-finite, or non-positive on a log/dB axis).
    #[error("plot '{plot}': no plottable data ({skipped} points were non-finite or non-positive on a log/dB axis)")]
    NoPlottableData { plot: String, skipped: usize },
    /// A user-supplied axis range is empty, reversed, non-finite or non-positive on a log axis.
    #[error("plot '{plot}': invalid {axis} range [{min}, {max}]")]
    InvalidRange {
        plot: String,
        axis: &'static str,
        min: f64,
        max: f64,
    },
    /// Canvas too small to hold axes and labels.
    #[error("plot '{plot}': canvas {width}x{height} px is too small (minimum 200x150)")]
    InvalidSize {
        plot: String,
        width: u32,
        height: u32,
    },
    /// The plotting backend failed (should not happen when writing to a string).
    #[error("plot '{plot}': rendering failed: {message}")]
    Render { plot: String, message: String },
}
