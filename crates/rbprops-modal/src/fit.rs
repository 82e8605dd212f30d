//! Orchestration: poles → selection → refinement → residues → records, per excitation,
//! in parallel over excitations.

use crate::band::BandData;
use crate::circle;
use crate::linalg;
use crate::lsce;
use crate::lscf;
use crate::lsfd::{self, Residuals};
use crate::options::{FitOptions, Method, PoleMode, PoleSearchParams};
use crate::pole::{mpc, Pole};
use crate::stabilisation::{self, StabilisationDiagram};
use crate::ModalError;
use rayon::prelude::*;
use rbprops_core::records::{ExcitationFitRecord, ModalFitRecord, ModeEstimate};
use rbprops_core::stats::chi2_isf_wilson_hilferty;
use rbprops_core::{c64, FrfSet, Geometry, Quantity};
use std::f64::consts::PI;

/// The residue convention written into every [`ModalFitRecord`].
pub const RESIDUE_CONVENTION: &str = "modal constants A (1/kg) of the receptance form \
H(w) = sum_r A_r/(w_r^2 - w^2 + 2i zeta_r w_r w), A_r = 2i w_d,r R_r from the pole-residue \
form R_r/(iw - lambda_r) + conj(R_r)/(iw - conj(lambda_r)), lambda_r = -zeta_r w_r + i w_d,r, \
whatever the input quantity";

/// Plot data of one excitation.
#[derive(Debug, Clone, PartialEq)]
pub struct ExcitationDiagnostics {
    /// The excitation's id.
    pub excitation: String,
    /// Poles per model order with their stability class (for PerSetup: the set-up's).
    pub stabilisation: StabilisationDiagram,
    /// Receptance, mobility or accelerance: the quantity of `synthesised`.
    pub quantity: Quantity,
    /// Lines of the fitted band.
    pub frequency_hz: Vec<f64>,
    /// Synthesised FRFs `[channel][line]` in the measured quantity, same lines; empty
    /// unless [`FitOptions::keep_synthesised`].
    pub synthesised: Vec<Vec<c64>>,
    /// The final poles `λ_r` (rad/s), ascending frequency.
    pub poles_rad_s: Vec<c64>,
}

/// Result of one excitation.
#[derive(Debug, Clone, PartialEq)]
pub struct ExcitationFit {
    /// The excitation's record as `modal-fit` writes it (modes, warnings, fit quality).
    pub record: ExcitationFitRecord,
    /// The identified modes, ascending frequency.
    pub modes: Vec<ModeEstimate>,
    /// Plot data.
    pub diagnostics: ExcitationDiagnostics,
    /// The warnings of `record` that say a pole has multiplicity above one, in the
    /// record's order: what the automatic poly-reference switch decides on.
    pub multiplicity: Vec<MultiplicityWarning>,
}

/// What showed that two poles of a single-reference fit cannot be told apart.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Multiplicity {
    /// The forward model-order test split one pole into a close pair.
    SplitPair,
    /// The pole refinement's information matrix is singular.
    SingularInformation,
    /// Two poles closer than the separable distance: one repeated root.
    RepeatedRoot,
    /// The residue basis of the poles is nearly singular.
    SingularResidueBasis,
}

/// A warning of an excitation's record that says a pole has multiplicity above one,
/// with its kind: the poly-reference switch decides on the kind, never on the text.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MultiplicityWarning {
    /// What showed the multiplicity.
    pub kind: Multiplicity,
    /// The warning as the record holds it.
    pub text: String,
}

/// Pushes a multiplicity warning onto the record's warnings and, typed, onto `kinds`.
fn warn_multiplicity(
    warnings: &mut Vec<String>,
    kinds: &mut Vec<MultiplicityWarning>,
    kind: Multiplicity,
    text: String,
) {
    warnings.push(text.clone());
    kinds.push(MultiplicityWarning { kind, text });
}

/// Result of a campaign.
#[derive(Debug, Clone, PartialEq)]
pub struct ModalFitOutput {
    /// The `modal-fit` record of every excitation.
    pub record: ModalFitRecord,
    /// One per excitation, geometry order (empty plot data for a failed excitation).
    pub diagnostics: Vec<ExcitationDiagnostics>,
}

/// Poles shared by the channels they were estimated from.
#[derive(Debug, Clone)]
struct PoleSet {
    poles: Vec<Pole>,
    /// Standard deviations of (f Hz, ζ) per pole.
    std: Vec<(f64, f64)>,
    confidence: Vec<f64>,
    /// Per-pole warnings (close modes, …).
    mode_warnings: Vec<Vec<String>>,
    diagram: StabilisationDiagram,
    warnings: Vec<String>,
    /// The multiplicity warnings among `warnings`, in order.
    multiplicity: Vec<MultiplicityWarning>,
}

fn check_shapes(geometry: &Geometry, frf: &FrfSet) -> Result<(), ModalError> {
    if frf.n_excitations != geometry.excitations.len() {
        return Err(ModalError::Shape(format!(
            "{} excitations in the FRF set, {} in the geometry",
            frf.n_excitations,
            geometry.excitations.len()
        )));
    }
    if frf.n_channels != geometry.channels.len() {
        return Err(ModalError::Shape(format!(
            "{} channels in the FRF set, {} in the geometry",
            frf.n_channels,
            geometry.channels.len()
        )));
    }
    if frf.values.len() != frf.n_excitations * frf.n_channels * frf.n_lines() {
        return Err(ModalError::Shape(format!(
            "{} values for {}×{}×{}",
            frf.values.len(),
            frf.n_excitations,
            frf.n_channels,
            frf.n_lines()
        )));
    }
    Ok(())
}

/// Channels with signal, and warnings for the others.
fn live_channels(band: &BandData, geometry: &Geometry, name: &str) -> (Vec<usize>, Vec<String>) {
    let mut live = Vec::new();
    let mut warnings = Vec::new();
    for (c, h) in band.channels.iter().enumerate() {
        // A channel has signal when its RMS is positive, i.e. when any |h|² is (stops at
        // the first such line instead of summing the whole channel).
        if h.iter().any(|z| z.norm_sqr() > 0.0) {
            live.push(c);
        } else {
            warnings.push(format!(
                "excitation '{name}': channel '{}' is identically zero in the band; it is left out of the pole estimate and its residues are 0",
                geometry.channels[c].id
            ));
        }
    }
    (live, warnings)
}

/// Residual variance below which a residual is rounding, not noise. The model-order
/// tests divide cost drops by the residual variance `σ̂² = cost/dof` of the weighted data,
/// which has unit mean square per complex line (`lsfd::line_weights`), so σ̂² is relative
/// to the data. Noise-free float64 data fit to 1e-15–1e-12 relative (σ̂² ~ 1e-30–1e-24,
/// the latter for ill-conditioned fits); float32-quantised data to ~6e-8 (σ̂² ~ 1e-15).
/// A floor of (1e-10)² lies well clear of both: it never touches measured or quantised
/// data, and on exact data it keeps rounding-level cost changes from reading as χ² values
/// of 1e28 (seen on the 300-line noise-free Test Case II before this floor).
const ROUNDING_VARIANCE: f64 = 1e-20;

/// The residual variance a χ² model-order test divides by, `cost/dof` floored at
/// [`ROUNDING_VARIANCE`]; `true` when floored (noise-free data: there is no σ² to speak of).
fn test_variance(cost: f64, dof: f64) -> (f64, bool) {
    let s2 = cost / dof;
    if s2.is_finite() && s2 > ROUNDING_VARIANCE {
        (s2, false)
    } else {
        (ROUNDING_VARIANCE, true)
    }
}

/// A cost change in the units of the model-order test, for warnings: `noisy` (a σ²
/// multiple), or, when the residual is at the rounding level, `exact`, a statement of that
/// instead of a σ² multiple (which would be a ratio of rounding errors).
fn in_sigma2(noisy: impl FnOnce() -> String, exact_text: &str, exact: bool) -> String {
    if exact {
        format!("{exact_text} (the residual is at the rounding level: noise-free data, no noise σ² to measure it in)")
    } else {
        noisy()
    }
}

/// Standard deviation of `(f, ζ)` from the covariance of `(Re λ, Im λ)`.
fn modal_std(p: &Pole, cov: &[[f64; 2]; 2]) -> (f64, f64) {
    let (re, im) = (p.0.re, p.0.im);
    let a = p.0.norm();
    let gf = [re / a / (2.0 * PI), im / a / (2.0 * PI)];
    let gz = [-im * im / (a * a * a), re * im / (a * a * a)];
    let q = |g: [f64; 2]| {
        (g[0] * g[0] * cov[0][0] + 2.0 * g[0] * g[1] * cov[0][1] + g[1] * g[1] * cov[1][1])
            .max(0.0)
            .sqrt()
    };
    (q(gf), q(gz))
}

/// Lines of the LSCF stabilisation sweep (decimated to about this many).
const SWEEP_LINES: usize = 1024;
/// Refinement lines: every line within this many half-power half-bandwidths of a pole
/// (≈ 97 % of the pole information, see `BandData::focus_indices`) …
const FOCUS_HALF_WIDTHS: f64 = 20.0;
/// … plus this many evenly spaced lines over the band.
const SKELETON_LINES: usize = 256;

/// How hard a stabilisation sweep works.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum SweepDepth {
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
    fn limits(self, max_order: usize) -> (usize, usize) {
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
fn safety_covered(sel: &stabilisation::Selection, f_hz: f64, new_mode_bandwidths: f64) -> bool {
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

/// The lines `keep` of every channel.
fn select_lines(chans: &[Vec<c64>], keep: &[usize]) -> Vec<Vec<c64>> {
    chans
        .iter()
        .map(|h| keep.iter().map(|&k| h[k]).collect())
        .collect()
}

/// Poles from the channels `chans` of `band` (one excitation, or a whole set-up).
fn estimate_poles(
    band: &BandData,
    chans: &[Vec<c64>],
    opts: &FitOptions,
    name: &str,
) -> Result<PoleSet, ModalError> {
    estimate_poles_from(band, chans, opts, name, None)
}

/// The per-pole results while the refinement and the model-order tests change the poles.
struct PoleTrack {
    poles: Vec<Pole>,
    /// Standard deviations of (f Hz, ζ) per pole.
    std: Vec<(f64, f64)>,
    confidence: Vec<f64>,
    mode_warnings: Vec<Vec<String>>,
}

/// How the drop-and-refine stage ended.
enum Refinement {
    /// The refined poles (possibly none left).
    Refined(lsfd::Refined),
    /// A dropped pole showed that the modes sit low in the band: the whole estimate was
    /// redone on a sub-band; its result.
    Restarted(PoleSet),
}

/// As [`estimate_poles`], with the pole-estimation sub-band capped at `cap_hz`.
///
/// Stages: the model-order limit ([`order_limit`]), the sweep plan that chooses the
/// sub-band of the stabilisation diagram ([`sweep_plan`]), the lower-band safety sweeps
/// ([`safety_sweeps`]), the refinement that drops computational poles
/// ([`refine_supported`]), the χ² model-order tests ([`OrderTest`]) and the close-pair
/// report ([`flag_close_pairs`]). Thresholds: [`crate::PoleSearchParams`].
fn estimate_poles_from(
    band: &BandData,
    chans: &[Vec<c64>],
    opts: &FitOptions,
    name: &str,
    cap_hz: Option<f64>,
) -> Result<PoleSet, ModalError> {
    let n = band.n_lines();
    let mut warnings = Vec::new();
    let mut multiplicity = Vec::new();
    let n_max = order_limit(n, opts, name, &mut warnings)?;
    let sweeper = Sweeper { chans, opts, name };
    let (sub, mut sel) = sweep_plan(band, cap_hz, &sweeper, &mut warnings)?;
    if opts.n_modes.is_none() {
        safety_sweeps(&sub, &mut sel, &sweeper)?;
    }
    warnings.extend(
        sel.warnings
            .iter()
            .map(|w| format!("excitation '{name}': {w}")),
    );
    if sel.modes.is_empty() {
        return Err(ModalError::NoModes {
            excitation: name.into(),
            reason: format!(
                "{} poles in the diagram up to order {n_max}, none stable in frequency, damping and shape",
                sel.diagram.poles.len()
            ),
        });
    }
    let mut track = PoleTrack {
        poles: sel.modes.iter().map(|m| m.pole).collect(),
        std: sel.modes.iter().map(|m| m.spread).collect(),
        confidence: sel.modes.iter().map(|m| m.presence).collect(),
        mode_warnings: vec![Vec::new(); sel.modes.len()],
    };
    let res = Residuals::for_band(opts.residual_terms, band);
    // Refinement and model-order test on the lines that carry the pole information:
    // those near the selected poles and the candidates the residual test may add, plus
    // an even skeleton for the residual terms (see `BandData::focus_indices`). The
    // residues are then fitted on every line.
    let focus: Vec<Pole> = track
        .poles
        .iter()
        .copied()
        .chain(sel.candidates.iter().map(|c| c.pole))
        .collect();
    let keep = band.focus_indices(&focus, FOCUS_HALF_WIDTHS, 4.0, SKELETON_LINES);
    let rband = band.lines(&keep);
    let rchans = select_lines(chans, &keep);
    let rn = rband.n_lines();
    if opts.refine && opts.method != Method::Circle {
        let rows = 2 * rn;
        let unknowns = 2 * track.poles.len() + 2;
        if rows <= unknowns + 2 * track.poles.len() {
            warnings.push(format!(
                "excitation '{name}': {n} lines are too few to refine {} poles; LSCF poles kept",
                track.poles.len()
            ));
        } else {
            let refine = RefineInputs {
                band,
                chans,
                rband: &rband,
                rchans: &rchans,
                res,
                opts,
                name,
                cap_hz,
                sub_top_hz: *sub.frequency_hz.last().unwrap(),
            };
            let mut r = match refine_supported(&refine, &mut track, &mut warnings)? {
                Refinement::Refined(r) => r,
                Refinement::Restarted(ps) => return Ok(ps),
            };
            if track.poles.is_empty() {
                return Err(ModalError::NoModes {
                    excitation: name.into(),
                    reason: "every selected pole was dropped by the refinement".into(),
                });
            }
            if opts.n_modes.is_none() {
                let test = OrderTest {
                    band: &rband,
                    chans: &rchans,
                    res,
                    threshold: chi2_isf_wilson_hilferty(
                        opts.search.order_test_z,
                        (2 + 2 * chans.len()) as f64,
                    ),
                    max_damping: opts.tolerances.max_damping,
                    full_band_w: (band.omega[0], *band.omega.last().unwrap()),
                    search: &opts.search,
                    name,
                };
                let mut tracked = TrackedPoles {
                    r: &mut r,
                    confidence: &mut track.confidence,
                    mode_warnings: &mut track.mode_warnings,
                    warnings: &mut warnings,
                    multiplicity: &mut multiplicity,
                };
                test.add_intermittent_modes(&mut tracked, &sel.candidates);
                test.prune_close_poles(&mut tracked);
                test.split_merged_poles(&mut tracked);
            }
            if r.singular {
                warn_multiplicity(
                    &mut warnings,
                    &mut multiplicity,
                    Multiplicity::SingularInformation,
                    format!(
                        "excitation '{name}': the poles are not all identifiable (singular information matrix): two poles cannot be separated"
                    ),
                );
            }
            if !r.converged {
                warnings.push(format!(
                    "excitation '{name}': pole refinement did not converge in {} iterations",
                    r.iterations
                ));
            }
            track.poles = r.poles.clone();
            track.std = track
                .poles
                .iter()
                .zip(&r.covariance)
                .map(|(p, c)| modal_std(p, c))
                .collect();
        }
    }
    let mut track = track.sorted();
    flag_close_pairs(
        &mut track,
        &opts.search,
        name,
        &mut warnings,
        &mut multiplicity,
    );
    Ok(PoleSet {
        poles: track.poles,
        std: track.std,
        confidence: track.confidence,
        mode_warnings: track.mode_warnings,
        diagram: sel.diagram,
        warnings,
        multiplicity,
    })
}

/// The highest model order the band supports: each order n needs n + 1 numerator and n
/// denominator coefficients per channel from 2N real equations; a margin of 2 keeps the
/// fit overdetermined. Too few lines for one mode is an error; a reduced order a warning.
fn order_limit(
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
struct Sweeper<'a> {
    chans: &'a [Vec<c64>],
    opts: &'a FitOptions,
    name: &'a str,
}

impl Sweeper<'_> {
    /// The diagram on the lines of `sub` (the first lines of the band) at `depth`, and the
    /// modes it selects.
    fn sweep(
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
    fn min_sweep_lines(&self) -> usize {
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
fn sweep_plan<'b>(
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
fn safety_sweeps(
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

/// What the drop-and-refine stage reads: the whole band (for a restart), the refinement
/// lines, and the top of the sub-band the diagram was drawn on.
struct RefineInputs<'a> {
    band: &'a BandData,
    chans: &'a [Vec<c64>],
    rband: &'a BandData,
    rchans: &'a [Vec<c64>],
    res: Residuals,
    opts: &'a FitOptions,
    name: &'a str,
    cap_hz: Option<f64>,
    sub_top_hz: f64,
}

/// Refines the poles jointly ([`lsfd::refine`]). Refinement is local: a pole it pushes
/// more than `max_refinement_shift_bandwidths` away, out of the band or past the damping
/// limit is not supported by the data (a computational pole that looked stable): drop it
/// and refine again. A spurious high pole can hide that the modes sit low in the band:
/// when one is dropped and the remaining modes sit low, the whole estimate is redone on
/// the lines up to `sub_band_margin` × the highest remaining mode.
fn refine_supported(
    p: &RefineInputs,
    track: &mut PoleTrack,
    warnings: &mut Vec<String>,
) -> Result<Refinement, ModalError> {
    let (band, opts, name, search) = (p.band, p.opts, p.name, &p.opts.search);
    let poles = &mut track.poles;
    let mut r = crate::prof::time(2, || lsfd::refine(poles, p.rband, p.rchans, p.res));
    let band_w = (band.omega[0], *band.omega.last().unwrap());
    loop {
        let bad = poles
            .iter()
            .zip(&r.poles)
            .enumerate()
            .map(|(i, (a, b))| {
                let off = b.damping() >= opts.tolerances.max_damping
                    || b.omega_n() < band_w.0
                    || b.omega_n() > band_w.1;
                (
                    i,
                    if off {
                        f64::INFINITY
                    } else {
                        a.distance_in_bandwidths(b)
                    },
                )
            })
            .filter(|(_, d)| *d > search.max_refinement_shift_bandwidths)
            .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)));
        let Some((i, d)) = bad else { break };
        warnings.push(format!(
            "excitation '{name}': pole at {:.4} Hz dropped: the refinement could not hold it (moved {d:.1} half-bandwidths or left the band), so it is computational",
            poles[i].frequency_hz()
        ));
        poles.remove(i);
        if let Some(f_top) = poles.iter().map(|p| p.frequency_hz()).reduce(f64::max) {
            let cap = search.sub_band_margin * f_top;
            let lines = band.frequency_hz.partition_point(|&f| f <= cap);
            if p.cap_hz.is_none()
                && cap < search.sub_band_max_fraction * p.sub_top_hz
                && lines >= 4 * opts.max_order.max(8)
            {
                let mut ps = estimate_poles_from(band, p.chans, opts, name, Some(cap))?;
                let mut w = warnings.clone();
                w.append(&mut ps.warnings);
                ps.warnings = w;
                return Ok(Refinement::Restarted(ps));
            }
        }
        track.std.remove(i);
        track.confidence.remove(i);
        track.mode_warnings.remove(i);
        if poles.is_empty() {
            break;
        }
        r = crate::prof::time(2, || lsfd::refine(poles, p.rband, p.rchans, p.res));
    }
    Ok(Refinement::Refined(r))
}

impl PoleTrack {
    /// Sorted by natural frequency (refinement may reorder two close poles).
    fn sorted(self) -> Self {
        let mut idx: Vec<usize> = (0..self.poles.len()).collect();
        idx.sort_by(|&a, &b| self.poles[a].omega_n().total_cmp(&self.poles[b].omega_n()));
        Self {
            poles: idx.iter().map(|&i| self.poles[i]).collect(),
            std: idx.iter().map(|&i| self.std[i]).collect(),
            confidence: idx.iter().map(|&i| self.confidence[i]).collect(),
            mode_warnings: idx.iter().map(|&i| self.mode_warnings[i].clone()).collect(),
        }
    }
}

/// Close pairs: says plainly when two poles cannot be told apart (closer than
/// `inseparable_bandwidths`, or than twice their combined frequency standard deviation:
/// both lose half their confidence) and notes the close ones (`close_bandwidths`).
fn flag_close_pairs(
    track: &mut PoleTrack,
    search: &PoleSearchParams,
    name: &str,
    warnings: &mut Vec<String>,
    multiplicity: &mut Vec<MultiplicityWarning>,
) {
    let PoleTrack {
        poles,
        std,
        confidence,
        mode_warnings,
    } = track;
    for i in 0..poles.len() {
        for j in i + 1..poles.len() {
            let d = poles[i].distance_in_bandwidths(&poles[j]);
            let sep_hz = (poles[j].frequency_hz() - poles[i].frequency_hz()).abs();
            let unc = 2.0 * (std[i].0.powi(2) + std[j].0.powi(2)).sqrt();
            if d < search.inseparable_bandwidths || (unc > 0.0 && sep_hz < unc) {
                let msg = format!(
                    "modes {} and {} ({:.5} and {:.5} Hz, {:.2} half-bandwidths apart) cannot be separated: treat them as one repeated root",
                    i + 1,
                    j + 1,
                    poles[i].frequency_hz(),
                    poles[j].frequency_hz(),
                    d
                );
                warn_multiplicity(
                    warnings,
                    multiplicity,
                    Multiplicity::RepeatedRoot,
                    format!("excitation '{name}': {msg}"),
                );
                mode_warnings[i].push(msg.clone());
                mode_warnings[j].push(msg);
                confidence[i] *= 0.5;
                confidence[j] *= 0.5;
            } else if d < search.close_bandwidths {
                let msg = format!(
                    "close to mode {} ({:.2} half-bandwidths): resolved, but sensitive to noise",
                    if i < j { j + 1 } else { i + 1 },
                    d
                );
                mode_warnings[i].push(msg.clone());
                mode_warnings[j]
                    .push(msg.replace(&format!("mode {}", j + 1), &format!("mode {}", i + 1)));
            }
        }
    }
}

/// The model-order tests after the refinement: the data a refinement runs on (the
/// refinement lines), the χ² threshold for one pole's 2 + 2·channels parameters and the
/// search thresholds.
struct OrderTest<'a> {
    band: &'a BandData,
    chans: &'a [Vec<c64>],
    res: Residuals,
    threshold: f64,
    max_damping: f64,
    /// The whole band's (ω_min, ω_max): where an added mode must lie.
    full_band_w: (f64, f64),
    search: &'a PoleSearchParams,
    name: &'a str,
}

/// The refined poles and what is kept per pole, as the model-order tests change them.
struct TrackedPoles<'a> {
    r: &'a mut lsfd::Refined,
    confidence: &'a mut Vec<f64>,
    mode_warnings: &'a mut Vec<Vec<String>>,
    warnings: &'a mut Vec<String>,
    multiplicity: &'a mut Vec<MultiplicityWarning>,
}

impl OrderTest<'_> {
    /// Residual degrees of freedom with `np` poles: 2 real equations per line and channel
    /// less the 2np + 2 residue and residual-term parameters per channel and the 2np pole
    /// parameters (at least 1).
    fn dof(&self, np: usize) -> f64 {
        let (rn, no) = (self.band.n_lines(), self.chans.len());
        (2 * rn * no)
            .saturating_sub(no * (2 * np + 2) + 2 * np)
            .max(1) as f64
    }

    /// Forward model-order step on the residual: a weak mode beside a strong one is often
    /// only intermittently stable in the diagram. Try each rejected cluster as an extra
    /// mode; keep it when the cost drop is significant for the 2 + 2·channels parameters
    /// it adds (χ² at the `order_test_z` level) and the refined pole is physical, separate
    /// and stays within `candidate_drift_bandwidths` of the cluster. A cheap screen (the
    /// cost drop with each candidate as it is, all from one QR, recomputed only after a
    /// candidate is accepted) spares the full refinement for unpromising candidates.
    fn add_intermittent_modes(
        &self,
        t: &mut TrackedPoles,
        candidates: &[stabilisation::SelectedPole],
    ) {
        let (band, chans, res, threshold, name) =
            (self.band, self.chans, self.res, self.threshold, self.name);
        let search = self.search;
        let rn = band.n_lines();
        let cand_poles: Vec<Pole> = candidates.iter().map(|c| c.pole).collect();
        let mut screen: Option<(f64, Vec<f64>)> = None;
        for (ci, cand) in candidates.iter().enumerate() {
            let r = &*t.r;
            let mut trial_poles = r.poles.clone();
            if trial_poles
                .iter()
                .any(|p| p.distance_in_bandwidths(&cand.pole) < search.inseparable_bandwidths)
            {
                continue;
            }
            trial_poles.push(cand.pole);
            if 2 * rn <= 2 * (2 * trial_poles.len() + 2) {
                break;
            }
            let dof0 = self.dof(trial_poles.len());
            let (c_now, c_with) = screen.get_or_insert_with(|| {
                crate::prof::time(3, || lsfd::screen_extra_poles(r, &cand_poles, band, chans))
            });
            let c_screen = c_with[ci];
            if (*c_now - c_screen) / test_variance(c_screen, dof0).0 < threshold {
                continue;
            }
            let r2 = crate::prof::time(2, || lsfd::refine(&trial_poles, band, chans, res));
            let added = *r2.poles.last().unwrap();
            let (s2, exact) = test_variance(r2.cost.1, self.dof(r2.poles.len()));
            let separate = r2.poles[..r2.poles.len() - 1]
                .iter()
                .all(|p| p.distance_in_bandwidths(&added) > search.inseparable_bandwidths);
            let physical = added.damping() > 0.0
                && added.damping() < self.max_damping
                && added.omega_n() >= self.full_band_w.0
                && added.omega_n() <= self.full_band_w.1;
            if physical
                && separate
                && !r2.singular
                && added.distance_in_bandwidths(&cand.pole) < search.candidate_drift_bandwidths
                && (r.cost.1 - r2.cost.1) / s2 > threshold
            {
                t.warnings.push(format!(
                    "excitation '{name}': mode at {:.4} Hz added by the residual test (intermittently stable in the diagram, {})",
                    added.frequency_hz(),
                    in_sigma2(
                        || format!("cost −{:.1}σ²", (r.cost.1 - r2.cost.1) / s2),
                        "cost lowered",
                        exact
                    )
                ));
                // Half its diagram presence: it was not stable throughout.
                t.confidence.push(0.5 * cand.presence);
                t.mode_warnings.push(vec![
                    "found by the residual model-order test, not stable throughout the diagram"
                        .into(),
                ]);
                *t.r = r2;
                screen = None;
            }
        }
    }

    /// Backward model-order step: a pole within two half-bandwidths of another, or with
    /// low diagram confidence, is dropped when the refit without it costs less than the
    /// χ² threshold (in units of the residual variance). Over-split close pairs (three
    /// poles for two modes) and weak computational poles go this way.
    fn prune_close_poles(&self, t: &mut TrackedPoles) {
        let search = self.search;
        loop {
            let r: &lsfd::Refined = t.r;
            let n = r.poles.len();
            if n < 2 {
                return;
            }
            let suspect = |i: usize| {
                t.confidence[i] < search.suspect_confidence
                    || (0..n).any(|j| {
                        j != i
                            && r.poles[i].distance_in_bandwidths(&r.poles[j])
                                < search.close_bandwidths
                    })
            };
            let (s2, exact) = test_variance(r.cost.1, self.dof(n));
            // The least significant suspect pole, if any is insignificant.
            let weakest = (0..n)
                .filter(|&i| suspect(i))
                .map(|i| {
                    let rest: Vec<Pole> = (0..n).filter(|&j| j != i).map(|j| r.poles[j]).collect();
                    let ri = crate::prof::time(2, || {
                        lsfd::refine(&rest, self.band, self.chans, self.res)
                    });
                    (i, (ri.cost.1 - r.cost.1) / s2, ri)
                })
                .filter(|(_, gain, ri)| *gain < self.threshold && !ri.singular)
                .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
            let Some((i, gain, ri)) = weakest else { return };
            t.warnings.push(format!(
            "excitation '{}': pole at {:.4} Hz dropped by the backward model-order test (it {}, below the χ² threshold {:.1})",
            self.name,
            r.poles[i].frequency_hz(),
            in_sigma2(
                || format!("lowers the cost by only {gain:.1}σ²"),
                "lowers the cost",
                exact
            ),
            self.threshold
        ));
            t.confidence.remove(i);
            t.mode_warnings.remove(i);
            *t.r = ri;
        }
    }

    /// Forward model-order step for merged pairs: a pair closer than its half-power
    /// bandwidth can come out of the diagram as one pole. Each pole gets a partner a
    /// little below and above it (screened from one QR); the best significant one is
    /// refined jointly and kept when the χ² drop is significant and the pair stays
    /// separate, physical and identifiable.
    fn split_merged_poles(&self, t: &mut TrackedPoles) {
        let TrackedPoles {
            r,
            confidence,
            mode_warnings,
            warnings,
            multiplicity,
        } = t;
        let r: &mut lsfd::Refined = r;
        let (band, chans, res, threshold, name) =
            (self.band, self.chans, self.res, self.threshold, self.name);
        let (search, max_damping) = (self.search, self.max_damping);
        let band_w = (band.omega[0], *band.omega.last().unwrap());
        let mut tried = 0;
        while tried < r.poles.len() {
            let n = r.poles.len();
            if 2 * band.n_lines() <= 2 * (2 * (n + 1) + 2) {
                return;
            }
            let partners: Vec<(usize, Pole)> = r
                .poles
                .iter()
                .enumerate()
                .flat_map(|(i, p)| {
                    let d = search.split_offset_bandwidths * p.half_bandwidth();
                    [-d, d].map(|x| (i, Pole(p.0 + c64::new(0.0, x))))
                })
                .filter(|(_, p)| p.0.im > band_w.0 && p.0.im < band_w.1)
                .collect();
            let cands: Vec<Pole> = partners.iter().map(|(_, p)| *p).collect();
            let (c_now, c_with) =
                crate::prof::time(3, || lsfd::screen_extra_poles(r, &cands, band, chans));
            let dof = self.dof(n + 1);
            let best = c_with
                .iter()
                .enumerate()
                .map(|(k, c)| (k, (c_now - c) / test_variance(*c, dof).0))
                .filter(|(_, g)| *g > threshold)
                .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)));
            let Some((k, _)) = best else { return };
            let (i, partner) = partners[k];
            let mut trial = r.poles.clone();
            trial.push(partner);
            let r2 = crate::prof::time(2, || lsfd::refine(&trial, band, chans, res));
            let added = *r2.poles.last().unwrap();
            let (s2, exact) = test_variance(r2.cost.1, dof);
            let gain = (r.cost.1 - r2.cost.1) / s2;
            let separate = r2.poles[..n]
                .iter()
                .all(|p| p.distance_in_bandwidths(&added) > search.inseparable_bandwidths);
            let physical = added.damping() > 0.0
                && added.damping() < max_damping
                && added.omega_n() >= band_w.0
                && added.omega_n() <= band_w.1;
            if !(physical && separate && !r2.singular && gain > threshold) {
                return;
            }
            warn_multiplicity(
                warnings,
                multiplicity,
                Multiplicity::SplitPair,
                format!(
                    "excitation '{name}': pole at {:.4} Hz split into {:.4} and {:.4} Hz by the forward model-order test ({}): a close pair",
                    r.poles[i].frequency_hz(),
                    r2.poles[i].frequency_hz(),
                    added.frequency_hz(),
                    in_sigma2(|| format!("cost −{gain:.1}σ²"), "cost lowered", exact)
                ),
            );
            confidence.push(confidence[i]);
            mode_warnings.push(vec![format!(
                "split from the pole at {:.4} Hz by the forward model-order test (close pair)",
                r.poles[i].frequency_hz()
            )]);
            *r = r2;
            tried += 1;
        }
    }
}

/// Fits one excitation. With [`PoleMode::PerSetup`] the poles come from all
/// excitations of its set-up (recomputed here; [`fit_campaign`] shares them).
pub fn fit_excitation(
    geometry: &Geometry,
    frf: &FrfSet,
    excitation: usize,
    opts: &FitOptions,
) -> Result<ExcitationFit, ModalError> {
    opts.validate()?;
    check_shapes(geometry, frf)?;
    if excitation >= frf.n_excitations {
        return Err(ModalError::NoSuchExcitation {
            index: excitation,
            n: frf.n_excitations,
        });
    }
    if opts.method == Method::Plscf {
        let setup = &geometry.excitations[excitation].setup;
        let members: Vec<usize> = (0..geometry.excitations.len())
            .filter(|&e| &geometry.excitations[e].setup == setup)
            .collect();
        let at = members.iter().position(|&e| e == excitation).unwrap();
        return Ok(crate::poly::fit_setup(geometry, frf, &members, opts)?.swap_remove(at));
    }
    let shared = match opts.poles {
        PoleMode::PerExcitation => None,
        PoleMode::PerSetup => {
            let setup = &geometry.excitations[excitation].setup;
            Some(setup_poles(geometry, frf, setup, opts)?)
        }
    };
    fit_one(geometry, frf, excitation, opts, shared.as_ref())
}

fn setup_poles(
    geometry: &Geometry,
    frf: &FrfSet,
    setup: &str,
    opts: &FitOptions,
) -> Result<PoleSet, ModalError> {
    let members: Vec<usize> = (0..geometry.excitations.len())
        .filter(|&e| geometry.excitations[e].setup == setup)
        .collect();
    let name = format!("set-up {setup}");
    let mut all: Option<BandData> = None;
    let mut chans = Vec::new();
    for &e in &members {
        let ename = &geometry.excitations[e].id;
        let b = BandData::extract(frf, e, opts.band_hz, ename)?;
        let (live, _) = live_channels(&b, geometry, ename);
        chans.extend(live.iter().map(|&c| b.channels[c].clone()));
        all.get_or_insert(b);
    }
    let band = all.ok_or_else(|| ModalError::BadInput {
        excitation: name.clone(),
        reason: "no excitation belongs to this set-up".into(),
    })?;
    let band = band.with_line_factors(opts.coherence_weighting.as_deref(), &members);
    if chans.is_empty() {
        return Err(ModalError::BadInput {
            excitation: name,
            reason: "every channel is zero".into(),
        });
    }
    estimate_poles(&band, &chans, opts, &name)
}

fn fit_one(
    geometry: &Geometry,
    frf: &FrfSet,
    e: usize,
    opts: &FitOptions,
    shared: Option<&PoleSet>,
) -> Result<ExcitationFit, ModalError> {
    let ex = &geometry.excitations[e];
    let name = ex.id.as_str();
    let band = BandData::extract(frf, e, opts.band_hz, name)?
        .with_line_factors(opts.coherence_weighting.as_deref(), &[e]);
    let (live, mut warnings) = live_channels(&band, geometry, name);
    if live.is_empty() {
        return Err(ModalError::BadInput {
            excitation: name.into(),
            reason: "every channel is identically zero in the band".into(),
        });
    }
    // The live channels (borrowed when every channel is live, the usual case).
    let live_data: std::borrow::Cow<[Vec<c64>]> = if live.len() == band.channels.len() {
        std::borrow::Cow::Borrowed(&band.channels)
    } else {
        std::borrow::Cow::Owned(live.iter().map(|&c| band.channels[c].clone()).collect())
    };
    let own;
    let ps = match shared {
        Some(p) => p,
        None => {
            own = estimate_poles(&band, &live_data, opts, name)?;
            &own
        }
    };
    warnings.extend(ps.warnings.iter().cloned());
    let mut multiplicity = ps.multiplicity.clone();
    let no = band.channels.len();
    let nm = ps.poles.len();

    // Modal constants, their std, per-mode extra info.
    let mut a_all: Vec<Vec<c64>> = vec![vec![c64::new(0.0, 0.0); no]; nm];
    let mut a_std: Vec<Vec<f64>> = vec![vec![0.0; no]; nm];
    let mut poles = ps.poles.clone();
    let mut fstd: Vec<(f64, f64)> = ps.std.clone();
    let mut mode_warn = ps.mode_warnings.clone();
    let synth: Vec<Vec<c64>>;
    match opts.method {
        Method::Circle => {
            let cf = circle::fit(&band, &ps.poles, opts.circle_min_separation);
            for (m, mode) in cf.modes.iter().enumerate() {
                poles[m] = mode.pole;
                fstd[m] = mode.std;
                a_all[m] = mode.modal_constants.clone();
                a_std[m] = mode.modal_constant_std.clone();
                mode_warn[m].extend(mode.warnings.iter().cloned());
            }
            warnings.extend(
                cf.warnings
                    .iter()
                    .map(|w| format!("excitation '{name}': {w}")),
            );
            synth = cf.synthesised;
        }
        Method::Lscf | Method::Lsce | Method::Plscf => {
            let res = Residuals::for_band(opts.residual_terms, &band);
            let rf = crate::prof::time(6, || {
                lsfd::fit_residues(&ps.poles, &band, &band.channels, res)
            });
            if rf.basis_conditioning < 1e-8 {
                warn_multiplicity(
                    &mut warnings,
                    &mut multiplicity,
                    Multiplicity::SingularResidueBasis,
                    format!(
                        "excitation '{name}': the residue basis is nearly singular (conditioning {:.1e}); two poles are not separable with these data",
                        rf.basis_conditioning
                    ),
                );
            }
            for m in 0..nm {
                let p = &ps.poles[m];
                for o in 0..no {
                    a_all[m][o] = p.modal_constant(rf.residues[m][o]);
                    a_std[m][o] = 2.0 * p.omega_d() * rf.residue_std[m][o];
                }
            }
            synth = rf.synthesised;
        }
    }

    let parts = ModeParts {
        poles,
        std: fstd,
        confidence: ps.confidence.clone(),
        mode_warnings: mode_warn,
        modal_constants: a_all,
        modal_constant_std: a_std,
        synthesised: synth,
        warnings,
        multiplicity,
        diagram: ps.diagram.clone(),
    };
    Ok(assemble(ex, &band, parts, opts, opts.method.record_name()))
}

/// What one excitation's records are made of, whichever estimator produced them.
pub(crate) struct ModeParts {
    /// Poles, ascending frequency.
    pub poles: Vec<Pole>,
    /// Standard deviations of (f Hz, ζ) per pole.
    pub std: Vec<(f64, f64)>,
    pub confidence: Vec<f64>,
    pub mode_warnings: Vec<Vec<String>>,
    /// Modal constants `A` (1/kg) per mode and channel, and their standard errors.
    pub modal_constants: Vec<Vec<c64>>,
    pub modal_constant_std: Vec<Vec<f64>>,
    /// Fitted FRFs `[channel][line]` in the measured quantity.
    pub synthesised: Vec<Vec<c64>>,
    pub warnings: Vec<String>,
    /// The multiplicity warnings among `warnings`, in order.
    pub multiplicity: Vec<MultiplicityWarning>,
    pub diagram: StabilisationDiagram,
}

/// The records of one excitation: fit error per channel, each mode's peak Norm
/// Indicator relative to the strongest (weak flags), and the plot data.
pub(crate) fn assemble(
    ex: &rbprops_core::Excitation,
    band: &BandData,
    parts: ModeParts,
    opts: &FitOptions,
    method: rbprops_core::records::FitMethod,
) -> ExcitationFit {
    let name = ex.id.as_str();
    let no = band.channels.len();
    let nm = parts.poles.len();
    let k = band.quantity.order();
    let fit_error: Vec<f64> = (0..no)
        .map(|o| {
            let h = &band.channels[o];
            let (meas, err) = (
                linalg::cdot(h, h),
                linalg::cdist_sqr(h, &parts.synthesised[o]),
            );
            if meas > 0.0 {
                err / meas
            } else {
                0.0
            }
        })
        .collect();

    // Peak Norm Indicator of each mode alone in the measured quantity.
    let ni: Vec<f64> = (0..nm)
        .map(|m| {
            let w = parts.poles[m].omega_n();
            let na = parts.modal_constants[m]
                .iter()
                .map(|z| z.norm_sqr())
                .sum::<f64>()
                .sqrt();
            na * w.powi(k) / (2.0 * parts.poles[m].damping().max(1e-12) * w * w)
        })
        .collect();
    let ni_max = ni.iter().cloned().fold(0.0, f64::max);
    let mut modes = Vec::with_capacity(nm);
    for m in 0..nm {
        let mut mw = parts.mode_warnings[m].clone();
        let rel_db = if ni_max > 0.0 && ni[m] > 0.0 {
            20.0 * (ni[m] / ni_max).log10()
        } else {
            f64::NEG_INFINITY
        };
        let na = parts.modal_constants[m]
            .iter()
            .map(|z| z.norm_sqr())
            .sum::<f64>()
            .sqrt();
        let ns = parts.modal_constant_std[m]
            .iter()
            .map(|s| s * s)
            .sum::<f64>()
            .sqrt();
        let mut weak = false;
        if rel_db < -opts.weak_below_db {
            weak = true;
            mw.push(format!(
                "barely excited: peak NI {rel_db:.1} dB below the excitation's strongest mode"
            ));
        }
        if ns > na / 3.0 {
            weak = true;
            mw.push(format!(
                "residue vector uncertain: ‖σ_A‖ = {ns:.3e} vs ‖A‖ = {na:.3e}"
            ));
        }
        modes.push(ModeEstimate {
            excitation: name.into(),
            setup: ex.setup.clone(),
            mode: m + 1,
            frequency_hz: parts.poles[m].frequency_hz(),
            frequency_std_hz: parts.std[m].0,
            damping_ratio: parts.poles[m].damping(),
            damping_std: parts.std[m].1,
            residues: parts.modal_constants[m].clone(),
            residue_std: parts.modal_constant_std[m].clone(),
            confidence: parts.confidence[m].clamp(0.0, 1.0),
            mpc: mpc(&parts.modal_constants[m]),
            weak,
            warnings: mw,
        });
    }
    let record = ExcitationFitRecord {
        excitation: name.into(),
        setup: ex.setup.clone(),
        method,
        model_order: nm,
        band_hz: band.band_hz(),
        n_lines: band.n_lines(),
        fit_error,
        warnings: parts.warnings,
    };
    ExcitationFit {
        record,
        modes,
        diagnostics: ExcitationDiagnostics {
            excitation: name.into(),
            stabilisation: parts.diagram,
            quantity: band.quantity,
            frequency_hz: band.frequency_hz.clone(),
            // Dropped here unless asked for: freed now, its pages serve the next
            // excitation instead of fresh ones (−140 page faults per excitation).
            synthesised: if opts.keep_synthesised {
                parts.synthesised
            } else {
                Vec::new()
            },
            poles_rad_s: parts.poles.iter().map(|p| p.0).collect(),
        },
        multiplicity: parts.multiplicity,
    }
}

/// Every excitation fitted with its own (or its set-up's shared) poles, in parallel.
fn single_reference_fits(
    geometry: &Geometry,
    frf: &FrfSet,
    opts: &FitOptions,
    shared: &[(String, Result<PoleSet, ModalError>)],
) -> Vec<Result<ExcitationFit, ModalError>> {
    (0..frf.n_excitations)
        .into_par_iter()
        .map(|e| {
            let setup = &geometry.excitations[e].setup;
            match shared.iter().find(|(s, _)| s == setup) {
                None => fit_one(geometry, frf, e, opts, None),
                Some((_, Ok(ps))) => fit_one(geometry, frf, e, opts, Some(ps)),
                Some((_, Err(err))) => Err(err.clone()),
            }
        })
        .collect()
}

/// The automatic choice of [`FitOptions::auto_poly_reference`], by evidence (see
/// [`crate::evidence`]): every set-up of two or more excitations whose per-excitation
/// fits show a repeated or near-repeated root, disagree on the number of modes near one
/// frequency, or fit one excitation far worse than the others is also fitted with
/// [`Method::Plscf`]; its records replace the per-excitation ones when it loses no mode
/// and explains every excitation as well. Returns what was decided per set-up.
fn choose_by_evidence(
    geometry: &Geometry,
    frf: &FrfSet,
    setups: &[String],
    opts: &FitOptions,
    results: &mut [Result<ExcitationFit, ModalError>],
) -> Vec<crate::evidence::SetupChoice> {
    let todo: Vec<(Vec<usize>, crate::evidence::Evidence)> = setups
        .iter()
        .filter_map(|s| {
            let members: Vec<usize> = (0..geometry.excitations.len())
                .filter(|&e| &geometry.excitations[e].setup == s)
                .collect();
            if members.len() < 2 {
                return None;
            }
            let fits: Vec<&ExcitationFit> = members
                .iter()
                .filter_map(|&e| results[e].as_ref().ok())
                .collect();
            crate::evidence::evidence(&fits).map(|why| (members, why))
        })
        .collect();
    if todo.is_empty() {
        return Vec::new();
    }
    let popts = FitOptions {
        method: Method::Plscf,
        ..opts.clone()
    };
    let refits: Vec<Result<Vec<ExcitationFit>, ModalError>> = todo
        .par_iter()
        .map(|(m, _)| crate::poly::fit_setup(geometry, frf, m, &popts))
        .collect();
    let mut choices = Vec::new();
    for ((members, evidence), refit) in todo.into_iter().zip(refits) {
        let setup = geometry.excitations[members[0]].setup.clone();
        let excitations: Vec<String> = members
            .iter()
            .map(|&e| geometry.excitations[e].id.clone())
            .collect();
        let comparison = match refit {
            Err(err) => Err(err.to_string()),
            Ok(fits) => {
                // Compared only when every per-excitation fit succeeded (a failed one has
                // nothing to lose); then the poly-reference fit is kept.
                let single: Vec<&ExcitationFit> = members
                    .iter()
                    .filter_map(|&e| results[e].as_ref().ok())
                    .collect();
                let c = if single.len() == members.len() {
                    crate::evidence::compare(&single, &fits)
                } else {
                    crate::evidence::Comparison {
                        poly_lost_hz: Vec::new(),
                        single_lacks: Vec::new(),
                        poly_worse: Vec::new(),
                        error_ratio: (f64::NAN, f64::NAN),
                    }
                };
                if c.keep_poly() {
                    // Said once, in the set-up's `fit_choice` diagnostic.
                    for (&e, fit) in members.iter().zip(fits) {
                        results[e] = Ok(fit);
                    }
                }
                Ok(c)
            }
        };
        choices.push(crate::evidence::SetupChoice {
            setup,
            excitations,
            evidence,
            comparison,
            single_method: opts.method.name(),
        });
    }
    choices
}

/// Every set-up fitted by the poly-reference method (set-ups in parallel); the results
/// in excitation order.
fn poly_reference_fits(
    geometry: &Geometry,
    frf: &FrfSet,
    setups: &[String],
    opts: &FitOptions,
) -> Vec<Result<ExcitationFit, ModalError>> {
    let members: Vec<Vec<usize>> = setups
        .iter()
        .map(|s| {
            (0..geometry.excitations.len())
                .filter(|&e| &geometry.excitations[e].setup == s)
                .collect()
        })
        .collect();
    let fits: Vec<Result<Vec<ExcitationFit>, ModalError>> = members
        .par_iter()
        .map(|m| crate::poly::fit_setup(geometry, frf, m, opts))
        .collect();
    let mut out: Vec<Option<Result<ExcitationFit, ModalError>>> =
        (0..frf.n_excitations).map(|_| None).collect();
    for (m, f) in members.iter().zip(fits) {
        match f {
            Ok(v) => {
                for (&e, fit) in m.iter().zip(v) {
                    out[e] = Some(Ok(fit));
                }
            }
            Err(err) => {
                for &e in m {
                    out[e] = Some(Err(err.clone()));
                }
            }
        }
    }
    out.into_iter()
        .map(|r| r.expect("every excitation belongs to one set-up"))
        .collect()
}

/// Fits every excitation in parallel (rayon). A failing excitation becomes a record
/// with `model_order = 0` and the reason in its warnings; the others still complete.
/// Errors only for invalid options or a geometry that does not match the FRF set.
pub fn fit_campaign(
    geometry: &Geometry,
    frf: &FrfSet,
    opts: &FitOptions,
) -> Result<ModalFitOutput, ModalError> {
    opts.validate()?;
    check_shapes(geometry, frf)?;
    let setups: Vec<String> = {
        let mut s: Vec<String> = geometry
            .excitations
            .iter()
            .map(|e| e.setup.clone())
            .collect();
        s.sort();
        s.dedup();
        s
    };
    let shared: Vec<(String, Result<PoleSet, ModalError>)> = match opts.poles {
        _ if opts.method == Method::Plscf => Vec::new(),
        PoleMode::PerExcitation => Vec::new(),
        PoleMode::PerSetup => setups
            .par_iter()
            .map(|s| (s.clone(), setup_poles(geometry, frf, s, opts)))
            .collect(),
    };
    let mut choices = Vec::new();
    let results: Vec<Result<ExcitationFit, ModalError>> = if opts.method == Method::Plscf {
        poly_reference_fits(geometry, frf, &setups, opts)
    } else {
        let mut r = single_reference_fits(geometry, frf, opts, &shared);
        if opts.auto_poly_reference
            && opts.poles == PoleMode::PerExcitation
            && matches!(opts.method, Method::Lscf | Method::Lsce)
        {
            choices = choose_by_evidence(geometry, frf, &setups, opts, &mut r);
        }
        r
    };
    let diagnostics_typed =
        crate::evidence::campaign_diagnostics(geometry, frf, &results, &choices, &setups, opts);
    let mut record = ModalFitRecord {
        residue_convention: RESIDUE_CONVENTION.into(),
        excitations: Vec::new(),
        modes: Vec::new(),
        window_correction: None,
        diagnostics: diagnostics_typed,
    };
    let mut diagnostics = Vec::new();
    for (e, r) in results.into_iter().enumerate() {
        let ex = &geometry.excitations[e];
        match r {
            Ok(fit) => {
                record.excitations.push(fit.record);
                record.modes.extend(fit.modes);
                diagnostics.push(fit.diagnostics);
            }
            Err(err) => {
                record.excitations.push(ExcitationFitRecord {
                    excitation: ex.id.clone(),
                    setup: ex.setup.clone(),
                    method: opts.method.record_name(),
                    model_order: 0,
                    band_hz: opts.band_hz.map(|(a, b)| [a, b]).unwrap_or([
                        frf.frequency_hz.first().copied().unwrap_or(0.0),
                        frf.frequency_hz.last().copied().unwrap_or(0.0),
                    ]),
                    n_lines: 0,
                    fit_error: Vec::new(),
                    warnings: vec![format!("fit failed: {err}")],
                });
                diagnostics.push(ExcitationDiagnostics {
                    excitation: ex.id.clone(),
                    stabilisation: StabilisationDiagram::default(),
                    quantity: frf.quantity,
                    frequency_hz: Vec::new(),
                    synthesised: Vec::new(),
                    poles_rad_s: Vec::new(),
                });
            }
        }
    }
    Ok(ModalFitOutput {
        record,
        diagnostics,
    })
}

#[cfg(test)]
mod statistic_tests {
    use super::*;

    #[test]
    fn rounding_level_residual_is_floored_and_said_so() {
        // Noisy data: σ̂² = cost/dof exactly, printed as a multiple.
        assert_eq!(test_variance(2e-6, 100.0), (2e-8, false));
        let noisy = || format!("cost −{:.1}σ²", 416.25);
        assert_eq!(in_sigma2(noisy, "cost lowered", false), "cost −416.2σ²");
        // Exact data (zero, rounding-level, or a non-finite cost): floored and flagged.
        for cost in [0.0, 1e-28, f64::NAN] {
            assert_eq!(test_variance(cost, 100.0), (ROUNDING_VARIANCE, true));
        }
        let s = in_sigma2(|| format!("cost −{:.1}σ²", 1.8e28), "cost lowered", true);
        assert!(s.starts_with("cost lowered (") && s.contains("rounding level"));
        assert!(!s.contains("18000"), "{s}");
        // Float32-quantised data (relative residual ~6e-8) stay far above the floor.
        assert!(!test_variance((6e-8f64).powi(2) * 100.0, 100.0).1);
    }
}

#[cfg(test)]
mod multiplicity_tests {
    use super::*;
    use rbprops_core::Quantity;
    use rbprops_testkit::synthetic as testdata;

    /// The rule the switch used before the warnings were typed: a phrase in the text.
    fn by_text(w: &str) -> bool {
        w.contains("treat them as one repeated root")
            || w.contains("by the forward model-order test")
            || w.contains("residue basis is nearly singular")
            || w.contains("not all identifiable")
    }

    /// Test-case campaigns with the second mode moved next to the first: every
    /// multiplicity warning is typed (the typed list is exactly the warnings the text
    /// rule picks, in order) and the switch's decision and reason are those of the text
    /// rule. At least one fit must report a multiplicity, or the test proves nothing.
    #[test]
    fn typed_multiplicity_decides_as_the_text_did() {
        let mut typed = 0;
        for (apart, noise) in [(5e-4, 0.0), (3e-3, 0.0), (3e-3, 0.01), (2e-2, 0.01)] {
            let mut case = testdata::test_case(3.0, 1024, Quantity::Accelerance);
            case.modes[1].frequency_hz = case.modes[0].frequency_hz * (1.0 + apart);
            case.frf = testdata::synthesise(
                &case.geometry,
                &case.modes,
                3.0,
                1024,
                Quantity::Accelerance,
            );
            let case = if noise > 0.0 {
                case.with_noise(noise, 7)
            } else {
                case
            };
            let opts = FitOptions::default();
            let results = single_reference_fits(&case.geometry, &case.frf, &opts, &[]);
            let fits: Vec<&ExcitationFit> =
                results.iter().filter_map(|r| r.as_ref().ok()).collect();
            for f in &fits {
                let texts: Vec<&String> = f.multiplicity.iter().map(|m| &m.text).collect();
                let picked: Vec<&String> =
                    f.record.warnings.iter().filter(|w| by_text(w)).collect();
                assert_eq!(texts, picked, "{apart} apart, noise {noise}");
                typed += texts.len();
            }
            // A reported multiplicity is evidence for the poly-reference fit.
            if fits.iter().any(|f| {
                f.multiplicity
                    .iter()
                    .any(|m| m.kind != Multiplicity::SplitPair)
            }) {
                assert!(
                    crate::evidence::evidence(&fits).is_some(),
                    "{apart} apart, noise {noise}"
                );
            }
        }
        assert!(typed > 0, "no fit reported a multiplicity");
    }

    /// The switch no longer reads texts: an excitation whose id contains a phrase of the
    /// old rule does not trigger it, and a typed warning does whatever its text.
    #[test]
    fn the_switch_reads_kinds_not_texts() {
        let case = testdata::test_case(3.0, 512, Quantity::Accelerance);
        let results = single_reference_fits(&case.geometry, &case.frf, &FitOptions::default(), &[]);
        let mut fits: Vec<ExcitationFit> = results.into_iter().map(|r| r.unwrap()).collect();
        // Fits that agree on the mode count and report no multiplicity: no switch.
        let n = fits.iter().map(|f| f.modes.len()).min().unwrap();
        for f in &mut fits {
            f.modes.truncate(n);
            f.diagnostics.poles_rad_s.truncate(n);
            f.multiplicity.clear();
            f.record.warnings.retain(|w| !by_text(w));
        }
        let reason = |fits: &[ExcitationFit]| {
            crate::evidence::evidence(&fits.iter().collect::<Vec<_>>()).map(|e| e.reason)
        };
        assert_eq!(reason(&fits), None);
        fits[0].record.warnings.push(
            "excitation 'not all identifiable': pole refinement did not converge in 40 iterations"
                .into(),
        );
        assert_eq!(reason(&fits), None);
        fits[1].multiplicity.push(MultiplicityWarning {
            kind: Multiplicity::RepeatedRoot,
            text: "excitation 'F1': modes 1 and 2 cannot be separated".into(),
        });
        let id = fits[1].record.excitation.clone();
        assert_eq!(
            reason(&fits),
            Some(format!(
                "the per-excitation fits of {id} report two poles they cannot separate"
            ))
        );
    }
}
