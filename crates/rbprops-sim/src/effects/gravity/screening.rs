//! `gravity_stiffness`'s screening form ([`GravityForm`]): rbprops-sim's cord geometric
//! stiffness (every spring read as a vertical cord of length ℓ) reparametrised so that
//! "absent" is a point of the parameter space: `K(φ) = φ₁·lateral(ℓ = 1) + φ₂·load
//! term`, φ₁ = 1/ℓ (1/m), φ₂ the load-term factor (physical value 1). The catalogue's own
//! parameter (ℓ, with ℓ → ∞ still leaving the load term) has no neutral value, so a score
//! test needs this form. Two tilts of the vertical and φ₅, the fraction by which springs
//! (rather than cords) turn with the sagged body, complete it, and for cords written as
//! axial springs the pose contrasts of their free lengths (see [`gravity_stiffness`]).
//! All are neutral at 0. Where the nominal model leaves rigid directions free, gravity
//! turns them into in-band pendulum resonances, far from linear in φ at φ = 0, and the
//! form is screened by a profile over cord lengths ([`gravity_profile`]).

use crate::effects::screening::{ScreeningForm, ScreeningKind, ScreeningResult};
use crate::effects::{BuildContext, Effect, ParamInfo};
use crate::model::DynamicModel;
use crate::spec::EffectSpec;
use crate::CampaignSpec;
use rbprops_core::{Geometry, Mat6, Vec3};

/// `gravity_stiffness` in its screening parametrisation (see the module docs).
#[derive(Debug, Clone)]
pub struct GravityForm {
    names: Vec<String>,
    values: Vec<f64>,
    /// Where each set-up's cord-length contrasts sit among the contrasts (see
    /// [`gravity_stiffness`]).
    slots: Vec<ContrastSlot>,
}

impl GravityForm {
    /// The neutral form (every φ 0) for a spec and its geometry.
    pub fn neutral(spec: &CampaignSpec, g: &Geometry) -> GravityForm {
        let (names, slots) = gravity_names(spec, g);
        GravityForm {
            values: vec![0.0; names.len()],
            names,
            slots,
        }
    }

    fn info(&self, i: usize) -> ParamInfo {
        let (unit, lo, hi, pl) = match i {
            0 => ("1/m", 0.0, 100.0, (0.2, 10.0)),
            1 => ("1", 0.0, 3.0, (0.5, 1.5)),
            // 0: the springs' stiffness stays along the spec's axes (cords); 1: it turns
            // with the sagged body (linear springs to the ground). Bounds wide enough
            // that neither end is pinned.
            _ if self.names[i] == SPRING_TURN => ("1", -2.0, 3.0, (-0.5, 1.5)),
            // Cord-length contrasts: a tester measures cords to a few centimetres.
            _ if self.names[i].contains(CONTRAST) => ("m", -0.5, 0.5, (-0.1, 0.1)),
            _ => ("rad", -0.5, 0.5, (-0.1, 0.1)),
        };
        ParamInfo {
            name: self.names[i].clone(),
            unit,
            lower: lo,
            upper: hi,
            plausible: pl,
        }
    }

    /// Finite-difference scales, in [`Effect::values`] order.
    pub fn scales(&self) -> Vec<f64> {
        (0..self.values.len())
            .map(|i| {
                if i < 2 || self.names[i] == SPRING_TURN {
                    1.0
                } else {
                    0.01
                }
            })
            .collect()
    }
}

/// The unit direction `d` tilted by the angles (a, b) about two axes perpendicular to
/// it: `normalize(d + a e₁ + b e₂)`, with e₁ = normalize(d × h), h the axis x unless d
/// is nearly along it (then y), and e₂ = d × e₁. The vertical of the gravity candidate
/// (a frame off by a few degrees, E15.4) is tilted so.
pub fn tilted_direction(d: &Vec3, a: f64, b: f64) -> Vec3 {
    let helper = if d.x.abs() < 0.9 {
        Vec3::x()
    } else {
        Vec3::y()
    };
    let e1 = d.cross(&helper).normalize();
    let e2 = d.cross(&e1);
    (d + e1 * a + e2 * b).normalize()
}

/// The rigid-body directions the nominal model of `spec` leaves free (zero-frequency
/// modes), per set-up: (set-up id, count); empty when there are none or the nominal
/// model cannot be built.
pub fn nominal_free_directions(spec: &CampaignSpec, g: &Geometry) -> Vec<(String, usize)> {
    let Ok(effects) = crate::effects::parse_effects(spec) else {
        return Vec::new();
    };
    match crate::build_models(spec, g, &effects) {
        Ok(models) => crate::free_directions(&models),
        Err(_) => Vec::new(),
    }
}

impl Effect for GravityForm {
    fn id(&self) -> &'static str {
        super::GravityStiffness::ID
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        (0..self.values.len()).map(|i| self.info(i)).collect()
    }
    fn values(&self) -> Vec<f64> {
        self.values.clone()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        if values.len() != self.values.len() {
            return Err(format!(
                "{} expects {} parameters, got {}",
                self.id(),
                self.values.len(),
                values.len()
            ));
        }
        if let Some(v) = values.iter().find(|v| !v.is_finite()) {
            return Err(format!("{}: parameter {v} is not finite", self.id()));
        }
        let mut e = self.clone();
        e.values = values.to_vec();
        Ok(Box::new(e))
    }
    fn parameters_json(&self) -> serde_json::Value {
        serde_json::Value::Object(
            self.names
                .iter()
                .zip(&self.values)
                .map(|(n, v)| (n.clone(), serde_json::json!(v)))
                .collect(),
        )
    }
    /// The catalogue's own form: `cord_length_m = [1/φ₁]`, or for a set-up with cords
    /// their unstretched lengths scaled by ρ = (1/φ₁)/L̄; `up` the spec's vertical tilted
    /// by the fitted (φ₃, φ₄) ([`tilted_direction`]) when they are not zero, else the
    /// spec's `up` if it gives one.
    fn spec_entry(&self, spec: &CampaignSpec) -> Result<EffectSpec, String> {
        let phi = GravityPhi::from_named(&self.names, &self.values);
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
            if phi.turn != 0.0 {
                t.insert("spring_turn_fraction".into(), phi.turn.into());
            }
            if let Some((i, l0)) = axial_free_lengths(spec, &phi)? {
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
            t.insert("up".into(), crate::spec::up_value([u.x, u.y, u.z]));
        } else if let Some(up) = spec.up {
            t.insert("up".into(), crate::spec::up_value(up));
        }
        Ok(EffectSpec {
            id: self.id().to_string(),
            parameters: t,
        })
    }
    /// φ₂ = 1 once 1/ℓ > 0: the load term is free at φ = 0 only so that the score test
    /// sees gravity's moment before any cord length is fitted; with cords in the model
    /// a factor other than 1 is no physics the catalogue (or [`Self::spec_entry`],
    /// which writes cord lengths only) can state, and left free it takes up what
    /// another effect should explain.
    fn physical_holds(&self) -> Vec<(usize, f64)> {
        let phi = GravityPhi::from_named(&self.names, &self.values);
        match self.names.iter().position(|n| n == LOAD_FACTOR) {
            Some(i) if phi.inverse_length > 0.0 => vec![(i, 1.0)],
            _ => Vec::new(),
        }
    }
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        let phi = GravityPhi::from_named(&self.names, &self.values);
        model.stiffness += gravity_stiffness(ctx, model, &phi, &self.slots)?;
        model.stiffness = (model.stiffness + model.stiffness.transpose()) * 0.5;
        Ok(())
    }
}

/// `gravity_stiffness`'s screening form ([`super::DESCRIPTORS`]): [`GravityForm`] at
/// φ = 0, screened by a score, or by a cord-length profile ([`gravity_profile`]) when the
/// nominal model has free directions (there gravity turns zero-frequency modes into
/// in-band pendulum resonances, far from linear in φ at φ = 0). A free–free body has
/// nothing to hang from: not screened, with a note.
pub(super) fn screen_gravity(spec: &CampaignSpec, g: &Geometry) -> ScreeningResult {
    let has_free = !nominal_free_directions(spec, g).is_empty();
    let suspended = spec
        .setups
        .iter()
        .any(|s| !s.springs.is_empty() || !s.cords.is_empty());
    if !suspended {
        return Err("gravity_stiffness is not screened: no set-up has springs or cords".into());
    }
    let e = GravityForm::neutral(spec, g);
    let n_params = e.values.len();
    Ok(Some(ScreeningForm {
        neutral: e.values(),
        scales: e.scales(),
        effect: Box::new(e),
        source: "rbprops-sim (reparametrised for screening)",
        screening: if has_free {
            gravity_profile(spec, n_params)
        } else {
            ScreeningKind::Score
        },
    }))
}

/// Whether φ₅ is a parameter of the gravity candidate: some set-up hangs on springs
/// alone (no cords: a cord set-up's hanging equilibrium already turns its springs), and
/// the nominal model leaves no rigid direction free (springs that cannot hold the body
/// have no sagged equilibrium to turn about). Elsewhere φ₅ would have no signature.
pub fn springs_can_sag(spec: &CampaignSpec, g: &Geometry) -> bool {
    spec.setups
        .iter()
        .enumerate()
        .any(|(i, _)| super::on_three_axis_springs(spec, i))
        && nominal_free_directions(spec, g).is_empty()
}

/// Geometric stiffness of cords along the spec's `up`, tilted by (φ₃, φ₄)
/// ([`tilted_direction`]), through rbprops-sim's own
/// [`super::geometric_stiffness`], split into its two parts:
/// `K(φ) = φ₁ [K_geo(ℓ = 1) − K_geo(ℓ → ∞)] + φ₂ K_geo(ℓ → ∞)`, exact for
/// K_geo(ℓ) = (1/ℓ)·lateral + load term; φ = (1/ℓ, 1, 0, 0, 0) reproduces the catalogue
/// effect. The tilt is bilinear with φ₁, φ₂: no signature at neutral, so the model
/// check frees it only after a refit has moved them. So is φ₅, which moves the load
/// term from the cords' reading of the springs (φ₅ = 0: tensions along ẑ, stiffness
/// axes fixed) to the springs as linear springs to the ground (φ₅ = 1: the exact Hessian
/// of the weight and the springs at the sagged equilibrium, `ΔK_s = K_E − K_nominal`
/// from [`super::hanging_equilibrium`], whose springs turn with
/// the body: `φ₂ [K_geo(∞) + φ₅ (ΔK_s − K_geo(∞))]`). A body sagging a few mrad on
/// stiff vertical springs couples bounce and sway through that turn (Rᵀk R − k, of order
/// ψ·k_z), which neither the cords' load term nor the per-axis stiffness scales can
/// express; the catalogue has no such entry, so the improved spec keeps the cords'
/// form and the report gives φ₅. φ₅ is a parameter only where springs alone hold the
/// body (see [`springs_can_sag`]): a cord set-up's equilibrium turns its springs already.
///
/// A set-up with cords (`[[setup.cord]]`) hangs instead: with `E` the body at the static
/// equilibrium of the weight and the cords (rbprops-sim's
/// [`super::hanging_equilibrium`], finite rotations, the spec's
/// unstretched lengths), `ΔK = K_E − K_nominal` (axial springs at the reference pose)
/// splits into the cords' lateral tension part `Lat = Σ T(a)ᵀ(T/L)(I − eeᵀ)T(a)` and the
/// rest (load term, axial springs turned with the body): `K(φ) = φ₁ L̄ Lat + φ₂ (ΔK − Lat)`,
/// L̄ the mean hanging length, so φ = (1/L̄, 1, 0, 0) is the hanging body exactly and φ₁
/// scales every cord's length in proportion (a cord length the data fit).
///
/// Cords written as axial springs hang from anchors at ℓ = 1/φ₁ along their axes
/// ([`CORD_INVERSE_LENGTH`] bounds it), so `φ₁ ℓ Lat` is the cords' own tension part at
/// the fitted length, and their free lengths `ℓ − T/k + δ` carry the set-up's
/// cord-length (pose) contrasts δ ([`length_changes`] of its slot of `slots` in
/// `contrasts`, [`pose_contrasts`]):
/// at δ = 0 the body hangs in the drawn pose (the tensions of the elastic balance, and
/// then ℓ only scales `Lat`, exactly as before); unequal cords move and tilt it to the
/// equilibrium they make, as splayed cords of unequal lengths do.
pub fn gravity_stiffness(
    ctx: &BuildContext,
    model: &DynamicModel,
    phi: &GravityPhi,
    slots: &[ContrastSlot],
) -> Result<Mat6, String> {
    use super::{geometric_stiffness, Cord, STANDARD_GRAVITY};
    let z = phi.up(ctx.spec);
    if !ctx.spec.setups[ctx.setup_index].cords.is_empty() {
        let eq = hanging(ctx.spec, ctx.setup_index, &model.mass, &z)?;
        let lbar = eq.lengths.iter().sum::<f64>() / eq.lengths.len() as f64;
        let dk = eq.stiffness - ctx.spec.setup_stiffness(ctx.setup_index);
        return Ok(eq.lateral * (phi.inverse_length * lbar) + (dk - eq.lateral) * phi.load);
    }
    // The cords' free lengths are cut for the spec's body: a mass an effect adds (a
    // force gauge's, a sensor's) loads and sags them as it would the real cords, as
    // the improved spec's `unstretched_length_m` ([`axial_free_lengths`]) states.
    let body = ctx.spec.properties().mass_matrix().0;
    if let Some((cords, springs)) = contrasted_cords(ctx.spec, ctx.setup_index, &body, phi, slots) {
        // Cords written as axial springs (vertical or splayed): hung like the set-up's
        // cords above, from anchors at ℓ, their free lengths changed by the set-up's
        // contrasts.
        let eq = super::hanging_equilibrium(&model.mass, &cords, &springs, STANDARD_GRAVITY, &z)
            .map_err(|e| format!("set-up '{}': {e}", ctx.spec.setups[ctx.setup_index].id))?;
        let dk = eq.stiffness - ctx.spec.setup_stiffness(ctx.setup_index);
        let ell = phi.anchor_length();
        return Ok(eq.lateral * (phi.inverse_length * ell) + (dk - eq.lateral) * phi.load);
    }
    // Springs with no stiffness along the vertical (side springs) hold no weight: they
    // are not cords and add no pendulum stiffness.
    let cords = |len: f64| -> Vec<Cord> {
        let all: Vec<Cord> = ctx
            .spec
            .springs(ctx.setup_index)
            .iter()
            .map(|s| Cord {
                at: s.at,
                length: len,
                axial_stiffness: (z.transpose() * s.stiffness * z)[0],
            })
            .collect();
        let kmax = all.iter().map(|c| c.axial_stiffness).fold(0.0, f64::max);
        all.into_iter()
            .filter(|c| c.axial_stiffness > 1e-9 * kmax)
            .collect()
    };
    let (k1, _) = geometric_stiffness(&model.mass, &cords(1.0), STANDARD_GRAVITY, &z)?;
    let (kinf, _) = geometric_stiffness(&model.mass, &cords(1e12), STANDARD_GRAVITY, &z)?;
    let mut load = kinf;
    let turn = phi.turn;
    if turn != 0.0 {
        // The springs as linear springs to the ground (not cords): at the body's sagged
        // equilibrium their stiffness axes turn with it, `Σ T(a)ᵀ Rᵀk R T(a)`, and their
        // preloads carry horizontal parts; the exact Hessian there less the nominal
        // springs, against the cords' load term. Springs that cannot hold the body
        // alone (a free direction) have no sagged equilibrium to turn about: there φ₅
        // has no signature, and the other parameters keep theirs.
        if let Ok(t) = super::springs_turn(
            ctx.spec,
            ctx.setup_index,
            &model.mass,
            STANDARD_GRAVITY,
            &z,
            &kinf,
        ) {
            load += t * turn;
        }
    }
    Ok((k1 - kinf) * phi.inverse_length + load * phi.load)
}

/// Set-up `i`'s springs read as cords ([`super::axial_spring_cords`]
/// for a body of mass matrix `mass` along the fitted vertical), anchored at
/// [`GravityPhi::anchor_length`], with free lengths `ℓ − T/k + δ`, δ the set-up's
/// contrasts of `slots` ([`length_changes`]); `None` when its springs are not cords.
fn contrasted_cords(
    spec: &CampaignSpec,
    i: usize,
    mass: &Mat6,
    phi: &GravityPhi,
    slots: &[ContrastSlot],
) -> Option<(Vec<super::AnchoredCord>, Vec<crate::suspension::Spring>)> {
    let ell = phi.anchor_length();
    let (mut cords, springs) = super::axial_spring_cords(
        spec,
        i,
        mass,
        super::STANDARD_GRAVITY,
        &phi.up(spec),
        |_| ell,
    )?;
    if let Some(slot) = slots.iter().find(|s| s.setup == i) {
        let c = &phi.contrasts[slot.start..slot.start + slot.patterns.len()];
        for (cord, d) in cords.iter_mut().zip(length_changes(c, &slot.patterns)) {
            cord.unstretched_length += d;
        }
    }
    Some((cords, springs))
}

/// Name of φ₁ = 1/ℓ (see [`gravity_stiffness`]).
pub const INVERSE_LENGTH: &str = "inverse_cord_length_per_m";
/// Name of φ₂, the load-term factor.
pub const LOAD_FACTOR: &str = "load_term_factor";
/// Names of (φ₃, φ₄), the tilts of the vertical.
pub const TILTS: [&str; 2] = ["up_tilt1_rad", "up_tilt2_rad"];
/// φ₅ (see [`gravity_stiffness`]).
pub const SPRING_TURN: &str = "spring_turn_fraction";
/// What every cord-length contrast's name holds (`{set-up}.cord_length_contrast{k}_m`).
pub const CONTRAST: &str = ".cord_length_contrast";

/// The gravity candidate's φ by meaning; absent parameters are 0.
#[derive(Debug, Clone, Copy)]
pub struct GravityPhi<'a> {
    /// φ₁ = 1/ℓ (1/m).
    pub inverse_length: f64,
    /// φ₂, the load-term factor.
    pub load: f64,
    /// (φ₃, φ₄), the tilts of the vertical (rad).
    pub tilt: (f64, f64),
    /// φ₅, the fraction by which springs turn with the sagged body.
    pub turn: f64,
    /// The cord-length contrasts of every set-up of cords written as springs, in the
    /// order of their [`ContrastSlot`]s.
    pub contrasts: &'a [f64],
}

impl<'a> GravityPhi<'a> {
    /// The values `phi` of the parameters `names` (the contrasts last).
    pub fn from_named(names: &[String], phi: &'a [f64]) -> GravityPhi<'a> {
        let get = |n: &str| names.iter().position(|x| x == n).map_or(0.0, |i| phi[i]);
        let start = names
            .iter()
            .position(|n| n.contains(CONTRAST))
            .unwrap_or(names.len());
        GravityPhi {
            inverse_length: get(INVERSE_LENGTH),
            load: get(LOAD_FACTOR),
            tilt: (get(TILTS[0]), get(TILTS[1])),
            turn: get(SPRING_TURN),
            contrasts: &phi[start..],
        }
    }
    /// The anchors' distance ℓ = 1/φ₁ of cords written as axial springs, φ₁ held in
    /// [`CORD_INVERSE_LENGTH`].
    pub fn anchor_length(&self) -> f64 {
        1.0 / self
            .inverse_length
            .clamp(CORD_INVERSE_LENGTH.0, CORD_INVERSE_LENGTH.1)
    }
    /// The spec's vertical tilted by (φ₃, φ₄) ([`tilted_direction`]).
    pub fn up(&self, spec: &CampaignSpec) -> Vec3 {
        tilted_direction(&spec.up_vector(), self.tilt.0, self.tilt.1)
    }
}

/// The gravity candidate's parameter names for `spec`, and where each set-up's contrasts
/// sit: φ₁, φ₂; the two tilts unless every set-up that hangs is of cords written as
/// springs (their pose contrasts move the body to its equilibrium, and a tilt of the
/// vertical would be nearly the same turn of the body, a gauge the fit slides along:
/// measured, a tilt pinned at its bound of 0.5 rad; and the tilt turns the cords by the
/// body's whole turn, where its attachments' sideways move leans them less); φ₅ where springs
/// can sag ([`springs_can_sag`]); the contrasts.
pub fn gravity_names(spec: &CampaignSpec, g: &Geometry) -> (Vec<String>, Vec<ContrastSlot>) {
    let (slots, contrasts) = contrast_slots(spec);
    let mut names = vec![INVERSE_LENGTH.to_string(), LOAD_FACTOR.to_string()];
    let tilted = spec.setups.iter().enumerate().any(|(i, s)| {
        (!s.springs.is_empty() || !s.cords.is_empty()) && !slots.iter().any(|c| c.setup == i)
    });
    if tilted {
        names.extend(TILTS.map(String::from));
    }
    if springs_can_sag(spec, g) {
        names.push(SPRING_TURN.into());
    }
    names.extend(contrasts);
    (names, slots)
}

/// The range of φ₁ = 1/ℓ (1/m) over which cords written as axial springs hang from
/// anchors at ℓ: 5 cm to 10 m (the catalogue's plausible cord lengths); outside it the
/// anchors stay at its end and φ₁ only scales the tension part, so that φ₁ = 0 (no
/// gravity stiffness) is still a point of the parameter space.
pub const CORD_INVERSE_LENGTH: (f64, f64) = (0.1, 20.0);

/// Where a set-up's cord-length contrasts sit in the gravity candidate's φ: set-up
/// index, first parameter, and the contrasts' patterns of free-length change (one
/// n-vector per contrast, orthonormal; see [`pose_contrasts`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ContrastSlot {
    /// Index of the set-up.
    pub setup: usize,
    /// Index of its first contrast among the contrasts.
    pub start: usize,
    /// The free-length change of every cord per unit of each contrast.
    pub patterns: Vec<Vec<f64>>,
}

/// The contrast slots of the set-ups whose springs are cords written as axial springs
/// (positions among the contrast parameters), and their names
/// (`{set-up}.cord_length_contrast{k}_m`).
pub fn contrast_slots(spec: &CampaignSpec) -> (Vec<ContrastSlot>, Vec<String>) {
    let (mut slots, mut names) = (Vec::new(), Vec::new());
    let mass = spec.properties().mass_matrix().0;
    for (i, s) in spec.setups.iter().enumerate() {
        let Some((cords, _)) = super::axial_spring_cords(
            spec,
            i,
            &mass,
            super::STANDARD_GRAVITY,
            &spec.up_vector(),
            |_| 1.0,
        ) else {
            continue;
        };
        let axes: Vec<(Vec3, Vec3)> = cords.iter().map(|c| (c.at, c.direction())).collect();
        let patterns = pose_contrasts(&axes);
        if patterns.is_empty() {
            continue;
        }
        let m = patterns.len();
        slots.push(ContrastSlot {
            setup: i,
            start: names.len(),
            patterns,
        });
        names.extend((1..=m).map(|k| format!("{}.cord_length_contrast{k}_m", s.id)));
    }
    (slots, names)
}

/// The contrasts of cords (attachment, unit axis) in the drawn pose: an orthonormal
/// basis of the free-length changes δ that sum to zero and that a small rigid motion
/// (u, θ) of the body would make, `δ_j = e_jᵀ u + (a_j × e_j)ᵀ θ`. Those are the changes
/// that move the pose: four splayed cords span all three zero-sum patterns; four
/// parallel cords two (roll and pitch), not their warp, a self-stress that moves no
/// pose and that stood in for non-proportional damping in the study (±2.7 cm with two
/// cords nearly slack). Zero-sum, because a common change of every free length is the
/// cord length ℓ's (for parallel cords exactly: the body only hangs lower), which φ₁
/// fits. Each pattern's largest entry is positive (a deterministic sign).
pub fn pose_contrasts(cords: &[(Vec3, Vec3)]) -> Vec<Vec<f64>> {
    let n = cords.len();
    if n < 2 {
        return Vec::new();
    }
    let a = nalgebra::DMatrix::from_fn(n, 6, |j, k| {
        let (at, e) = cords[j];
        if k < 3 {
            e[k]
        } else {
            at.cross(&e)[k - 3]
        }
    });
    let svd = a.svd(true, false);
    let u = svd.u.expect("requested");
    let smax = svd.singular_values.max();
    // The range of the rigid motions' stretches, orthonormal (n × r).
    let range: Vec<nalgebra::DVector<f64>> = (0..svd.singular_values.len())
        .filter(|&k| svd.singular_values[k] > 1e-9 * smax)
        .map(|k| u.column(k).into_owned())
        .collect();
    // Within it, the complement of the uniform change: Gram–Schmidt of the range's
    // vectors against 1/√n and each other.
    let mut basis: Vec<nalgebra::DVector<f64>> =
        vec![nalgebra::DVector::from_element(n, 1.0 / (n as f64).sqrt())];
    for v in range {
        let mut w = v;
        for b in &basis {
            w -= b * b.dot(&w);
        }
        if w.norm() > 1e-6 {
            basis.push(w.normalize());
        }
    }
    basis
        .into_iter()
        .skip(1)
        .map(|b| {
            let k = b.iamax();
            let sign = if b[k] < 0.0 { -1.0 } else { 1.0 };
            b.iter().map(|x| sign * x).collect()
        })
        .collect()
}

/// The free-length changes δ (m) of the contrasts `c` along `patterns`.
pub fn length_changes(c: &[f64], patterns: &[Vec<f64>]) -> Vec<f64> {
    let n = patterns.first().map_or(0, Vec::len);
    let mut d = vec![0.0; n];
    for (ck, b) in c.iter().zip(patterns) {
        for (dj, bj) in d.iter_mut().zip(b) {
            *dj += ck * bj;
        }
    }
    d
}

/// The free lengths (m) of the fitted gravity effect `phi` for the
/// catalogue, where the spec has one set-up of cords written as axial springs and its
/// fitted contrasts are not all zero: `ℓ − T/k + δ` per cord (tensions of the nominal
/// body along the fitted vertical), with that set-up's index. `None` otherwise (several
/// such set-ups: the catalogue's one list cannot hold them; the report has the values).
pub fn axial_free_lengths(
    spec: &CampaignSpec,
    phi: &GravityPhi,
) -> Result<Option<(usize, Vec<f64>)>, String> {
    let slots = contrast_slots(spec).0;
    let [slot] = slots.as_slice() else {
        return Ok(None);
    };
    if phi.contrasts.iter().all(|c| *c == 0.0) {
        return Ok(None);
    }
    let mass = spec.properties().mass_matrix().0;
    let (cords, _) = contrasted_cords(spec, slot.setup, &mass, phi, &slots).ok_or_else(|| {
        format!(
            "gravity_stiffness: set-up '{}' no longer reads as cords",
            spec.setups[slot.setup].id
        )
    })?;
    Ok(Some((
        slot.setup,
        cords.iter().map(|c| c.unstretched_length).collect(),
    )))
}

/// The hanging equilibrium of set-up `i`'s cords and springs for a body of mass matrix
/// `mass` under standard gravity along `−up`.
pub fn hanging(
    spec: &CampaignSpec,
    i: usize,
    mass: &Mat6,
    up: &Vec3,
) -> Result<super::HangingEquilibrium, String> {
    super::hanging_equilibrium(
        mass,
        &spec.cords(i),
        &spec.plain_springs(i),
        super::STANDARD_GRAVITY,
        up,
    )
    .map_err(|e| format!("set-up '{}': {e}", spec.setups[i].id))
}

/// Relative step of the cord lengths of [`gravity_profile`]: 5 %, below the 6 % width in
/// length (ℓ ∝ 1/ω²) of a pendulum resonance at 1.5 % damping, so a point falls on the
/// resonance's flank and the refit starts in its basin.
const GRAVITY_LENGTH_STEP: f64 = 0.05;

/// The `gravity_stiffness` profile for a nominal model with free directions: the hanging
/// body (φ = (1/ℓ, 1, 0, 0)) at lengths ℓ in steps of [`GRAVITY_LENGTH_STEP`]: ×0.37 to
/// ×2.7 the cords' mean hanging length when the spec has cords (L₀ + T/k of the nominal
/// body), else 0.2 to 5 m.
pub fn gravity_profile(spec: &CampaignSpec, n_params: usize) -> ScreeningKind {
    let up = spec.up_vector();
    let m = spec.properties().mass_matrix().0;
    let lbar = spec
        .setups
        .iter()
        .enumerate()
        .filter(|(_, s)| !s.cords.is_empty())
        .find_map(|(i, _)| hanging(spec, i, &m, &up).ok())
        .map(|eq| eq.lengths.iter().sum::<f64>() / eq.lengths.len() as f64);
    let lengths: Vec<f64> = match lbar {
        Some(l) => (-20..=20)
            .map(|k| l * (GRAVITY_LENGTH_STEP * k as f64).exp())
            .collect(),
        None => {
            let n = ((5.0f64 / 0.2).ln() / GRAVITY_LENGTH_STEP).ceil() as i32;
            (0..=n)
                .map(|k| 0.2 * (GRAVITY_LENGTH_STEP * k as f64).exp())
                .collect()
        }
    };
    ScreeningKind::Profile {
        grid: lengths
            .iter()
            .map(|l| {
                let mut phi = vec![1.0 / l, 1.0, 0.0, 0.0];
                phi.resize(n_params, 0.0);
                phi
            })
            .collect(),
        delay_scan: false,
    }
}

#[cfg(test)]
mod tests {
    /// φ₂ is held at 1 only once the cords have a length (1/ℓ > 0): at the neutral point
    /// and at 1/ℓ ≤ 0 it stays free, as the score test needs.
    #[test]
    fn load_factor_is_held_at_one_once_the_cords_have_a_length() {
        use super::{GravityForm, LOAD_FACTOR};
        use crate::effects::Effect;
        let text = crate::examples::example("test-case-2").expect("built-in");
        let spec = crate::CampaignSpec::from_toml_str(text).expect("valid spec");
        let form = GravityForm::neutral(&spec, &spec.geometry().expect("geometry"));
        let i = form
            .parameters()
            .iter()
            .position(|p| p.name == LOAD_FACTOR)
            .expect("a load-term factor");
        let at = |inv_len: f64, load: f64| {
            let mut v = form.values();
            v[0] = inv_len;
            v[i] = load;
            form.with_values(&v).expect("values").physical_holds()
        };
        assert!(at(0.0, 0.0).is_empty());
        assert!(at(0.0, 0.8).is_empty());
        assert!(at(-0.1, 0.8).is_empty());
        assert_eq!(at(0.5, 0.8), vec![(i, 1.0)]);
        assert_eq!(at(1e-6, 1.3), vec![(i, 1.0)]);
    }

    use super::pose_contrasts;
    use rbprops_core::Vec3;

    fn check_orthonormal_zero_sum(p: &[Vec<f64>]) {
        for (a, pa) in p.iter().enumerate() {
            assert!(pa.iter().sum::<f64>().abs() < 1e-12, "{pa:?}");
            for (b, pb) in p.iter().enumerate() {
                let dot: f64 = pa.iter().zip(pb).map(|(x, y)| x * y).sum();
                let want = if a == b { 1.0 } else { 0.0 };
                assert!((dot - want).abs() < 1e-12, "⟨b{a}, b{b}⟩ = {dot}");
            }
        }
    }

    /// Four parallel cords at a rectangle's corners: the contrasts are roll and pitch
    /// (two), orthogonal to the warp (+, −, −, +) that moves no pose; four splayed cords:
    /// all three zero-sum patterns. Orthonormal and zero-sum either way.
    #[test]
    fn pose_contrasts_are_the_zero_sum_stretches_of_rigid_motions() {
        let at = [
            Vec3::new(0.02, -0.13, 0.17),
            Vec3::new(0.34, -0.13, 0.17),
            Vec3::new(0.02, 0.20, 0.17),
            Vec3::new(0.34, 0.20, 0.17),
        ];
        let parallel: Vec<(Vec3, Vec3)> = at.iter().map(|a| (*a, Vec3::z())).collect();
        let p = pose_contrasts(&parallel);
        assert_eq!(p.len(), 2);
        check_orthonormal_zero_sum(&p);
        for b in &p {
            let warp = (b[0] - b[1] - b[2] + b[3]) / 2.0;
            assert!(warp.abs() < 1e-12, "{b:?}");
        }
        let anchors = [
            Vec3::new(-0.13, -0.28, 1.2),
            Vec3::new(0.49, -0.28, 1.2),
            Vec3::new(-0.13, 0.35, 1.2),
            Vec3::new(0.49, 0.35, 1.2),
        ];
        let splayed: Vec<(Vec3, Vec3)> = at
            .iter()
            .zip(&anchors)
            .map(|(a, b)| (*a, (b - a).normalize()))
            .collect();
        let p = pose_contrasts(&splayed);
        assert_eq!(p.len(), 3);
        check_orthonormal_zero_sum(&p);
        // Two cords: one contrast, the one against the other.
        let p = pose_contrasts(&parallel[..2]);
        assert_eq!(p.len(), 1);
        assert!((p[0][0] + p[0][1]).abs() < 1e-12 && (p[0][0].abs() - 0.5f64.sqrt()).abs() < 1e-12);
    }
}
