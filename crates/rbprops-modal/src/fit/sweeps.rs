//! The stabilisation sweeps of one excitation: the model-order limit the band allows,
//! the sweep plan that finds the sub-band where the modes are (locator depth first,
//! then a full diagram there), and the lower-band safety sweeps that add modes crowded
//! near z = 1, where the z-domain polynomial would need far higher orders.

use super::poles::select_lines;
use crate::band::BandData;
use crate::options::{FitOptions, Method};
use crate::pole::Pole;
use crate::stabilisation::{self};
use crate::ModalError;
use crate::{lsce, lscf};
use rbprops_core::c64;

/// Lines of the LSCF stabilisation sweep (decimated to about this many).
pub(super) const SWEEP_LINES: usize = 1024;

/// How hard a stabilisation sweep works.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum SweepDepth {
    /// The full diagram: orders up to `max_order` on [`SWEEP_LINES`] lines.
    Full,
    /// Where are the modes? Only the highest stable mode matters (it sets the
    /// pole-estimation sub-band, with a factor-2 margin), so a lower order on fewer
    /// lines does: the strong modes stabilise early, and the companion eigenvalue
    /// problems, the dominant cost, grow as the fourth power of the top order.
    Locate,
    /// The lower-quarter safety sweeps, which only add modes low in a sub-band that
    /// the full sweep above it has already covered; few modes can live there.
    Safety,
}

impl SweepDepth {
    /// (highest order, decimated line count) for a diagram whose full depth is `max_order`.
    pub(super) fn limits(self, max_order: usize) -> (usize, usize) {
        match self {
            SweepDepth::Full => (max_order, SWEEP_LINES),
            SweepDepth::Locate | SweepDepth::Safety => (max_order.min(24), SWEEP_LINES / 2),
        }
    }
}

/// Whether a safety sweep could only repeat what `sel` already shows below `f_hz`: the
/// wider sweep resolved a stable mode there (its order reached that deep in its band),
/// and neither a candidate cluster nor a physical pole of its highest order lies there
/// away from the selected modes (a safety sweep adds only poles at least
/// `new_mode_bandwidths` half-bandwidths from every known mode).
pub(super) fn safety_covered(
    sel: &stabilisation::Selection,
    f_hz: f64,
    new_mode_bandwidths: f64,
) -> bool {
    let below = |p: &Pole| p.frequency_hz() < f_hz;
    let unexplained = |p: &Pole| {
        below(p)
            && sel
                .modes
                .iter()
                .all(|m| m.pole.distance_in_bandwidths(p) >= new_mode_bandwidths)
    };
    let top = sel.diagram.max_order;
    sel.modes.iter().any(|m| below(&m.pole))
        && !sel.candidates.iter().any(|c| unexplained(&c.pole))
        && !sel.diagram.poles.iter().any(|d| {
            d.order == top
                && d.class != stabilisation::StabilityClass::Computational
                && unexplained(&Pole::from_modal(d.frequency_hz, d.damping_ratio))
        })
}

/// The highest model order the band supports: each order n needs n + 1 numerator and n
/// denominator coefficients per channel from 2N real equations; a margin of 2 keeps the
/// fit overdetermined. Too few lines for one mode is an error; a reduced order a warning.
pub(super) fn order_limit(
    n: usize,
    opts: &FitOptions,
    name: &str,
    warnings: &mut Vec<String>,
) -> Result<usize, ModalError> {
    let n_max = opts.max_order.min(n.saturating_sub(2));
    if n_max < 2 || n < 4 {
        return Err(ModalError::BadInput {
            excitation: name.into(),
            reason: format!(
                "{n} lines in the band: too few for even one mode (need at least 4 lines)"
            ),
        });
    }
    if n_max < opts.max_order {
        warnings.push(format!(
            "excitation '{name}': only {n} lines in the band, maximum model order reduced from {} to {n_max}",
            opts.max_order
        ));
    }
    Ok(n_max)
}

/// Draws stabilisation diagrams of the channels `chans` on sub-bands of their band.
pub(super) struct Sweeper<'a> {
    pub(super) chans: &'a [Vec<c64>],
    pub(super) opts: &'a FitOptions,
    pub(super) name: &'a str,
}

impl Sweeper<'_> {
    /// The diagram on the lines of `sub` (the first lines of the band) at `depth`, and the
    /// modes it selects.
    pub(super) fn sweep(
        &self,
        sub: &BandData,
        depth: SweepDepth,
    ) -> Result<stabilisation::Selection, ModalError> {
        let (opts, chans) = (self.opts, self.chans);
        let (max_order, max_lines) = depth.limits(opts.max_order);
        let nm = max_order.min(sub.n_lines().saturating_sub(2));
        let orders = match opts.method {
            Method::Lscf | Method::Circle | Method::Plscf => {
                // LSCF works on any axis: decimate the lines and solve even orders only.
                let keep = BandData::decimation_indices(sub.n_lines(), max_lines);
                let dec = sub.lines(&keep);
                let dec_chans = select_lines(chans, &keep);
                let nm = nm.min(dec.n_lines().saturating_sub(2));
                crate::prof::time(0, || lscf::sweep_orders(&dec, &dec_chans, nm, 2))
            }
            Method::Lsce => {
                let sub_chans: Vec<Vec<c64>> =
                    chans.iter().map(|h| h[..sub.n_lines()].to_vec()).collect();
                lsce::sweep(sub, &sub_chans, nm).map_err(|reason| ModalError::Axis {
                    excitation: self.name.into(),
                    method: "LSCE",
                    reason,
                })?
            }
        };
        let band_w = (sub.omega[0], *sub.omega.last().unwrap());
        Ok(crate::prof::time(1, || {
            stabilisation::select(&orders, band_w, &opts.tolerances, opts.n_modes)
        }))
    }

    /// The fewest lines a sub-band sweep may have.
    pub(super) fn min_sweep_lines(&self) -> usize {
        4 * self.opts.max_order.max(8)
    }
}

/// The sweep plan: which sub-band the stabilisation diagram is drawn on. Polynomial
/// (z-domain) estimators need a model order that grows with the band relative to where
/// the modes are: rigid-body modes in the bottom quarter of a baseband need ~5× more
/// orders than the same modes filling the band. So when the stable modes all sit low,
/// the sweep is repeated on the lines up to `sub_band_margin` × the highest stable mode
/// (or `sub_band_without_modes` of the band when none is stable). The first pass over the
/// whole band only has to say where the modes are, so it runs at locator depth; a full
/// sweep follows on whatever band that leaves. Returns the sub-band and its selection
/// (the refinement and the residues still use the whole band).
pub(super) fn sweep_plan<'b>(
    band: &'b BandData,
    cap_hz: Option<f64>,
    sweeper: &Sweeper,
    warnings: &mut Vec<String>,
) -> Result<(std::borrow::Cow<'b, BandData>, stabilisation::Selection), ModalError> {
    let (opts, name, search) = (sweeper.opts, sweeper.name, &sweeper.opts.search);
    // Borrowed while it is the whole band (no copy of every channel).
    let mut sub = match cap_hz {
        Some(f) => std::borrow::Cow::Owned(band.up_to(f)),
        None => std::borrow::Cow::Borrowed(band),
    };
    let mut depth = if opts.method == Method::Lsce || opts.n_modes.is_some() {
        SweepDepth::Full
    } else {
        SweepDepth::Locate
    };
    loop {
        let sel = sweeper.sweep(&sub, depth)?;
        let top = *sub.frequency_hz.last().unwrap();
        let target = match sel
            .modes
            .iter()
            .map(|m| m.pole.frequency_hz())
            .reduce(f64::max)
        {
            Some(f) => search.sub_band_margin * f,
            None => search.sub_band_without_modes * top,
        };
        let lines = sub.frequency_hz.partition_point(|&f| f <= target);
        if target < search.sub_band_max_fraction * top && lines >= sweeper.min_sweep_lines() {
            warnings.push(format!(
                "excitation '{name}': poles estimated on {:.4}–{target:.4} Hz, where the modes are (residues on the whole band)",
                sub.frequency_hz[0]
            ));
            sub = std::borrow::Cow::Owned(sub.up_to(target));
            depth = SweepDepth::Full;
            continue;
        }
        if depth != SweepDepth::Full {
            depth = SweepDepth::Full;
            continue;
        }
        return Ok((sub, sel));
    }
}

/// The safety sweeps. On wide bands, modes far below the band's top crowd near z = 1 and
/// need far higher orders than the sweep allows (and decimation may under-sample them).
/// Sweep the lowest `safety_fraction` of `sub` again, and again, and add to `sel` the
/// modes each finds in the lowest `safety_keep_fraction` of its sub-band that the wider
/// sweeps did not; a sub-band the wider sweep already covers ([`safety_covered`]) is
/// skipped. The modes end sorted by natural frequency.
pub(super) fn safety_sweeps(
    sub: &BandData,
    sel: &mut stabilisation::Selection,
    sweeper: &Sweeper,
) -> Result<(), ModalError> {
    let search = &sweeper.opts.search;
    let mut low = search.safety_fraction * *sub.frequency_hz.last().unwrap();
    loop {
        let lower = sub.up_to(low);
        if lower.n_lines() < sweeper.min_sweep_lines() {
            break;
        }
        if safety_covered(
            sel,
            search.safety_keep_fraction * low,
            search.new_mode_bandwidths,
        ) {
            low *= search.safety_fraction;
            continue;
        }
        let s_low = sweeper.sweep(&lower, SweepDepth::Safety)?;
        for m in s_low.modes {
            let known = sel
                .modes
                .iter()
                .any(|k| k.pole.distance_in_bandwidths(&m.pole) < search.new_mode_bandwidths);
            if m.pole.frequency_hz() < search.safety_keep_fraction * low && !known {
                sel.modes.push(m);
            }
        }
        low *= search.safety_fraction;
    }
    sel.modes
        .sort_by(|a, b| a.pole.omega_n().total_cmp(&b.pole.omega_n()));
    Ok(())
}
