//! Axis scales, ranges and tick positions.
//!
//! Every chart in this crate is drawn in *plot space*: x as given, y after the
//! scale's transform (log10 or dB). All axes are therefore linear `f64`
//! coordinates carrying an explicit list of tick positions, which keeps one
//! concrete coordinate type for all plot kinds and lets us label log axes by
//! decade (10⁻⁶, 10⁻⁵, …) the way FRF plots are read.

use std::ops::Range;

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};

use crate::error::PlotError;

/// How values are mapped onto an axis.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Scale {
    /// Values as given.
    #[default]
    Linear,
    /// Logarithmic axis labelled in decades. Values must be positive; others are skipped.
    Log10,
    /// Amplitude in decibels, `20·log10(|v|)` (re 1 unit of the data). Values must be
    /// positive magnitudes; zero and negative values are skipped. Axis ranges
    /// given for this scale are in dB.
    Decibel,
}

impl Scale {
    /// Plot-space coordinate of a data value, or `None` if it cannot be shown.
    pub fn transform(self, v: f64) -> Option<f64> {
        if !v.is_finite() {
            return None;
        }
        match self {
            Scale::Linear => Some(v),
            Scale::Log10 if v > 0.0 => Some(v.log10()),
            Scale::Decibel if v > 0.0 => Some(20.0 * v.log10()),
            _ => None,
        }
    }

    /// Plot-space coordinate of a user-given axis limit (dB limits are already in dB).
    fn transform_limit(self, v: f64) -> Option<f64> {
        match self {
            Scale::Decibel if v.is_finite() => Some(v),
            _ => self.transform(v),
        }
    }
}

/// The plotters coordinate used for every axis: linear `f64` in plot space
/// with explicit bold (labelled) and light (minor grid) tick positions.
#[derive(Debug, Clone)]
pub(crate) struct Axis {
    lo: f64,
    hi: f64,
    bold: Vec<f64>,
    light: Vec<f64>,
}

impl Ranged for Axis {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    // Same mapping as plotters' `RangedCoordf64`.
    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        let logic = (*v - self.lo) / (self.hi - self.lo);
        let actual = limit.1 - limit.0;
        if actual == 0 || !logic.is_finite() {
            return if logic.is_sign_negative() {
                limit.0
            } else {
                limit.1
            };
        }
        if actual > 0 {
            limit.0 + (actual as f64 * logic + 1e-3).floor() as i32
        } else {
            limit.0 + (actual as f64 * logic - 1e-3).ceil() as i32
        }
    }

    fn key_points<H: KeyPointHint>(&self, hint: H) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.light.clone()
        } else {
            self.bold.clone()
        }
    }

    fn range(&self) -> Range<f64> {
        self.lo..self.hi
    }
}

/// A resolved axis: plot-space limits, tick positions and labelling.
#[derive(Debug, Clone)]
pub(crate) struct AxisSpec {
    pub lo: f64,
    pub hi: f64,
    pub bold: Vec<f64>,
    pub light: Vec<f64>,
    pub scale: Scale,
    /// Decimal places for linear labels (`None`: scientific notation).
    decimals: Option<usize>,
    /// Category names; tick at `i + 0.5` is labelled `categories[i]`.
    categories: Vec<String>,
}

/// How an automatic range is widened around the data.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Fit {
    /// Exactly the data extent (frequency axes).
    Tight,
    /// 5 % margin then rounded out to whole tick steps (value axes).
    Nice,
}

impl AxisSpec {
    /// Resolve an axis from the plot-space extent of the data (`data`, may be
    /// `None` if there is none) or a user range (in axis units, see [`Scale`]).
    pub fn resolve(
        plot: &str,
        axis: &'static str,
        scale: Scale,
        data: Option<(f64, f64)>,
        user: Option<(f64, f64)>,
        fit: Fit,
    ) -> Result<AxisSpec, PlotError> {
        let invalid = |min: f64, max: f64| PlotError::InvalidRange {
            plot: plot.to_string(),
            axis,
            min,
            max,
        };
        let (lo, hi, fit) = match user {
            Some((a, b)) => {
                let (ta, tb) = (scale.transform_limit(a), scale.transform_limit(b));
                match (ta, tb) {
                    (Some(ta), Some(tb)) if tb > ta => (ta, tb, Fit::Tight),
                    _ => return Err(invalid(a, b)),
                }
            }
            None => {
                let (lo, hi) = data.unwrap_or((0.0, 1.0));
                (lo, hi, fit)
            }
        };
        let (lo, hi) = widen_degenerate(lo, hi, scale);
        Ok(match scale {
            Scale::Log10 => Self::decades(lo, hi, user.is_some()),
            _ => Self::linear(lo, hi, fit, scale),
        })
    }

    fn linear(lo: f64, hi: f64, fit: Fit, scale: Scale) -> AxisSpec {
        let (mut lo, mut hi) = (lo, hi);
        if fit == Fit::Nice {
            let pad = 0.05 * (hi - lo);
            lo -= pad;
            hi += pad;
        }
        let (step, minor) = nice_step((hi - lo) / 8.0);
        if fit == Fit::Nice {
            lo = (lo / step).floor() * step;
            hi = (hi / step).ceil() * step;
        }
        let bold = ticks_in(lo, hi, step);
        let light = ticks_in(lo, hi, step / minor as f64);
        let magnitude = lo.abs().max(hi.abs());
        let decimals = if magnitude >= 1e6 || (magnitude > 0.0 && magnitude < 1e-3) {
            None
        } else {
            Some(decimals_for(step))
        };
        AxisSpec {
            lo,
            hi,
            bold,
            light,
            scale,
            decimals,
            categories: vec![],
        }
    }

    /// Log axis in plot space (log10 of the value), bounds on whole decades
    /// unless the user fixed them.
    fn decades(lo: f64, hi: f64, user: bool) -> AxisSpec {
        let (lo, hi) = if user {
            (lo, hi)
        } else {
            let (l, h) = (lo.floor(), hi.ceil());
            (l, if h > l { h } else { l + 1.0 })
        };
        let first = lo.ceil() as i64;
        let last = hi.floor() as i64;
        let n = (last - first + 1).max(1);
        // At most ~10 labelled decades.
        let every = ((n + 9) / 10).max(1);
        let bold: Vec<f64> = (first..=last)
            .filter(|d| (d - first) % every == 0)
            .map(|d| d as f64)
            .collect();
        let light: Vec<f64> = if n <= 8 {
            (first - 1..=last)
                .flat_map(|d| (1..10).map(move |m| d as f64 + (m as f64).log10()))
                .filter(|&v| v >= lo - 1e-12 && v <= hi + 1e-12)
                .collect()
        } else {
            vec![]
        };
        AxisSpec {
            lo,
            hi,
            bold,
            light,
            scale: Scale::Log10,
            decimals: None,
            categories: vec![],
        }
    }

    /// Integer ticks (model orders, category indices) over `[lo, hi]`.
    pub fn integers(lo: f64, hi: f64) -> AxisSpec {
        let (step, _) = nice_step(((hi - lo) / 10.0).max(1.0));
        let step = step.max(1.0).round();
        AxisSpec {
            lo,
            hi,
            bold: ticks_in(lo, hi, step),
            light: vec![],
            scale: Scale::Linear,
            decimals: Some(0),
            categories: vec![],
        }
    }

    /// Categorical axis over `[0, n]`: category `i` occupies `[i, i+1]` and is
    /// labelled at its centre. Without categories: a unit axis with no ticks.
    pub fn categorical(categories: Vec<String>) -> AxisSpec {
        let n = categories.len();
        AxisSpec {
            lo: 0.0,
            hi: n.max(1) as f64,
            bold: (0..n).map(|i| i as f64 + 0.5).collect(),
            light: vec![],
            scale: Scale::Linear,
            decimals: Some(0),
            categories,
        }
    }

    pub fn contains(&self, v: f64) -> bool {
        v >= self.lo && v <= self.hi
    }

    /// The plotters coordinate for this axis.
    pub fn coord(&self) -> Axis {
        Axis {
            lo: self.lo,
            hi: self.hi,
            bold: self.bold.clone(),
            light: self.light.clone(),
        }
    }

    /// Tick label text for a plot-space tick position.
    pub fn label(&self, v: f64) -> String {
        if !self.categories.is_empty() {
            let i = (v - 0.5).round();
            return match self.categories.get(i as usize) {
                Some(l) if i >= 0.0 => l.clone(),
                _ => String::new(),
            };
        }
        match self.scale {
            Scale::Log10 => decade_label(v),
            _ => format_number(v, self.decimals),
        }
    }
}

fn widen_degenerate(lo: f64, hi: f64, scale: Scale) -> (f64, f64) {
    if hi > lo {
        return (lo, hi);
    }
    let half = match scale {
        Scale::Log10 => 0.5,
        Scale::Decibel => 5.0,
        Scale::Linear => (lo.abs() * 0.1).max(1.0),
    };
    (lo - half, hi + half)
}

/// Step of 1, 2, 2.5 or 5 × 10ⁿ not below `raw`, and the number of minor
/// divisions that suits it.
fn nice_step(raw: f64) -> (f64, u32) {
    let raw = if raw.is_finite() && raw > 0.0 {
        raw
    } else {
        1.0
    };
    let exp = raw.log10().floor();
    let base = 10f64.powf(exp);
    let m = raw / base;
    let (mant, minor) = if m <= 1.0 {
        (1.0, 5)
    } else if m <= 2.0 {
        (2.0, 4)
    } else if m <= 2.5 {
        (2.5, 5)
    } else if m <= 5.0 {
        (5.0, 5)
    } else {
        (10.0, 5)
    };
    (mant * base, minor)
}

fn ticks_in(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    let eps = step * 1e-9;
    let first = (lo / step - 1e-9).ceil() as i64;
    let last = (hi / step + 1e-9).floor() as i64;
    (first..=last)
        .map(|k| {
            let v = k as f64 * step;
            // Avoid "-0" labels and 1e-17 residues.
            if v.abs() < eps {
                0.0
            } else {
                v
            }
        })
        .collect()
}

fn decimals_for(step: f64) -> usize {
    let mut d = 0usize;
    let mut s = step;
    while (s - s.round()).abs() > 1e-9 * s.abs().max(1.0) && d < 12 {
        s *= 10.0;
        d += 1;
    }
    d
}

/// Fixed-point with `decimals`, or compact scientific (`1.5e-5`) when `None`.
pub(crate) fn format_number(v: f64, decimals: Option<usize>) -> String {
    let s = match decimals {
        Some(d) => format!("{v:.d$}"),
        None if v == 0.0 => "0".to_string(),
        None => {
            let s = format!("{v:.3e}");
            // Trim mantissa zeros: 1.500e-5 -> 1.5e-5
            match s.split_once('e') {
                Some((m, e)) => {
                    let m = if m.contains('.') {
                        m.trim_end_matches('0').trim_end_matches('.')
                    } else {
                        m
                    };
                    format!("{m}e{e}")
                }
                None => s,
            }
        }
    };
    if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
        s[1..].to_string()
    } else {
        s
    }
}

/// "10ⁿ" with Unicode superscripts for an integer decade; other positions
/// (user-fixed limits) get a compact number.
fn decade_label(v: f64) -> String {
    let r = v.round();
    if (v - r).abs() > 1e-9 {
        return format_number(10f64.powf(v), None);
    }
    const SUP: [char; 10] = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
    let n = r as i64;
    let mut s = String::from("10");
    if n < 0 {
        s.push('⁻');
    }
    for c in n.unsigned_abs().to_string().chars() {
        s.push(SUP[c.to_digit(10).unwrap_or(0) as usize]);
    }
    s
}

/// Min and max of the finite values of an iterator.
pub(crate) fn extent(values: impl IntoIterator<Item = f64>) -> Option<(f64, f64)> {
    values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold(None, |acc, v| match acc {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transforms() {
        assert_eq!(Scale::Log10.transform(1e-3), Some(-3.0));
        assert_eq!(Scale::Decibel.transform(0.1), Some(-20.0));
        assert_eq!(Scale::Log10.transform(0.0), None);
        assert_eq!(Scale::Decibel.transform(-1.0), None);
        assert_eq!(Scale::Linear.transform(f64::NAN), None);
        assert_eq!(Scale::Linear.transform(-2.0), Some(-2.0));
    }

    #[test]
    fn nice_linear_axis_covers_data_and_ends_on_ticks() {
        let a =
            AxisSpec::resolve("t", "y", Scale::Linear, Some((0.13, 9.7)), None, Fit::Nice).unwrap();
        assert!(a.lo <= 0.13 && a.hi >= 9.7);
        assert_eq!(a.bold.first().copied(), Some(a.lo));
        assert_eq!(a.bold.last().copied(), Some(a.hi));
        assert!(a.bold.len() >= 5 && a.bold.len() <= 13, "{:?}", a.bold);
        let labels: Vec<String> = a.bold.iter().map(|&v| a.label(v)).collect();
        assert!(labels.iter().all(|l| !l.contains('e')), "{labels:?}");
    }

    #[test]
    fn tight_axis_is_exact() {
        let a = AxisSpec::resolve(
            "t",
            "x",
            Scale::Linear,
            Some((2.0, 400.0)),
            None,
            Fit::Tight,
        )
        .unwrap();
        assert_eq!((a.lo, a.hi), (2.0, 400.0));
        assert!(a.bold.iter().all(|&t| (2.0..=400.0).contains(&t)));
        assert_eq!(a.label(100.0), "100");
    }

    #[test]
    fn log_axis_snaps_to_decades_with_superscript_labels() {
        let a = AxisSpec::resolve(
            "t",
            "y",
            Scale::Log10,
            Some((2e-7f64.log10(), 3e-4f64.log10())),
            None,
            Fit::Nice,
        )
        .unwrap();
        assert_eq!((a.lo, a.hi), (-7.0, -3.0));
        assert_eq!(a.bold, vec![-7.0, -6.0, -5.0, -4.0, -3.0]);
        assert_eq!(a.label(-6.0), "10⁻⁶");
        assert_eq!(a.label(2.0), "10²");
        // 8 minor lines per decade plus the decade lines themselves.
        assert_eq!(a.light.len(), 4 * 9 + 1);
    }

    #[test]
    fn degenerate_and_invalid_ranges() {
        let a =
            AxisSpec::resolve("t", "y", Scale::Linear, Some((3.0, 3.0)), None, Fit::Nice).unwrap();
        assert!(a.lo < 3.0 && a.hi > 3.0);
        let e = AxisSpec::resolve("t", "y", Scale::Log10, None, Some((0.0, 1.0)), Fit::Nice)
            .unwrap_err();
        assert!(matches!(e, PlotError::InvalidRange { axis: "y", .. }));
        let e = AxisSpec::resolve("t", "x", Scale::Linear, None, Some((5.0, 1.0)), Fit::Nice)
            .unwrap_err();
        assert!(e.to_string().contains("invalid x range"));
        // dB limits are taken in dB.
        let a = AxisSpec::resolve(
            "t",
            "y",
            Scale::Decibel,
            None,
            Some((-120.0, -20.0)),
            Fit::Nice,
        )
        .unwrap();
        assert_eq!((a.lo, a.hi), (-120.0, -20.0));
    }

    #[test]
    fn categorical_labels_at_centres() {
        let a = AxisSpec::categorical(vec!["I".into(), "II".into()]);
        assert_eq!((a.lo, a.hi), (0.0, 2.0));
        assert_eq!(a.bold, vec![0.5, 1.5]);
        assert_eq!(a.label(1.5), "II");
        assert_eq!(a.label(2.5), "");
        assert_eq!(a.label(-0.5), "");
    }

    #[test]
    fn number_formatting() {
        assert_eq!(format_number(-0.0, Some(1)), "0.0");
        assert_eq!(format_number(1.5e-5, None), "1.5e-5");
        assert_eq!(format_number(2.0e7, None), "2e7");
        assert_eq!(decimals_for(0.25), 2);
        assert_eq!(decimals_for(50.0), 0);
    }
}
