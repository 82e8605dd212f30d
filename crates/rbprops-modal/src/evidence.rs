//! The automatic choice between the per-excitation (single-reference) fits of a set-up
//! and its poly-reference fit, by evidence, and the typed diagnostics of a campaign fit.
//!
//! **When to try the poly-reference fit.** A set-up of two or more excitations is refitted
//! with [`crate::Method::Plscf`] when its per-excitation fits show one of:
//! - a pole with multiplicity above one (a split pair, a singular information matrix or
//!   residue basis, two poles closer than the separable distance: [`crate::fit::Multiplicity`]);
//! - a disagreement on the number of modes near one frequency: one fit has `n ≥ 2` poles
//!   within [`NEAR_BANDWIDTHS`] half-bandwidths of a pole where another fit has fewer but
//!   at least one (a pair merged in one excitation) — a mode missing from an excitation
//!   altogether (weakly excited) is not evidence;
//! - two poles of two excitations within [`NEAR_BANDWIDTHS`] of each other that differ by
//!   more than [`DISTINCT_SIGMAS`] combined standard errors (and 1e-6 relative), neither
//!   of them a mode its excitation barely drives: each excitation drives a different
//!   member of a near-repeated pair;
//! - an excitation whose fit error (median over its channels) is more than
//!   [`ERROR_RATIO`] times the set-up's lowest and above [`ERROR_FLOOR`]: its model misses
//!   something the others do not.
//!
//! **Which fit to keep.** The poly-reference fit is kept when it loses no mode (for every
//! pole of every per-excitation fit, the poly-reference fit has at least as many poles
//! within one half-bandwidth as that fit has there; modes the excitation barely excites
//! are not counted) and explains every excitation's FRFs as well (fit error at most
//! [`ERROR_RATIO_KEEP`] times the per-excitation one, plus [`ERROR_FLOOR`]). Otherwise the
//! per-excitation fits stay. Either way one [`DiagnosticKind::FitChoice`] says which and why.

use crate::fit::ExcitationFit;
use crate::options::PoleSearchParams;
use crate::pole::Pole;
use rbprops_core::records::{Diagnostic, DiagnosticKind, DiagnosticSubject, Severity};

/// Poles within this many half-bandwidths are "near one frequency" for the evidence.
pub const NEAR_BANDWIDTHS: f64 = 2.0;
/// Two excitations' poles near one frequency are distinct modes when they differ by more
/// than this many combined standard errors. Not 5: a per-excitation fit's frequency
/// standard error (linearised, from its own residual) understates the scatter of a mode
/// its excitation drives only moderately; one mode seen by two excitations of a
/// synthetic recording read 6.9 of them apart (`exp_window` test, 1 % noise), while the
/// near-repeated pairs the rule is for (0.3 % apart) read tens to hundreds.
pub const DISTINCT_SIGMAS: f64 = 10.0;
/// An excitation's fit error is an outlier above this multiple of its set-up's lowest.
pub const ERROR_RATIO: f64 = 100.0;
/// Fit errors (normalised ‖H − Ĥ‖²/‖H‖²) below this are rounding, whatever their ratio:
/// float64 data fit to 1e-24–1e-30, float32-quantised data to ~4e-15, measured data to
/// the noise (1e-4 at 1 % noise).
pub const ERROR_FLOOR: f64 = 1e-10;
/// The poly-reference fit explains an excitation as well when its fit error is at most
/// this multiple of the per-excitation fit's (it has fewer parameters: one pole set for
/// all excitations, so its residual is slightly larger at the same noise; a lost or
/// merged mode raises it by orders of magnitude).
pub const ERROR_RATIO_KEEP: f64 = 2.0;
/// Window (half-bandwidths) of the "loses no mode" comparison.
pub const SAME_MODE_BANDWIDTHS: f64 = 1.0;

/// Why a set-up's per-excitation fits call for a poly-reference fit.
#[derive(Debug, Clone, PartialEq)]
pub struct Evidence {
    /// The reason in words.
    pub reason: String,
    /// Near which frequencies (Hz).
    pub frequencies_hz: Vec<f64>,
    /// The excitations it was seen in.
    pub excitations: Vec<String>,
}

fn poles(f: &ExcitationFit) -> Vec<Pole> {
    f.diagnostics.poles_rad_s.iter().map(|&p| Pole(p)).collect()
}

/// Median of the channels' fit errors.
pub(crate) fn median_fit_error(f: &ExcitationFit) -> f64 {
    let mut v: Vec<f64> = f
        .record
        .fit_error
        .iter()
        .copied()
        .filter(|x| x.is_finite())
        .collect();
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn near(ps: &[Pole], p: &Pole, bw: f64) -> usize {
    ps.iter()
        .filter(|q| q.distance_in_bandwidths(p) < bw)
        .count()
}

/// Close pairs of fit `a` that fit `b` merged: for each pair (`i`, `j`) of `a` closer than
/// [`NEAR_BANDWIDTHS`], `b` has exactly one pole near either, and that pole is none of the
/// two (it lies more than a quarter of their distance from the nearer): a blend. A `b`
/// pole on one member of the pair is that mode, the other one merely not driven by `b`.
fn merged_pairs(pa: &[Pole], pb: &[Pole]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    for i in 0..pa.len() {
        for j in i + 1..pa.len() {
            let d = pa[i].distance_in_bandwidths(&pa[j]);
            if d >= NEAR_BANDWIDTHS {
                continue;
            }
            let qs: Vec<&Pole> = pb
                .iter()
                .filter(|q| {
                    q.distance_in_bandwidths(&pa[i]) < NEAR_BANDWIDTHS
                        || q.distance_in_bandwidths(&pa[j]) < NEAR_BANDWIDTHS
                })
                .collect();
            if let [q] = qs[..] {
                let nearer = q
                    .distance_in_bandwidths(&pa[i])
                    .min(q.distance_in_bandwidths(&pa[j]));
                if nearer > 0.25 * d {
                    out.push((i, j));
                }
            }
        }
    }
    out
}

/// The evidence for a poly-reference fit among the per-excitation fits of one set-up
/// (module documentation), or `None`.
pub fn evidence(fits: &[&ExcitationFit]) -> Option<Evidence> {
    if fits.len() < 2 {
        return None;
    }
    // 1. A pole with multiplicity above one. A split by the forward model-order test
    // counts only when the split pair ends near one frequency: the test also "splits" a
    // weakly excited neighbour several bandwidths away (the demo's 0.95/1.13 Hz pair, 10
    // half-bandwidths apart), which is no repeated root.
    let close_pair = |f: &ExcitationFit| {
        let ps = poles(f);
        (0..ps.len()).any(|i| {
            (i + 1..ps.len()).any(|j| ps[i].distance_in_bandwidths(&ps[j]) < NEAR_BANDWIDTHS)
        })
    };
    let mult: Vec<&&ExcitationFit> = fits
        .iter()
        .filter(|f| {
            f.multiplicity
                .iter()
                .any(|m| m.kind != crate::fit::Multiplicity::SplitPair || close_pair(f))
        })
        .collect();
    if !mult.is_empty() {
        return Some(Evidence {
            reason: format!(
                "the per-excitation fits of {} report two poles they cannot separate",
                names(mult.iter().map(|f| &f.record.excitation))
            ),
            frequencies_hz: Vec::new(),
            excitations: mult.iter().map(|f| f.record.excitation.clone()).collect(),
        });
    }
    let all: Vec<Vec<Pole>> = fits.iter().map(|f| poles(f)).collect();
    // 2. Disagreement on the number of modes near one frequency: a pair merged.
    for (a, pa) in all.iter().enumerate() {
        for (b, pb) in all.iter().enumerate() {
            if let Some(&(i, j)) = merged_pairs(pa, pb).first() {
                let (fi, fj) = (pa[i].frequency_hz(), pa[j].frequency_hz());
                return Some(Evidence {
                    reason: format!(
                        "the fit of {} has two modes at {fi:.4} and {fj:.4} Hz where that of {} has one between them: a close pair merged",
                        fits[a].record.excitation, fits[b].record.excitation
                    ),
                    frequencies_hz: vec![fi, fj],
                    excitations: vec![
                        fits[a].record.excitation.clone(),
                        fits[b].record.excitation.clone(),
                    ],
                });
            }
        }
    }
    // 3. Two excitations see distinct poles near one frequency.
    for a in 0..fits.len() {
        for b in a + 1..fits.len() {
            for (i, p) in all[a].iter().enumerate() {
                for (j, q) in all[b].iter().enumerate() {
                    if p.distance_in_bandwidths(q) >= NEAR_BANDWIDTHS {
                        continue;
                    }
                    // A mode an excitation barely drives has a pole its data hardly
                    // determine (its standard error understates it): not evidence.
                    if fits[a].modes.get(i).is_none_or(|m| m.weak)
                        || fits[b].modes.get(j).is_none_or(|m| m.weak)
                    {
                        continue;
                    }
                    let (fp, fq) = (p.frequency_hz(), q.frequency_hz());
                    let sp = fits[a].modes[i].frequency_std_hz;
                    let sq = fits[b].modes[j].frequency_std_hz;
                    let d = (fp - fq).abs();
                    if d > DISTINCT_SIGMAS * (sp * sp + sq * sq).sqrt() && d > 1e-6 * fp.max(fq) {
                        return Some(Evidence {
                            reason: format!(
                                "{} and {} see different poles near one frequency ({fp:.5} and {fq:.5} Hz, {:.1} combined standard errors apart): a near-repeated pair",
                                fits[a].record.excitation,
                                fits[b].record.excitation,
                                d / (sp * sp + sq * sq).sqrt().max(f64::MIN_POSITIVE)
                            ),
                            frequencies_hz: vec![fp.min(fq), fp.max(fq)],
                            excitations: vec![
                                fits[a].record.excitation.clone(),
                                fits[b].record.excitation.clone(),
                            ],
                        });
                    }
                }
            }
        }
    }
    // 4. An excitation fits far worse than the others.
    let errs: Vec<f64> = fits.iter().map(|f| median_fit_error(f)).collect();
    let best = errs.iter().copied().fold(f64::INFINITY, f64::min);
    let bad: Vec<usize> = (0..fits.len())
        .filter(|&e| errs[e] > ERROR_FLOOR && errs[e] > ERROR_RATIO * best)
        .collect();
    if !bad.is_empty() {
        return Some(Evidence {
            reason: format!(
                "the fit error of {} is {} times the set-up's lowest ({:.1e}): its model misses something",
                names(bad.iter().map(|&e| &fits[e].record.excitation)),
                format_ratio(bad.iter().map(|&e| errs[e]).fold(0.0, f64::max) / best),
                best
            ),
            frequencies_hz: Vec::new(),
            excitations: bad.iter().map(|&e| fits[e].record.excitation.clone()).collect(),
        });
    }
    None
}

fn format_ratio(r: f64) -> String {
    if r.is_finite() {
        format!("{r:.1e}")
    } else {
        "far more than".into()
    }
}

fn names<'a>(it: impl Iterator<Item = &'a String>) -> String {
    it.map(|s| s.as_str()).collect::<Vec<_>>().join(", ")
}

/// The comparison of a set-up's poly-reference fit with its per-excitation fits.
#[derive(Debug, Clone, PartialEq)]
pub struct Comparison {
    /// Frequencies (Hz) of modes a per-excitation fit found (and drives) that the
    /// poly-reference fit lost.
    pub poly_lost_hz: Vec<f64>,
    /// (excitation, frequency Hz) of poly-reference modes a per-excitation fit lacks.
    pub single_lacks: Vec<(String, f64)>,
    /// Excitations the poly-reference fit explains worse, with (poly, single) fit errors.
    pub poly_worse: Vec<(String, f64, f64)>,
    /// Largest and smallest ratio poly / single of the excitations' fit errors.
    pub error_ratio: (f64, f64),
}

impl Comparison {
    /// Whether the poly-reference fit is the one to keep.
    pub fn keep_poly(&self) -> bool {
        self.poly_lost_hz.is_empty() && self.poly_worse.is_empty()
    }
}

/// Compares the poly-reference fits `poly` of a set-up with its per-excitation fits
/// `single` (same members, same order).
pub fn compare(single: &[&ExcitationFit], poly: &[ExcitationFit]) -> Comparison {
    let pp = poles(&poly[0]);
    let mut poly_lost_hz: Vec<f64> = Vec::new();
    let mut single_lacks = Vec::new();
    let mut poly_worse = Vec::new();
    let (mut rmax, mut rmin) = (0.0f64, f64::INFINITY);
    for (s, p) in single.iter().zip(poly) {
        let sp = poles(s);
        for (i, q) in sp.iter().enumerate() {
            if s.modes[i].weak {
                continue;
            }
            let ns = sp
                .iter()
                .zip(&s.modes)
                .filter(|(x, m)| !m.weak && x.distance_in_bandwidths(q) < SAME_MODE_BANDWIDTHS)
                .count();
            if near(&pp, q, SAME_MODE_BANDWIDTHS) < ns
                && !poly_lost_hz
                    .iter()
                    .any(|f| (f / q.frequency_hz() - 1.0).abs() < 1e-3)
            {
                poly_lost_hz.push(q.frequency_hz());
            }
        }
        for q in &pp {
            if near(&sp, q, SAME_MODE_BANDWIDTHS) < near(&pp, q, SAME_MODE_BANDWIDTHS) {
                single_lacks.push((s.record.excitation.clone(), q.frequency_hz()));
            }
        }
        let (es, ep) = (median_fit_error(s), median_fit_error(p));
        if ep > ERROR_RATIO_KEEP * es + ERROR_FLOOR {
            poly_worse.push((s.record.excitation.clone(), ep, es));
        }
        if es > 0.0 {
            rmax = rmax.max(ep / es);
            rmin = rmin.min(ep / es);
        }
    }
    Comparison {
        poly_lost_hz,
        single_lacks,
        poly_worse,
        error_ratio: (rmax, rmin),
    }
}

/// What was decided for one set-up.
#[derive(Debug, Clone)]
pub(crate) struct SetupChoice {
    pub setup: String,
    pub excitations: Vec<String>,
    pub evidence: Evidence,
    /// `None`: the poly-reference fit failed (its error).
    pub comparison: Result<Comparison, String>,
    /// The name of the single-reference method.
    pub single_method: &'static str,
}

impl SetupChoice {
    /// The one [`DiagnosticKind::FitChoice`] diagnostic of this set-up (and a
    /// [`DiagnosticKind::DroppedMode`] warning when the kept fit lacks a mode the other found).
    pub fn diagnostics(&self) -> Vec<Diagnostic> {
        let subject = DiagnosticSubject {
            setup: Some(self.setup.clone()),
            excitations: self.excitations.clone(),
            ..Default::default()
        };
        let m = self.single_method;
        let mut out = Vec::new();
        let message = match &self.comparison {
            Err(e) => format!(
                "per-excitation ({m}) fits kept: {}, but the poly-reference fit failed ({e})",
                self.evidence.reason
            ),
            Ok(c) if c.keep_poly() => {
                let mut t = format!(
                    "poly-reference fit (plscf) kept instead of the per-excitation ({m}) fits: {}; it loses no mode and explains every excitation as well (fit error {} the per-excitation one's)",
                    self.evidence.reason,
                    ratio_range(c.error_ratio)
                );
                if !c.single_lacks.is_empty() {
                    t.push_str(&format!(
                        ", and has every mode in every excitation (the per-excitation fits lacked {} excitation–mode pair{})",
                        c.single_lacks.len(),
                        if c.single_lacks.len() == 1 { "" } else { "s" }
                    ));
                }
                t
            }
            Ok(c) => {
                let mut why = Vec::new();
                if !c.poly_lost_hz.is_empty() {
                    why.push(format!(
                        "the poly-reference fit loses the mode{} at {} Hz",
                        if c.poly_lost_hz.len() == 1 { "" } else { "s" },
                        hz_list(&c.poly_lost_hz)
                    ));
                }
                if !c.poly_worse.is_empty() {
                    let (e, p, s) = c
                        .poly_worse
                        .iter()
                        .max_by(|a, b| (a.1 / a.2).total_cmp(&(b.1 / b.2)))
                        .unwrap();
                    why.push(format!(
                        "it explains {} worse (fit error {p:.2e} against {s:.2e} for {e})",
                        names(c.poly_worse.iter().map(|w| &w.0))
                    ));
                }
                if !c.single_lacks.is_empty() {
                    let mut hz: Vec<f64> = c.single_lacks.iter().map(|x| x.1).collect();
                    hz.sort_by(f64::total_cmp);
                    hz.dedup_by(|a, b| (*a / *b - 1.0).abs() < 1e-9);
                    out.push(Diagnostic {
                        stage: "modal-fit".into(),
                        kind: DiagnosticKind::DroppedMode,
                        severity: Severity::Warning,
                        subject: DiagnosticSubject {
                            excitations: dedup(c.single_lacks.iter().map(|x| x.0.clone())),
                            frequencies_hz: hz.clone(),
                            ..subject.clone()
                        },
                        message: format!(
                            "the poly-reference fit finds modes at {} Hz that these per-excitation fits lack, but it was not kept (it loses another mode or fits worse)",
                            hz_list(&hz)
                        ),
                        advice: "compare both fits (--method lscf and --method plscf) and check the band and the mode count (--modes)".into(),
                    });
                }
                format!(
                    "per-excitation ({m}) fits kept: {}, but {}",
                    self.evidence.reason,
                    why.join("; ")
                )
            }
        };
        out.insert(
            0,
            Diagnostic {
                stage: "modal-fit".into(),
                kind: DiagnosticKind::FitChoice,
                severity: Severity::Note,
                subject,
                message,
                advice: String::new(),
            },
        );
        out
    }
}

fn dedup(it: impl Iterator<Item = String>) -> Vec<String> {
    let mut v: Vec<String> = Vec::new();
    for s in it {
        if !v.contains(&s) {
            v.push(s);
        }
    }
    v
}

fn hz_list(f: &[f64]) -> String {
    f.iter()
        .map(|x| format!("{x:.4}"))
        .collect::<Vec<_>>()
        .join(", ")
}

fn ratio_range((hi, lo): (f64, f64)) -> String {
    if !(hi.is_finite() && lo.is_finite()) || hi == 0.0 {
        "at most that of".into()
    } else if (hi / lo - 1.0).abs() < 0.05 {
        format!("{hi:.2} times")
    } else {
        format!("{lo:.2e} to {hi:.2} times")
    }
}

fn diag(
    kind: DiagnosticKind,
    severity: Severity,
    subject: DiagnosticSubject,
    message: String,
    advice: &str,
) -> Diagnostic {
    Diagnostic {
        stage: "modal-fit".into(),
        kind,
        severity,
        subject,
        message,
        advice: advice.into(),
    }
}

/// A pair of poles near one frequency as one excitation's fit has it.
struct Pair {
    excitation: String,
    f: (f64, f64),
    pole: Pole,
    distance: f64,
    inseparable: bool,
}

/// The typed diagnostics of a campaign fit, one per fact, set-up by set-up (sorted):
/// the fit choice, failed excitations, dead channels, repeated roots and close pairs,
/// merged pairs, fit errors far above the noise, weakly excited modes, and one count of
/// the pole search's adjustments. `fits[e]` is excitation `e`'s kept result.
pub(crate) fn campaign_diagnostics(
    geometry: &rbprops_core::Geometry,
    frf: &dyn rbprops_core::FrfSource,
    fits: &[Result<ExcitationFit, crate::ModalError>],
    choices: &[SetupChoice],
    setups: &[String],
    opts: &crate::FitOptions,
) -> Vec<Diagnostic> {
    let mut out = Vec::new();
    for setup in setups {
        let members: Vec<usize> = (0..geometry.excitations.len())
            .filter(|&e| &geometry.excitations[e].setup == setup)
            .collect();
        if let Some(c) = choices.iter().find(|c| &c.setup == setup) {
            out.extend(c.diagnostics());
        }
        failed_excitations(geometry, fits, &members, setup, &mut out);
        dead_channels(geometry, frf, &members, (setup, opts), &mut out);
        let ok: Vec<&ExcitationFit> = members
            .iter()
            .filter_map(|&e| fits[e].as_ref().ok())
            .collect();
        if ok.is_empty() {
            continue;
        }
        let poly = ok
            .iter()
            .all(|f| f.record.method == rbprops_core::records::FitMethod::Plscf);
        if poly {
            poly_reference_pairs(&ok, &opts.search, setup, &mut out);
        } else {
            single_reference_pairs(&ok, &opts.search, setup, &mut out);
        }
        out.extend(fit_errors_above_noise(&ok, setup));
        out.extend(weak_modes(&ok, setup));
        out.extend(pole_search_notes(&ok, setup));
    }
    out
}

/// The subject "set-up `setup`, these excitations".
fn setup_subject(setup: &str, excitations: Vec<String>) -> DiagnosticSubject {
    DiagnosticSubject {
        setup: Some(setup.into()),
        excitations,
        ..Default::default()
    }
}

/// The ids of the excitations of `ok`, in order.
fn excitation_ids(ok: &[&ExcitationFit]) -> Vec<String> {
    ok.iter().map(|f| f.record.excitation.clone()).collect()
}

/// One [`DiagnosticKind::ExcitationFailed`] per member whose fit failed.
fn failed_excitations(
    geometry: &rbprops_core::Geometry,
    fits: &[Result<ExcitationFit, crate::ModalError>],
    members: &[usize],
    setup: &str,
    out: &mut Vec<Diagnostic>,
) {
    for &e in members {
        if let Err(err) = &fits[e] {
            out.push(diag(
                DiagnosticKind::ExcitationFailed,
                Severity::ChangesAnswer,
                setup_subject(setup, vec![geometry.excitations[e].id.clone()]),
                format!("fit failed: {err}"),
                "check the band (--band) and that the excitation drives the structure",
            ));
        }
    }
}

/// Dead channels: one [`DiagnosticKind::DeadChannel`] per channel identically zero in
/// the band, naming the excitations where it is.
fn dead_channels(
    geometry: &rbprops_core::Geometry,
    frf: &dyn rbprops_core::FrfSource,
    members: &[usize],
    (setup, opts): (&str, &crate::FitOptions),
    out: &mut Vec<Diagnostic>,
) {
    // Each member's FRFs asked for once (a reader gives one excitation at a time); an
    // excitation it cannot give has already stopped the fit.
    let is_dead: Vec<Vec<bool>> = members
        .iter()
        .map(|&e| {
            let Ok(x) = frf.excitation(e) else {
                return vec![false; geometry.channels.len()];
            };
            (0..geometry.channels.len())
                .map(|c| {
                    let h = x.set().frf(x.index(), c);
                    frf.frequency_hz().iter().zip(h).all(|(f, z)| {
                        z.norm_sqr() == 0.0 || opts.band_hz.is_some_and(|(a, b)| *f < a || *f > b)
                    })
                })
                .collect()
        })
        .collect();
    for (c, ch) in geometry.channels.iter().enumerate() {
        let dead: Vec<String> = members
            .iter()
            .zip(&is_dead)
            .filter(|(_, d)| d[c])
            .map(|(&e, _)| geometry.excitations[e].id.clone())
            .collect();
        if !dead.is_empty() {
            out.push(diag(
                DiagnosticKind::DeadChannel,
                Severity::ChangesAnswer,
                DiagnosticSubject {
                    channel: Some(ch.id.clone()),
                    ..setup_subject(setup, dead)
                },
                "identically zero in the band: left out of the pole estimate, its residues are 0"
                    .into(),
                "check the sensor, its cable and the channel map",
            ));
        }
    }
}

/// A poly-reference fit's close pairs (one pole set for the set-up), once each, naming
/// every excitation: a repeated root (closer than [`crate::poly::REPEATED_BANDWIDTHS`]),
/// a near-repeated root (closer than `inseparable_bandwidths`) or a close pair, all
/// notes: the participation vectors separate them.
fn poly_reference_pairs(
    ok: &[&ExcitationFit],
    search: &PoleSearchParams,
    setup: &str,
    out: &mut Vec<Diagnostic>,
) {
    let all_ids = excitation_ids(ok);
    let ps = poles(ok[0]);
    for i in 0..ps.len() {
        for j in i + 1..ps.len() {
            let d = ps[i].distance_in_bandwidths(&ps[j]);
            if d >= search.close_bandwidths {
                continue;
            }
            let subject = DiagnosticSubject {
                modes: vec![i + 1, j + 1],
                frequencies_hz: vec![ps[i].frequency_hz(), ps[j].frequency_hz()],
                ..setup_subject(setup, all_ids.clone())
            };
            if d < crate::poly::REPEATED_BANDWIDTHS {
                out.push(diag(
                    DiagnosticKind::RepeatedRoot,
                    Severity::Note,
                    subject,
                    "one root of multiplicity 2: its modes are the reciprocal basis of the residue matrix (poly-reference fit)".into(),
                    "",
                ));
            } else if d < search.inseparable_bandwidths {
                out.push(diag(
                    DiagnosticKind::RepeatedRoot,
                    Severity::Note,
                    subject,
                    format!("a near-repeated root ({d:.2} half-bandwidths apart: one peak), separated by the poly-reference fit through the participation of every excitation"),
                    "",
                ));
            } else {
                out.push(diag(
                    DiagnosticKind::CloseModes,
                    Severity::Note,
                    subject,
                    format!("{d:.2} half-bandwidths apart, separated by the poly-reference fit"),
                    "",
                ));
            }
        }
    }
}

/// Fit errors far above the noise the set-up fits to: one warning naming the
/// excitations whose median fit error exceeds 0.1, or [`ERROR_RATIO`] × the best
/// excitation's above [`ERROR_FLOOR`].
fn fit_errors_above_noise(ok: &[&ExcitationFit], setup: &str) -> Option<Diagnostic> {
    let all_ids = excitation_ids(ok);
    let errs: Vec<f64> = ok.iter().map(|f| median_fit_error(f)).collect();
    let best = errs.iter().copied().fold(f64::INFINITY, f64::min);
    let bad: Vec<usize> = (0..ok.len())
        .filter(|&k| errs[k] > 0.1 || (errs[k] > ERROR_FLOOR && errs[k] > ERROR_RATIO * best))
        .collect();
    let worst = bad
        .iter()
        .copied()
        .max_by(|&a, &b| errs[a].total_cmp(&errs[b]))?;
    Some(diag(
        DiagnosticKind::FitErrorAboveNoise,
        Severity::Warning,
        setup_subject(setup, bad.iter().map(|&k| all_ids[k].clone()).collect()),
        format!(
            "median fit error up to {:.2e} ({}), against {best:.2e} for the set-up's best-fitted excitation",
            errs[worst], all_ids[worst]
        ),
        "look for a merged or missing mode in these excitations (--plot), an undeclared window (--exp-window) or an elastic mode in the band",
    ))
}

/// Weakly excited modes, once per set-up: their frequencies and the excitations.
fn weak_modes(ok: &[&ExcitationFit], setup: &str) -> Option<Diagnostic> {
    let weak: Vec<(String, f64)> = ok
        .iter()
        .flat_map(|f| {
            f.modes
                .iter()
                .filter(|m| m.weak)
                .map(|m| (m.excitation.clone(), m.frequency_hz))
        })
        .collect();
    if weak.is_empty() {
        return None;
    }
    let mut hz: Vec<f64> = weak.iter().map(|w| w.1).collect();
    hz.sort_by(f64::total_cmp);
    hz.dedup_by(|a, b| (*a / *b - 1.0).abs() < 1e-3);
    Some(diag(
        DiagnosticKind::WeakModes,
        Severity::Note,
        DiagnosticSubject {
            frequencies_hz: hz,
            ..setup_subject(setup, dedup(weak.into_iter().map(|w| w.0)))
        },
        "barely excited in these excitations (peak NI more than 20 dB below the strongest mode, or residues uncertain); other excitations' estimates are preferred".into(),
        "",
    ))
}

/// The pole search's adjustments, counted once (each is listed in the records'
/// warnings).
fn pole_search_notes(ok: &[&ExcitationFit], setup: &str) -> Option<Diagnostic> {
    let n: usize = ok.iter().map(|f| f.record.warnings.len()).sum::<usize>()
        + ok.iter()
            .flat_map(|f| &f.modes)
            .map(|m| m.warnings.len())
            .sum::<usize>();
    (n > 0).then(|| {
        diag(
            DiagnosticKind::PoleSearch,
            Severity::Note,
            setup_subject(setup, excitation_ids(ok)),
            format!("{n} notes of the pole search and the records (model-order tests, sub-bands, close pairs); each is in the excitations' and modes' warnings"),
            "",
        )
    })
}

/// Close pairs of per-excitation fits, grouped across excitations: one
/// [`DiagnosticKind::RepeatedRoot`] warning per pair some fit cannot separate (the
/// per-excitation fits were kept, so its split is arbitrary), one
/// [`DiagnosticKind::CloseModes`] note per resolved pair, and one
/// [`DiagnosticKind::MergedModes`] warning per frequency where a fit has fewer modes than
/// another.
fn single_reference_pairs(
    ok: &[&ExcitationFit],
    search: &PoleSearchParams,
    setup: &str,
    out: &mut Vec<Diagnostic>,
) {
    let pairs = close_pairs(ok, search);
    let groups = group_pairs(&pairs);
    for g in &groups {
        out.push(pair_group_diagnostic(g, setup));
    }
    // Other multiplicity reports (a singular information matrix or residue basis) with no
    // close pair to name.
    if groups.iter().all(|g| !g.iter().any(|p| p.inseparable)) {
        out.extend(unnamed_multiplicity(ok, setup));
    }
    merged_pair_warnings(ok, setup, out);
}

/// Every fit's pairs of poles closer than `close_bandwidths`, each marked inseparable
/// when closer than `inseparable_bandwidths` or than twice their combined frequency
/// standard deviation.
fn close_pairs(ok: &[&ExcitationFit], search: &PoleSearchParams) -> Vec<Pair> {
    let mut pairs: Vec<Pair> = Vec::new();
    for f in ok {
        let ps = poles(f);
        for i in 0..ps.len() {
            for j in i + 1..ps.len() {
                let d = ps[i].distance_in_bandwidths(&ps[j]);
                if d >= search.close_bandwidths {
                    continue;
                }
                let (si, sj) = (f.modes[i].frequency_std_hz, f.modes[j].frequency_std_hz);
                let sep = (ps[j].frequency_hz() - ps[i].frequency_hz()).abs();
                let unc = 2.0 * (si * si + sj * sj).sqrt();
                pairs.push(Pair {
                    excitation: f.record.excitation.clone(),
                    f: (ps[i].frequency_hz(), ps[j].frequency_hz()),
                    pole: ps[i],
                    distance: d,
                    inseparable: d < search.inseparable_bandwidths || (unc > 0.0 && sep < unc),
                });
            }
        }
    }
    pairs
}

/// The pairs grouped by frequency: a pair joins the first group whose first pair lies
/// within [`NEAR_BANDWIDTHS`].
fn group_pairs(pairs: &[Pair]) -> Vec<Vec<&Pair>> {
    let mut groups: Vec<Vec<&Pair>> = Vec::new();
    for p in pairs {
        match groups
            .iter_mut()
            .find(|g| g[0].pole.distance_in_bandwidths(&p.pole) < NEAR_BANDWIDTHS)
        {
            Some(g) => g.push(p),
            None => groups.push(vec![p]),
        }
    }
    groups
}

/// One group's diagnostic: a repeated-root warning when some fit cannot separate the
/// pair, else a close-modes note.
fn pair_group_diagnostic(g: &[&Pair], setup: &str) -> Diagnostic {
    let inseparable = g.iter().any(|p| p.inseparable);
    let ex = dedup(g.iter().map(|p| p.excitation.clone()));
    let lo = g.iter().map(|p| p.f.0).fold(f64::INFINITY, f64::min);
    let hi = g.iter().map(|p| p.f.1).fold(0.0, f64::max);
    let dmin = g.iter().map(|p| p.distance).fold(f64::INFINITY, f64::min);
    let subject = DiagnosticSubject {
        frequencies_hz: vec![lo, hi],
        ..setup_subject(setup, ex)
    };
    if inseparable {
        diag(
            DiagnosticKind::RepeatedRoot,
            Severity::Warning,
            subject,
            format!("two poles {dmin:.2} half-bandwidths apart that the per-excitation fits cannot separate: their split into two modes is arbitrary"),
            "fit the set-up with --method plscf (poly-reference), which separates them by their participation",
        )
    } else {
        diag(
            DiagnosticKind::CloseModes,
            Severity::Note,
            subject,
            format!("{dmin:.2} half-bandwidths apart, resolved by the per-excitation fits"),
            "",
        )
    }
}

/// A warning naming the fits that report a multiplicity other than a split pair (a
/// singular information matrix or residue basis).
fn unnamed_multiplicity(ok: &[&ExcitationFit], setup: &str) -> Option<Diagnostic> {
    let ex: Vec<String> = ok
        .iter()
        .filter(|f| {
            f.multiplicity
                .iter()
                .any(|m| m.kind != crate::fit::Multiplicity::SplitPair)
        })
        .map(|f| f.record.excitation.clone())
        .collect();
    (!ex.is_empty()).then(|| {
        diag(
            DiagnosticKind::RepeatedRoot,
            Severity::Warning,
            setup_subject(setup, ex),
            "two poles are not separable with these data (singular information matrix or residue basis)".into(),
            "fit the set-up with --method plscf (poly-reference)",
        )
    })
}

/// Merged pairs: a fit with one pole between two of another fit's, once per frequency.
fn merged_pair_warnings(ok: &[&ExcitationFit], setup: &str, out: &mut Vec<Diagnostic>) {
    let all: Vec<Vec<Pole>> = ok.iter().map(|f| poles(f)).collect();
    let mut seen: Vec<Pole> = Vec::new();
    for (a, pa) in all.iter().enumerate() {
        for (i, j) in (0..all.len())
            .filter(|&b| b != a)
            .flat_map(|b| merged_pairs(pa, &all[b]))
            .collect::<Vec<_>>()
        {
            if seen
                .iter()
                .any(|s| s.distance_in_bandwidths(&pa[i]) < NEAR_BANDWIDTHS)
            {
                continue;
            }
            seen.push(pa[i]);
            let fewer: Vec<String> = (0..all.len())
                .filter(|&b| b != a && merged_pairs(pa, &all[b]).contains(&(i, j)))
                .map(|b| ok[b].record.excitation.clone())
                .collect();
            let (fi, fj) = (pa[i].frequency_hz(), pa[j].frequency_hz());
            out.push(diag(
                DiagnosticKind::MergedModes,
                Severity::Warning,
                DiagnosticSubject {
                    setup: Some(setup.into()),
                    excitations: fewer,
                    frequencies_hz: vec![fi, fj],
                    ..Default::default()
                },
                format!(
                    "one mode between {fi:.4} and {fj:.4} Hz, where {}'s fit has two: a close pair taken for one mode",
                    ok[a].record.excitation
                ),
                "fit the set-up with --method plscf (poly-reference), or select these modes from another excitation",
            ));
        }
    }
}
