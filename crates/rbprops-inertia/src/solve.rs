//! The `rb-solve` stage: selected modes (and optionally FRFs) in, [`InertiaEstimate`]s out.

mod mass_line_estimate;

use crate::consistency::nearest_consistent;
use crate::error::InertiaError;
use crate::lsq::LinearConstraint;
use crate::mass_line::{MassLineBand, MassLineOptions};
use crate::modal_estimators::{bretl_conti, describe_null_space, mount_stiffness, toivola_nuutila};
use crate::params::{params_of, N_PARAMS};
use crate::rigid_check::{self, matched_observations, rigid_body_check, Observation};
use crate::shapes::{
    resolve_origin, rigid_shapes, OriginChoice, RigidFrame, RigidShape, ShapeDiagnostics,
};
use crate::uncertainty::{propagate, property_vector, Propagation, N_PROPS};
use mass_line_estimate::mass_line_estimate;
use rbprops_core::records::{Diagnostic, DiagnosticKind, DiagnosticSubject, Severity};
use rbprops_core::records::{
    ErrorsRecord, EstimateMethod, InertiaEstimate, ModalFitRecord, PropertiesRecord,
    RigidBodyCheckRecord, SelectedMode, SelectionRecord, SystematicIntervalRecord,
    UncertaintyMethod,
};
use rbprops_core::{
    c64, FrfSource, Geometry, InertiaProperties, MassMatrix6, Mat6, RigidBodyProperties, Vec3, Vec6,
};
use serde::{Deserialize, Serialize};

/// The estimators (`rb-solve --method bretl-conti,toivola-nuutila,mass-line`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Estimator {
    // `help = None`: `rb-solve --help` lists the names alone, as it always has.
    /// Paper Eq. (2), six modes.
    #[cfg_attr(feature = "clap", value(help = None))]
    BretlConti,
    /// Paper Eq. (10), four or more modes.
    #[cfg_attr(feature = "clap", value(help = None))]
    ToivolaNuutila,
    /// Inertia restraint (mass line) from the FRFs, Lee et al. 1999.
    #[cfg_attr(feature = "clap", value(help = None))]
    MassLine,
}

impl Estimator {
    /// The `method` string of [`InertiaEstimate`].
    pub fn name(self) -> &'static str {
        self.method().as_str()
    }

    /// The `method` of [`InertiaEstimate`].
    pub fn method(self) -> EstimateMethod {
        match self {
            Estimator::BretlConti => EstimateMethod::BretlConti,
            Estimator::ToivolaNuutila => EstimateMethod::ToivolaNuutila,
            Estimator::MassLine => EstimateMethod::MassLine,
        }
    }
}

/// Knowledge that does not come from the measurement. Used by the least-squares
/// estimators (Toivola–Nuutila, mass line) only; every estimate that used it says so in
/// its first warning.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct SideInformation {
    /// Exact mass (kg), imposed as a constraint.
    pub known_mass_kg: Option<f64>,
    /// Exact centre of mass, geometry frame (m), imposed as the constraints `m c = (mc)`.
    pub known_com_m: Option<[f64; 3]>,
    /// Nominal properties: fix only the parameter combinations the data leave undetermined.
    pub nominal: Option<PropertiesRecord>,
}

impl SideInformation {
    /// True when no side information is given.
    pub fn is_empty(&self) -> bool {
        self.known_mass_kg.is_none() && self.known_com_m.is_none() && self.nominal.is_none()
    }
}

/// Options of [`solve`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SolveOptions {
    /// Default: all three (the mass line is skipped with a warning when no FRFs are given).
    pub estimators: Vec<Estimator>,
    /// Default: the geometry's origin.
    pub origin: OriginChoice,
    /// Reference properties for the paper's relative errors.
    pub reference: Option<PropertiesRecord>,
    /// Options of the mass-line estimator (band, terms).
    pub mass_line: MassLineOptions,
    /// Known values imposed on the estimates as exact constraints.
    pub side_information: SideInformation,
    /// 0 (default): linearised propagation; otherwise Monte Carlo with this many draws.
    pub monte_carlo_samples: usize,
    /// Seed of the Monte Carlo draws (default 0).
    pub seed: u64,
    /// Rigid-body consistency check and systematic (jackknife) interval of the modal
    /// estimates (default true; resampling replicates switch it off).
    #[serde(default = "yes")]
    pub rigid_body_check: bool,
}

fn yes() -> bool {
    true
}

impl Default for SolveOptions {
    fn default() -> Self {
        Self {
            estimators: vec![
                Estimator::BretlConti,
                Estimator::ToivolaNuutila,
                Estimator::MassLine,
            ],
            origin: OriginChoice::GeometryOrigin,
            reference: None,
            mass_line: MassLineOptions::default(),
            side_information: SideInformation::default(),
            monte_carlo_samples: 0,
            seed: 0,
            rigid_body_check: true,
        }
    }
}

/// Everything [`solve`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct SolveOutput {
    /// One estimate per estimator and set-up, followed (for each inconsistent one) by its
    /// nearest physically consistent version, method `<method>_projected`.
    pub estimates: Vec<InertiaEstimate>,
    /// The rigid-body transform of every selected mode (Eq. 5), for reports.
    pub shapes: Vec<ShapeDiagnostics>,
    /// The mass-line band actually used.
    pub mass_line_band: Option<MassLineBand>,
    /// What the solve noticed, typed, one diagnostic per fact (the estimates carry
    /// their own).
    pub diagnostics: Vec<Diagnostic>,
}

/// Largest relative standard error of the mass for a mass-line estimate to be reported.
pub const MASS_LINE_MAX_RELATIVE_STD: f64 = 0.05;

/// Relative rigid-body residual above which a shape is flagged.
pub const SHAPE_RESIDUAL_WARNING: f64 = 0.1;
/// Complexity angle above which a mode is flagged (rad).
pub const COMPLEXITY_WARNING_RAD: f64 = 0.2;

/// Runs the requested estimators. Per set-up, the selected modes give Bretl–Conti and
/// Toivola–Nuutila estimates; the mass line uses all excitations of `frf` jointly (it does
/// not depend on the suspension). An estimator that cannot run adds a warning naming the
/// cause; if none produces a result the causes are returned as [`InertiaError::NoEstimate`].
pub fn solve(
    geometry: &Geometry,
    modal: &ModalFitRecord,
    selection: &SelectionRecord,
    frf: Option<&dyn FrfSource>,
    opts: &SolveOptions,
) -> Result<SolveOutput, InertiaError> {
    geometry.validate()?;
    let origin = resolve_origin(geometry, &opts.origin)?;
    let frame = RigidFrame::new(geometry, origin)?;
    let mut out = Collected {
        warnings: input_notes(geometry, &frame, selection),
        ..Default::default()
    };
    let propagation = if opts.monte_carlo_samples > 0 {
        Propagation::MonteCarlo {
            samples: opts.monte_carlo_samples,
            seed: opts.seed,
        }
    } else {
        Propagation::Linearised
    };
    let side = SideConstraints::new(&opts.side_information, &origin)?;
    let run = Solver {
        geometry,
        modal,
        opts,
        frame: &frame,
        side: &side,
        propagation,
    };
    let mut setups: Vec<&str> = Vec::new();
    for s in &selection.selected {
        if !setups.contains(&s.setup.as_str()) {
            setups.push(&s.setup);
        }
    }
    for setup in &setups {
        run.modal_estimates(selection, setup, &mut out)?;
    }
    let mut band = None;
    let mut mass_line_failure = None;
    if opts.estimators.contains(&Estimator::MassLine) {
        match frf {
            None => mass_line_failure = Some("mass_line: no FRFs were given".into()),
            Some(frf) => {
                match mass_line_estimate(
                    &frame,
                    geometry,
                    modal,
                    selection,
                    frf,
                    opts,
                    &side,
                    propagation,
                ) {
                    Ok((parts, b)) => {
                        band = Some(b);
                        out.estimates
                            .extend(parts.finish(&origin, opts.reference.as_ref())?);
                    }
                    // Kept apart: the mass line is a cross-check of the modal
                    // estimates, and it refuses a band too short or too noisy.
                    Err(e) => mass_line_failure = Some(e.to_string()),
                }
            }
        }
    }
    out.finish(band, mass_line_failure)
}

/// Notes on the inputs: a channel set that resolves the six rigid motions although the
/// geometry's own observability check fails, and every mode the selection misses.
fn input_notes(
    geometry: &Geometry,
    frame: &RigidFrame,
    selection: &SelectionRecord,
) -> Vec<Diagnostic> {
    let mut warnings = Vec::new();
    if let Err(e) = geometry.check_rigid_observability() {
        // The channels still resolve the six motions: a note.
        warnings.push(diagnostic(
            DiagnosticKind::GeometryObservability,
            Severity::Note,
            DiagnosticSubject::run(),
            format!(
                "geometry: {e}; the channel set still resolves six rigid motions (cond(SᵀS) = {:.3e})",
                frame.basis.condition
            ),
        ));
    }
    for m in &selection.missing {
        warnings.push(diagnostic(
            DiagnosticKind::ModeMissing,
            Severity::ChangesAnswer,
            DiagnosticSubject::setup(&m.setup).mode(m.mode, m.frequency_hz),
            format!("is missing: {}", m.reason),
        ));
    }
    warnings
}

/// What every estimator of one solve reads.
struct Solver<'a> {
    geometry: &'a Geometry,
    modal: &'a ModalFitRecord,
    opts: &'a SolveOptions,
    frame: &'a RigidFrame,
    side: &'a SideConstraints,
    propagation: Propagation,
}

/// What the solve collects, estimator by estimator.
#[derive(Default)]
struct Collected {
    estimates: Vec<InertiaEstimate>,
    /// Why an estimator could not run, one line each.
    failures: Vec<String>,
    shapes: Vec<ShapeDiagnostics>,
    warnings: Vec<Diagnostic>,
}

impl Solver<'_> {
    /// The modal estimators (Bretl–Conti, Toivola–Nuutila) on one set-up's selected modes:
    /// their rigid-body shapes (Eq. 5), with the rigid-body check and the systematic
    /// standard errors when asked.
    fn modal_estimates(
        &self,
        selection: &SelectionRecord,
        setup: &str,
        out: &mut Collected,
    ) -> Result<(), InertiaError> {
        let (frame, opts) = (self.frame, self.opts);
        let sel: Vec<_> = selection
            .selected
            .iter()
            .filter(|s| s.setup == *setup)
            .cloned()
            .collect();
        let (shapes, errors) = rigid_shapes(frame, self.modal, &sel);
        for e in errors {
            out.warnings.push(diagnostic(
                DiagnosticKind::ModeLeftOut,
                Severity::ChangesAnswer,
                DiagnosticSubject::setup(setup),
                format!("{e}; the mode is left out"),
            ));
        }
        shape_warnings(&shapes, &mut out.warnings);
        out.shapes
            .extend(shapes.iter().map(|s| s.diagnostics(frame)));
        let used: Vec<SelectedMode> = shapes.iter().map(|s| s.selected.clone()).collect();
        let (observations, check) = if opts.rigid_body_check {
            let obs = matched_observations(frame, self.modal, &used);
            let check = rigid_body_check(frame, self.geometry, &obs);
            if let Some(w) = check.as_ref().and_then(|c| rigid_check::warning(c)) {
                out.warnings.push(diagnostic(
                    DiagnosticKind::RigidBodyInconsistent,
                    Severity::Warning,
                    DiagnosticSubject::setup(setup),
                    w,
                ));
            }
            (obs, check)
        } else {
            (Vec::new(), None)
        };
        for est in [Estimator::BretlConti, Estimator::ToivolaNuutila] {
            if !opts.estimators.contains(&est) {
                continue;
            }
            match modal_estimate(est, frame, setup, &shapes, self.side, self.propagation) {
                Ok(mut parts) => {
                    if opts.rigid_body_check {
                        parts.check = check.clone();
                        parts.systematic = systematic_std(
                            est,
                            self.geometry,
                            frame,
                            self.modal,
                            &used,
                            &observations,
                            self.side,
                        );
                    }
                    out.estimates
                        .extend(parts.finish(&frame.origin, opts.reference.as_ref())?)
                }
                Err(e) => out.failures.push(format!("set-up '{setup}': {e}")),
            }
        }
        Ok(())
    }
}

impl Collected {
    /// The output, or [`InertiaError::NoEstimate`] with every cause when nothing came out.
    fn finish(
        mut self,
        band: Option<MassLineBand>,
        mass_line_failure: Option<String>,
    ) -> Result<SolveOutput, InertiaError> {
        if self.estimates.is_empty() {
            self.failures.extend(mass_line_failure);
            if self.failures.is_empty() {
                self.failures
                    .push("no modes were selected and no estimator was requested".into());
            }
            return Err(InertiaError::NoEstimate(self.failures));
        }
        // The other estimators' results stand: a modal estimator's failure is a warning (a
        // set-up's estimate is missing); the mass line's refusal, with the modal estimates
        // there, a note (it is their cross-check, and refuses rather than mislead).
        let failed = |f, severity| {
            diagnostic(
                DiagnosticKind::EstimatorFailed,
                severity,
                DiagnosticSubject::run(),
                f,
            )
        };
        self.warnings.extend(
            self.failures
                .into_iter()
                .map(|f| failed(f, Severity::Warning)),
        );
        self.warnings
            .extend(mass_line_failure.map(|f| failed(f, Severity::Note)));
        Ok(SolveOutput {
            estimates: self.estimates,
            shapes: self.shapes,
            mass_line_band: band,
            diagnostics: self.warnings,
        })
    }
}

/// Notes on the shapes used: each handled as stated, so notes; whether the shapes move as
/// one rigid body within their noise is the rigid-body check's calibrated warning.
fn shape_warnings(shapes: &[RigidShape], warnings: &mut Vec<Diagnostic>) {
    for s in shapes {
        let id = || {
            DiagnosticSubject::setup(&s.selected.setup)
                .excitation(&s.selected.excitation)
                .mode(s.selected.mode, s.selected.frequency_hz)
        };
        if s.core.relative_residual > SHAPE_RESIDUAL_WARNING {
            warnings.push(diagnostic(
                DiagnosticKind::ShapeNotRigid,
                Severity::Note,
                id(),
                format!(
                    "the shape is {:.1} % away from rigid-body motion (‖A − Sq‖/‖A‖)",
                    100.0 * s.core.relative_residual
                ),
            ));
        }
        if s.core.complexity_angle_rad.abs() > COMPLEXITY_WARNING_RAD {
            warnings.push(diagnostic(
                DiagnosticKind::ComplexResidues,
                Severity::Note,
                id(),
                format!(
                    "complex residues (rotated by {:.3} rad onto the real line)",
                    s.core.complexity_angle_rad
                ),
            ));
        }
        if s.estimate.weak {
            warnings.push(diagnostic(
                DiagnosticKind::WeakModes,
                Severity::Note,
                id(),
                "the modal fit marked this mode as weakly excited",
            ));
        }
    }
}

/// A diagnostic of `rb-solve`.
fn diagnostic(
    kind: DiagnosticKind,
    severity: Severity,
    subject: DiagnosticSubject,
    message: impl Into<String>,
) -> Diagnostic {
    Diagnostic::new("rb-solve", kind, severity, subject, message)
}

/// Side information as constraints about the working origin.
struct SideConstraints {
    constraints: Vec<LinearConstraint>,
    nominal: Option<[f64; N_PARAMS]>,
    labels: Vec<String>,
}

impl SideConstraints {
    fn new(side: &SideInformation, origin: &Vec3) -> Result<Self, InertiaError> {
        let mut constraints = Vec::new();
        let mut labels = Vec::new();
        if let Some(m) = side.known_mass_kg {
            if !(m > 0.0 && m.is_finite()) {
                return Err(InertiaError::SideInformation(format!(
                    "known mass {m} kg is not positive"
                )));
            }
            let mut row = [0.0; N_PARAMS];
            row[0] = 1.0;
            let label = format!("known mass {m} kg");
            constraints.push(LinearConstraint {
                row,
                value: m,
                label: label.clone(),
            });
            labels.push(label);
        }
        if let Some(c) = side.known_com_m {
            if c.iter().any(|x| !x.is_finite()) {
                return Err(InertiaError::SideInformation(format!(
                    "known centre of mass {c:?} is not finite"
                )));
            }
            let co = Vec3::from(c) - origin;
            // m c_o,i − (m c)_i = 0: linear and homogeneous in p, whether or not m is known.
            for i in 0..3 {
                let mut row = [0.0; N_PARAMS];
                row[0] = co[i];
                row[1 + i] = -1.0;
                constraints.push(LinearConstraint {
                    row,
                    value: 0.0,
                    label: format!("known centre of mass, {} component", ["x", "y", "z"][i]),
                });
            }
            labels.push(format!("known centre of mass {c:?} m"));
        }
        let nominal = match &side.nominal {
            None => None,
            Some(rec) => {
                let p = rec.to_properties();
                p.validate()?;
                labels.push(format!(
                    "nominal values (mass {} kg) fix the combinations the data leave undetermined",
                    rec.mass_kg
                ));
                Some(params_of(&p.with_origin_at(origin).mass_matrix()))
            }
        };
        Ok(Self {
            constraints,
            nominal,
            labels,
        })
    }

    /// The side information used, as a warning: the estimate rests on it, not only on
    /// the measurement.
    fn label(&self, setup: Option<&str>) -> Option<Diagnostic> {
        (!self.labels.is_empty()).then(|| {
            diagnostic(
                DiagnosticKind::SideInformation,
                Severity::Warning,
                setup.map_or_else(DiagnosticSubject::run, DiagnosticSubject::setup),
                format!(
                    "SIDE INFORMATION (not from the measurement): {}",
                    self.labels.join("; ")
                ),
            )
        })
    }
}

/// An estimate before packaging.
struct EstimateParts {
    method: EstimateMethod,
    setup: String,
    /// About the working origin.
    mass_matrix: MassMatrix6,
    std: Option<[f64; N_PROPS]>,
    uncertainty_method: UncertaintyMethod,
    mount_stiffness: Option<Mat6>,
    residual: f64,
    modes_used: Vec<usize>,
    excitations_used: Vec<String>,
    warnings: Vec<Diagnostic>,
    check: Option<RigidBodyCheckRecord>,
    /// Jackknife systematic standard errors and how they were obtained.
    systematic: Option<([f64; N_PROPS], String)>,
}

/// Properties in the geometry frame from a mass matrix about `origin`.
fn properties_about(m0: &MassMatrix6, origin: &Vec3) -> RigidBodyProperties {
    let p = m0.properties();
    RigidBodyProperties {
        com: p.com + origin,
        ..p
    }
}

fn finite(x: f64, what: &str) -> Result<f64, InertiaError> {
    if x.is_finite() {
        Ok(x)
    } else {
        Err(InertiaError::NonFinite { what: what.into() })
    }
}

impl EstimateParts {
    fn finish(
        self,
        origin: &Vec3,
        reference: Option<&PropertiesRecord>,
    ) -> Result<Vec<InertiaEstimate>, InertiaError> {
        let props = properties_about(&self.mass_matrix, origin);
        for v in property_vector(&props) {
            finite(v, &format!("{} properties", self.method))?;
        }
        let violations = props.consistency_violations();
        let mut est = self.package(&props, origin, reference, self.warnings.clone());
        est.physically_consistent = violations.is_empty();
        est.diagnostics.extend(violations.iter().map(|v| {
            self.diagnostic_of(
                DiagnosticKind::PhysicallyInconsistent,
                Severity::ChangesAnswer,
                v.clone(),
            )
        }));
        let mut out = vec![est];
        if !violations.is_empty() && props.mass > 0.0 {
            let fixed = nearest_consistent(&props);
            let mut w = self.warnings.clone();
            w.push(self.diagnostic_of(DiagnosticKind::ProjectedEstimate, Severity::Note, format!(
                "nearest physically consistent version of the {} estimate: same mass, CoM and principal axes, principal moments projected onto the triangle-inequality cone; standard errors are those of the unprojected estimate",
                self.method
            )));
            let mut p = self.package(&fixed, origin, reference, w);
            p.method = self.method.projected();
            p.physically_consistent = fixed.consistency_violations().is_empty();
            out.push(p);
        }
        Ok(out)
    }

    /// A diagnostic about this estimate (its set-up the subject).
    fn diagnostic_of(
        &self,
        kind: DiagnosticKind,
        severity: Severity,
        message: String,
    ) -> Diagnostic {
        diagnostic(
            kind,
            severity,
            DiagnosticSubject::setup(&self.setup),
            message,
        )
    }

    fn package(
        &self,
        props: &RigidBodyProperties,
        origin: &Vec3,
        reference: Option<&PropertiesRecord>,
        warnings: Vec<Diagnostic>,
    ) -> InertiaEstimate {
        let rec = PropertiesRecord::from_properties(props);
        let std = InertiaProperties::from_vector(&self.std.unwrap_or([0.0; N_PROPS]));
        let pr = props.products_of_inertia();
        let (moments, axes) = props.principal();
        let errors = reference.map(|r| {
            // Paper Figs. 14–17: CoM error relative to the CoM's distance from the origin.
            let e = props
                .with_origin_at(origin)
                .relative_errors(&r.to_properties().with_origin_at(origin));
            ErrorsRecord {
                mass: e.mass,
                com: e.com,
                inertia: e.inertia,
                sum: e.sum,
            }
        });
        let mut est = InertiaEstimate {
            method: self.method,
            setup: self.setup.clone(),
            origin_m: (*origin).into(),
            mass_kg: rec.mass_kg,
            mass_std_kg: std.mass,
            com_m: rec.com_m,
            com_std_m: std.com.into(),
            inertia_cm_kg_m2: rec.inertia_cm_kg_m2,
            inertia_cm_std_kg_m2: std.tensor_standard_errors(),
            products_of_inertia_kg_m2: pr,
            products_of_inertia_std_kg_m2: std.products,
            principal_moments_kg_m2: moments.into(),
            principal_axes: std::array::from_fn(|r| std::array::from_fn(|c| axes[(r, c)])),
            mount_stiffness: self
                .mount_stiffness
                .map(|k| std::array::from_fn(|r| std::array::from_fn(|c| k[(r, c)]))),
            residual: self.residual,
            uncertainty_method: self.uncertainty_method,
            uncertainty_source: None,
            modes_used: self.modes_used.clone(),
            excitations_used: self.excitations_used.clone(),
            errors,
            physically_consistent: true,
            diagnostics: warnings,
            rigid_body_consistent: self.check.as_ref().map(|c| c.rigid_body_consistent),
            rigid_body_check: self.check.clone(),
            systematic: self.systematic.as_ref().map(|(s, how)| {
                let s = InertiaProperties::from_vector(s);
                SystematicIntervalRecord {
                    method: how.clone(),
                    mass_std_kg: s.mass,
                    com_std_m: s.com.into(),
                    inertia_cm_std_kg_m2: s.tensor_standard_errors(),
                    mass_95_kg: [0.0; 2],
                    com_95_m: [[0.0; 2]; 3],
                    inertia_cm_95_kg_m2: [[[0.0; 2]; 3]; 3],
                }
            }),
        };
        est.update_systematic_interval();
        est
    }
}

fn distinct(ids: impl Iterator<Item = String>) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for id in ids {
        if !out.contains(&id) {
            out.push(id);
        }
    }
    out
}

/// Flattened `[re, im]` residues of the shapes and their standard deviations.
fn residue_inputs(shapes: &[RigidShape], warnings: &mut Vec<Diagnostic>) -> (Vec<f64>, Vec<f64>) {
    let mut x = Vec::new();
    let mut s = Vec::new();
    for sh in shapes {
        let est = &sh.estimate;
        let ok = est.residue_std.len() == est.residues.len()
            && est.residue_std.iter().all(|v| v.is_finite() && *v >= 0.0);
        if !ok {
            warnings.push(diagnostic(
                DiagnosticKind::UncertaintyIncomplete,
                Severity::Warning,
                DiagnosticSubject::setup(&sh.selected.setup)
                    .excitation(&sh.selected.excitation)
                    .mode_number(sh.selected.mode),
                format!(
                "{} residue standard errors for {} residues (or invalid values); its uncertainty is taken as zero",
                est.residue_std.len(),
                est.residues.len()
            )));
        }
        for (i, z) in est.residues.iter().enumerate() {
            let si = if ok { est.residue_std[i] } else { 0.0 };
            x.extend([z.re, z.im]);
            s.extend([si, si]);
        }
    }
    (x, s)
}

/// Mass-normalised shapes from a flattened residue vector (for uncertainty propagation).
fn shapes_from_inputs(
    frame: &RigidFrame,
    shapes: &[RigidShape],
    x: &[f64],
) -> Result<Vec<Vec6>, InertiaError> {
    let mut off = 0;
    let mut out = Vec::with_capacity(shapes.len());
    for sh in shapes {
        let n = sh.estimate.residues.len();
        let res: Vec<c64> = (0..n)
            .map(|i| c64::new(x[off + 2 * i], x[off + 2 * i + 1]))
            .collect();
        off += 2 * n;
        let core = frame
            .shape(sh.excitation, &res)
            .map_err(|reason| InertiaError::Mode {
                setup: sh.selected.setup.clone(),
                mode: sh.selected.mode,
                excitation: sh.selected.excitation.clone(),
                reason,
            })?;
        out.push(core.phi0);
    }
    Ok(out)
}

fn uncertainty<F>(
    f: F,
    x: &[f64],
    sigma: &[f64],
    how: Propagation,
    warnings: &mut Vec<Diagnostic>,
) -> (Option<[f64; N_PROPS]>, UncertaintyMethod)
where
    F: Fn(&[f64]) -> Result<[f64; N_PROPS], InertiaError> + Sync,
{
    if sigma.iter().all(|s| *s == 0.0) {
        warnings.push(diagnostic(
            DiagnosticKind::UncertaintyIncomplete,
            Severity::Warning,
            DiagnosticSubject::run(),
            "no input standard errors: the reported standard errors are zero",
        ));
        return (None, UncertaintyMethod::None);
    }
    match propagate(f, x, sigma, how) {
        Ok(s) => (Some(s), how.record_name()),
        Err(e) => {
            warnings.push(diagnostic(
                DiagnosticKind::UncertaintyIncomplete,
                Severity::Warning,
                DiagnosticSubject::run(),
                format!(
                    "uncertainty propagation failed ({e}); standard errors are reported as zero"
                ),
            ));
            (None, UncertaintyMethod::None)
        }
    }
}

fn modal_estimate(
    est: Estimator,
    frame: &RigidFrame,
    setup: &str,
    shapes: &[RigidShape],
    side: &SideConstraints,
    how: Propagation,
) -> Result<EstimateParts, InertiaError> {
    let phi0: Vec<Vec6> = shapes.iter().map(|s| s.core.phi0).collect();
    let omegas: Vec<f64> = shapes.iter().map(RigidShape::omega).collect();
    let origin = frame.origin;
    let mut warnings = Vec::new();
    let (mass_matrix, residual) = match est {
        Estimator::BretlConti => {
            let bc = bretl_conti(&phi0)?;
            if bc.condition > 1e4 {
                warnings.push(diagnostic(
                    DiagnosticKind::IllConditioned,
                    Severity::Warning,
                    DiagnosticSubject::setup(setup),
                    format!(
                        "Φ0 is poorly conditioned (cond = {:.3e}): the estimate is sensitive to shape errors",
                        bc.condition
                    ),
                ));
            }
            (bc.mass_matrix, bc.residual)
        }
        Estimator::ToivolaNuutila => {
            if let Some(l) = side.label(Some(setup)) {
                warnings.push(l);
            }
            let tn = toivola_nuutila(&phi0, &side.constraints, None)?;
            if tn.rank < N_PARAMS {
                let description = describe_null_space(&tn, &phi0);
                if side.nominal.is_none() {
                    return Err(InertiaError::Unidentifiable {
                        method: "toivola_nuutila",
                        rank: tn.rank,
                        description,
                    });
                }
                warnings.push(diagnostic(
                    DiagnosticKind::IllConditioned,
                    Severity::Warning,
                    DiagnosticSubject::setup(setup),
                    format!(
                        "rank {} of 10: {description}; the nominal values fix it",
                        tn.rank
                    ),
                ));
            } else if tn.condition > 1e6 {
                warnings.push(diagnostic(
                    DiagnosticKind::IllConditioned,
                    Severity::Warning,
                    DiagnosticSubject::setup(setup),
                    format!(
                        "the orthogonality equations are poorly conditioned (cond = {:.3e})",
                        tn.condition
                    ),
                ));
            }
            let tn = toivola_nuutila(&phi0, &side.constraints, side.nominal.as_ref())?;
            (tn.mass_matrix, tn.residual)
        }
        Estimator::MassLine => unreachable!("the mass line is not a modal estimator"),
    };
    let k0 = if phi0.len() == 6 {
        match mount_stiffness(&phi0, &omegas) {
            Ok(k) => Some(k),
            Err(e) => {
                warnings.push(diagnostic(
                    DiagnosticKind::MountStiffness,
                    Severity::Note,
                    DiagnosticSubject::setup(setup),
                    format!("mount stiffness: {e}"),
                ));
                None
            }
        }
    } else {
        None
    };
    let (x, sigma) = residue_inputs(shapes, &mut warnings);
    let f = |xs: &[f64]| -> Result<[f64; N_PROPS], InertiaError> {
        let ph = shapes_from_inputs(frame, shapes, xs)?;
        let m0 = match est {
            Estimator::BretlConti => bretl_conti(&ph)?.mass_matrix,
            _ => toivola_nuutila(&ph, &side.constraints, side.nominal.as_ref())?.mass_matrix,
        };
        Ok(property_vector(&properties_about(&m0, &origin)))
    };
    let (std, method) = uncertainty(f, &x, &sigma, how, &mut warnings);
    Ok(EstimateParts {
        method: est.method(),
        setup: setup.to_string(),
        mass_matrix,
        std,
        uncertainty_method: method,
        mount_stiffness: k0,
        residual,
        modes_used: shapes.iter().map(|s| s.selected.mode).collect(),
        excitations_used: distinct(shapes.iter().map(|s| s.selected.excitation.clone())),
        warnings,
        check: None,
        systematic: None,
    })
}

/// Property vector of one modal estimator on a set of shapes, no uncertainty.
fn point_estimate(
    est: Estimator,
    origin: &Vec3,
    shapes: &[RigidShape],
    side: &SideConstraints,
) -> Result<[f64; N_PROPS], InertiaError> {
    let phi0: Vec<Vec6> = shapes.iter().map(|s| s.core.phi0).collect();
    let m0 = match est {
        Estimator::BretlConti => bretl_conti(&phi0)?.mass_matrix,
        _ => toivola_nuutila(&phi0, &side.constraints, side.nominal.as_ref())?.mass_matrix,
    };
    let v = property_vector(&properties_about(&m0, origin));
    if v.iter().all(|x| x.is_finite()) {
        Ok(v)
    } else {
        Err(InertiaError::NonFinite {
            what: "jackknife estimate".into(),
        })
    }
}

/// Delete-one jackknife variance `(n−1)/n Σ(θ_(i) − θ̄)²` of each property.
fn jackknife_variance(reps: &[[f64; N_PROPS]]) -> [f64; N_PROPS] {
    let n = reps.len() as f64;
    std::array::from_fn(|k| {
        if reps.len() < 2 {
            return 0.0;
        }
        let mean = reps.iter().map(|r| r[k]).sum::<f64>() / n;
        (n - 1.0) / n * reps.iter().map(|r| (r[k] - mean).powi(2)).sum::<f64>()
    })
}

/// The systematic standard errors of one modal estimator (see [`crate::rigid_check`]):
/// leave-one-sensor-out (leave-one-channel-out when the other sensors cannot see all six
/// rigid motions) plus leave-one-excitation-out jackknife variances. `None` when no unit
/// could be left out.
#[allow(clippy::too_many_arguments)]
fn systematic_std(
    est: Estimator,
    geometry: &Geometry,
    frame: &RigidFrame,
    modal: &ModalFitRecord,
    used: &[SelectedMode],
    observations: &[Vec<Observation>],
    side: &SideConstraints,
) -> Option<([f64; N_PROPS], String)> {
    let origin = frame.origin;
    // The selected estimates only, so that leaving channels out copies little.
    let picked = ModalFitRecord {
        modes: used
            .iter()
            .filter_map(|s| {
                modal
                    .modes
                    .iter()
                    .find(|m| m.excitation == s.excitation && m.mode == s.excitation_mode)
                    .cloned()
            })
            .collect(),
        ..Default::default()
    };
    let without_channels = |drop: &[usize]| -> Option<[f64; N_PROPS]> {
        let mut g = geometry.clone();
        g.channels = g
            .channels
            .iter()
            .enumerate()
            .filter(|(i, _)| !drop.contains(i))
            .map(|(_, c)| c.clone())
            .collect();
        let f = RigidFrame::new(&g, origin).ok()?;
        let mut m = picked.clone();
        for e in &mut m.modes {
            e.residues = keep_entries(&e.residues, drop);
            e.residue_std = keep_entries(&e.residue_std, drop);
        }
        let (shapes, errors) = rigid_shapes(&f, &m, used);
        if !errors.is_empty() {
            return None;
        }
        point_estimate(est, &origin, &shapes, side).ok()
    };
    let sensors = rigid_check::sensor_groups(geometry);
    let mut unit_reps: Vec<[f64; N_PROPS]> = sensors
        .iter()
        .filter_map(|(_, g)| without_channels(g))
        .collect();
    let mut how = format!(
        "jackknife: {} of {} sensors left out",
        unit_reps.len(),
        sensors.len()
    );
    if unit_reps.len() < sensors.len() {
        let n = geometry.channels.len();
        unit_reps = (0..n).filter_map(|i| without_channels(&[i])).collect();
        how = format!(
            "jackknife: {} of {n} channels left out (without a whole sensor the others cannot see all six rigid motions)",
            unit_reps.len()
        );
    }
    // Leave one excitation out: each of its modes re-normalised by the other excitation
    // that sees it most strongly, or dropped when none does.
    let mut exc_used: Vec<usize> = Vec::new();
    for s in used {
        if let Some(k) = frame.excitation_index(&s.excitation) {
            if !exc_used.contains(&k) {
                exc_used.push(k);
            }
        }
    }
    let mut exc_reps = Vec::new();
    for &k in &exc_used {
        let mut sel = Vec::new();
        for (s, obs) in used.iter().zip(observations) {
            if frame.excitation_index(&s.excitation) != Some(k) {
                sel.push(s.clone());
                continue;
            }
            let alt = obs
                .iter()
                .filter(|o| o.excitation != k)
                .filter_map(|o| {
                    frame
                        .shape(o.excitation, &o.estimate.residues)
                        .ok()
                        .map(|c| (o, c.force_projection))
                })
                .max_by(|a, b| a.1.total_cmp(&b.1));
            if let Some((o, _)) = alt {
                sel.push(SelectedMode {
                    excitation: o.estimate.excitation.clone(),
                    excitation_mode: o.estimate.mode,
                    ..s.clone()
                });
            }
        }
        let (shapes, _) = rigid_shapes(frame, modal, &sel);
        if let Ok(v) = point_estimate(est, &origin, &shapes, side) {
            exc_reps.push(v);
        }
    }
    if unit_reps.len() < 2 && exc_reps.len() < 2 {
        return None;
    }
    how.push_str(&format!(
        "; {} of {} excitations left out",
        exc_reps.len(),
        exc_used.len()
    ));
    let a = jackknife_variance(&unit_reps);
    let b = jackknife_variance(&exc_reps);
    Some((std::array::from_fn(|k| (a[k] + b[k]).sqrt()), how))
}

/// The entries of `v` whose index is not in `drop`.
fn keep_entries<T: Copy>(v: &[T], drop: &[usize]) -> Vec<T> {
    v.iter()
        .enumerate()
        .filter(|(i, _)| !drop.contains(i))
        .map(|(_, x)| *x)
        .collect()
}
