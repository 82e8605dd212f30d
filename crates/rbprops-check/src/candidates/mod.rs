//! Candidate effects for screening: rbprops-sim's physics catalogue, each effect at its
//! neutral ("absent") parameter values. An effect with a neutral table
//! ([`NeutralForm::Table`]) is screened in the catalogue's own form by a score test; the
//! others bring their screening form from their own module in rbprops-sim
//! ([`NeutralForm::Screened`]: gravity stiffness reparametrised, high-pass, record length
//! and cord mass through reciprocals, added mass through its non-rigid part, elastic
//! modes in their in-band form and as a residual flexibility).
//!
//! What stays here is the check's own reasoning: the notes on a spec whose vertical or
//! free directions are in doubt (`gravity`) and the residual's delay scan (`lag`).

mod gravity;
mod lag;

pub use gravity::{free_direction_note, vertical_axis_doubt};
pub use lag::delay_peaks;
/// How a candidate is screened (rbprops-sim's [`rbprops_sim::effects::screening::ScreeningKind`]).
pub use rbprops_sim::effects::screening::ScreeningKind as Screening;

use rbprops_core::Geometry;
use rbprops_sim::effects::screening::ScreeningForm;
use rbprops_sim::effects::{Effect, NeutralForm};
use rbprops_sim::CampaignSpec;

/// The catalogue entry of a candidate: what it is and how to reveal or separate it.
#[derive(Debug)]
pub struct Candidate {
    /// The effect's catalogue id (`{id}_k` for a further instance).
    pub id: String,
    /// One-line title for reports.
    pub title: String,
    /// The effect at its neutral parameter values.
    pub effect: Box<dyn Effect>,
    /// Parameter values at which the effect vanishes (the nominal model).
    pub neutral: Vec<f64>,
    /// Typical parameter magnitude (finite-difference step scale).
    pub scales: Vec<f64>,
    /// Where its form comes from: "rbprops-sim" for a neutral table, else its screening
    /// form's ([`ScreeningForm::source`]).
    pub source: &'static str,
    /// What measurement or side information would reveal it when the free parameters
    /// absorb it.
    pub reveal: &'static str,
    /// How it is screened at the current model.
    pub screening: Screening,
    /// A further instance of physics that can occur more than once (a second elastic
    /// mode): the id of the instance before it. It is screened only once that one has
    /// left the pool (accepted, or excluded as absorbed or ambiguous), so a recording that
    /// needs one such term is screened exactly as if there were no further instances.
    pub follows: Option<String>,
}

impl Candidate {
    /// Half of parameter `j`'s plausible range (∞ where the effect gives none): how far a
    /// coordinate can move as that physics, the scale of "resolvable" in screening and
    /// in the refit's freeing of dropped coordinates (docs/physics.md, M5).
    pub fn half_range(&self, j: usize) -> f64 {
        self.effect.parameters().get(j).map_or(f64::INFINITY, |i| {
            0.5 * (i.plausible.1 - i.plausible.0).abs()
        })
    }
}

/// Human title and "what would reveal or separate it" for a catalogue id (from
/// rbprops-sim's registry).
pub fn describe(id: &str) -> (&'static str, &'static str) {
    match rbprops_sim::effects::descriptor(id) {
        Some(d) => (d.title, d.reveal),
        None => ("catalogue effect", "side information on this effect"),
    }
}

/// The candidate list for a spec: rbprops-sim's catalogue
/// ([`rbprops_sim::effects::registry`]) at neutral parameter values, those with a neutral
/// table first in its order, then those with a screening form in theirs
/// ([`rbprops_sim::effects::screening::Screened::rank`]), then the further instances of
/// repeatable physics. Effects already switched on in the nominal spec are not
/// candidates. Also returns notes on catalogue effects that could not be screened.
pub fn candidates(spec: &CampaignSpec, geometry: &Geometry) -> (Vec<Candidate>, Vec<String>) {
    let mut out: Vec<Candidate> = Vec::new();
    let mut notes = Vec::new();
    let in_spec: Vec<&str> = spec.effects.iter().map(|e| e.id.as_str()).collect();
    catalogue_candidates(spec, geometry, &in_spec, &mut out, &mut notes);
    screened_candidates(spec, geometry, &in_spec, &mut out, &mut notes);
    let further: Vec<Candidate> = out
        .iter()
        .filter(|c| rbprops_sim::effects::descriptor(&c.id).is_some_and(|d| d.repeatable))
        .flat_map(|c| further_instances(c, FURTHER_INSTANCES))
        .collect();
    out.extend(further);
    (out, notes)
}

/// Further instances of each repeatable candidate
/// ([`rbprops_sim::effects::EffectDescriptor::repeatable`]: elastic modes and out-of-band
/// terms; several modes just above the band with different shapes are not one residual
/// flexibility, each needs its own pole) beyond the first. They open one at a
/// time ([`Candidate::follows`]); a recording that uses the last one is told so.
pub const FURTHER_INSTANCES: usize = 3;

/// Instances 2..=n+1 of `first`, named `{id}_2`, `{id}_3`, …, each following the one
/// before it, at the same neutral point and screened the same way.
fn further_instances(first: &Candidate, n: usize) -> Vec<Candidate> {
    let name = |k: usize| {
        if k == 1 {
            first.id.clone()
        } else {
            format!("{}_{k}", first.id)
        }
    };
    // A chain: an instance that cannot be built ends it (the next would follow nothing).
    (2..=n + 1)
        .map_while(|k| {
            let effect = first.effect.with_values(&first.neutral).ok()?;
            Some(Candidate {
                id: name(k),
                title: format!("{} (term {k})", first.title),
                effect,
                neutral: first.neutral.clone(),
                scales: first.scales.clone(),
                source: first.source,
                reveal: first.reveal,
                screening: first.screening.clone(),
                follows: Some(name(k - 1)),
            })
        })
        .collect()
}

/// The catalogue's effects with a neutral table, in its order, at their neutral values and
/// screened by a score; skipped when the spec switches them on, and noted when they have
/// no parameters.
fn catalogue_candidates(
    spec: &CampaignSpec,
    geometry: &Geometry,
    in_spec: &[&str],
    out: &mut Vec<Candidate>,
    notes: &mut Vec<String>,
) {
    for d in rbprops_sim::effects::registry() {
        let id = d.id;
        let NeutralForm::Table(build) = d.neutral else {
            continue;
        };
        if in_spec.contains(&id) {
            continue;
        }
        let parameters = build(spec, geometry);
        let entry = rbprops_sim::spec::EffectSpec {
            id: id.to_string(),
            parameters,
        };
        match rbprops_sim::effects::parse_effect(&entry) {
            Ok(e) if !e.values().is_empty() => {
                let neutral = e.values();
                let scales = e
                    .parameters()
                    .iter()
                    .map(|p| ((p.plausible.1 - p.plausible.0).abs() / 5.0).max(1e-9))
                    .collect();
                let (title, reveal) = describe(id);
                out.push(Candidate {
                    id: id.to_string(),
                    title: title.to_string(),
                    effect: e,
                    neutral,
                    scales,
                    source: "rbprops-sim",
                    reveal,
                    screening: Screening::Score,
                    follows: None,
                });
            }
            Ok(_) => notes.push(format!("catalogue effect '{id}' has no parameters to fit; not screened")),
            Err(problem) => notes.push(format!(
                "catalogue effect '{id}': no neutral form known to the model check ({problem}); not screened"
            )),
        }
    }
}

/// The catalogue's effects with a screening form, in the forms' order, each at its
/// neutral point; skipped when the spec switches them on or the form has nothing to
/// screen, and noted when the form says why it is not screened.
fn screened_candidates(
    spec: &CampaignSpec,
    geometry: &Geometry,
    in_spec: &[&str],
    out: &mut Vec<Candidate>,
    notes: &mut Vec<String>,
) {
    let mut screened: Vec<_> = rbprops_sim::effects::registry()
        .iter()
        .filter_map(|d| match d.neutral {
            NeutralForm::Screened(s) => Some((*d, s)),
            NeutralForm::Table(_) => None,
        })
        .collect();
    screened.sort_by_key(|(_, s)| s.rank);
    for (d, s) in screened {
        if in_spec.contains(&d.id) {
            continue;
        }
        match (s.form)(spec, geometry) {
            Ok(Some(form)) => out.push(Candidate {
                id: d.id.to_string(),
                title: d.title.to_string(),
                effect: form.effect,
                neutral: form.neutral,
                scales: form.scales,
                source: form.source,
                reveal: d.reveal,
                screening: form.screening,
                follows: None,
            }),
            Ok(None) => {}
            Err(note) => notes.push(note),
        }
    }
}

/// The spec entry of a fitted effect: its own [`Effect::spec_entry`], the catalogue's
/// form where the screening form has another parametrisation (`gravity_stiffness` →
/// `cord_length_m = [1/φ₁]`, `record_truncation` → `record_length_s = 1/φ`), else the
/// effect's parameters (the per-sensor high-pass writes its catalogue form,
/// `time_constants_s` per channel).
pub fn catalogue_entry(
    e: &dyn Effect,
    spec: &CampaignSpec,
) -> Result<rbprops_sim::spec::EffectSpec, String> {
    if rbprops_sim::effects::descriptor(e.id()).is_none() {
        return Err(format!(
            "rbprops-sim's catalogue has no '{}' (fitted parameters are in the report)",
            e.id()
        ));
    }
    e.spec_entry(spec)
}

/// The screening form of catalogue effect `id` for `spec` at `values` (for fixtures and
/// tests: the recording side of a concealed effect in its screening parametrisation).
pub fn screening_effect(
    id: &str,
    spec: &CampaignSpec,
    values: &[f64],
) -> Result<Box<dyn Effect>, String> {
    let g = spec.geometry().map_err(|e| e.to_string())?;
    let form: ScreeningForm = rbprops_sim::effects::screening_form(id, spec, &g)?
        .ok_or_else(|| format!("no screening form of '{id}' for this spec"))?;
    form.effect.with_values(values)
}
