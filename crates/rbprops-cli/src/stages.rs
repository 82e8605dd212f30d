//! The pipeline stages as functions on a [`RunRecord`]: the executables and the campaign
//! runner call the same code, so a campaign row equals the single run exactly.

use anyhow::{Context, Result};
use rbprops_core::records::{InertiaEstimate, ModalFitRecord, SelectionRecord, TruthRecord};
use rbprops_formats::{topics, RunRecord};

/// `frf-sim`: a campaign spec (TOML text) to a fresh record and the simulator's notes.
/// `source` names it in errors.
pub fn simulate(text: &str, source: &str, seed: Option<u64>) -> Result<(RunRecord, Vec<String>)> {
    let spec = simulated_spec(text, source, seed)?;
    let sim = rbprops_sim::simulate(&spec).map_err(|e| anyhow::anyhow!("{source}: {e}"))?;
    let mut rec = simulation_record(text, &sim.geometry, &sim.truth)?;
    // Moved, not copied: the FRF set is the record's bulk (issue 41's memory bound).
    rec.frf = Some(sim.frf);
    Ok((rec, sim.notes))
}

/// [`simulate`] with the FRFs made one excitation at a time as the output asks for them
/// (issue 41): the record without its FRF set, and the simulation that gives it
/// ([`crate::write_output_with`] writes the two as [`simulate`]'s record).
pub fn simulate_deferred(
    text: &str,
    source: &str,
    seed: Option<u64>,
) -> Result<(RunRecord, rbprops_sim::DeferredSimulation)> {
    let spec = simulated_spec(text, source, seed)?;
    let sim =
        rbprops_sim::simulate_deferred(&spec).map_err(|e| anyhow::anyhow!("{source}: {e}"))?;
    let rec = simulation_record(text, &sim.geometry, &sim.truth)?;
    Ok((rec, sim))
}

/// The campaign spec of `text` with the seed given on the command line.
fn simulated_spec(
    text: &str,
    source: &str,
    seed: Option<u64>,
) -> Result<rbprops_sim::CampaignSpec> {
    let mut spec = rbprops_sim::CampaignSpec::from_toml_str(text)
        .map_err(|e| anyhow::anyhow!("{source}: {e}"))?;
    if let Some(seed) = seed {
        spec.seed = seed;
    }
    Ok(spec)
}

/// A simulation's record without its FRFs: provenance, geometry and truth.
fn simulation_record(
    text: &str,
    geometry: &rbprops_core::Geometry,
    truth: &TruthRecord,
) -> Result<RunRecord> {
    let mut rec = RunRecord::default();
    rec.push_provenance(crate::provenance(
        "frf-sim",
        &rbprops_formats::sha256_hex(text.as_bytes()),
    ))?;
    rec.set_geometry(geometry);
    rec.set(topics::TRUTH, std::slice::from_ref(truth));
    Ok(rec)
}

/// `modal-fit` on a record: adds the `modal_fit` topic. When the recording's processing
/// topic names an exponential window, the fit sees the prefiltered FRFs and its poles are
/// corrected for the window (`rbprops_core::WindowCorrection`; the record says so).
pub fn modal_fit(
    rec: &mut RunRecord,
    opts: &rbprops_modal::FitOptions,
    input_sha256: &str,
) -> Result<rbprops_modal::ModalFitOutput> {
    modal_fit_windowed(rec, opts, None, input_sha256)
}

/// [`modal_fit`] with an exponential window τ (s) that overrides the recording's; it is
/// written into the record's processing topic, so later stages see the same window.
pub fn modal_fit_windowed(
    rec: &mut RunRecord,
    opts: &rbprops_modal::FitOptions,
    exp_window_s: Option<f64>,
    input_sha256: &str,
) -> Result<rbprops_modal::ModalFitOutput> {
    modal_fit_from(rec, None, opts, exp_window_s, input_sha256)
}

/// [`modal_fit_windowed`] with the FRFs from `frf` (an input's set left in its file,
/// `StageIo::read_deferring`) instead of the record's: each fit asks for its
/// excitation's FRFs and keeps only its band.
pub fn modal_fit_from(
    rec: &mut RunRecord,
    frf: Option<&dyn rbprops_core::FrfSource>,
    opts: &rbprops_modal::FitOptions,
    exp_window_s: Option<f64>,
    input_sha256: &str,
) -> Result<rbprops_modal::ModalFitOutput> {
    use rbprops_core::records::{ProcessingRecord, PROCESSING_TOPIC};
    let mut processing: ProcessingRecord = rec.get_one(PROCESSING_TOPIC)?.unwrap_or_default();
    let source = if exp_window_s.is_some() {
        processing.exponential_window_s = exp_window_s;
        rec.set(PROCESSING_TOPIC, std::slice::from_ref(&processing));
        "--exp-window"
    } else {
        "recording"
    };
    let window = processing
        .exponential_window_s
        .map(rbprops_core::WindowCorrection::new)
        .transpose()
        .context("exponential window")?;
    let (geometry, frf) = geometry_and_frf(rec, frf)?;
    if let Some(b) = opts.band_hz {
        crate::args::check_band("--band", b, frf.frequency_hz())?;
    }
    let out = match window {
        None => rbprops_modal::fit_campaign(&geometry, frf, opts)?,
        Some(w) => {
            // Each excitation prefiltered as the fit asks for it (never the whole set).
            let prefiltered = rbprops_core::Prefiltered { window: &w, frf };
            let mut out = rbprops_modal::fit_campaign(&geometry, &prefiltered, opts)?;
            w.correct_modal_fit(&mut out.record, source)?;
            out.record
                .diagnostics
                .push(rbprops_core::records::Diagnostic {
                    stage: "modal-fit".into(),
                    kind: rbprops_core::records::DiagnosticKind::WindowCorrection,
                    severity: rbprops_core::records::Severity::Note,
                    subject: Default::default(),
                    message: format!(
                        "poles corrected for the exponential window τ = {} s ({source})",
                        w.time_constant_s
                    ),
                    advice: String::new(),
                });
            out
        }
    };
    if out.record.modes.is_empty() && !out.record.excitations.is_empty() {
        let why: Vec<String> = out
            .record
            .excitations
            .iter()
            .filter_map(|e| e.warnings.first().map(|w| format!("{}: {w}", e.excitation)))
            .take(3)
            .collect();
        anyhow::bail!(
            "no mode identified in any of the {} excitations{}",
            out.record.excitations.len(),
            if why.is_empty() {
                String::new()
            } else {
                format!(" ({})", why.join("; "))
            }
        );
    }
    rec.push_provenance(crate::provenance("modal-fit", input_sha256))?;
    rec.set(topics::MODAL_FIT, std::slice::from_ref(&out.record));
    Ok(out)
}

/// `ni-select` on a record: adds the `selection` topic.
pub fn ni_select(
    rec: &mut RunRecord,
    opts: &rbprops_ni::SelectOptions,
    input_sha256: &str,
) -> Result<rbprops_ni::SelectionOutput> {
    ni_select_from(rec, None, opts, input_sha256)
}

/// [`ni_select`] with the FRFs from `frf` (an input's set left in its file,
/// `StageIo::read_deferring`) instead of the record's: one excitation is held at a time.
pub fn ni_select_from(
    rec: &mut RunRecord,
    frf: Option<&dyn rbprops_core::FrfSource>,
    opts: &rbprops_ni::SelectOptions,
    input_sha256: &str,
) -> Result<rbprops_ni::SelectionOutput> {
    let (geometry, frf) = geometry_and_frf(rec, frf)?;
    let modal: ModalFitRecord = rec
        .get_one(topics::MODAL_FIT)?
        .context("no modal_fit topic (run modal-fit first)")?;
    crate::validate::modal_fit(&modal, geometry.channels.len())?;
    let out = rbprops_ni::select_modes(&geometry, frf, &modal, opts)?;
    rec.push_provenance(crate::provenance("ni-select", input_sha256))?;
    rec.set(topics::SELECTION, std::slice::from_ref(&out.record));
    Ok(out)
}

/// The record's geometry and the FRFs: `frf` when given (a deferred input's), else the
/// record's set (both required).
fn geometry_and_frf<'a>(
    rec: &'a RunRecord,
    frf: Option<&'a dyn rbprops_core::FrfSource>,
) -> Result<(rbprops_core::Geometry, &'a dyn rbprops_core::FrfSource)> {
    Ok(match frf {
        Some(f) => (
            rec.geometry()?.context("no geometry topic in the input")?,
            f,
        ),
        None => {
            let (g, f) = rec.require_geometry_and_frf()?;
            (g, f as &dyn rbprops_core::FrfSource)
        }
    })
}

/// How `rb-solve` obtains the standard errors of the modal estimates.
/// The standard-error choices of `rb-solve --uncertainty`, `rbprops campaign
/// --uncertainty` and the campaign file's `uncertainty` key.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum UncertaintyChoice {
    /// FRF-level parametric bootstrap of the modal estimators (rbprops-uq).
    #[default]
    Bootstrap,
    /// Propagation of the residue standard errors (or Monte Carlo with --monte-carlo).
    #[value(alias = "linearized")]
    #[serde(alias = "linearized")]
    Linearised,
}

impl UncertaintyChoice {
    /// The choice with the default options (a bootstrap of 100 replicates, seed 0).
    pub fn with_defaults(self) -> Uncertainty {
        match self {
            UncertaintyChoice::Bootstrap => Uncertainty::Bootstrap(Default::default()),
            UncertaintyChoice::Linearised => Uncertainty::Linearised,
        }
    }
}

/// How `rb-solve` obtains its standard errors, resolved from [`UncertaintyChoice`].
#[derive(Debug, Clone, PartialEq, Default)]
pub enum Uncertainty {
    /// `rbprops_inertia` propagation of the residue standard errors (linearised, or Monte
    /// Carlo with `SolveOptions::monte_carlo_samples`).
    #[default]
    Linearised,
    /// FRF-level parametric bootstrap (`rbprops_uq`).
    Bootstrap(rbprops_uq::BootstrapOptions),
}

/// `rb-solve` on a record: adds the `estimates` topic. With `use_truth`, the truth topic
/// (when present and no reference is set) provides the reference for relative errors.
pub fn rb_solve(
    rec: &mut RunRecord,
    opts: &rbprops_inertia::SolveOptions,
    use_truth: bool,
    input_sha256: &str,
) -> Result<rbprops_inertia::SolveOutput> {
    rb_solve_with(rec, opts, &Uncertainty::Linearised, use_truth, input_sha256).map(|(o, _)| o)
}

/// What `rb-solve` gives: the solve's output and, with the bootstrap, the bootstrap's.
pub type SolveWithBootstrap = (
    rbprops_inertia::SolveOutput,
    Option<rbprops_uq::BootstrapOutput>,
);

/// [`rb_solve`] with a choice of [`Uncertainty`]; with the bootstrap, also its output
/// (`None` when it could not run: the warnings say why and the linearised errors stay).
pub fn rb_solve_with(
    rec: &mut RunRecord,
    opts: &rbprops_inertia::SolveOptions,
    uncertainty: &Uncertainty,
    use_truth: bool,
    input_sha256: &str,
) -> Result<SolveWithBootstrap> {
    rb_solve_from(rec, None, opts, uncertainty, use_truth, input_sha256)
}

/// Whether `rb-solve` with `uncertainty` needs the input's FRF set in the record rather
/// than left in its file: the bootstrap of a record whose line variances or weights are
/// made from the set's values (a variance or coherence topic).
pub fn rb_solve_needs_the_set(rec: &RunRecord, uncertainty: &Uncertainty) -> bool {
    matches!(uncertainty, Uncertainty::Bootstrap(_))
        && (rec.topic(rbprops_formats::topics::FRF_VARIANCE).is_some()
            || rec.topic(rbprops_formats::topics::COHERENCE).is_some())
}

/// [`rb_solve_with`] with the FRFs from `frf` (an input's set left in its file,
/// `StageIo::read_deferring`) instead of the record's: both the linearised errors (the
/// mass line) and the bootstrap (its model) read one excitation at a time, unless
/// [`rb_solve_needs_the_set`].
pub fn rb_solve_from(
    rec: &mut RunRecord,
    frf: Option<&dyn rbprops_core::FrfSource>,
    opts: &rbprops_inertia::SolveOptions,
    uncertainty: &Uncertainty,
    use_truth: bool,
    input_sha256: &str,
) -> Result<SolveWithBootstrap> {
    // The FRFs stay borrowed from the record (no copy: at 102,401 lines × 3 excitations
    // one is 44 MB) until the estimates are written back.
    let (geometry, frf) = geometry_and_frf(rec, frf)?;
    let modal: ModalFitRecord = rec
        .get_one(topics::MODAL_FIT)?
        .context("no modal_fit topic (run modal-fit first)")?;
    let selection: SelectionRecord = rec
        .get_one(topics::SELECTION)?
        .context("no selection topic (run ni-select first)")?;
    crate::validate::modal_fit(&modal, geometry.channels.len())?;
    crate::validate::selection(&selection, &modal)?;
    if let Some(b) = opts.mass_line.band_hz {
        crate::args::check_band("--mass-line-band", b, frf.frequency_hz())?;
    }
    let mut opts = opts.clone();
    if opts.reference.is_none() && use_truth {
        opts.reference = rec
            .get_one::<TruthRecord>(topics::TRUTH)?
            .map(|t| t.properties);
    }
    let (mut out, boot) = match uncertainty {
        Uncertainty::Linearised => (
            rbprops_inertia::solve(&geometry, &modal, &selection, Some(frf), &opts)?,
            None,
        ),
        Uncertainty::Bootstrap(b) => {
            // Line variances and weights are made from the set's values: a record with
            // them must carry its set (`rb_solve_needs_the_set`).
            let given = crate::variance::for_bootstrap(rec)?;
            let mut b = b.clone();
            if b.fit_weighting.is_none() {
                b.fit_weighting = crate::variance::fit_weighting(rec)?.map(std::sync::Arc::new);
            }
            if b.scratch.is_none() {
                b.scratch = Some(crate::samples::bootstrap_scratch());
            }
            rbprops_uq::solve_with_bootstrap(
                &geometry,
                &modal,
                &selection,
                frf,
                &opts,
                &b,
                given.as_ref(),
            )?
        }
    };
    // A reference with a zero mass, centre of mass or inertia has no relative error:
    // omitted (with a warning), never written as a JSON null where a number belongs.
    let mut undefined = false;
    for e in &mut out.estimates {
        if let Some(r) = &e.errors {
            if ![r.mass, r.com, r.inertia, r.sum]
                .iter()
                .all(|x| x.is_finite())
            {
                e.errors = None;
                undefined = true;
            }
        }
    }
    if undefined {
        out.diagnostics.push(rbprops_core::records::Diagnostic::new(
            "rb-solve",
            rbprops_core::records::DiagnosticKind::ReferenceErrors,
            rbprops_core::records::Severity::Note,
            Default::default(),
            "the reference's mass, centre of mass (about the origin) or inertia is zero: relative errors are undefined and omitted",
        ));
    }
    rec.push_provenance(crate::provenance("rb-solve", input_sha256))?;
    rec.set::<InertiaEstimate>(topics::ESTIMATES, &out.estimates);
    // The solve's own diagnostics travel with the record, so a campaign, `rbprops report`
    // and a later reader see what rb-solve printed (an empty list writes no topic).
    if out.diagnostics.is_empty() {
        rec.remove(topics::SOLVE_DIAGNOSTICS);
    } else {
        rec.set(topics::SOLVE_DIAGNOSTICS, &out.diagnostics);
    }
    Ok((out, boot))
}
