//! Candidate effects for screening: rbprops-sim's physics catalogue, completed by local
//! implementations (of rbprops-sim's own [`Effect`] trait) for ids the catalogue does
//! not offer yet. Each candidate starts at its neutral ("absent") parameter values.
//!
//! The per-effect screening forms live in the submodules: `local` (effects the check
//! implements itself), `gravity`, `reciprocal` (catalogue effects through another
//! parametrisation), `non_rigid` (`added_mass`), and `lag` (the residual's delay scan).

use rbprops_sim::effects::elastic::ElasticMode;
use rbprops_sim::effects::gravity::GravityStiffness;
use rbprops_sim::effects::mass::AddedMass;
use rbprops_sim::effects::processing::RecordTruncation;
use rbprops_sim::effects::sensors::TransducerHighpass;
mod gravity;
mod lag;
mod local;
mod non_rigid;
mod reciprocal;

pub use gravity::{free_direction_note, vertical_axis_doubt};
pub use lag::delay_peaks;
pub use local::{local_effect, tilted_direction, LocalEffect};
pub use non_rigid::NonRigidMass;
pub use reciprocal::Reciprocal;

use gravity::hanging;
use local::{local_candidates, Kind, RESIDUAL_FLEXIBILITY_TEXT};
use non_rigid::added_mass_candidate;
use reciprocal::{cord_mass_candidate, record_truncation_candidate, transducer_highpass_candidate};

use rbprops_core::Geometry;
use rbprops_sim::effects::{Effect, NeutralForm};
use rbprops_sim::CampaignSpec;

/// The catalogue entry of a candidate: what it is and how to reveal or separate it.
#[derive(Debug)]
pub struct Candidate {
    /// The effect's id (the simulator's catalogue id, or a local one).
    pub id: String,
    /// One-line title for reports.
    pub title: String,
    /// The effect at its neutral parameter values.
    pub effect: Box<dyn Effect>,
    /// Parameter values at which the effect vanishes (the nominal model).
    pub neutral: Vec<f64>,
    /// Typical parameter magnitude (finite-difference step scale).
    pub scales: Vec<f64>,
    /// "rbprops-sim" or "rbprops-check (local)".
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

/// How a candidate is screened: its first-order evidence at the current model.
#[derive(Debug, Clone, PartialEq)]
pub enum Screening {
    /// Score (Lagrange-multiplier) test at the neutral point.
    Score,
    /// The signature vanishes to every order at the neutral point (a record length →
    /// ∞, a cord mass → 0 whose modes leave the band), so no score exists: a profile
    /// over these parameter points (linearised likelihood ratio with the current
    /// model's parameters re-adjusted). With `delay_scan`, a record length seen through
    /// φ = 1/T: the profile also tries the lags [`delay_peaks`] finds in the residual.
    Profile {
        /// Parameter points of the profile, each a full parameter vector of the candidate.
        grid: Vec<Vec<f64>>,
        /// Also try the lags the residual's delay scan finds (a record length via `φ = 1/T`).
        delay_scan: bool,
    },
    /// An in-band resonance ([`crate::resonance`]), bilinear in its shapes: the profile
    /// over (ω, ζ) of the linear residue fit to the residual proposes its points.
    Resonance,
}

/// Human title and "what would reveal or separate it" for a catalogue id (from
/// rbprops-sim's registry) or the local residual flexibility.
pub fn describe(id: &str) -> (&'static str, &'static str) {
    if let Some(d) = rbprops_sim::effects::descriptor(id) {
        return (d.title, d.reveal);
    }
    if id == Kind::ResidualFlexibility.id() {
        return RESIDUAL_FLEXIBILITY_TEXT;
    }
    ("catalogue effect", "side information on this effect")
}

/// The parameter table of a neutral ("absent") instance of a catalogue effect, from
/// rbprops-sim's registry; `None` for an id screened through a local reparametrised
/// form ([`NeutralForm::Reparametrised`]: `record_truncation` and `transducer_highpass`
/// through reciprocals, `cord_mass` by a profile, `gravity_stiffness`, `added_mass`,
/// `elastic_mode` as residual flexibility and an in-band resonance; module docs) or
/// unknown.
fn neutral_entry(id: &str, spec: &CampaignSpec, g: &Geometry) -> Option<toml::Table> {
    match rbprops_sim::effects::descriptor(id)?.neutral {
        NeutralForm::Table(build) => Some(build(spec, g)),
        NeutralForm::Reparametrised => None,
    }
}

/// Whether the model check screens a catalogue id through its own local form, because
/// the catalogue's parametrisation has no neutral point (see module docs).
fn reparametrised(id: &str) -> bool {
    rbprops_sim::effects::descriptor(id)
        .is_some_and(|d| matches!(d.neutral, NeutralForm::Reparametrised))
}

/// The candidate list for a spec: rbprops-sim's catalogue
/// ([`rbprops_sim::effects::registry`], in its order) at neutral parameter values, completed by
/// the local effects the catalogue does not offer (yet). Effects already switched on in
/// the nominal spec are not candidates. Also returns notes on catalogue effects that
/// could not be screened.
pub fn candidates(spec: &CampaignSpec, geometry: &Geometry) -> (Vec<Candidate>, Vec<String>) {
    let mut out: Vec<Candidate> = Vec::new();
    let mut notes = Vec::new();
    let in_spec: Vec<&str> = spec.effects.iter().map(|e| e.id.as_str()).collect();
    catalogue_candidates(spec, geometry, &in_spec, &mut out, &mut notes);
    local_candidates(spec, geometry, &in_spec, &mut out, &mut notes);
    if reparametrised(TransducerHighpass::ID) && !in_spec.contains(&TransducerHighpass::ID) {
        out.push(transducer_highpass_candidate(geometry));
    }
    if !in_spec.contains(&RecordTruncation::ID) {
        out.push(record_truncation_candidate(spec));
    }
    out.extend(cord_mass_candidate(spec, &in_spec, &mut notes));
    if !in_spec.contains(&AddedMass::ID) {
        out.push(added_mass_candidate());
    }
    if !in_spec.contains(&ElasticMode::ID) && !spec.channels().is_empty() {
        out.push(elastic_mode_candidate(spec));
    }
    let further: Vec<Candidate> = out
        .iter()
        .filter(|c| REPEATABLE.contains(&c.id.as_str()))
        .flat_map(|c| further_instances(c, FURTHER_INSTANCES))
        .collect();
    out.extend(further);
    (out, notes)
}

/// Physics a recording may hold more than once, each occurrence its own term: elastic
/// modes (a pole with its residues, in or above the band) and out-of-band terms (one
/// pole per excitation with a general residue matrix). Several modes just above the band
/// with different shapes are not one residual flexibility: each needs its own pole.
const REPEATABLE: [&str; 2] = [ElasticMode::ID, "residual_flexibility"];

/// Further instances of each repeatable candidate beyond the first. They open one at a
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

/// The catalogue's effects, in its order, at their neutral values and screened by a score;
/// skipped when the spec switches them on or the check reparametrises them, and noted when
/// they have no neutral form or no parameters.
fn catalogue_candidates(
    spec: &CampaignSpec,
    geometry: &Geometry,
    in_spec: &[&str],
    out: &mut Vec<Candidate>,
    notes: &mut Vec<String>,
) {
    for d in rbprops_sim::effects::registry() {
        let id = d.id;
        if in_spec.contains(&id) || reparametrised(id) {
            continue;
        }
        let Some(parameters) = neutral_entry(id, spec, geometry) else {
            notes.push(format!(
                "catalogue effect '{id}' is not screened: its parametrisation has no neutral (\"absent\") value the model check can start from"
            ));
            continue;
        };
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

/// An elastic mode in the band, in its in-band form (one pole, a residue per channel and
/// excitation), screened by the resonance search.
fn elastic_mode_candidate(spec: &CampaignSpec) -> Candidate {
    let (title, reveal) = describe(ElasticMode::ID);
    let e = crate::resonance::InBandResonance::neutral(spec);
    Candidate {
        id: ElasticMode::ID.into(),
        title: title.into(),
        neutral: e.values(),
        scales: e.scales(),
        effect: Box::new(e),
        source: "rbprops-sim (in-band form: one pole, a residue per channel and excitation; screened by a profile)",
        reveal,
        screening: Screening::Resonance,
        follows: None,
    }
}

/// The spec entry of a fitted effect: the catalogue's own form where one exists
/// (`gravity_stiffness` → `cord_length_m = [1/φ₁]`), else the effect's parameters (the
/// per-sensor high-pass writes its catalogue form, `time_constants_s` per channel). The
/// gravity entry gets `up`: the spec's vertical tilted by the fitted (φ₃, φ₄)
/// ([`tilted_direction`]) when they are not zero, else the spec's `up` if it gives one.
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
    if e.id() == RecordTruncation::ID
        && e.parameters()
            .first()
            .is_some_and(|p| p.name == "inverse_record_length_per_s")
    {
        let v = e.values();
        if !(v[0] > 0.0) {
            return Err("record_truncation: fitted 1/T is not positive".into());
        }
        let mut t = toml::Table::new();
        t.insert("record_length_s".into(), (1.0 / v[0]).into());
        return Ok(rbprops_sim::spec::EffectSpec {
            id: e.id().to_string(),
            parameters: t,
        });
    }
    let parameters = if e.id() == GravityStiffness::ID
        && e.parameters()
            .first()
            .is_some_and(|p| p.name == gravity::INVERSE_LENGTH)
    {
        let v = e.values();
        let names: Vec<String> = e.parameters().into_iter().map(|p| p.name).collect();
        let phi = gravity::GravityPhi::from_named(&names, &v);
        if !(phi.inverse_length > 0.0) {
            return Err("gravity_stiffness: fitted 1/ℓ is not positive".into());
        }
        let mut t = toml::Table::new();
        let (a, b) = phi.tilt;
        if let Some(i) = spec.setups.iter().position(|s| !s.cords.is_empty()) {
            // Hanging lengths scaled by ρ = (1/φ₁)/L̄, written as unstretched lengths
            // L₀ = ρL − T/k (tensions of the nominal body: the fitted mass moves T/k by
            // the same fraction, well below the length's standard error).
            let z = tilted_direction(&spec.up_vector(), a, b);
            let eq = hanging(spec, i, &spec.properties().mass_matrix().0, &z)?;
            let lbar = eq.lengths.iter().sum::<f64>() / eq.lengths.len() as f64;
            let rho = 1.0 / (phi.inverse_length * lbar);
            let l0: Vec<toml::Value> = spec
                .cords(i)
                .iter()
                .zip(eq.lengths.iter().zip(&eq.tensions))
                .map(|(c, (l, tn))| (rho * l - tn / c.axial_stiffness).into())
                .collect();
            t.insert("unstretched_length_m".into(), toml::Value::Array(l0));
            if spec.setups.len() > 1 {
                t.insert("setup".into(), spec.setups[i].id.clone().into());
            }
        } else {
            t.insert(
                "cord_length_m".into(),
                toml::Value::Array(vec![(1.0 / phi.inverse_length).into()]),
            );
            if let Some((i, l0)) = gravity::axial_free_lengths(spec, &phi)? {
                t.insert(
                    "unstretched_length_m".into(),
                    toml::Value::Array(l0.into_iter().map(toml::Value::from).collect()),
                );
                if spec.setups.len() > 1 {
                    t.insert("setup".into(), spec.setups[i].id.clone().into());
                }
            }
        }
        if a != 0.0 || b != 0.0 {
            let u = tilted_direction(&spec.up_vector(), a, b);
            t.insert("up".into(), rbprops_sim::spec::up_value([u.x, u.y, u.z]));
        } else if let Some(up) = spec.up {
            t.insert("up".into(), rbprops_sim::spec::up_value(up));
        }
        t
    } else {
        toml::Table::try_from(e.parameters_json())
            .map_err(|err| format!("effect '{}': parameters do not map to TOML: {err}", e.id()))?
    };
    Ok(rbprops_sim::spec::EffectSpec {
        id: e.id().to_string(),
        parameters,
    })
}
