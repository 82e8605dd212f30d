//! Poly-reference identification of one suspension set-up: pLSCF stabilisation sweep
//! over every excitation at once ([`crate::plscf`]), automatic pole selection
//! ([`crate::stabilisation`], participation vectors as the shapes), joint refinement of
//! the poles and participation vectors on every line ([`crate::plsfd_refine`]: the
//! sweep's z-domain poles carry a bias of up to ~1e-3 that the s-domain model removes),
//! poly-reference LSFD ([`crate::plsfd`]), then the same per-excitation records as the
//! single-reference path, with shared poles and residues `ψ_r l_re`.

use crate::band::BandData;
use crate::fit::{assemble, ExcitationFit, ModeParts};
use crate::lsfd::Residuals;
use crate::options::FitOptions;
use crate::plscf::{self, PolyData};
use crate::plsfd;
use crate::plsfd_refine;
use crate::pole::Pole;
use crate::reciprocity;
use crate::setup_bands::{Bands, SetupBands};
use crate::stabilisation::{self, Selection};
use crate::ModalError;
use rbprops_core::{c64, FrfSource, Geometry};

/// The method name written into the records.
pub const METHOD: rbprops_core::records::FitMethod = rbprops_core::records::FitMethod::Plscf;

/// Lines of the stabilisation sweep (decimated to about this many).
const SWEEP_LINES: usize = 1024;

/// Highest matrix order of the sweep for `ni` references: about `max_order` poles
/// (as the single-reference diagram), and at least 8 orders for the selection.
pub(crate) fn max_matrix_order(max_order: usize, ni: usize) -> usize {
    max_order.div_ceil(ni.max(1)).max(8)
}

/// The poles of one set-up with their participation vectors and diagram.
#[derive(Debug, Clone)]
pub(crate) struct PolyPoles {
    pub poles: Vec<Pole>,
    /// `parts[r][e]`, unit norm.
    pub parts: Vec<Vec<c64>>,
    pub std: Vec<(f64, f64)>,
    pub confidence: Vec<f64>,
    pub selection: Selection,
    pub warnings: Vec<String>,
}

/// pLSCF sweep and selection on `bands` (one per excitation). When every stable mode
/// sits low in the band, the sweep is repeated on the lines up to twice the highest one
/// (polynomial z-domain models need far higher orders for modes crowded near z = 1).
pub(crate) fn estimate(
    bands: &dyn Bands,
    opts: &FitOptions,
    name: &str,
) -> Result<PolyPoles, ModalError> {
    let ni = bands.len();
    let axis = bands.band(0)?.frequency_hz.clone();
    let n_max = max_matrix_order(opts.max_order, ni);
    let mut warnings = Vec::new();
    let mut top_hz = *axis.last().unwrap();
    let mut pass = 0;
    let mut sel = loop {
        let sel = sweep_and_select(bands, top_hz, n_max, opts, name)?;
        let f_top = sel
            .modes
            .iter()
            .map(|m| m.pole.frequency_hz())
            .reduce(f64::max);
        let target = 2.0 * f_top.unwrap_or(0.25 * top_hz);
        let lines = axis.partition_point(|&f| f <= target);
        if pass < 2 && target < 0.6 * top_hz && lines >= 4 * n_max.max(8) {
            warnings.push(format!(
                "{name}: poles estimated on {:.4}–{target:.4} Hz, where the modes are (shapes on the whole band)",
                axis[0]
            ));
            top_hz = target;
            pass += 1;
            continue;
        }
        break sel;
    };
    // Modes low in a wide band crowd near z = 1, where the z-domain polynomial needs far
    // higher orders to resolve them (a pendulum pair at 5 % of the band merges, a weak
    // yaw mode next to it is missed). Below a quarter of the band the poles are taken
    // from a sweep on that lower part alone (where those modes are spread out), and the
    // whole-band sweep keeps the modes above it. Not when the mode count is forced. Tried
    // even when the whole-band sweep found no mode down there: on noise-free data of the
    // reference generator's cord recordings (modes at 0.5–0.75 Hz and 4–5.9 Hz on a
    // 0–10 Hz axis) it found only the upper three, and the lower band holds the other three.
    if opts.n_modes.is_none() {
        let low_top = 0.25 * top_hz;
        let cut = 0.8 * low_top;
        let lines = axis.partition_point(|&f| f <= low_top);
        if lines >= 4 * n_max.max(8) {
            if let Ok(low) = sweep_and_select(bands, low_top, n_max, opts, name) {
                let low_modes: Vec<_> = low
                    .modes
                    .into_iter()
                    .filter(|m| m.pole.frequency_hz() < cut)
                    .collect();
                let before = sel
                    .modes
                    .iter()
                    .filter(|m| m.pole.frequency_hz() < cut)
                    .count();
                if low_modes.len() > before {
                    warnings.push(format!(
                        "{name}: poles below {cut:.4} Hz from a sweep on {:.4}–{low_top:.4} Hz ({} modes there instead of {before})",
                        axis[0],
                        low_modes.len()
                    ));
                    sel.modes.retain(|m| m.pole.frequency_hz() >= cut);
                    sel.modes.extend(low_modes);
                    sel.modes
                        .sort_by(|a, b| a.pole.frequency_hz().total_cmp(&b.pole.frequency_hz()));
                }
            }
        }
    }
    warnings.extend(sel.warnings.iter().map(|w| format!("{name}: {w}")));
    if sel.modes.is_empty() {
        return Err(ModalError::NoModes {
            excitation: name.into(),
            reason: format!(
                "{} poles in the poly-reference diagram up to order {}, none stable in frequency, damping and participation",
                sel.diagram.poles.len(),
                sel.diagram.max_order
            ),
        });
    }
    Ok(PolyPoles {
        poles: sel.modes.iter().map(|m| m.pole).collect(),
        parts: sel.modes.iter().map(|m| m.shape.clone()).collect(),
        std: sel.modes.iter().map(|m| m.spread).collect(),
        confidence: sel.modes.iter().map(|m| m.presence).collect(),
        selection: sel,
        warnings,
    })
}

/// One pLSCF sweep of `bands` cut at `top_hz` (decimated to [`SWEEP_LINES`]) and its
/// automatic pole selection, each selected pole with its own participation vector.
fn sweep_and_select(
    bands: &dyn Bands,
    top_hz: f64,
    n_max: usize,
    opts: &FitOptions,
    name: &str,
) -> Result<Selection, ModalError> {
    // The lines up to `top_hz`, decimated, as indices into the bands: on many
    // references the sweep's data are their principal references on those lines, made
    // without a decimated copy of every band (issue 41).
    let (keep, omega) = {
        let first = bands.band(0)?;
        let below = first.frequency_hz.partition_point(|&f| f <= top_hz);
        let keep = BandData::decimation_indices(below, SWEEP_LINES);
        let omega: Vec<f64> = keep.iter().map(|&k| first.omega[k]).collect();
        (keep, omega)
    };
    let nl = omega.len();
    let n_here = n_max.min(nl.saturating_sub(2) / 2);
    if n_here < 1 || nl < 4 {
        return Err(ModalError::BadInput {
            excitation: name.into(),
            reason: format!("{nl} lines in the band: too few for a poly-reference fit"),
        });
    }
    let orders = match plscf::PrincipalReferences::of_bands(bands, &keep)? {
        Some(p) => p.sweep(&omega, n_here),
        None => {
            // Every reference swept (at most 16, or data of more directions): held.
            let dec: Vec<BandData> = (0..bands.len())
                .map(|e| Ok(bands.band(e)?.lines(&keep)))
                .collect::<Result<_, ModalError>>()?;
            let no = dec[0].channels.len();
            let data = PolyData {
                omega: &omega,
                h: (0..no)
                    .map(|o| dec.iter().map(|b| b.channels[o].as_slice()).collect())
                    .collect(),
            };
            plscf::sweep(&data, n_here)
        }
    };
    let band_w = (omega[0], *omega.last().unwrap());
    let shared = plscf::stabilisation_shapes(&orders);
    let mut sel = stabilisation::select(&shared, band_w, &opts.tolerances, opts.n_modes);
    // Back to each selected pole's own participation vector (the representative is
    // a pole of the sweep, bitwise).
    for m in sel.modes.iter_mut().chain(sel.candidates.iter_mut()) {
        if let Some(l) = orders.iter().find_map(|o| {
            o.poles
                .iter()
                .position(|p| p.0 == m.pole.0)
                .map(|i| o.shapes[i].clone())
        }) {
            m.shape = l;
        }
    }
    Ok(sel)
}

/// Poles closer than this many half-power half-bandwidths are one repeated root.
/// With 1 % noise the two poles the sweep finds for an exactly repeated root lie 0.03–0.05
/// half-bandwidths apart (measured on the reference generator's repeated pendulum and
/// rocking pairs, ζ = 2 %), so 0.02 split them into two arbitrary modes (J 25 % off);
/// a pair 0.3 % apart at ζ = 2 % is 0.15 half-bandwidths apart, 2.5 times this, and
/// stays two roots.
pub(crate) const REPEATED_BANDWIDTHS: f64 = 0.06;

/// Groups (ascending indices, two or more) of poles that are one repeated root: chains
/// of neighbours closer than [`REPEATED_BANDWIDTHS`].
fn repeated_groups(poles: &[Pole]) -> Vec<Vec<usize>> {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for i in 0..poles.len() {
        let joined = groups.iter_mut().find(|g| {
            g.iter()
                .any(|&j| poles[j].distance_in_bandwidths(&poles[i]) < REPEATED_BANDWIDTHS)
        });
        match joined {
            Some(g) => g.push(i),
            None => groups.push(vec![i]),
        }
    }
    groups.retain(|g| g.len() >= 2);
    groups
}

/// Root index of each of `n` modes: the modes of one of `groups` share one.
fn root_indices(n: usize, groups: &[Vec<usize>]) -> Vec<usize> {
    let mut roots = vec![usize::MAX; n];
    let mut next = 0;
    for i in 0..n {
        if roots[i] != usize::MAX {
            continue;
        }
        match groups.iter().find(|g| g.contains(&i)) {
            Some(g) => g.iter().for_each(|&j| roots[j] = next),
            None => roots[i] = next,
        }
        next += 1;
    }
    roots
}

/// Joint refinement of the sweep's poles and participation vectors on every line of
/// the set-up ([`plsfd_refine::refine_set_up`]); the sweep's values are kept when it fails to
/// lower the cost or moves a pole by more than a half-bandwidth (a mode lost to a
/// neighbour), with a warning.
fn refine_poles(
    pp: &mut PolyPoles,
    groups: &[Vec<usize>],
    bands: &dyn Bands,
    res: Residuals,
    name: &str,
    warnings: &mut Vec<String>,
) -> Result<(), ModalError> {
    let roots = root_indices(pp.poles.len(), groups);
    let rf = crate::prof::time(2, || {
        plsfd_refine::refine_set_up(&pp.poles, &pp.parts, &roots, bands, res)
    })?;
    let moved = pp
        .poles
        .iter()
        .zip(&rf.poles)
        .any(|(a, b)| a.distance_in_bandwidths(b) > MAX_REFINEMENT_BANDWIDTHS);
    if !(rf.cost.1 <= rf.cost.0) || moved {
        warnings.push(format!(
            "{name}: the poly-reference pole refinement was not used (cost {:.3e} → {:.3e}, a pole moved more than {MAX_REFINEMENT_BANDWIDTHS} half-bandwidths: {moved}); poles from the sweep",
            rf.cost.0, rf.cost.1
        ));
        return Ok(());
    }
    if rf.references < bands.len() {
        warnings.push(format!(
            "{name}: poles refined on {} principal references of the {} excitations (more than {} excitations)",
            rf.references,
            bands.len(),
            plsfd_refine::MAX_REFINEMENT_REFERENCES
        ));
    }
    if !rf.converged {
        warnings.push(format!(
            "{name}: the poly-reference pole refinement stopped at its limit of {} iterations before converging; its poles lower the cost ({:.3e} → {:.3e}) and are used, but may be short of the minimum",
            rf.iterations, rf.cost.0, rf.cost.1
        ));
    }
    pp.poles = rf.poles;
    pp.parts = rf.parts;
    Ok(())
}

/// A refined pole further than this many half-bandwidths from the sweep's has been
/// captured by another mode or by noise: the refinement is then not used.
const MAX_REFINEMENT_BANDWIDTHS: f64 = 1.0;

/// Fits the excitations `members` of one set-up together; one [`ExcitationFit`] per
/// member, in the order given.
///
/// Stages: the pLSCF sweep and selection ([`estimate`]), the joint refinement
/// ([`refine_poles`]), the poly-reference LSFD ([`plsfd::fit_shapes`]), the reciprocal
/// basis of each repeated root ([`make_repeated_roots_reciprocal`]), then one record
/// per excitation ([`excitation_records`]).
pub(crate) fn fit_setup(
    geometry: &Geometry,
    frf: &dyn FrfSource,
    members: &[usize],
    opts: &FitOptions,
) -> Result<Vec<ExcitationFit>, ModalError> {
    fit_setup_holding(geometry, frf, members, opts, crate::setup_bands::HELD_BYTES)
}

/// [`fit_setup`] with the set-up's bands held whole up to `held_bytes`
/// ([`SetupBands`]).
fn fit_setup_holding(
    geometry: &Geometry,
    frf: &dyn FrfSource,
    members: &[usize],
    opts: &FitOptions,
    held_bytes: usize,
) -> Result<Vec<ExcitationFit>, ModalError> {
    let setup = &geometry.excitations[members[0]].setup;
    let name = format!("set-up {setup}");
    let bands = SetupBands::new(geometry, frf, members, opts.band_hz, held_bytes)?;
    let mut warnings = zero_channel_warnings(geometry, &bands, &name)?;
    let mut pp = crate::prof::time(0, || estimate(&bands, opts, &name))?;
    warnings.extend(pp.warnings.iter().cloned());
    let res = Residuals::for_band(opts.residual_terms, bands.first());
    // Repeated roots: one pole per group from here on.
    let groups = repeated_groups(&pp.poles);
    refine_poles(&mut pp, &groups, &bands, res, &name, &mut warnings)?;
    let mut sf = crate::prof::time(6, || plsfd::fit_shapes(&pp.poles, &pp.parts, &bands, res))?;
    if !groups.is_empty() {
        let fit = SetupFit {
            geometry,
            members,
            name: &name,
        };
        warnings.extend(make_repeated_roots_reciprocal(&fit, &groups, &sf, &mut pp));
        sf = crate::prof::time(6, || plsfd::fit_shapes(&pp.poles, &pp.parts, &bands, res))?;
    }
    if sf.basis_conditioning < 1e-8 {
        warnings.push(format!(
            "{name}: the poly-reference shape basis is nearly singular (conditioning {:.1e}): two poles with the same participation cannot be separated",
            sf.basis_conditioning
        ));
    }
    let mode_warnings = close_pair_notes(&pp.poles);
    let fit = SetupFit {
        geometry,
        members,
        name: &name,
    };
    excitation_records(&fit, &bands, (&pp, &sf), (mode_warnings, warnings), opts)
}

/// The set-up being fitted: its geometry, its excitations and its name in messages.
struct SetupFit<'a> {
    geometry: &'a Geometry,
    members: &'a [usize],
    name: &'a str,
}

/// A warning per channel identically zero in the band for every excitation (its
/// residues are 0); an error when every channel is.
fn zero_channel_warnings(
    geometry: &Geometry,
    bands: &dyn Bands,
    name: &str,
) -> Result<Vec<String>, ModalError> {
    let no = bands.band(0)?.channels.len();
    let mut zero = vec![true; no];
    for e in 0..bands.len() {
        let b = bands.band(e)?;
        for (z, h) in zero.iter_mut().zip(&b.channels) {
            *z = *z && h.iter().all(|v| v.norm_sqr() == 0.0);
        }
    }
    let warnings: Vec<String> = (0..no)
        .filter(|&o| zero[o])
        .map(|o| {
            format!(
                "{name}: channel '{}' is identically zero in the band for every excitation; its residues are 0",
                geometry.channels[o].id
            )
        })
        .collect();
    if warnings.len() == no {
        return Err(ModalError::BadInput {
            excitation: name.into(),
            reason: "every channel is identically zero in the band".into(),
        });
    }
    Ok(warnings)
}

/// Repeated roots: the split of a group's residue matrix `Σ ψ_r l_rᵀ` into modes is
/// arbitrary; each group gets the reciprocal split (see [`reciprocity`]: participation
/// = shape at the forces) and the mean of its poles, for the shapes to be refitted
/// with. Returns one warning per group (its modes, or why they stay arbitrary).
fn make_repeated_roots_reciprocal(
    fit: &SetupFit,
    groups: &[Vec<usize>],
    sf: &plsfd::ShapeFit,
    pp: &mut PolyPoles,
) -> Vec<String> {
    let name = fit.name;
    let mut warnings = Vec::new();
    for g in groups {
        let psi: Vec<Vec<c64>> = g.iter().map(|&r| sf.shapes[r].clone()).collect();
        let parts: Vec<Vec<c64>> = g.iter().map(|&r| pp.parts[r].clone()).collect();
        let freqs: Vec<String> = g
            .iter()
            .map(|&r| format!("{:.5}", pp.poles[r].frequency_hz()))
            .collect();
        match reciprocity::reciprocal_participation(fit.geometry, fit.members, &psi, &parts) {
            Ok(l) => {
                let mean = g.iter().map(|&r| pp.poles[r].0).sum::<c64>() / g.len() as f64;
                for (&r, l) in g.iter().zip(l) {
                    pp.parts[r] = l;
                    pp.poles[r] = Pole(mean);
                }
                warnings.push(format!(
                    "{name}: poles at {} Hz are one root of multiplicity {} (within {REPEATED_BANDWIDTHS} half-bandwidths); its modes are the reciprocal basis of the residue matrix (participation = shape at the forces)",
                    freqs.join(", "),
                    g.len()
                ));
            }
            Err(why) => warnings.push(format!(
                "{name}: poles at {} Hz are one repeated root, but its modes could not be made reciprocal ({why}): their split is arbitrary, use their sum",
                freqs.join(", ")
            )),
        }
    }
    warnings
}

/// Per mode, a note for each other mode closer than two half-bandwidths (separated by
/// their participation vectors, which a single-reference fit cannot do).
fn close_pair_notes(poles: &[Pole]) -> Vec<Vec<String>> {
    let nm = poles.len();
    let mut mode_warnings = vec![Vec::new(); nm];
    for i in 0..nm {
        for j in i + 1..nm {
            let d = poles[i].distance_in_bandwidths(&poles[j]);
            if d < 2.0 {
                let msg = |other: usize| {
                    format!(
                        "close to mode {other} ({d:.2} half-bandwidths): separated by its participation vector (poly-reference)"
                    )
                };
                mode_warnings[i].push(msg(j + 1));
                mode_warnings[j].push(msg(i + 1));
            }
        }
    }
    mode_warnings
}

/// One [`ExcitationFit`] per member: shared poles, its residues `ψ_r l_re` as modal
/// constants `A = 2iω_d R` (standard errors scaled alike) and its fitted FRFs.
fn excitation_records(
    fit: &SetupFit,
    bands: &dyn Bands,
    (pp, sf): (&PolyPoles, &plsfd::ShapeFit),
    (mode_warnings, warnings): (Vec<Vec<String>>, Vec<String>),
    opts: &FitOptions,
) -> Result<Vec<ExcitationFit>, ModalError> {
    let nm = pp.poles.len();
    let diagram = pp.selection.diagram.clone();
    // Every excitation's fitted FRFs and fit errors first, then the records: made in
    // one loop, each record's small vectors took pieces of the space freed by the
    // previous excitation's fitted FRFs, and the heap grew by about a band per
    // excitation (issue 41: 43 MB at 192 excitations × 1,601 lines). The band's axis
    // is the set-up's: the records take it from the first.
    let mut fitted = Vec::with_capacity(fit.members.len());
    for ei in 0..fit.members.len() {
        let band = bands.band(ei)?;
        let synthesised = sf.synthesised(ei, &band);
        let error = crate::fit::fit_error(&band, &synthesised);
        fitted.push((error, opts.keep_synthesised.then_some(synthesised)));
    }
    let axis = bands.band(0)?;
    let mut out = Vec::with_capacity(fit.members.len());
    for ((ei, &e), (error, synthesised)) in fit.members.iter().enumerate().zip(fitted) {
        let ex = &fit.geometry.excitations[e];
        let a: Vec<Vec<c64>> = (0..nm)
            .map(|r| {
                sf.residues[ei][r]
                    .iter()
                    .map(|&x| pp.poles[r].modal_constant(x))
                    .collect()
            })
            .collect();
        let a_std: Vec<Vec<f64>> = (0..nm)
            .map(|r| {
                sf.residue_std[ei][r]
                    .iter()
                    .map(|s| 2.0 * pp.poles[r].omega_d() * s)
                    .collect()
            })
            .collect();
        let parts = ModeParts {
            poles: pp.poles.clone(),
            std: pp.std.clone(),
            confidence: pp.confidence.clone(),
            mode_warnings: mode_warnings.clone(),
            modal_constants: a,
            modal_constant_std: a_std,
            synthesised: synthesised.unwrap_or_default(),
            fit_error: Some(error),
            warnings: warnings.clone(),
            // The poly-reference fit is what a multiplicity switches to: none to report.
            multiplicity: Vec::new(),
            diagram: diagram.clone(),
        };
        out.push(assemble(ex, &axis, parts, opts, METHOD));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rbprops_testkit::synthetic;

    /// The whole poly-reference fit of a set-up of 20 excitations (1 % noise, so that
    /// the sweep and the refinement run on principal references) with its bands held
    /// whole, and read again from the source on every pass with one held at a time:
    /// the same records, modes and fit errors, bit for bit.
    #[test]
    fn a_set_up_read_again_fits_as_held() {
        let body = synthetic::test_case_body();
        let geometry = synthetic::test_case_geometry(&body, &synthetic::fibonacci_forces(20));
        let modes = synthetic::close_modes(5.0, 16).modes;
        let frf = synthetic::synthesise(
            &geometry,
            &modes,
            5.0,
            600,
            rbprops_core::Quantity::Accelerance,
        );
        let noisy = synthetic::Synthetic {
            geometry,
            modes,
            frf,
        }
        .with_noise(0.01, 77);
        let members: Vec<usize> = (0..20).collect();
        let opts = FitOptions {
            method: crate::options::Method::Plscf,
            ..Default::default()
        };
        let fit =
            |held| fit_setup_holding(&noisy.geometry, &noisy.frf, &members, &opts, held).unwrap();
        let (held, again) = (fit(usize::MAX), fit(0));
        assert!(
            !held.is_empty() && held[0].modes.len() >= 6,
            "{} modes",
            held[0].modes.len()
        );
        assert!(
            held[0]
                .record
                .warnings
                .iter()
                .any(|w| w.contains("principal references")),
            "refined on principal references: {:?}",
            held[0].record.warnings
        );
        for (a, b) in held.iter().zip(&again) {
            // Debug prints each f64 in its shortest round-trip form: equal text, equal bits.
            assert_eq!(format!("{:?}", a.record), format!("{:?}", b.record));
            assert_eq!(format!("{:?}", a.modes), format!("{:?}", b.modes));
        }
    }
}
