//! Orchestration: poles → selection → refinement → residues → records, per excitation,
//! in parallel over excitations.

mod order_tests;
mod poles;
mod records;
mod sweeps;

use poles::estimate_poles;
pub(crate) use records::{assemble, fit_error, ModeParts};

use crate::band::BandData;
use crate::circle;
use crate::lsfd::{self, Residuals};
use crate::options::{FitOptions, Method, PoleMode};
use crate::pole::Pole;
use crate::stabilisation::StabilisationDiagram;
use crate::ModalError;
use rayon::prelude::*;
use rbprops_core::records::{ExcitationFitRecord, ModalFitRecord, ModeEstimate};
use rbprops_core::{c64, FrfSource, Geometry, Quantity};
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

fn check_shapes(geometry: &Geometry, frf: &dyn FrfSource) -> Result<(), ModalError> {
    if frf.n_excitations() != geometry.excitations.len() {
        return Err(ModalError::Shape(format!(
            "{} excitations in the FRF set, {} in the geometry",
            frf.n_excitations(),
            geometry.excitations.len()
        )));
    }
    if frf.n_channels() != geometry.channels.len() {
        return Err(ModalError::Shape(format!(
            "{} channels in the FRF set, {} in the geometry",
            frf.n_channels(),
            geometry.channels.len()
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

/// Fits one excitation. With [`PoleMode::PerSetup`] the poles come from all
/// excitations of its set-up (recomputed here; [`fit_campaign`] shares them).
pub fn fit_excitation(
    geometry: &Geometry,
    frf: &dyn FrfSource,
    excitation: usize,
    opts: &FitOptions,
) -> Result<ExcitationFit, ModalError> {
    opts.validate()?;
    check_shapes(geometry, frf)?;
    if excitation >= frf.n_excitations() {
        return Err(ModalError::NoSuchExcitation {
            index: excitation,
            n: frf.n_excitations(),
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
    frf: &dyn FrfSource,
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
        let b = BandData::extract_from(frf, e, opts.band_hz, ename)?;
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
    frf: &dyn FrfSource,
    e: usize,
    opts: &FitOptions,
    shared: Option<&PoleSet>,
) -> Result<ExcitationFit, ModalError> {
    let ex = &geometry.excitations[e];
    let name = ex.id.as_str();
    let band = BandData::extract_from(frf, e, opts.band_hz, name)?
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
        fit_error: None,
        warnings,
        multiplicity,
        diagram: ps.diagram.clone(),
    };
    Ok(assemble(ex, &band, parts, opts, opts.method.record_name()))
}

/// Every excitation fitted with its own (or its set-up's shared) poles, in parallel
/// unless an excitation is large (`rbprops_core::excitations_in_parallel`); each fit
/// depends only on its excitation, so the results are the same either way.
fn single_reference_fits(
    geometry: &Geometry,
    frf: &dyn FrfSource,
    opts: &FitOptions,
    shared: &[(String, Result<PoleSet, ModalError>)],
) -> Vec<Result<ExcitationFit, ModalError>> {
    let fit = |e: usize| {
        let setup = &geometry.excitations[e].setup;
        match shared.iter().find(|(s, _)| s == setup) {
            None => fit_one(geometry, frf, e, opts, None),
            Some((_, Ok(ps))) => fit_one(geometry, frf, e, opts, Some(ps)),
            Some((_, Err(err))) => Err(err.clone()),
        }
    };
    if rbprops_core::excitations_in_parallel(frf) {
        (0..frf.n_excitations()).into_par_iter().map(fit).collect()
    } else {
        (0..frf.n_excitations()).map(fit).collect()
    }
}

/// The automatic choice of [`FitOptions::auto_poly_reference`], by evidence (see
/// [`crate::evidence`]): every set-up of two or more excitations whose per-excitation
/// fits show a repeated or near-repeated root, disagree on the number of modes near one
/// frequency, or fit one excitation far worse than the others is also fitted with
/// [`Method::Plscf`]; its records replace the per-excitation ones when it loses no mode
/// and explains every excitation as well. Returns what was decided per set-up.
fn choose_by_evidence(
    geometry: &Geometry,
    frf: &dyn FrfSource,
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
    frf: &dyn FrfSource,
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
        (0..frf.n_excitations()).map(|_| None).collect();
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
    frf: &dyn FrfSource,
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
    // A source that could not give an excitation stops the run (its file changed).
    if let Some(Err(e)) = results
        .iter()
        .find(|r| matches!(r, Err(ModalError::Source(_))))
    {
        return Err(e.clone());
    }
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
                        frf.frequency_hz().first().copied().unwrap_or(0.0),
                        frf.frequency_hz().last().copied().unwrap_or(0.0),
                    ]),
                    n_lines: 0,
                    fit_error: Vec::new(),
                    warnings: vec![format!("fit failed: {err}")],
                });
                diagnostics.push(ExcitationDiagnostics {
                    excitation: ex.id.clone(),
                    stabilisation: StabilisationDiagram::default(),
                    quantity: frf.quantity(),
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
