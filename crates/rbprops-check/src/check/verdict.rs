//! The end of a pass: the final model's numbers (gauges centred, covariances, inertia
//! before and after, corrected parameters, accepted effects with standard errors), the
//! improved spec, the localisation maps, the noise-band verdict and the short text.

use super::acceptance::{fit_covariance, Accepted, IMPLAUSIBLE};
use super::gauges::centre_gauges;
use super::problem::{active_dims, Act, Prior, Problem};
use super::selection::{Findings, Model, Selection};
use super::{effect_spec, known_sensor_masses, CheckOptions};
use crate::error::CheckError;
use crate::lm::Fit;
use crate::locate::{bands, residual_map};
use crate::params::{inertia_quantities, theta_to_inertia, ParamKind, INERTIA_NAMES};
use crate::predict::Layout;
use crate::report::{
    diagnostic, AcceptedEffect, AmbiguousFamily, CorrectedParameter, FittedParameter,
    InertiaEstimateReport, RelativeChange, ScreenEntry, Unexplained,
};
use crate::{ModelCheckReport, RecordingNoise};
use nalgebra::DMatrix;
use rbprops_core::c64;
use rbprops_core::records::{Diagnostic, DiagnosticKind, Severity};
use rbprops_sim::effects::gains::GlobalGain;
use rbprops_sim::effects::mass::SensorMass;
use rbprops_sim::effects::Effect;
use rbprops_sim::CampaignSpec;

pub(super) fn inertia_report(
    label: &str,
    theta: &[f64],
    cov: &DMatrix<f64>,
) -> InertiaEstimateReport {
    let body = theta_to_inertia(&theta[..10]);
    let q0 = inertia_quantities(&body);
    // Delta method: g = ∂q/∂θ by central differences.
    let mut g = DMatrix::zeros(10, 10);
    for j in 0..10 {
        let h = 1e-6 * theta[j].abs().max(1e-3);
        let mut tp = theta[..10].to_vec();
        tp[j] += h;
        let mut tm = theta[..10].to_vec();
        tm[j] -= h;
        let (qp, qm) = (
            inertia_quantities(&theta_to_inertia(&tp)),
            inertia_quantities(&theta_to_inertia(&tm)),
        );
        for i in 0..10 {
            g[(i, j)] = (qp[i] - qm[i]) / (2.0 * h);
        }
    }
    let c = cov.view((0, 0), (10, 10)).into_owned();
    let cq = &g * c * g.transpose();
    let j = body.inertia_cm;
    InertiaEstimateReport {
        label: label.into(),
        mass_kg: q0[0],
        com_m: [q0[1], q0[2], q0[3]],
        moments_kg_m2: [q0[4], q0[5], q0[6]],
        products_kg_m2: [q0[7], q0[8], q0[9]],
        inertia_cm_kg_m2: std::array::from_fn(|r| std::array::from_fn(|c| j[(r, c)])),
        standard_errors: std::array::from_fn(|i| cq[(i, i)].max(0.0).sqrt()),
    }
}

pub(super) fn quantities(r: &InertiaEstimateReport) -> [f64; 10] {
    [
        r.mass_kg,
        r.com_m[0],
        r.com_m[1],
        r.com_m[2],
        r.moments_kg_m2[0],
        r.moments_kg_m2[1],
        r.moments_kg_m2[2],
        r.products_kg_m2[0],
        r.products_kg_m2[1],
        r.products_kg_m2[2],
    ]
}

/// Relative changes; CoM and products relative to a size scale (√(J̄/m) and J̄) so a
/// quantity near zero does not produce a meaningless ratio.
pub(super) fn inertia_change(
    before: &InertiaEstimateReport,
    after: &InertiaEstimateReport,
) -> Vec<RelativeChange> {
    let (b, a) = (quantities(before), quantities(after));
    let jbar = (b[4] + b[5] + b[6]) / 3.0;
    let len = (jbar / b[0]).sqrt();
    (0..10)
        .map(|i| {
            let denom = match i {
                1..=3 => len,
                7..=9 => jbar,
                _ => b[i].abs(),
            };
            RelativeChange {
                quantity: INERTIA_NAMES[i].to_string(),
                relative: (a[i] - b[i]) / denom.max(f64::MIN_POSITIVE),
            }
        })
        .collect()
}

pub(super) fn model_modes_band(
    spec: &CampaignSpec,
    layout: &Layout,
    effects: &[Box<dyn Effect>],
) -> (f64, f64) {
    match rbprops_sim::build_models(spec, &layout.spec_geometry, effects) {
        Ok(ms) => {
            // Free directions (0 Hz) are no suspension modes: they bound no band.
            let fs: Vec<f64> = ms
                .iter()
                .flat_map(|m| m.modes.iter().filter(|r| !r.is_free()))
                .map(|r| r.frequency_hz)
                .collect();
            if fs.is_empty() {
                return (
                    layout.frequency_hz[0],
                    layout.frequency_hz[layout.n_lines() - 1],
                );
            }
            (
                fs.iter().cloned().fold(f64::INFINITY, f64::min),
                fs.iter().cloned().fold(0.0, f64::max),
            )
        }
        Err(_) => (
            layout.frequency_hz[0],
            layout.frequency_hz[layout.n_lines() - 1],
        ),
    }
}

/// Smallest upper end of the noise band: χ²/ν within 5 % of 1 counts as the floor even
/// where ν is so large that the statistical band is narrower, since a noise model given
/// as side information (repeats, a data sheet) is not known better than that.
pub const MIN_BAND_UPPER: f64 = 1.05;

/// The band of χ²/ν consistent with noise: the central 99.73 % interval (the ±3 sd of a
/// normal) of χ²/ν with ν degrees of freedom when the noise variance is estimated with
/// relative standard error `se`, i.e. of F(ν, 2/se²) ([`rbprops_core::stats::chi2_nu_band`];
/// χ²_ν/ν when se = 0), with its upper end at least [`MIN_BAND_UPPER`]. Both ends are
/// positive.
pub fn noise_band(nu: f64, se: f64) -> [f64; 2] {
    let [lo, hi] = rbprops_core::stats::chi2_nu_band(nu, se, rbprops_core::stats::BAND_TAIL);
    [lo, hi.max(MIN_BAND_UPPER)]
}

/// χ²/ν of a fit with `nu` degrees of freedom as the verdict reads it, κ χ²/ν (κ the
/// line-correlation inflation), and its noise band for the effective ν/κ and the noise
/// variance's relative standard error `se`.
pub(super) fn chi2_nu_in_band(chi2: f64, nu: f64, kappa: f64, se: f64) -> (f64, [f64; 2]) {
    (kappa * chi2 / nu, noise_band(nu / kappa, se))
}

/// The floor rule: χ²/ν of the final model inside the noise `band` and no residual cell
/// flagged. With no fitted noise (a = b = 0 on every channel) σ is the precision floor
/// alone, and its computation-floor part is a bound on the agreement of two exact
/// computations, not a variance: a χ²/ν below the band then means agreement within it.
pub(super) fn at_noise_floor(
    chi2_nu: f64,
    band: [f64; 2],
    noise: &RecordingNoise,
    flagged: &[String],
) -> bool {
    let precision_only = noise.relative.iter().chain(&noise.floor).all(|x| *x == 0.0);
    (chi2_nu >= band[0] || precision_only) && chi2_nu <= band[1] && flagged.is_empty()
}

/// `x` with `n` significant digits.
pub(super) fn sig(x: f64, n: i32) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let e = x.abs().log10().floor() as i32;
    if (-3..6).contains(&e) {
        format!("{:.*}", (n - 1 - e).max(0) as usize, x)
    } else {
        format!("{:.*e}", (n - 1) as usize, x)
    }
}

pub(super) fn pct(x: f64) -> String {
    format!("{:+.1} %", 100.0 * x)
}

/// The short human verdict.
pub fn verdict(r: &ModelCheckReport) -> String {
    let mut parts = Vec::new();
    if r.accepted.is_empty() && r.ambiguous.is_empty() {
        parts.push("no missing physics found".to_string());
    } else {
        for a in &r.accepted {
            let ps: Vec<String> = a
                .parameters
                .iter()
                .filter(|p| p.standard_error > 0.0 && (p.value / p.standard_error).abs() > 3.0)
                .take(4)
                .map(|p| {
                    format!(
                        "{} = {} ± {} {}",
                        p.name,
                        sig(p.value, 4),
                        sig(p.standard_error, 2),
                        p.unit
                    )
                })
                .collect();
            parts.push(format!(
                "missing: {} [{}] ({})",
                a.title,
                a.id,
                ps.join(", ")
            ));
        }
        for f in &r.ambiguous {
            parts.push(format!(
                "missing: one of {} (indistinguishable here; to separate: {})",
                f.ids.join(" / "),
                f.separating_measurement
            ));
        }
    }
    let sig: Vec<String> = r
        .corrected_parameters
        .iter()
        .filter(|c| c.significant)
        .take(4)
        .map(|c| format!("{} {} → {}", c.name, sig(c.nominal, 4), sig(c.fitted, 4)))
        .collect();
    if !sig.is_empty() {
        parts.push(format!("corrected: {}", sig.join(", ")));
    }
    let floor = if r.noise_floor_reached {
        "noise floor reached".to_string()
    } else if let Some(u) = &r.unexplained {
        u.summary.clone()
    } else {
        let cells: Vec<String> = r.residuals_after.flagged.iter().take(3).cloned().collect();
        if cells.is_empty() {
            "not at the noise floor".to_string()
        } else {
            format!(
                "not at the noise floor; remaining residual in {}",
                cells.join(", ")
            )
        }
    };
    parts.push(format!(
        "χ²/ν {:.3} (nominal {:.3}) → {:.3}, {floor}",
        r.chi2_nu_before, r.chi2_nu_nominal, r.chi2_nu_after
    ));
    if !r.accepted.is_empty() || !r.ambiguous.is_empty() {
        let mut ch: Vec<&RelativeChange> = r.inertia_change.iter().collect();
        let mass = ch[0];
        ch.sort_by(|a, b| b.relative.abs().total_cmp(&a.relative.abs()));
        let top: Vec<String> = ch
            .iter()
            .filter(|c| c.quantity != "mass_kg")
            .take(2)
            .map(|c| format!("{} {}", c.quantity, pct(c.relative)))
            .collect();
        parts.push(format!(
            "inertia change: mass {}, {}",
            pct(mass.relative),
            top.join(", ")
        ));
    }
    for n in &r.not_observable {
        if n.id == GlobalGain::ID || n.id == SensorMass::ID {
            parts.push(format!(
                "cannot be seen: {} ({}; would need {})",
                n.title, n.reason, n.would_reveal
            ));
        }
    }
    parts.join("; ")
}

/// Groups of the residual map (sensor points, excitations, bands) whose z exceeds this
/// are named as where the unexplained residual sits: the flagging level of the map's
/// cells ([`crate::locate`]), a 3e-7 one-sided tail for a group at the noise floor.
const GROUP_Z: f64 = 5.0;

/// The unexplained section: where the residual of the final model sits (the groups of
/// the map above [`GROUP_Z`], strongest first, and its flagged cells), its rigid and
/// quadrature fractions, and the candidates the selection rejected as implausible.
pub(super) fn unexplained(
    map: &crate::locate::ResidualMap,
    screening: &[ScreenEntry],
    chi2_nu: f64,
) -> Unexplained {
    // The groups' labels name their kind ("sensor 3", "excitation force1", "band …").
    let mut groups: Vec<&crate::locate::ResidualTotal> = map
        .per_sensor
        .iter()
        .chain(&map.per_excitation)
        .chain(&map.per_band)
        .filter(|g| g.z > GROUP_Z)
        .collect();
    groups.sort_by(|a, b| b.z.total_cmp(&a.z));
    let groups: Vec<String> = groups
        .iter()
        .map(|g| format!("{} (χ²/n {:.2}, z {:.1})", g.group, g.chi2_nu, g.z))
        .collect();
    let (mut chi2, mut non_rigid, mut quad) = (0.0, 0.0, 0.0);
    for c in &map.cells {
        chi2 += c.chi2;
        non_rigid += c.chi2_non_rigid;
        quad += c.chi2_quadrature;
    }
    let frac = |x: f64| if chi2 > 0.0 { x / chi2 } else { 0.0 };
    let mut implausible: Vec<String> = Vec::new();
    for e in screening {
        if let Some(i) = e.decision.find(IMPLAUSIBLE) {
            let text = format!("{}: {}", e.id, e.decision[i + IMPLAUSIBLE.len()..].trim());
            if !implausible
                .iter()
                .any(|t| t.starts_with(&format!("{}:", e.id)))
            {
                implausible.push(text);
            }
        }
    }
    let place = if groups.is_empty() {
        "spread over the channels, excitations and bands (no group stands out)".to_string()
    } else {
        groups
            .iter()
            .take(4)
            .cloned()
            .collect::<Vec<_>>()
            .join(", ")
    };
    let summary = format!(
        "not explained by a catalogue effect with plausible values: χ²/ν {chi2_nu:.3} remains, in {place}; {:.0} % of it not rigid-body motion of the sensors, {:.0} % in quadrature with the model{}",
        100.0 * frac(non_rigid),
        100.0 * frac(quad),
        if implausible.is_empty() {
            String::new()
        } else {
            format!(
                "; fitted only with implausible values: {}",
                implausible.join("; ")
            )
        }
    );
    Unexplained {
        summary,
        groups,
        non_rigid_fraction: frac(non_rigid),
        quadrature_fraction: frac(quad),
        implausible,
    }
}

/// What the end of a pass needs besides the selection's state.
pub(super) struct Finish<'p, 'a> {
    pub(super) spec: &'p CampaignSpec,
    pub(super) options: &'p CheckOptions,
    pub(super) p: &'p Problem<'a>,
    pub(super) noise_model: RecordingNoise,
    pub(super) base: Fit,
    pub(super) theta_nom: &'p [f64],
    pub(super) chi2_nominal: f64,
    pub(super) free_base: usize,
    /// The weighting for noise correlated from line to line: χ²/ν is stated per line
    /// (×κ) with a band of ν/κ effective lines ([`crate::correlation`]).
    pub(super) inflation: Option<crate::correlation::Inflation>,
}

/// What [`Finish::report`] ends with.
pub(super) struct Finished {
    pub(super) report: ModelCheckReport,
    /// The nominal spec with the fitted parameters and the accepted effects.
    pub(super) improved_spec: CampaignSpec,
    /// The final model: the second pass's prior.
    pub(super) prior: Prior,
    /// The final model's prediction, in the layout's order.
    pub(super) final_pred: Vec<c64>,
    /// The baseline fit's prediction (nominal physics).
    pub(super) base_pred: Vec<c64>,
}

impl<'p, 'a> Finish<'p, 'a> {
    /// Final numbers, with the accepted effects' gauges centred, and the report.
    pub(super) fn report(
        self,
        sel: Selection,
        mut warnings: Vec<Diagnostic>,
        method: Vec<String>,
    ) -> Result<Finished, CheckError> {
        let (p, base) = (self.p, &self.base);
        let (layout, y, sigma) = (p.layout, p.y, p.sigma);
        let nb = p.n_base();
        let n_real = p.n_real();
        let nu_base = n_real - self.free_base as f64;
        let base_pred = p.model(&base.theta, &[])?;
        let Model {
            mut active,
            cur,
            accepted: evidence,
        } = sel.model;
        let Findings {
            screening,
            not_observable,
            ambiguous,
            ..
        } = sel.findings;
        debug_assert!(
            ambiguous.iter().all(|f| active
                .iter()
                .any(|a| Some(&p.cands[a.c].id) == f.ids.first())),
            "an ambiguous family whose accepted member left the model (Selection::forget_family)"
        );
        let cur = centre_gauges(p, cur, &mut active, self.options.max_iterations);
        let free_final = self.free_base + active_dims(&active);
        let nu_after = n_real - free_final as f64;
        let final_pred = p.model(&cur.theta, &active)?;
        let cov_base = fit_covariance(base, nu_base);
        let cov_final = fit_covariance(&cur, nu_after);
        let inertia_nominal =
            inertia_report("nominal spec", self.theta_nom, &DMatrix::zeros(nb, nb));
        let inertia_before =
            inertia_report("baseline fit (nominal physics)", &base.theta, &cov_base);
        let inertia_after = inertia_report(
            "final fit (FRF-level estimate with accepted effects)",
            &cur.theta,
            &cov_final,
        );
        let change = inertia_change(&inertia_before, &inertia_after);
        let corrected = self.corrected(&inertia_nominal, &inertia_after, &cur.theta, &cov_final);
        let (accepted, improved_effects, final_effects) = self.accepted_effects(
            &active,
            &evidence,
            &ambiguous,
            &cur.theta,
            &cov_final,
            &mut warnings,
        )?;
        let improved_spec = self.improved_spec(&cur.theta, improved_effects, &mut warnings)?;
        // Localisation maps.
        let (spec_b, eff_b) = p.build(&base.theta, &[])?;
        let (f_lo, f_hi) = model_modes_band(&spec_b, layout, &eff_b);
        let bnds = bands(f_lo, f_hi, &layout.frequency_hz);
        let residuals_before = residual_map(layout, y, &base_pred, sigma, bnds.clone());
        let residuals_after = residual_map(layout, y, &final_pred, sigma, bnds);
        let noise_model = self.noise_model;
        let kappa = self.inflation.map_or(1.0, |i| i.kappa);
        let (chi2_nu_after, band) =
            chi2_nu_in_band(cur.chi2, nu_after, kappa, noise_model.variance_scale_se);
        let noise_floor_reached =
            at_noise_floor(chi2_nu_after, band, &noise_model, &residuals_after.flagged);
        let unexplained = (!noise_floor_reached)
            .then(|| unexplained(&residuals_after, &screening, chi2_nu_after));
        let mut report = ModelCheckReport {
            campaign: self.spec.name.clone(),
            verdict: String::new(),
            accepted,
            ambiguous,
            unexplained,
            not_observable,
            chi2_nu_nominal: kappa * self.chi2_nominal / n_real,
            chi2_nu_before: kappa * base.chi2 / nu_base,
            chi2_nu_after,
            nu_before: nu_base,
            nu_after,
            noise_band: band,
            noise_floor_reached,
            noise: noise_model,
            n_values: p.used.len(),
            corrected_parameters: corrected,
            inertia_nominal,
            inertia_before,
            inertia_after,
            inertia_change: change,
            screening,
            residuals_before,
            residuals_after,
            method,
            diagnostics: warnings,
        };
        report.verdict = verdict(&report);
        let prior = Prior {
            base: cur.theta[..nb].to_vec(),
            effects: final_effects,
        };
        Ok(Finished {
            report,
            improved_spec,
            prior,
            final_pred,
            base_pred,
        })
    }

    /// Corrected parameters of the nominal model: from the final fit `th` (covariance
    /// `cov`), where the accepted effects no longer bias them (without accepted effects
    /// it is the baseline fit).
    fn corrected(
        &self,
        inertia_nominal: &InertiaEstimateReport,
        inertia_after: &InertiaEstimateReport,
        th: &[f64],
        cov: &DMatrix<f64>,
    ) -> Vec<CorrectedParameter> {
        let (p, theta_nom) = (self.p, self.theta_nom);
        let mut corrected = Vec::new();
        let qn = quantities(inertia_nominal);
        let qb = quantities(inertia_after);
        for i in 0..10 {
            let se = inertia_after.standard_errors[i];
            let z = if se > 0.0 { (qb[i] - qn[i]) / se } else { 0.0 };
            corrected.push(CorrectedParameter {
                name: INERTIA_NAMES[i].to_string(),
                nominal: qn[i],
                fitted: qb[i],
                standard_error: se,
                z,
                significant: z.abs() > 3.0,
            });
        }
        for (k, kind) in p.baseline.kinds.iter().enumerate() {
            let (name, nom, fit, se) = match kind {
                ParamKind::Inertia(_) => continue,
                ParamKind::StiffnessScale { .. } => (
                    p.baseline.names[k].replace("ln_stiffness_scale", "stiffness_factor"),
                    1.0,
                    th[k].exp(),
                    th[k].exp() * cov[(k, k)].max(0.0).sqrt(),
                ),
                ParamKind::ModalDampingLog(_) => (
                    p.baseline.names[k].replace("ln_ratio", "ratio"),
                    theta_nom[k].exp(),
                    th[k].exp(),
                    th[k].exp() * cov[(k, k)].max(0.0).sqrt(),
                ),
                _ => (
                    p.baseline.names[k].clone(),
                    theta_nom[k],
                    th[k],
                    cov[(k, k)].max(0.0).sqrt(),
                ),
            };
            let z = if se > 0.0 { (fit - nom) / se } else { 0.0 };
            corrected.push(CorrectedParameter {
                name,
                nominal: nom,
                fitted: fit,
                standard_error: se,
                z,
                significant: z.abs() > 3.0,
            });
        }
        corrected
    }

    /// The accepted effects with standard errors (φ = neutral + B α, Cov φ = B Cov α Bᵀ)
    /// and their evidence, the catalogue entries of the improved spec, and each active
    /// effect's φ. A member of an ambiguous family is reported as the family.
    #[allow(clippy::type_complexity)]
    fn accepted_effects(
        &self,
        active: &[Act],
        evidence: &[Accepted],
        ambiguous: &[AmbiguousFamily],
        theta: &[f64],
        cov_final: &DMatrix<f64>,
        warnings: &mut Vec<Diagnostic>,
    ) -> Result<
        (
            Vec<AcceptedEffect>,
            Vec<rbprops_sim::spec::EffectSpec>,
            Vec<(String, Vec<f64>)>,
        ),
        CheckError,
    > {
        let p = self.p;
        let mut accepted = Vec::new();
        let mut offset = p.n_base();
        let mut improved_effects = Vec::new();
        // Entries are written for the fitted body (the improved spec's): a cord's free
        // length `ℓ − T/k` depends on the weight it carries.
        let fitted_spec = p.baseline.apply(&theta[..p.n_base()]);
        let mut final_effects = Vec::new();
        for (a, ev) in active.iter().zip(evidence) {
            let cand = &p.cands[a.c];
            let d = a.dim();
            let infos = cand.effect.parameters();
            // φ = neutral + B α, Cov φ = B Cov α Bᵀ.
            let phi = a.phi(&cand.neutral, &theta[offset..offset + d]);
            final_effects.push((cand.id.clone(), phi.clone()));
            let ca = cov_final.view((offset, offset), (d, d)).into_owned();
            let mut cphi = DMatrix::zeros(phi.len(), phi.len());
            for (r, &i) in a.kept.iter().enumerate() {
                for (c, &j) in a.kept.iter().enumerate() {
                    cphi[(i, j)] = ca[(r, c)];
                }
            }
            let params = (0..phi.len())
                .map(|j| FittedParameter {
                    name: infos[j].name.clone(),
                    unit: infos[j].unit.to_string(),
                    value: phi[j],
                    standard_error: cphi[(j, j)].max(0.0).sqrt(),
                })
                .collect();
            let eff = cand.effect.with_values(&phi).map_err(CheckError::Model)?;
            match effect_spec(eff.as_ref(), &fitted_spec) {
                Ok(e) => improved_effects.push(e),
                Err(e) => warnings.push(diagnostic(
                    DiagnosticKind::CheckProcedure,
                    Severity::Note,
                    format!("'{}' is not written to the improved spec: {e}", cand.id),
                )),
            }
            offset += d;
            if ambiguous.iter().any(|a| a.ids[0] == cand.id) {
                continue;
            }
            accepted.push(AcceptedEffect {
                id: cand.id.clone(),
                title: cand.title.clone(),
                source: cand.source.to_string(),
                parameters: params,
                delta_chi2: ev.dchi2,
                dof: ev.rank,
                lr_threshold: ev.threshold,
                delta_bic: ev.dbic,
                inertia_change: ev.inertia_change.clone(),
                gauge_directions: a.gauge.clone(),
                held_out: ev.held_out.clone(),
                held_out_excitations: ev.held_out_exc.clone(),
                change_over_precision_floor: ev.practical,
                plausible: p.plausibility(theta, a.c, &phi),
            });
        }
        Ok((accepted, improved_effects, final_effects))
    }

    /// The nominal spec with the fitted parameters `theta`, the accepted effects
    /// switched on and the known sensor masses as an effect.
    fn improved_spec(
        &self,
        theta: &[f64],
        improved_effects: Vec<rbprops_sim::spec::EffectSpec>,
        warnings: &mut Vec<Diagnostic>,
    ) -> Result<CampaignSpec, CheckError> {
        let (p, spec, options) = (self.p, self.spec, self.options);
        let (mut improved_spec, fx) = p.build(theta, &[])?;
        drop(fx);
        improved_spec.effects.extend(improved_effects);
        if !options.sensor_masses_kg.is_empty() {
            let e = known_sensor_masses(options, p.layout)?;
            improved_spec.effects.push(effect_spec(&e, spec)?);
        }
        for e in &improved_spec.effects {
            if rbprops_sim::effects::parse_effect(e).is_err() {
                warnings.push(diagnostic(DiagnosticKind::CheckProcedure, Severity::Warning, format!(
                    "the improved spec switches on '{}', which this rbprops-sim version does not know yet: frf-sim will reject it until the catalogue has it",
                    e.id
                )));
            }
        }
        Ok(improved_spec)
    }
}
