//! Catalogue effects through another parametrisation ([`Reciprocal`]):
//! - `transducer_highpass` through 1/τ_j, one τ per sensor (the channels at a point).
//! - `record_truncation` through 1/T. Its signature (residues scaled by 1 − e^{λT},
//!   leakage ripple) vanishes faster than any power of 1/T at 1/T = 0, so no score test
//!   can see it: it is screened by a profile over T = 1/(kΔf), k = 1..8 (the DFT
//!   record of the recording's line spacing Δf, zero-padded k times), completed by the
//!   lags where the residual's lag transform rises or peaks ([`delay_peaks`]): any
//!   1/(8Δf) < T < 1/Δf, the refit then optimises 1/T continuously.
//! - `cord_mass` with one mass per length μ and one length ℓ for all cords. At first
//!   order in μ a massive cord is a point mass μℓ/3 at its attachment (absorbed by the
//!   free inertia); its visible part, the string modes `f_n = (n/2ℓ)√(T/μ)`, is
//!   non-analytic at μ = 0, so it too is screened by a profile over (μ, ℓ).

use super::{describe, Candidate, Screening};
use rbprops_core::Geometry;
use rbprops_sim::effects::cords::CordMass;
use rbprops_sim::effects::processing::RecordTruncation;
use rbprops_sim::effects::sensors::TransducerHighpass;
use rbprops_sim::effects::{BuildContext, Effect, OutputBlock, ParamInfo};
use rbprops_sim::model::DynamicModel;
use rbprops_sim::CampaignSpec;

/// A catalogue effect whose parameters (a time constant, a length) are neutral only at
/// infinity, fitted through their reciprocals: φ = 1/τ, with φ = 0 meaning "absent" (no
/// effect at all) and φ > 0 building the catalogue effect with τ = 1/φ.
pub struct Reciprocal {
    id: &'static str,
    infos: Vec<ParamInfo>,
    values: Vec<f64>,
    inner: Option<Box<dyn Effect>>,
    build: Build,
}

/// Builds the catalogue effect from the reciprocal parameters (`None`: absent).
type Build =
    std::sync::Arc<dyn Fn(&[f64]) -> Result<Option<Box<dyn Effect>>, String> + Send + Sync>;

impl std::fmt::Debug for Reciprocal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Reciprocal")
            .field("id", &self.id)
            .field("values", &self.values)
            .field("inner", &self.inner)
            .finish()
    }
}

/// The sensors of a geometry: the channels at each point, in first-channel order. The
/// channels of one sensor share its conditioner, so they share a high-pass.
fn sensors(g: &Geometry) -> Vec<(String, Vec<String>)> {
    let mut out: Vec<(String, Vec<String>)> = Vec::new();
    for c in &g.channels {
        match out.iter_mut().find(|(p, _)| *p == c.point) {
            Some((_, ids)) => ids.push(c.id.clone()),
            None => out.push((c.point.clone(), vec![c.id.clone()])),
        }
    }
    out
}

/// `transducer_highpass` with one time constant τ_j per sensor (the channels at one
/// point), through φ_j = 1/τ_j: mixed sensor types (an IEPE triaxial with τ = 1 s among
/// DC-coupled ones) are as common as one τ for all, which is the case φ_j all equal.
fn highpass_build(sensors: Vec<(String, Vec<String>)>) -> Build {
    std::sync::Arc::new(move |v: &[f64]| {
        if let Some(x) = v.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
            return Err(format!("1/τ must be finite and ≥ 0, got {x}"));
        }
        let mut per_channel = toml::Table::new();
        for ((_, channels), &phi) in sensors.iter().zip(v) {
            if phi > 0.0 {
                for c in channels {
                    per_channel.insert(c.clone(), (1.0 / phi).into());
                }
            }
        }
        if per_channel.is_empty() {
            return Ok(None);
        }
        let mut t = toml::Table::new();
        t.insert("time_constants_s".into(), per_channel.into());
        rbprops_sim::effects::parse_effect(&rbprops_sim::spec::EffectSpec {
            id: TransducerHighpass::ID.into(),
            parameters: t,
        })
        .map(Some)
    })
}

/// `record_truncation` through φ = 1/T (record length T).
fn truncation_build(v: &[f64]) -> Result<Option<Box<dyn Effect>>, String> {
    if v[0] < 0.0 || !v[0].is_finite() {
        return Err(format!("1/T must be finite and ≥ 0, got {}", v[0]));
    }
    if v[0] == 0.0 {
        return Ok(None);
    }
    let mut t = toml::Table::new();
    t.insert("record_length_s".into(), (1.0 / v[0]).into());
    rbprops_sim::effects::parse_effect(&rbprops_sim::spec::EffectSpec {
        id: RecordTruncation::ID.into(),
        parameters: t,
    })
    .map(Some)
}

/// The `cord_mass` entry with one mass per length μ (kg/m) and one length ℓ (m) for
/// every cord hanging along `up` (the spec's; the catalogue's defaults for the cord
/// modes: 8 per direction, 1 % damping).
fn cord_entry(mu: f64, l: f64, up: Option<[f64; 3]>) -> rbprops_sim::spec::EffectSpec {
    let mut t = toml::Table::new();
    if let Some(up) = up {
        t.insert("up".into(), rbprops_sim::spec::up_value(up));
    }
    t.insert(
        "mass_per_length_kg_per_m".into(),
        toml::Value::Array(vec![mu.into()]),
    );
    t.insert("cord_length_m".into(), toml::Value::Array(vec![l.into()]));
    rbprops_sim::spec::EffectSpec {
        id: CordMass::ID.into(),
        parameters: t,
    }
}

/// `cord_mass` through [`cord_entry`]; μ = 0 is "absent" whatever ℓ.
fn cord_build(v: &[f64], up: Option<[f64; 3]>) -> Result<Option<Box<dyn Effect>>, String> {
    if !(v[0] >= 0.0 && v[0].is_finite() && v[1] > 0.0 && v[1].is_finite()) {
        return Err(format!(
            "cord μ = {} kg/m, ℓ = {} m: need μ ≥ 0, ℓ > 0",
            v[0], v[1]
        ));
    }
    if v[0] == 0.0 {
        return Ok(None);
    }
    rbprops_sim::effects::parse_effect(&cord_entry(v[0], v[1], up)).map(Some)
}

/// Cord masses `m = μℓ` (kg) of the `cord_mass` profile, a factor 2.5 apart.
const CORD_MASSES_KG: [f64; 4] = [0.015, 0.04, 0.1, 0.25];

/// Ratio of neighbouring first string frequencies on the `cord_mass` profile: the
/// half-power width `2ζ` of a cord mode at the catalogue's ζ = 1 %, so that any string
/// mode is within half a width of a profile frequency.
const CORD_FREQUENCY_RATIO: f64 = 1.02;

/// Cord lengths ℓ (m) and masses per length μ (kg/m) the profile spans.
const CORD_LENGTHS_M: (f64, f64) = (0.2, 5.0);

const CORD_MASSES_PER_LENGTH: (f64, f64) = (0.005, 0.3);

/// Mean static tension T̄ (N) of the cords of every set-up with springs, for the spec's
/// body (the statics of rbprops-sim's `cord_mass`); `None` when it has no positive one.
fn mean_cord_tension(spec: &CampaignSpec) -> Option<f64> {
    let cm: rbprops_sim::effects::cords::CordMass =
        toml::Value::Table(cord_entry(1.0, 1.0, spec.up).parameters)
            .try_into()
            .ok()?;
    let props = spec.properties();
    let mut tensions = Vec::new();
    for (si, s) in spec.setups.iter().enumerate() {
        if !s.springs.is_empty() {
            let cords = cm.cords(spec, si, props.mass, &props.com).ok()?;
            tensions.extend(cords.iter().map(|c| c.tension));
        }
    }
    let t = tensions.iter().sum::<f64>() / tensions.len() as f64;
    (t > 0.0 && t.is_finite()).then_some(t)
}

/// The `cord_mass` profile over (μ, ℓ), laid out as cord mass `m = μℓ` × first string
/// frequency `f = (1/2ℓ)√(T̄/μ) = ½√(T̄/(mℓ))` at the mean tension T̄, i.e.
/// `ℓ = T̄/(4f²m)`, `μ = m/ℓ`: the string modes are narrow peaks, so the frequencies step
/// by [`CORD_FREQUENCY_RATIO`] from the band's start (or the longest cord) to 1.2× its
/// stop, while the cord mass, which only scales them, steps coarsely. Points outside
/// [`CORD_LENGTHS_M`] × [`CORD_MASSES_PER_LENGTH`] are left out.
fn cord_grid(tension: f64, start_hz: f64, stop_hz: f64) -> Vec<Vec<f64>> {
    let mut grid = Vec::new();
    for m in CORD_MASSES_KG {
        let length = |f: f64| tension / (4.0 * f * f * m);
        let f0 = start_hz.max(0.5 * (tension / (m * CORD_LENGTHS_M.1)).sqrt());
        let points = (0..)
            .map(|k| f0 * CORD_FREQUENCY_RATIO.powi(k))
            .take_while(|&f| f <= 1.2 * stop_hz && length(f) >= CORD_LENGTHS_M.0);
        for f in points {
            let (mu, l) = (m / length(f), length(f));
            if (CORD_MASSES_PER_LENGTH.0..=CORD_MASSES_PER_LENGTH.1).contains(&mu) {
                grid.push(vec![mu, l]);
            }
        }
    }
    grid
}

impl Effect for Reciprocal {
    fn id(&self) -> &'static str {
        self.id
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        self.infos.clone()
    }
    fn values(&self) -> Vec<f64> {
        self.values.clone()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        if values.len() != self.values.len() {
            return Err(format!(
                "{} expects {} values, got {}",
                self.id,
                self.values.len(),
                values.len()
            ));
        }
        if let Some((v, pi)) = values
            .iter()
            .zip(&self.infos)
            .find(|(v, pi)| !(v.is_finite() && **v >= pi.lower && **v <= pi.upper))
        {
            return Err(format!(
                "{}: {} = {v} outside [{}, {}]",
                self.id, pi.name, pi.lower, pi.upper
            ));
        }
        Ok(Box::new(Reciprocal {
            id: self.id,
            infos: self.infos.clone(),
            values: values.to_vec(),
            inner: (self.build)(values)?,
            build: self.build.clone(),
        }))
    }
    fn parameters_json(&self) -> serde_json::Value {
        match &self.inner {
            Some(e) => e.parameters_json(),
            None => serde_json::json!({}),
        }
    }
    fn order(&self) -> u8 {
        self.inner.as_ref().map_or(1, |e| e.order())
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        match &self.inner {
            Some(e) => e.modify_structure(ctx, model),
            None => Ok(()),
        }
    }
    fn modify_damping(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        match &self.inner {
            Some(e) => e.modify_damping(ctx, model),
            None => Ok(()),
        }
    }
    fn transform_output(&self, block: &mut OutputBlock) {
        if let Some(e) = &self.inner {
            e.transform_output(block);
        }
    }
}

/// The transducer high-pass reparametrised by inverse time constants (one per sensor), so
/// that its neutral value, no high-pass, is 0 rather than an infinite time constant.
pub(super) fn transducer_highpass_candidate(geometry: &Geometry) -> Candidate {
    let (title, reveal) = describe(TransducerHighpass::ID);
    let groups = sensors(geometry);
    let infos: Vec<ParamInfo> = groups
        .iter()
        .map(|(sensor, _)| ParamInfo {
            name: format!("inverse_time_constant_per_s.{sensor}"),
            unit: "1/s",
            lower: 0.0,
            upper: f64::INFINITY,
            plausible: (0.0, 2.0),
        })
        .collect();
    let n = infos.len();
    Candidate {
        id: TransducerHighpass::ID.into(),
        title: title.into(),
        effect: Box::new(Reciprocal {
            id: TransducerHighpass::ID,
            infos,
            values: vec![0.0; n],
            inner: None,
            build: highpass_build(groups),
        }),
        neutral: vec![0.0; n],
        scales: vec![0.05; n],
        source: "rbprops-sim (reparametrised for screening)",
        reveal,
        screening: Screening::Score,
        follows: None,
    }
}

/// Record truncation reparametrised by the inverse record length (neutral: 0, an endless
/// record) and screened by a profile over the record lengths zero padding can give.
pub(super) fn record_truncation_candidate(spec: &CampaignSpec) -> Candidate {
    let (title, reveal) = describe(RecordTruncation::ID);
    // The record length is 1/Δf of the recording's lines, or a fraction of it
    // when the records were zero-padded: T = 1/(kΔf), k = 1..8. The leakage
    // ripple's phase ωT makes χ² oscillate in T on a scale of 1/ω_max, so a
    // record padded by a non-integer factor (to a power of two) is off this grid
    // and outside the refit's reach from it: such a T is located by the lag scan
    // of the residual (`delay_scan`, [`delay_peaks`]) and added to the profile.
    let fr = &spec.frequency;
    let df = if fr.lines > 1 && fr.stop_hz > fr.start_hz {
        (fr.stop_hz - fr.start_hz) / (fr.lines - 1) as f64
    } else {
        1.0 / 16.0
    };
    let grid: Vec<Vec<f64>> = (1..=8).map(|k| vec![k as f64 * df]).collect();
    Candidate {
        id: RecordTruncation::ID.into(),
        title: title.into(),
        effect: Box::new(Reciprocal {
            id: RecordTruncation::ID,
            infos: vec![ParamInfo {
                name: "inverse_record_length_per_s".into(),
                unit: "1/s",
                lower: 0.0,
                upper: 10.0,
                plausible: (1.0 / 64.0, 0.25),
            }],
            values: vec![0.0],
            inner: None,
            build: std::sync::Arc::new(truncation_build),
        }),
        neutral: vec![0.0],
        scales: vec![0.005],
        source: "rbprops-sim (reparametrised for screening)",
        reveal,
        screening: Screening::Profile {
            grid,
            delay_scan: true,
        },
        follows: None,
    }
}

/// The cords' own mass (string modes of the suspension), screened by a profile over cord
/// mass and length; only when the spec has springs whose tension puts a plausible cord's
/// string mode in (or just above) the band, with a note when it has springs but no such cord.
pub(super) fn cord_mass_candidate(
    spec: &CampaignSpec,
    in_spec: &[&str],
    notes: &mut Vec<String>,
) -> Option<Candidate> {
    let has_springs = spec.setups.iter().any(|s| !s.springs.is_empty());
    let cord_profile = if in_spec.contains(&CordMass::ID) || !has_springs {
        Vec::new()
    } else {
        mean_cord_tension(spec)
            .map(|t| cord_grid(t, spec.frequency.start_hz, spec.frequency.stop_hz))
            .unwrap_or_default()
    };
    if !in_spec.contains(&CordMass::ID) && has_springs && cord_profile.is_empty() {
        notes.push("cord_mass is not screened: the springs hold no cord tension, or no cord of plausible length and mass has a string mode below 1.2× the band's top".into());
    }
    if cord_profile.is_empty() {
        return None;
    }
    let (title, reveal) = describe(CordMass::ID);
    let grid = cord_profile;
    Some(Candidate {
        id: CordMass::ID.into(),
        title: title.into(),
        effect: Box::new(Reciprocal {
            id: CordMass::ID,
            infos: vec![
                ParamInfo {
                    name: "mass_per_length_kg_per_m".into(),
                    unit: "kg/m",
                    lower: 0.0,
                    upper: 10.0,
                    plausible: (0.01, 0.15),
                },
                ParamInfo {
                    name: "cord_length_m".into(),
                    unit: "m",
                    lower: 0.05,
                    upper: 50.0,
                    plausible: (0.2, 5.0),
                },
            ],
            values: vec![0.0, 1.0],
            inner: None,
            build: {
                let up = spec.up;
                std::sync::Arc::new(move |v: &[f64]| cord_build(v, up))
            },
        }),
        neutral: vec![0.0, 1.0],
        // The parameters' own magnitudes, so the finite-difference step is 1e-7 of
        // μ and ℓ: the string modes make some FRF values (antiresonances, cross
        // terms near 0 Hz) 1e-9 of the largest, where the model's roundoff is ~1e-7
        // of the value, and a smaller step turns that into Jacobian noise.
        scales: vec![0.1, 1.0],
        source: "rbprops-sim (screened by a parameter profile)",
        reveal,
        screening: Screening::Profile {
            grid,
            delay_scan: false,
        },
        follows: None,
    })
}
