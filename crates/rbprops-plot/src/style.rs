//! Colours, line styles and the SVG post-processing that gives dashed lines.
//!
//! plotters' SVG backend cannot emit `stroke-dasharray`, and its
//! `DashedLineSeries` splits a curve into hundreds of separate elements. We
//! instead tag dashed strokes with a reserved opacity value (never used for
//! anything else in this crate) and rewrite that attribute once the document is
//! complete, so a dashed series stays a single `<polyline>`.

use plotters::style::{RGBAColor, ShapeStyle};

/// An sRGB colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Rgb(pub u8, pub u8, pub u8);

impl Rgb {
    /// Error bars and reference lines.
    pub const BLACK: Rgb = Rgb(0, 0, 0);
    /// Vertical markers and the identity line.
    pub const GREY: Rgb = Rgb(110, 110, 110);

    /// The colour written `0xRRGGBB`.
    pub(crate) const fn from_hex(rrggbb: u32) -> Rgb {
        Rgb((rrggbb >> 16) as u8, (rrggbb >> 8) as u8, rrggbb as u8)
    }

    /// A colour table written as `0xRRGGBB` values (the form colour maps are published in).
    pub(crate) const fn table<const N: usize>(rrggbb: [u32; N]) -> [Rgb; N] {
        let mut colours = [Rgb(0, 0, 0); N];
        let mut i = 0;
        while i < N {
            colours[i] = Rgb::from_hex(rrggbb[i]);
            i += 1;
        }
        colours
    }

    /// Colour `i` of the default categorical palette (Tableau 10, the
    /// matplotlib default), cycling after ten.
    pub fn palette(i: usize) -> Rgb {
        const TAB10: [Rgb; 10] = Rgb::table([
            0x1f77b4, 0xff7f0e, 0x2ca02c, 0xd62728, 0x9467bd, 0x8c564b, 0xe377c2, 0x7f7f7f,
            0xbcbd22, 0x17becf,
        ]);
        TAB10[i % TAB10.len()]
    }

    /// The `#RRGGBB` form written by the SVG backend (useful for tests and
    /// for finding a series in the document).
    pub fn hex(self) -> String {
        format!("#{:02X}{:02X}{:02X}", self.0, self.1, self.2)
    }

    pub(crate) fn rgba(self, alpha: f64) -> RGBAColor {
        RGBAColor(self.0, self.1, self.2, alpha)
    }

    /// Relative luminance (ITU-R BT.709 weights on gamma-encoded values; good
    /// enough to choose black or white text on a cell).
    pub(crate) fn luminance(self) -> f64 {
        (0.2126 * self.0 as f64 + 0.7152 * self.1 as f64 + 0.0722 * self.2 as f64) / 255.0
    }
}

/// Stroke pattern of a line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LineStyle {
    /// Continuous line (by convention: measured data).
    #[default]
    Solid,
    /// Dashed line (by convention: synthesised / fitted data).
    Dashed,
    /// Dotted line (e.g. a third data set such as "nominal").
    Dotted,
}

/// Where the legend box sits: right of the plotting area (the default, so it never
/// hides data), or in a corner inside it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LegendPosition {
    /// Right of the plotting area (and of a secondary axis), top-aligned; the chart is
    /// narrowed to make room.
    #[default]
    Outside,
    /// Inside the plotting area, upper right corner.
    UpperRight,
    /// Inside the plotting area, upper left corner.
    UpperLeft,
    /// Inside the plotting area, lower left corner.
    LowerLeft,
    /// Inside the plotting area, lower right corner.
    LowerRight,
    /// No legend.
    Hidden,
}

impl LegendPosition {
    /// Plotters' position inside the plotting area (`None`: hidden, or drawn outside
    /// by this crate).
    pub(crate) fn to_plotters(self) -> Option<plotters::chart::SeriesLabelPosition> {
        use plotters::chart::SeriesLabelPosition as P;
        match self {
            LegendPosition::Outside => None,
            LegendPosition::UpperRight => Some(P::UpperRight),
            LegendPosition::UpperLeft => Some(P::UpperLeft),
            LegendPosition::LowerLeft => Some(P::LowerLeft),
            LegendPosition::LowerRight => Some(P::LowerRight),
            LegendPosition::Hidden => None,
        }
    }
}

/// Pixels between the plotting area (or its right axis) and an outside legend.
pub(crate) const OUTSIDE_GAP: u32 = 12;

/// Canvas size in pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlotSize {
    /// Width (px).
    pub width: u32,
    /// Height (px).
    pub height: u32,
}

impl Default for PlotSize {
    fn default() -> Self {
        PlotSize {
            width: 1000,
            height: 600,
        }
    }
}

// Reserved opacities that mark a stroke pattern; rewritten by `finish_svg`.
// No other element in this crate uses these alpha values.
const DASHED_ALPHA: f64 = 0.991;
const DOTTED_ALPHA: f64 = 0.992;
const MARKER_ALPHA: f64 = 0.993;

/// A plotters stroke style for a curve of colour `c` and pattern `style`.
pub(crate) fn stroke(c: Rgb, style: LineStyle, width: u32) -> ShapeStyle {
    let alpha = match style {
        LineStyle::Solid => 1.0,
        LineStyle::Dashed => DASHED_ALPHA,
        LineStyle::Dotted => DOTTED_ALPHA,
    };
    ShapeStyle {
        color: c.rgba(alpha),
        filled: false,
        stroke_width: width,
    }
}

/// Thin dashed grey style used for vertical/horizontal annotation lines.
pub(crate) fn marker_stroke(c: Rgb) -> ShapeStyle {
    ShapeStyle {
        color: c.rgba(MARKER_ALPHA),
        filled: false,
        stroke_width: 1,
    }
}

/// Replace the reserved opacity tags with real dash patterns.
pub(crate) fn finish_svg(svg: String) -> String {
    svg.replace(
        &format!("opacity=\"{DASHED_ALPHA}\""),
        "opacity=\"1\" stroke-dasharray=\"9 5\"",
    )
    .replace(
        &format!("opacity=\"{DOTTED_ALPHA}\""),
        "opacity=\"1\" stroke-dasharray=\"2 3\"",
    )
    .replace(
        &format!("opacity=\"{MARKER_ALPHA}\""),
        "opacity=\"0.8\" stroke-dasharray=\"5 4\"",
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn palette_cycles_and_hex_is_uppercase() {
        assert_eq!(Rgb::palette(0), Rgb::palette(10));
        assert_ne!(Rgb::palette(0), Rgb::palette(1));
        assert_eq!(Rgb(255, 127, 14).hex(), "#FF7F0E");
    }

    /// A table written `0xRRGGBB` gives the bytes in red, green, blue order.
    #[test]
    fn hex_tables_read_red_green_blue() {
        assert_eq!(Rgb::from_hex(0xff7f0e), Rgb(255, 127, 14));
        assert_eq!(
            Rgb::table([0x010203, 0xfdfeff]),
            [Rgb(1, 2, 3), Rgb(253, 254, 255)]
        );
        assert_eq!(Rgb::palette(9).hex(), "#17BECF");
    }

    #[test]
    fn dash_tags_are_rewritten() {
        let s = finish_svg(format!(
            "<polyline opacity=\"{DASHED_ALPHA}\"/><polyline opacity=\"{DOTTED_ALPHA}\"/><line opacity=\"1\"/>"
        ));
        assert!(s.contains("stroke-dasharray=\"9 5\""));
        assert!(s.contains("stroke-dasharray=\"2 3\""));
        assert!(!s.contains("0.991") && !s.contains("0.992"));
        assert!(s.contains("<line opacity=\"1\"/>"));
    }
}
