//! Typed errors. Every variant names the plot (its title) and, where relevant,
//! the series so that a CLI can tell the user exactly which input was bad.

/// Why a plot could not be drawn.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlotError {
    /// The plot has nothing to draw (no series, no poles, no cells, no bars).
    #[error("plot '{plot}': nothing to draw ({what} is empty)")]
    Empty {
        /// The plot's title.
        plot: String,
        /// Which input is empty, e.g. "series".
        what: &'static str,
    },
    /// A series has zero points.
    #[error("plot '{plot}': series '{series}' has no points")]
    EmptySeries {
        /// The plot's title.
        plot: String,
        /// The series' name.
        series: String,
    },
    /// Paired vectors of a series differ in length.
    #[error("plot '{plot}': series '{series}': {what} has {found} entries, expected {expected}")]
    LengthMismatch {
        /// The plot's title.
        plot: String,
        /// The series' name.
        series: String,
        /// Which vector is off, e.g. "y" or "errors".
        what: &'static str,
        /// Length it must have (that of the series' x).
        expected: usize,
        /// Length it has.
        found: usize,
    },
    /// Every point of the plot was unplottable (non-finite, or non-positive on a log/dB axis).
    #[error("plot '{plot}': no plottable data ({skipped} points were non-finite or non-positive on a log/dB axis)")]
    NoPlottableData {
        /// The plot's title.
        plot: String,
        /// How many points were dropped.
        skipped: usize,
    },
    /// A user-supplied axis range is empty, reversed, non-finite or non-positive on a log axis.
    #[error("plot '{plot}': invalid {axis} range [{min}, {max}]")]
    InvalidRange {
        /// The plot's title.
        plot: String,
        /// Which axis, "x" or "y".
        axis: &'static str,
        /// Lower limit as given.
        min: f64,
        /// Upper limit as given.
        max: f64,
    },
    /// Canvas too small to hold axes and labels.
    #[error("plot '{plot}': canvas {width}x{height} px is too small (minimum 200x150)")]
    InvalidSize {
        /// The plot's title.
        plot: String,
        /// Width as given (px).
        width: u32,
        /// Height as given (px).
        height: u32,
    },
    /// The plotting backend failed (should not happen when writing to a string).
    #[error("plot '{plot}': rendering failed: {message}")]
    Render {
        /// The plot's title.
        plot: String,
        /// The backend's message.
        message: String,
    },
}
