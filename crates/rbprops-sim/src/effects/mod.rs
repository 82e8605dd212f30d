//! The physics catalogue: effects that modify the nominal model (see
//! docs/physics.md). Each effect is switched on in the spec as
//! `[[effect]] id = "..."` with its parameters. Each module lists the effects it
//! implements as `DESCRIPTORS` ([`EffectDescriptor`]: id, title, parse, neutral form,
//! docs line, example), and [`registry`] chains them: the spec validation
//! ([`parse_effect`]), the gravity direction ([`parse_effect_in`]), the effect examples
//! and the model check's candidates all read it, so an effect is added in its module
//! alone. Each effect is a plain struct deserialised from its spec table (unknown
//! parameters are refused) that implements [`Effect`].

pub mod cords;
pub mod damping;
pub mod elastic;
pub mod gains;
pub mod gravity;
pub mod mass;
pub mod mounts;
pub mod orientation;
pub mod placement;
pub mod processing;
pub mod screening;
pub mod sensors;

use crate::model::DynamicModel;
use crate::spec::{CampaignSpec, EffectSpec};
use rbprops_core::records::EffectRecord;
use rbprops_core::{c64, Geometry, RigidBodyProperties};

/// Description of one effect parameter, for fitters and for documentation.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamInfo {
    /// Parameter name as the spec writes it (`gains[1x]`, …).
    pub name: String,
    /// Unit of the parameter, e.g. `kg` or `N/m`.
    pub unit: &'static str,
    /// Hard bounds: values outside make the effect unphysical.
    pub lower: f64,
    /// Upper hard bound.
    pub upper: f64,
    /// Plausible range in real tests (for priors and starting values).
    pub plausible: (f64, f64),
}

/// What an effect may need to know about the campaign while it modifies a model.
pub struct BuildContext<'a> {
    /// The campaign spec.
    pub spec: &'a CampaignSpec,
    /// The body's true properties.
    pub properties: &'a RigidBodyProperties,
    /// The campaign's geometry.
    pub geometry: &'a Geometry,
    /// Index of the set-up whose model is being built.
    pub setup_index: usize,
}

/// One block of FRFs (all channels of one excitation, `[channel][line]`, receptance)
/// handed to [`Effect::transform_output`].
pub struct OutputBlock<'a> {
    /// The campaign's geometry (channel and excitation ids, in the block's order).
    pub geometry: &'a Geometry,
    /// Index of the excitation in the geometry.
    pub excitation: usize,
    /// Frequency of every line (Hz).
    pub frequency_hz: &'a [f64],
    /// Number of channels (`values` holds `n_channels × lines`).
    pub n_channels: usize,
    /// The FRFs, `[channel][line]` flattened, modified in place.
    pub values: &'a mut [c64],
}

/// An effect of the physics catalogue. Effects act in three places, in this order:
/// on the structure (M, K, outputs, inputs, extra modes) before the nominal damping is
/// assembled from the resulting modes; on the damping after it; and on the computed
/// receptance FRFs (before quantity conversion and noise). `transform_output` must act
/// as a per-line, per-channel gain (it then commutes with the quantity conversion): for
/// inputs observed through [`crate::observe`] it receives values already in the
/// campaign's quantity.
pub trait Effect: Send + Sync + std::fmt::Debug {
    /// Stable snake_case id, as written in the spec.
    fn id(&self) -> &'static str;
    /// The effect's numeric parameters with bounds, in [`Self::values`] order.
    fn parameters(&self) -> Vec<ParamInfo>;
    /// Current numeric parameter values.
    fn values(&self) -> Vec<f64>;
    /// The same effect with other numeric parameter values (for fitting).
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String>;
    /// The parameters as a JSON object, for `TruthRecord.effects`.
    fn parameters_json(&self) -> serde_json::Value;
    /// Checks the parameters on their own, without the campaign (finite, within their
    /// bounds, the lists they need given): what [`Self::with_values`] refuses.
    fn check_values(&self) -> Result<(), String> {
        Ok(())
    }
    /// Checks the parameters against the campaign (ids exist, counts match, bounds):
    /// [`Self::check_values`], and what the campaign must provide where the effect says so.
    fn check(&self, _spec: &CampaignSpec) -> Result<(), String> {
        self.check_values()
    }
    /// Effects apply in ascending order (stable in spec order): masses and the forces'
    /// points and directions (0) before everything else (1), so that gravity sees the
    /// loaded body and a gauge's mass or a stinger sits where its force acts; gravity in the sensor
    /// equation (2) last, so that it sees the final output rows; `cord_mass` (2) reduces
    /// the final M and K and reads the final rows and columns; `suspension_drift` (2)
    /// scales the stiffness built before it.
    fn order(&self) -> u8 {
        1
    }
    /// Changes the structure: M, K, output rows, input columns, extra modes.
    fn modify_structure(
        &self,
        _ctx: &BuildContext,
        _model: &mut DynamicModel,
    ) -> Result<(), String> {
        Ok(())
    }
    /// Changes the damping, after the nominal damping is assembled.
    fn modify_damping(&self, _ctx: &BuildContext, _model: &mut DynamicModel) -> Result<(), String> {
        Ok(())
    }
    /// Changes the computed FRFs of one excitation, as a per-line, per-channel gain.
    fn transform_output(&self, _block: &mut OutputBlock) {}
    /// Which FRFs each parameter ([`Self::values`] order) can change, for fitters that
    /// perturb parameters reaching disjoint FRFs in one evaluation. A declaration other
    /// than [`Reach::Any`] must hold whatever the other effects: it does for a parameter
    /// that acts only through what the simulator keeps per channel and excitation, the
    /// output row of channel c or the input of excitation e (every effect reads and
    /// writes rows and inputs one by one, and each input is solved on its own), a
    /// per-channel gain of [`Self::transform_output`] or an extra mode's
    /// `at_channels[c]` for a mode whose `at_excitations` is zero but at e (each FRF
    /// `H_ce` is assembled from its own channel's and excitation's terms). Default:
    /// every parameter `Any`.
    fn parameter_reach(&self, _geometry: &Geometry) -> Vec<Reach> {
        vec![Reach::Any; self.values().len()]
    }
    /// Its catalogue entry (`[[effect]]` table) in `spec`: by default its parameters as
    /// the spec writes them ([`Self::parameters_json`]). A screening form in another
    /// parametrisation ([`screening`]) writes the catalogue's own.
    fn spec_entry(&self, _spec: &CampaignSpec) -> Result<EffectSpec, String> {
        table_entry(self.id(), self.parameters_json())
    }
    /// Coordinates free only so that a score test sees the effect from its neutral
    /// point, each with the physical value it takes once the effect is in a model at
    /// these values (the gravity form's load-term factor, 1 once its cords have a
    /// length): a fitter that has accepted the effect holds them there, so the model it
    /// reports is the one [`Self::spec_entry`] writes. Indices in [`Self::values`] order.
    /// Default: none.
    fn physical_holds(&self) -> Vec<(usize, f64)> {
        Vec::new()
    }
    /// The effect as the truth records it: its id and parameters.
    fn record(&self) -> EffectRecord {
        EffectRecord {
            id: self.id().to_string(),
            parameters: self.parameters_json(),
        }
    }
}

/// The FRFs one effect parameter can change ([`Effect::parameter_reach`]); channel and
/// excitation indices are those of the geometry the effect is built with.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Reach {
    /// Any FRF (nothing narrower declared).
    Any,
    /// The FRFs of some channels, every excitation.
    Channels(Vec<usize>),
    /// The FRFs of one excitation, every channel.
    Excitation(usize),
    /// The one FRF of a channel and an excitation.
    Cell {
        /// Channel index.
        channel: usize,
        /// Excitation index.
        excitation: usize,
    },
}

impl Reach {
    /// Whether the FRF of channel `c` and excitation `e` is reached.
    pub fn reaches(&self, c: usize, e: usize) -> bool {
        match *self {
            Reach::Any => true,
            Reach::Channels(ref chs) => chs.contains(&c),
            Reach::Excitation(ex) => ex == e,
            Reach::Cell {
                channel,
                excitation,
            } => channel == c && excitation == e,
        }
    }
}

/// The reach of a map's parameters, `per` values per key in key order: the channels
/// whose `key` (their id, their sensor point) is that key.
pub(crate) fn channel_reach<'a>(
    keys: impl Iterator<Item = &'a String>,
    per: usize,
    geometry: &Geometry,
    key: impl Fn(&rbprops_core::geometry::Channel) -> &str,
) -> Vec<Reach> {
    keys.flat_map(|k| {
        let channels: Vec<usize> = (0..geometry.channels.len())
            .filter(|&c| key(&geometry.channels[c]) == k)
            .collect();
        std::iter::repeat_n(Reach::Channels(channels), per)
    })
    .collect()
}

/// The reach of a map's parameters keyed by excitation id, `per` values per key in key
/// order: that excitation's FRFs (its input column, attached mass and stiffness: each
/// input is solved on its own).
pub(crate) fn excitation_reach<'a>(
    keys: impl Iterator<Item = &'a String>,
    per: usize,
    geometry: &Geometry,
) -> Vec<Reach> {
    keys.flat_map(|k| {
        let mut at = (0..geometry.excitations.len()).filter(|&e| &geometry.excitations[e].id == k);
        let reach = match (at.next(), at.next()) {
            (Some(e), None) => Reach::Excitation(e),
            _ => Reach::Any,
        };
        std::iter::repeat_n(reach, per)
    })
    .collect()
}

/// The catalogue entry of effect `id` whose spec parameters are `json` (an object).
pub(crate) fn table_entry(id: &str, json: serde_json::Value) -> Result<EffectSpec, String> {
    let parameters = toml::Table::try_from(json)
        .map_err(|err| format!("effect '{id}': parameters do not map to TOML: {err}"))?;
    Ok(EffectSpec {
        id: id.to_string(),
        parameters,
    })
}

/// What the model check starts an effect's screening from (docs/physics.md, M5).
#[derive(Clone, Copy)]
pub enum NeutralForm {
    /// The spec parameter table of the effect switched on but absent (every gain 1,
    /// every added stiffness 0), for a spec and its geometry: a score test starts there.
    Table(fn(&CampaignSpec, &Geometry) -> toml::Table),
    /// The catalogue's parametrisation has no usable neutral point (a length or time
    /// constant absent only at infinity, a shape bilinear at zero), or the effect needs
    /// its own scales or profile: its module builds a screening form in another
    /// parametrisation ([`screening::Screened`]).
    Screened(screening::Screened),
}

/// The screening form of effect `id` for a spec and its geometry: its descriptor's
/// [`NeutralForm::Screened`] form (`Ok(None)`: nothing to screen, or the effect is
/// screened from its neutral table); unknown ids are an error.
pub fn screening_form(id: &str, spec: &CampaignSpec, g: &Geometry) -> screening::ScreeningResult {
    match descriptor(id).map(|d| d.neutral) {
        Some(NeutralForm::Screened(s)) => (s.form)(spec, g),
        Some(NeutralForm::Table(_)) => Ok(None),
        None => Err(format!("no effect '{id}'")),
    }
}

/// One effect of the physics catalogue: everything the crates need to know about it,
/// in one place (its module's `DESCRIPTORS`, chained by [`registry`]).
pub struct EffectDescriptor {
    /// Stable snake_case id, as written in the spec.
    pub id: &'static str,
    /// Place in the catalogue, in the order the effects were added: the registry, the
    /// error listing of known ids and the model check's candidates follow it (the
    /// check's determinism depends on that order). A new effect takes the next number.
    pub rank: u16,
    /// Human title (reports, listings).
    pub title: &'static str,
    /// What measurement or side information would reveal or separate it.
    pub reveal: &'static str,
    /// Its line in docs/physics.md ("Effect ids"): the catalogue entry (E*n*) and what
    /// the spec parameters are.
    pub docs: &'static str,
    /// Builds the effect from its spec table; the error says what is wrong.
    pub parse: fn(&EffectSpec) -> Result<Box<dyn Effect>, String>,
    /// Its neutral ("absent") form for screening.
    pub neutral: NeutralForm,
    /// Its physics depends on the direction of gravity: an entry without its own `up`
    /// takes the spec's ([`CampaignSpec::up`]).
    pub follows_spec_up: bool,
    /// Physics a recording may hold more than once, each occurrence its own term (elastic
    /// modes, a pole with its residues; out-of-band terms): the model check also screens
    /// further instances of it (`{id}_2`, …), each its own term.
    pub repeatable: bool,
    /// Its example campaign (`fixtures/specs/effects/<id>.toml`: test-case-2 with this
    /// effect alone and 1 % noise).
    pub example: &'static str,
    /// What a tester would judge physically plausible for it, as the quantities a tester
    /// reads (degrees of misorientation, millimetres of position, percent of gain, grams
    /// of mass), each with its range (docs/physics.md, "Plausible values"): a model check
    /// does not claim the effect with a fitted value outside. `None`: every value the
    /// effect accepts is plausible.
    pub plausible: Option<fn(&EffectSpec, &CampaignSpec) -> Result<Vec<Plausible>, String>>,
}

/// One physical quantity of a fitted effect and the range a tester would find plausible
/// ([`EffectDescriptor::plausible`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Plausible {
    /// What it is, with the item it belongs to (`sensor 2: angle`).
    pub quantity: String,
    /// Its unit as a tester reads it (`deg`, `mm`, `%`, `g`, `Hz`).
    pub unit: String,
    /// The fitted value in that unit.
    pub value: f64,
    /// The plausible range `[lower, upper]`, same unit.
    pub range: [f64; 2],
}

impl Plausible {
    /// A quantity `value` in `unit` with its plausible `range`.
    pub fn new(quantity: impl Into<String>, unit: &str, value: f64, range: [f64; 2]) -> Self {
        Plausible {
            quantity: quantity.into(),
            unit: unit.into(),
            value,
            range,
        }
    }
    /// The value lies in its range (a NaN does not).
    pub fn holds(&self) -> bool {
        self.value >= self.range[0] && self.value <= self.range[1]
    }
}

/// The plausibility of an effect given as a catalogue entry (its descriptor's
/// [`EffectDescriptor::plausible`]); empty when the effect has no ranges or is unknown.
pub fn plausibility(entry: &EffectSpec, spec: &CampaignSpec) -> Result<Vec<Plausible>, String> {
    match descriptor(&entry.id).and_then(|d| d.plausible) {
        Some(f) => f(entry, spec),
        None => Ok(Vec::new()),
    }
}

/// The angle (degrees) of each rotation vector of a per-item map, as plausibility items
/// `"<what> <id>: angle"` with the range `[0, max_deg]`.
pub(crate) fn angles_deg(
    what: &str,
    map: &std::collections::BTreeMap<String, [f64; 3]>,
    max_deg: f64,
) -> Vec<Plausible> {
    map.iter()
        .map(|(k, v)| {
            let a = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
                .sqrt()
                .to_degrees();
            Plausible::new(format!("{what} {k}: angle"), "deg", a, [0.0, max_deg])
        })
        .collect()
}

/// The length (mm) of each offset of a per-item map, with the range `[0, max_mm]`.
pub(crate) fn offsets_mm(
    what: &str,
    map: &std::collections::BTreeMap<String, [f64; 3]>,
    max_mm: f64,
) -> Vec<Plausible> {
    map.iter()
        .map(|(k, v)| {
            let d = 1e3 * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            Plausible::new(format!("{what} {k}: offset"), "mm", d, [0.0, max_mm])
        })
        .collect()
}

impl std::fmt::Debug for EffectDescriptor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EffectDescriptor")
            .field("id", &self.id)
            .field("rank", &self.rank)
            .finish_non_exhaustive()
    }
}

/// Every effect this version knows, in catalogue order ([`EffectDescriptor::rank`]):
/// the modules' descriptor lists chained.
pub fn registry() -> &'static [&'static EffectDescriptor] {
    static REGISTRY: std::sync::OnceLock<Vec<&'static EffectDescriptor>> =
        std::sync::OnceLock::new();
    REGISTRY.get_or_init(|| {
        let mut all: Vec<&'static EffectDescriptor> = [
            gravity::DESCRIPTORS,
            mass::DESCRIPTORS,
            gains::DESCRIPTORS,
            orientation::DESCRIPTORS,
            elastic::DESCRIPTORS,
            damping::DESCRIPTORS,
            processing::DESCRIPTORS,
            placement::DESCRIPTORS,
            sensors::DESCRIPTORS,
            mounts::DESCRIPTORS,
            cords::DESCRIPTORS,
        ]
        .into_iter()
        .flatten()
        .collect();
        all.sort_by_key(|d| d.rank);
        all
    })
}

/// The descriptor of an effect id.
pub fn descriptor(id: &str) -> Option<&'static EffectDescriptor> {
    registry().iter().copied().find(|d| d.id == id)
}

/// Ids of the effects this version knows, in catalogue order ([`registry`]).
pub static KNOWN_EFFECTS: std::sync::LazyLock<Vec<&'static str>> =
    std::sync::LazyLock::new(|| registry().iter().map(|d| d.id).collect());

/// The effects whose physics depends on the direction of gravity
/// ([`EffectDescriptor::follows_spec_up`]): an entry without its own `up` takes the
/// spec's ([`CampaignSpec::up`]).
pub static GRAVITY_EFFECTS: std::sync::LazyLock<Vec<&'static str>> =
    std::sync::LazyLock::new(|| {
        registry()
            .iter()
            .filter(|d| d.follows_spec_up)
            .map(|d| d.id)
            .collect()
    });

/// Serde default of `g_m_per_s2` for the gravity-related effects (standard gravity).
pub(crate) fn default_g() -> f64 {
    gravity::STANDARD_GRAVITY
}

/// Serde default of `up`: the geometry's +z axis points up.
pub(crate) fn default_up() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// Parameter descriptions of a per-spring (or per-cord) list `name[i]`.
pub(crate) fn list_info(
    name: &str,
    unit: &'static str,
    n: usize,
    plausible: (f64, f64),
) -> Vec<ParamInfo> {
    (0..n)
        .map(|i| positive_info(format!("{name}[{i}]"), unit, plausible))
        .collect()
}

/// Parameter descriptions of a per-id map parameter, `name.{id}` in key order.
pub(crate) fn map_info(
    name: &str,
    map: &std::collections::BTreeMap<String, f64>,
    unit: &'static str,
    plausible: (f64, f64),
) -> Vec<ParamInfo> {
    map.keys()
        .map(|k| positive_info(format!("{name}.{k}"), unit, plausible))
        .collect()
}

/// Description of a parameter that is positive (bounded below by 0, unbounded above).
pub(crate) fn positive_info(name: String, unit: &'static str, plausible: (f64, f64)) -> ParamInfo {
    ParamInfo {
        name,
        unit,
        lower: 0.0,
        upper: f64::INFINITY,
        plausible,
    }
}

/// Description of a parameter without hard bounds (a mode shape value, a coupling).
pub(crate) fn unbounded_info(name: String, unit: &'static str, plausible: (f64, f64)) -> ParamInfo {
    ParamInfo {
        name,
        unit,
        lower: f64::NEG_INFINITY,
        upper: f64::INFINITY,
        plausible,
    }
}

/// Description of a signed parameter within `±bound`, plausible within `±plausible`.
pub(crate) fn symmetric_info(
    name: String,
    unit: &'static str,
    bound: f64,
    plausible: f64,
) -> ParamInfo {
    ParamInfo {
        name,
        unit,
        lower: -bound,
        upper: bound,
        plausible: (-plausible, plausible),
    }
}

/// What the ids of a per-id parameter name in the campaign.
#[derive(Clone, Copy, Debug)]
pub(crate) enum IdKind {
    /// A sensor of the spec.
    Sensor,
    /// An excitation of the spec.
    Excitation,
}

impl IdKind {
    /// Checks that the ids of the parameter `field` name this kind of item of the spec.
    fn check_defined<'a>(
        self,
        spec: &CampaignSpec,
        field: &str,
        ids: impl IntoIterator<Item = &'a String>,
    ) -> Result<(), String> {
        match self {
            IdKind::Sensor => check_sensors_defined(spec, field, ids),
            IdKind::Excitation => check_excitations_defined(spec, field, ids),
        }
    }
}

/// A per-id map of 3-vectors as an effect's parameter (offsets, rotation vectors): its
/// spec name, unit, hard bound on each vector's norm, plausible size of a component and
/// what its ids name.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Vec3MapParam {
    /// Parameter name as the spec writes it.
    pub name: &'static str,
    /// Unit of every component.
    pub unit: &'static str,
    /// Largest norm accepted (and hard bound of every component).
    pub bound: f64,
    /// Plausible size of a component in real tests.
    pub plausible: f64,
    /// What the map's ids name.
    pub ids: IdKind,
}

impl Vec3MapParam {
    /// Parameter descriptions, `name.{id}.{x,y,z}` in key order.
    pub(crate) fn info(
        &self,
        map: &std::collections::BTreeMap<String, [f64; 3]>,
    ) -> Vec<ParamInfo> {
        map.keys()
            .flat_map(|k| {
                ["x", "y", "z"].map(|a| {
                    symmetric_info(
                        format!("{}.{k}.{a}", self.name),
                        self.unit,
                        self.bound,
                        self.plausible,
                    )
                })
            })
            .collect()
    }
    /// The values, three per id in key order ([`Self::info`] order).
    pub(crate) fn values(&self, map: &std::collections::BTreeMap<String, [f64; 3]>) -> Vec<f64> {
        map.values().flatten().copied().collect()
    }
    /// Checks the map on its own: one entry at least, every vector finite and within the
    /// bound.
    pub(crate) fn check_values(
        &self,
        map: &std::collections::BTreeMap<String, [f64; 3]>,
    ) -> Result<(), String> {
        let (name, bound) = (self.name, self.bound);
        if map.is_empty() {
            return Err(format!("{name}: list at least one entry"));
        }
        for (k, v) in map {
            if v.iter().any(|x| !x.is_finite()) || rbprops_core::Vec3::from(*v).norm() > bound {
                return Err(format!(
                    "{name}.{k}: need a finite vector of norm at most {bound}, got {v:?}"
                ));
            }
        }
        Ok(())
    }
    /// Checks that the map's ids name items of the spec.
    pub(crate) fn check_ids(
        &self,
        spec: &CampaignSpec,
        map: &std::collections::BTreeMap<String, [f64; 3]>,
    ) -> Result<(), String> {
        self.ids.check_defined(spec, self.name, map.keys())
    }
}

/// Parameter descriptions of a positive value common to every id (`common`, when given)
/// followed by its per-id overrides (`map_name.{id}` in key order).
pub(crate) fn common_and_map_info(
    common_name: &str,
    common: Option<f64>,
    map_name: &str,
    map: &std::collections::BTreeMap<String, f64>,
    unit: &'static str,
    plausible: (f64, f64),
) -> Vec<ParamInfo> {
    let mut v: Vec<ParamInfo> = common
        .map(|_| positive_info(common_name.to_string(), unit, plausible))
        .into_iter()
        .collect();
    v.extend(map_info(map_name, map, unit, plausible));
    v
}

/// The values of a value common to every id (when given) followed by its per-id map, in
/// [`common_and_map_info`] order.
pub(crate) fn common_and_map_values(
    common: Option<f64>,
    map: &std::collections::BTreeMap<String, f64>,
) -> Vec<f64> {
    common.iter().chain(map.values()).copied().collect()
}

/// The effect a fitter's new values make ([`Effect::with_values`]), once they pass
/// [`Effect::check_values`].
pub(crate) fn checked<E: Effect + 'static>(effect: E) -> Result<Box<dyn Effect>, String> {
    effect.check_values()?;
    Ok(Box::new(effect))
}

/// `values` (a fitter's new values, in key order) as a replacement of a per-id map.
pub(crate) fn replace_map(
    map: &std::collections::BTreeMap<String, f64>,
    values: &[f64],
) -> Result<std::collections::BTreeMap<String, f64>, String> {
    if values.len() != map.len() {
        return Err(format!(
            "expected {} values, got {}",
            map.len(),
            values.len()
        ));
    }
    Ok(map.keys().cloned().zip(values.iter().copied()).collect())
}

/// `values` as a replacement of an optional value for every id followed by a per-id map
/// (a fitter's new values for an effect with both, in that order).
pub(crate) fn replace_common_and_map(
    common: Option<f64>,
    map: &std::collections::BTreeMap<String, f64>,
    values: &[f64],
) -> Result<(Option<f64>, std::collections::BTreeMap<String, f64>), String> {
    let (common_value, per_id) = split_values(values, usize::from(common.is_some()), map.len())?;
    Ok((common_value.first().copied(), replace_map(map, per_id)?))
}

/// `values` (three per id, in key order) as a replacement of a per-id map of 3-vectors.
pub(crate) fn replace_vec3_map(
    map: &std::collections::BTreeMap<String, [f64; 3]>,
    values: &[f64],
) -> Result<std::collections::BTreeMap<String, [f64; 3]>, String> {
    if values.len() != 3 * map.len() {
        return Err(format!(
            "expected {} values, got {}",
            3 * map.len(),
            values.len()
        ));
    }
    Ok(map
        .keys()
        .zip(values.chunks_exact(3))
        .map(|(k, v)| (k.clone(), [v[0], v[1], v[2]]))
        .collect())
}

/// `values` split into two concatenated lists of lengths `na` and `nb` (a fitter's new
/// values for an effect with two parameter lists).
pub(crate) fn split_values(
    values: &[f64],
    na: usize,
    nb: usize,
) -> Result<(&[f64], &[f64]), String> {
    if values.len() != na + nb {
        return Err(format!("expected {} values, got {}", na + nb, values.len()));
    }
    Ok(values.split_at(na))
}

/// `values` as the new value of a one-parameter effect (a fitter's new values).
pub(crate) fn single_value(values: &[f64]) -> Result<f64, String> {
    match values {
        [v] => Ok(*v),
        _ => Err(format!("expected 1 value, got {}", values.len())),
    }
}

/// `values` as a replacement of a list parameter of length `n` (a fitter's new values).
pub(crate) fn replace_list(n: usize, values: &[f64]) -> Result<Vec<f64>, String> {
    if values.len() != n {
        return Err(format!("expected {n} values, got {}", values.len()));
    }
    Ok(values.to_vec())
}

/// A per-id map parameter with one value for every id (a neutral table's entry).
pub(crate) fn per_id(ids: impl IntoIterator<Item = String>, value: toml::Value) -> toml::Value {
    toml::Value::Table(ids.into_iter().map(|k| (k, value.clone())).collect())
}

/// The zero 3-vector of a neutral table.
pub(crate) fn zero3_value() -> toml::Value {
    toml::Value::Array(vec![0.0.into(), 0.0.into(), 0.0.into()])
}

/// The channel ids of a geometry, in its order.
pub(crate) fn channel_ids(g: &Geometry) -> Vec<String> {
    g.channels.iter().map(|c| c.id.clone()).collect()
}

/// The excitation ids of a geometry, in its order.
pub(crate) fn excitation_ids(g: &Geometry) -> Vec<String> {
    g.excitations.iter().map(|e| e.id.clone()).collect()
}

/// The sensor ids of a spec, in its order.
pub(crate) fn sensor_ids(spec: &CampaignSpec) -> Vec<String> {
    spec.sensors.iter().map(|s| s.id.clone()).collect()
}

/// A neutral table of one per-sensor parameter `name`, `value` for every sensor.
pub(crate) fn per_sensor_table(spec: &CampaignSpec, name: &str, value: toml::Value) -> toml::Table {
    table([(name, per_id(sensor_ids(spec), value))])
}

/// A neutral table of one per-channel parameter `name`, `value` for every channel.
pub(crate) fn per_channel_table(g: &Geometry, name: &str, value: toml::Value) -> toml::Table {
    table([(name, per_id(channel_ids(g), value))])
}

/// A neutral table of one per-excitation parameter `name`, `value` for every excitation.
pub(crate) fn per_excitation_table(g: &Geometry, name: &str, value: toml::Value) -> toml::Table {
    table([(name, per_id(excitation_ids(g), value))])
}

/// A parameter table from its entries.
pub(crate) fn table<const N: usize>(entries: [(&str, toml::Value); N]) -> toml::Table {
    entries
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect()
}

/// Checks that every value of the per-id map `field` is finite and non-negative (a
/// stiffness, a mass).
pub(crate) fn check_non_negative_map(
    field: &str,
    map: &std::collections::BTreeMap<String, f64>,
) -> Result<(), String> {
    match map.iter().find(|(_, v)| !(v.is_finite() && **v >= 0.0)) {
        Some((k, v)) => Err(format!("{field}.{k}: must be finite and ≥ 0, got {v}")),
        None => Ok(()),
    }
}

/// Checks that `v` (the parameter `field`) is a unit vector.
pub(crate) fn check_unit_vector(field: &str, v: [f64; 3]) -> Result<(), String> {
    let n = rbprops_core::Vec3::from(v).norm();
    if !n.is_finite() || (n - 1.0).abs() > 1e-6 {
        return Err(format!("{field}: not a unit vector (|d| = {n:.6})"));
    }
    Ok(())
}

/// Checks that every id of the parameter `field` names a `kind` (sensor, channel,
/// excitation) of `defined`; the first one that does not (in `ids` order) is the error.
fn check_defined<'a>(
    field: &str,
    kind: &str,
    ids: impl IntoIterator<Item = &'a String>,
    defined: &[&str],
) -> Result<(), String> {
    match ids.into_iter().find(|k| !defined.contains(&k.as_str())) {
        Some(k) => Err(format!("{field}: {kind} '{k}' is not defined")),
        None => Ok(()),
    }
}

/// Checks that the ids of the parameter `field` are sensors of the spec.
pub(crate) fn check_sensors_defined<'a>(
    spec: &CampaignSpec,
    field: &str,
    ids: impl IntoIterator<Item = &'a String>,
) -> Result<(), String> {
    let defined: Vec<&str> = spec.sensors.iter().map(|s| s.id.as_str()).collect();
    check_defined(field, "sensor", ids, &defined)
}

/// Checks that the ids of the parameter `field` are channels of the spec.
pub(crate) fn check_channels_defined<'a>(
    spec: &CampaignSpec,
    field: &str,
    ids: impl IntoIterator<Item = &'a String>,
) -> Result<(), String> {
    let channels = spec.channels();
    let defined: Vec<&str> = channels.iter().map(|c| c.id.as_str()).collect();
    check_defined(field, "channel", ids, &defined)
}

/// Checks that the ids of the parameter `field` are excitations of the spec.
pub(crate) fn check_excitations_defined<'a>(
    spec: &CampaignSpec,
    field: &str,
    ids: impl IntoIterator<Item = &'a String>,
) -> Result<(), String> {
    let defined: Vec<&str> = spec.excitations.iter().map(|e| e.id.as_str()).collect();
    check_defined(field, "excitation", ids, &defined)
}

/// Whether an effect limited to an optional set-up acts in set-up `setup` (all set-ups
/// when it names none).
pub(crate) fn acts_in_setup(only: Option<&str>, setup: &str) -> bool {
    only.is_none_or(|id| id == setup)
}

/// Checks that an optional set-up id names a set-up of the spec.
pub(crate) fn check_setup(spec: &CampaignSpec, setup: Option<&str>) -> Result<(), String> {
    match setup {
        Some(id) if !spec.setups.iter().any(|s| s.id == id) => {
            Err(format!("setup: set-up '{id}' is not defined"))
        }
        _ => Ok(()),
    }
}

pub(crate) fn params<T: serde::de::DeserializeOwned>(spec: &EffectSpec) -> Result<T, String> {
    toml::Value::Table(spec.parameters.clone())
        .try_into()
        .map_err(|e| format!("effect '{}': {}", spec.id, e.to_string().trim()))
}

/// [`EffectDescriptor::parse`] of an effect that is its spec table deserialised.
pub(crate) fn parse_as<T>(spec: &EffectSpec) -> Result<Box<dyn Effect>, String>
where
    T: serde::de::DeserializeOwned + Effect + 'static,
{
    Ok(Box::new(params::<T>(spec)?))
}

/// Builds an effect from its spec entry ([`EffectDescriptor::parse`]); the error says
/// what is wrong.
pub fn parse_effect(spec: &EffectSpec) -> Result<Box<dyn Effect>, String> {
    match descriptor(&spec.id) {
        Some(d) => (d.parse)(spec),
        None => Err(format!(
            "unknown effect id '{}' (known: {})",
            spec.id,
            KNOWN_EFFECTS.join(", ")
        )),
    }
}

/// Builds an effect from its entry in `spec`: [`parse_effect`], with the spec's `up` as
/// the default `up` of a gravity effect.
pub fn parse_effect_in(entry: &EffectSpec, spec: &CampaignSpec) -> Result<Box<dyn Effect>, String> {
    match spec.up {
        Some(up)
            if descriptor(&entry.id).is_some_and(|d| d.follows_spec_up)
                && !entry.parameters.contains_key("up") =>
        {
            let mut e = entry.clone();
            e.parameters.insert("up".into(), crate::spec::up_value(up));
            parse_effect(&e)
        }
        _ => parse_effect(entry),
    }
}

/// Parses and orders a spec's effects ([`Effect::order`], then spec order).
pub fn parse_effects(spec: &CampaignSpec) -> Result<Vec<Box<dyn Effect>>, (usize, String)> {
    let mut v = Vec::with_capacity(spec.effects.len());
    for (i, e) in spec.effects.iter().enumerate() {
        let eff = parse_effect_in(e, spec).map_err(|p| (i, p))?;
        eff.check(spec).map_err(|p| (i, p))?;
        v.push(eff);
    }
    v.sort_by_key(|e| e.order());
    Ok(v)
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    /// A fitter's values go to the common value first (when there is one), then to the map
    /// in key order; a wrong count is refused with the count expected.
    #[test]
    fn common_value_then_map_in_key_order() {
        let map: BTreeMap<String, f64> = [("b".into(), 1.0), ("a".into(), 2.0)].into();
        let (common, new) = super::replace_common_and_map(Some(9.0), &map, &[3.0, 4.0, 5.0])
            .expect("three values for a common value and two ids");
        assert_eq!(common, Some(3.0));
        assert_eq!(new, [("a".into(), 4.0), ("b".into(), 5.0)].into());
        let (common, new) = super::replace_common_and_map(None, &map, &[6.0, 7.0]).unwrap();
        assert_eq!((common, new["a"], new["b"]), (None, 6.0, 7.0));
        assert_eq!(
            super::replace_common_and_map(None, &map, &[1.0; 3]),
            Err("expected 2 values, got 3".into())
        );
    }

    /// A one-parameter effect takes exactly one value.
    #[test]
    fn single_value_takes_exactly_one() {
        assert_eq!(super::single_value(&[2.5]), Ok(2.5));
        assert_eq!(
            super::single_value(&[]),
            Err("expected 1 value, got 0".into())
        );
        assert_eq!(
            super::single_value(&[1.0, 2.0]),
            Err("expected 1 value, got 2".into())
        );
    }
}
