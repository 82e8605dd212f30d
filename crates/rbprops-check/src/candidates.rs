//! Candidate effects for screening: rbprops-sim's physics catalogue, completed by local
//! implementations (of rbprops-sim's own [`Effect`] trait) for ids the catalogue does
//! not offer yet. Each candidate starts at its neutral ("absent") parameter values.
//!
//! Local effects (equations; all neutral at 0):
//! - `channel_gain` (E10): channel i reads (1+ε_i)·H_i.
//! - `excitation_gain` (E12 sensitivity): excitation e's FRFs scaled by (1+δ_e).
//! - `global_gain` (E10 global): every FRF scaled by (1+κ). Absorbed by the free mass.
//! - `sensor_misorientation` (E8): the channels at a point sense along R(ψ) s, with
//!   `R(ψ) = exp([ψ]×)` (Rodrigues), three angles per sensor point.
//! - `sensor_mass` (E7): point mass m_p at each sensor point, M += m_p T(p)ᵀT(p).
//!   Absorbed by the free inertia.
//! - `gravity_stiffness` (E1): rbprops-sim's cord geometric stiffness (every spring read
//!   as a vertical cord of length ℓ) reparametrised so that "absent" is a point of the
//!   parameter space: `K(φ) = φ₁·lateral(ℓ = 1) + φ₂·load term`, φ₁ = 1/ℓ (1/m), φ₂ the
//!   load-term factor (physical value 1). The catalogue's own parameter (ℓ, with ℓ → ∞
//!   still leaving the load term) has no neutral value, so a score test needs this form.
//!   Two tilts of the vertical and φ₅, the fraction by which springs (rather than cords)
//!   turn with the sagged body, complete it (see `gravity_stiffness`).
//! - `nonproportional_damping` (E5): dashpots at the spring points,
//!   C += Σ_i T(a_i)ᵀ diag(c_x, c_y, c_z) T(a_i), per set-up. Only a recording-side
//!   helper ([`local_effect`]): the candidate screened is the catalogue's general
//!   viscous damping (`modal_coupling`, see `neutral_entry` and docs/physics.md, E5).
//! - `residual_flexibility` (E13): elastic modes above the band seen as a general
//!   residual flexibility matrix R (channels × excitations, m/N): one mode at f_e per
//!   excitation, `H += R_ce ω_e²/(ω_e² − ω² + 2iζ_e ω_e ω)`, with q =
//!   (f_top/f_e)² and ζ_e the last two parameters (neutral 1/16 and 0: an undamped mode
//!   at 4× the top of the band). Both are bilinear with R (no signature while R = 0),
//!   so the model check frees them after a refit has moved R; they then reach a mode
//!   just above the band, whose damping shows where the rigid part of an FRF nearly
//!   cancels and the mode's tail dominates. (The catalogue's `elastic_mode` is bilinear
//!   in its shapes, with no usable neutral point.)
//! - `force_direction` (E12): excitation e pushes along normalise(d + β₁u₁ + β₂u₂),
//!   u₁, u₂ ⟂ d.
//!
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
//! - `added_mass` through its non-rigid part ([`NonRigidMass`]): of a symmetric 6×6
//!   `M_a = [[A, B], [Bᵀ, C]]`, the rigid-structured part (A ∝ I, B antisymmetric, any
//!   C: 10 directions) is exactly what the free inertia absorbs, so only the rest is
//!   fitted: A traceless, B symmetric, C = 0 (11 parameters). The rigid part stays in the
//!   reported inertia, which is then that of the body with it.

use rbprops_core::geometry::cross_matrix;
use rbprops_core::{rigid_transform, Geometry, Mat3, Mat6, Vec3};
use rbprops_sim::effects::{BuildContext, Effect, NeutralForm, OutputBlock, ParamInfo, Reach};
use rbprops_sim::model::DynamicModel;
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
    /// Point masses rigidly attached to the body: an exact gauge of the free inertia
    /// unless the total mass is pinned by a weighed mass, then a score test.
    RigidMassGauge,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    ChannelGain,
    ExcitationGain,
    GlobalGain,
    SensorMisorientation,
    SensorMass,
    GravityStiffness,
    MountDashpots,
    ForceDirection,
    ResidualFlexibility,
}

const ALL: [Kind; 9] = [
    Kind::ResidualFlexibility,
    Kind::GravityStiffness,
    Kind::SensorMisorientation,
    Kind::ChannelGain,
    Kind::ExcitationGain,
    Kind::ForceDirection,
    Kind::MountDashpots,
    Kind::SensorMass,
    Kind::GlobalGain,
];

impl Kind {
    fn id(self) -> &'static str {
        match self {
            Kind::ChannelGain => "channel_gain",
            Kind::ExcitationGain => "excitation_gain",
            Kind::GlobalGain => "global_gain",
            Kind::SensorMisorientation => "sensor_misorientation",
            Kind::SensorMass => "sensor_mass",
            Kind::GravityStiffness => "gravity_stiffness",
            Kind::MountDashpots => "nonproportional_damping",
            Kind::ForceDirection => "force_direction",
            Kind::ResidualFlexibility => "residual_flexibility",
        }
    }
    fn title(self) -> &'static str {
        describe(self.id()).0
    }
    fn reveal(self) -> &'static str {
        describe(self.id()).1
    }
}

/// Title and "what would reveal it" of the one local candidate the catalogue does not
/// have (the catalogue's own come from its registry).
const RESIDUAL_FLEXIBILITY_TEXT: (&str, &str) = (
    "elastic modes above the band (residual flexibility)",
    "data closer to the first elastic mode, or its measured frequency",
);

/// A locally implemented catalogue effect (see the module docs for the equations).
#[derive(Debug, Clone)]
pub struct LocalEffect {
    kind: Kind,
    names: Vec<String>,
    values: Vec<f64>,
    /// Channel index → point index (sensor groups), for misorientation.
    groups: Vec<Vec<usize>>,
    /// Point positions (sensor points), for sensor_mass.
    points: Vec<Vec3>,
    /// Top of the band (Hz): the residual flexibility's modes sit at f_top/√q.
    band_top_hz: f64,
}

/// Name of the gravity candidate's fifth parameter φ₅ (see [`gravity_stiffness`]).
const SPRING_TURN: &str = "spring_turn_fraction";

/// Whether φ₅ is a parameter of the gravity candidate: some set-up hangs on springs
/// alone (no cords: a cord set-up's hanging equilibrium already turns its springs), and
/// the nominal model leaves no rigid direction free (springs that cannot hold the body
/// have no sagged equilibrium to turn about). Elsewhere φ₅ would have no signature.
fn springs_can_sag(spec: &CampaignSpec, g: &Geometry) -> bool {
    spec.setups
        .iter()
        .enumerate()
        .any(|(i, s)| s.cords.is_empty() && !s.springs.is_empty() && !splayed_springs(spec, i))
        && free_direction_note(spec, g).is_none()
}

/// Set-up `i`'s springs are splayed cords written as axial springs (rbprops-sim's
/// [`rbprops_sim::effects::gravity::splayed_spring_cords`]): the gravity candidate hangs
/// the body on them as on cords.
fn splayed_springs(spec: &CampaignSpec, i: usize) -> bool {
    rbprops_sim::effects::gravity::splayed_spring_cords(
        spec,
        i,
        &spec.properties().mass_matrix().0,
        rbprops_sim::effects::gravity::STANDARD_GRAVITY,
        &spec.up_vector(),
        |_| 1.0,
    )
    .is_some()
}

/// Name of the residual flexibility's frequency parameter q = (f_top/f_e)².
const RESIDUAL_MODE_Q: &str = "band_top_over_mode_frequency_squared";
/// Its neutral value: the modes at 4× the top of the band, where their ω² growth is
/// what an elastic mode above the band shows.
const RESIDUAL_MODE_Q_NEUTRAL: f64 = 1.0 / 16.0;
/// Name of the residual flexibility's modal damping ratio (neutral 0).
const RESIDUAL_MODE_DAMPING: &str = "mode_damping_ratio";

fn sensor_groups(g: &Geometry) -> (Vec<String>, Vec<Vec<usize>>, Vec<Vec3>) {
    let mut ids: Vec<String> = Vec::new();
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut pos = Vec::new();
    for (i, c) in g.channels.iter().enumerate() {
        match ids.iter().position(|p| *p == c.point) {
            Some(k) => groups[k].push(i),
            None => {
                ids.push(c.point.clone());
                groups.push(vec![i]);
                pos.push(c.position);
            }
        }
    }
    (ids, groups, pos)
}

impl LocalEffect {
    fn neutral(kind: Kind, spec: &CampaignSpec, g: &Geometry) -> LocalEffect {
        let (pids, groups, points) = sensor_groups(g);
        let names: Vec<String> = match kind {
            Kind::ChannelGain => g
                .channels
                .iter()
                .map(|c| format!("{}.gain_error", c.id))
                .collect(),
            Kind::ExcitationGain => g
                .excitations
                .iter()
                .map(|e| format!("{}.gain_error", e.id))
                .collect(),
            Kind::GlobalGain => vec!["gain_error".into()],
            Kind::SensorMisorientation => pids
                .iter()
                .flat_map(|p| ["rx", "ry", "rz"].map(|a| format!("{p}.{a}_rad")))
                .collect(),
            Kind::SensorMass => pids.iter().map(|p| format!("{p}.mass_kg")).collect(),
            Kind::GravityStiffness => {
                let mut v: Vec<String> = vec![
                    "inverse_cord_length_per_m".into(),
                    "load_term_factor".into(),
                    "up_tilt1_rad".into(),
                    "up_tilt2_rad".into(),
                ];
                if springs_can_sag(spec, g) {
                    v.push(SPRING_TURN.into());
                }
                v
            }
            Kind::MountDashpots => spec
                .setups
                .iter()
                .flat_map(|s| ["x", "y", "z"].map(|a| format!("{}.dashpot_{a}_n_s_per_m", s.id)))
                .collect(),
            Kind::ResidualFlexibility => g
                .excitations
                .iter()
                .flat_map(|e| {
                    g.channels
                        .iter()
                        .map(move |c| format!("{}.{}.receptance_m_per_n", c.id, e.id))
                })
                .chain([RESIDUAL_MODE_Q, RESIDUAL_MODE_DAMPING].map(String::from))
                .collect(),
            Kind::ForceDirection => g
                .excitations
                .iter()
                .flat_map(|e| ["tilt1", "tilt2"].map(|a| format!("{}.{a}_rad", e.id)))
                .collect(),
        };
        let mut values = vec![0.0; names.len()];
        if kind == Kind::ResidualFlexibility {
            values[names.len() - 2] = RESIDUAL_MODE_Q_NEUTRAL;
        }
        LocalEffect {
            kind,
            values,
            names,
            groups,
            points,
            band_top_hz: spec.frequency.stop_hz,
        }
    }

    fn info(&self, i: usize) -> ParamInfo {
        let (unit, lo, hi, pl) = match self.kind {
            Kind::ChannelGain | Kind::ExcitationGain | Kind::GlobalGain => {
                ("1", -0.5, 0.5, (-0.05, 0.05))
            }
            Kind::SensorMisorientation | Kind::ForceDirection => ("rad", -0.5, 0.5, (-0.1, 0.1)),
            Kind::ResidualFlexibility if i + 1 == self.values.len() => ("1", 0.0, 0.5, (0.0, 0.05)),
            Kind::ResidualFlexibility if i + 2 == self.values.len() => {
                ("1", 1e-4, 0.95, (0.0, 0.5))
            }
            Kind::ResidualFlexibility => ("m/N", f64::NEG_INFINITY, f64::INFINITY, (-1e-4, 1e-4)),
            Kind::SensorMass => ("kg", 0.0, f64::INFINITY, (0.0, 0.5)),
            Kind::GravityStiffness if i == 0 => ("1/m", 0.0, 100.0, (0.2, 10.0)),
            Kind::GravityStiffness if i == 1 => ("1", 0.0, 3.0, (0.5, 1.5)),
            // 0: the springs' stiffness stays along the spec's axes (cords); 1: it turns
            // with the sagged body (linear springs to the ground). Bounds wide enough
            // that neither end is pinned.
            Kind::GravityStiffness if i == 4 => ("1", -2.0, 3.0, (-0.5, 1.5)),
            Kind::GravityStiffness => ("rad", -0.5, 0.5, (-0.1, 0.1)),
            Kind::MountDashpots => ("N s/m", 0.0, f64::INFINITY, (0.0, 100.0)),
        };
        ParamInfo {
            name: self.names[i].clone(),
            unit,
            lower: lo,
            upper: hi,
            plausible: pl,
        }
    }

    fn scale(&self, spec: &CampaignSpec) -> Vec<f64> {
        let m = spec.body.mass_kg;
        (0..self.values.len())
            .map(|i| match self.kind {
                Kind::ChannelGain | Kind::ExcitationGain | Kind::GlobalGain => 0.01,
                Kind::SensorMisorientation | Kind::ForceDirection => 0.01,
                Kind::ResidualFlexibility if i + 1 == self.values.len() => 0.001,
                Kind::ResidualFlexibility if i + 2 == self.values.len() => 0.01,
                Kind::ResidualFlexibility => {
                    let w = std::f64::consts::TAU * spec.frequency.stop_hz.max(1e-3);
                    1e-3 / (m * w * w)
                }
                Kind::SensorMass => 0.01 * m,
                Kind::GravityStiffness => {
                    if i < 2 || i == 4 {
                        1.0
                    } else {
                        0.01
                    }
                }
                Kind::MountDashpots => {
                    // 1 % critical damping of the stiffest spring of the set-up, roughly.
                    let k = spec
                        .setups
                        .iter()
                        .flat_map(|s| s.springs.iter())
                        .map(|s| {
                            s.stiffness_n_per_m
                                .map(|k| k[0].max(k[1]).max(k[2]))
                                .unwrap_or(100.0)
                        })
                        .fold(1.0, f64::max);
                    0.02 * (k * m).sqrt()
                }
            })
            .collect()
    }
}

fn rodrigues(psi: &Vec3) -> Mat3 {
    let t = psi.norm();
    let k = cross_matrix(psi);
    if t < 1e-12 {
        return Mat3::identity() + k;
    }
    Mat3::identity() + k * (t.sin() / t) + k * k * ((1.0 - t.cos()) / (t * t))
}

/// The unit direction `d` tilted by the angles (a, b) about two axes perpendicular to
/// it: `normalize(d + a e₁ + b e₂)`, with e₁ = normalize(d × h), h the axis x unless d
/// is nearly along it (then y), and e₂ = d × e₁. The vertical of the gravity candidate
/// (a frame off by a few degrees, E15.4) and a force's direction (E12) are tilted so.
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

/// Geometric stiffness of cords along the spec's `up`, tilted by (φ₃, φ₄)
/// ([`tilted_direction`]), through rbprops-sim's own
/// [`rbprops_sim::effects::gravity::geometric_stiffness`], split into its two parts:
/// `K(φ) = φ₁ [K_geo(ℓ = 1) − K_geo(ℓ → ∞)] + φ₂ K_geo(ℓ → ∞)`, exact for
/// K_geo(ℓ) = (1/ℓ)·lateral + load term; φ = (1/ℓ, 1, 0, 0, 0) reproduces the catalogue
/// effect. The tilt is bilinear with φ₁, φ₂: no signature at neutral, so the model
/// check frees it only after a refit has moved them. So is φ₅, which moves the load
/// term from the cords' reading of the springs (φ₅ = 0: tensions along ẑ, stiffness
/// axes fixed) to the springs as linear springs to the ground (φ₅ = 1: the exact Hessian
/// of the weight and the springs at the sagged equilibrium, `ΔK_s = K_E − K_nominal`
/// from [`rbprops_sim::effects::gravity::hanging_equilibrium`], whose springs turn with
/// the body: `φ₂ [K_geo(∞) + φ₅ (ΔK_s − K_geo(∞))]`). A body sagging a few mrad on
/// stiff vertical springs couples bounce and sway through that turn (Rᵀk R − k, of order
/// ψ·k_z), which neither the cords' load term nor the per-axis stiffness scales can
/// express; the catalogue has no such entry, so the improved spec keeps the cords'
/// form and the report gives φ₅. φ₅ is a parameter only where springs alone hold the
/// body (see [`springs_can_sag`]): a cord set-up's equilibrium turns its springs already.
///
/// A set-up with cords (`[[setup.cord]]`) hangs instead: with `E` the body at the static
/// equilibrium of the weight and the cords (rbprops-sim's
/// [`rbprops_sim::effects::gravity::hanging_equilibrium`], finite rotations, the spec's
/// unstretched lengths), `ΔK = K_E − K_nominal` (axial springs at the reference pose)
/// splits into the cords' lateral tension part `Lat = Σ T(a)ᵀ(T/L)(I − eeᵀ)T(a)` and the
/// rest (load term, axial springs turned with the body): `K(φ) = φ₁ L̄ Lat + φ₂ (ΔK − Lat)`,
/// L̄ the mean hanging length, so φ = (1/L̄, 1, 0, 0) is the hanging body exactly and φ₁
/// scales every cord's length in proportion (a cord length the data fit).
fn gravity_stiffness(
    ctx: &BuildContext,
    model: &DynamicModel,
    phi: &[f64],
) -> Result<Mat6, String> {
    use rbprops_sim::effects::gravity::{geometric_stiffness, Cord, STANDARD_GRAVITY};
    let z = tilted_direction(&ctx.spec.up_vector(), phi[2], phi[3]);
    if !ctx.spec.setups[ctx.setup_index].cords.is_empty() {
        let eq = hanging(ctx.spec, ctx.setup_index, &model.mass, &z)?;
        let lbar = eq.lengths.iter().sum::<f64>() / eq.lengths.len() as f64;
        let dk = eq.stiffness - ctx.spec.setup_stiffness(ctx.setup_index);
        return Ok(eq.lateral * (phi[0] * lbar) + (dk - eq.lateral) * phi[1]);
    }
    if let Some((cords, springs)) = rbprops_sim::effects::gravity::splayed_spring_cords(
        ctx.spec,
        ctx.setup_index,
        &model.mass,
        STANDARD_GRAVITY,
        &z,
        |_| 1.0,
    ) {
        // Splayed cords written as axial springs: hung like the set-up's cords above,
        // at 1 m (φ₁ scales the tension part to the fitted length).
        let eq = rbprops_sim::effects::gravity::hanging_equilibrium(
            &model.mass,
            &cords,
            &springs,
            STANDARD_GRAVITY,
            &z,
        )
        .map_err(|e| format!("set-up '{}': {e}", ctx.spec.setups[ctx.setup_index].id))?;
        let lbar = eq.lengths.iter().sum::<f64>() / eq.lengths.len() as f64;
        let dk = eq.stiffness - ctx.spec.setup_stiffness(ctx.setup_index);
        return Ok(eq.lateral * (phi[0] * lbar) + (dk - eq.lateral) * phi[1]);
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
    let turn = phi.get(4).copied().unwrap_or(0.0);
    if turn != 0.0 {
        // The springs as linear springs to the ground (not cords): at the body's sagged
        // equilibrium their stiffness axes turn with it, `Σ T(a)ᵀ Rᵀk R T(a)`, and their
        // preloads carry horizontal parts; the exact Hessian there less the nominal
        // springs, against the cords' load term. Springs that cannot hold the body
        // alone (a free direction) have no sagged equilibrium to turn about: there φ₅
        // has no signature, and the other parameters keep theirs.
        if let Ok(eq) = hanging(ctx.spec, ctx.setup_index, &model.mass, &z) {
            let dk = eq.stiffness - ctx.spec.setup_stiffness(ctx.setup_index);
            load += (dk - kinf) * turn;
        }
    }
    Ok((k1 - kinf) * phi[0] + load * phi[1])
}

/// The hanging equilibrium of set-up `i`'s cords and springs for a body of mass matrix
/// `mass` under standard gravity along `−up`.
fn hanging(
    spec: &CampaignSpec,
    i: usize,
    mass: &Mat6,
    up: &Vec3,
) -> Result<rbprops_sim::effects::gravity::HangingEquilibrium, String> {
    rbprops_sim::effects::gravity::hanging_equilibrium(
        mass,
        &spec.cords(i),
        &spec.plain_springs(i),
        rbprops_sim::effects::gravity::STANDARD_GRAVITY,
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
fn gravity_profile(spec: &CampaignSpec, n_params: usize) -> Screening {
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
    Screening::Profile {
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

/// A warning when the nominal model leaves rigid-body directions free (zero-frequency
/// modes, e.g. cords read as axial springs, or a free–free body): their FRFs are mass
/// lines, the 0 Hz line cannot be modelled, and the gravity stiffness the cords would
/// add is screened like any candidate.
pub fn free_direction_note(spec: &CampaignSpec, geometry: &Geometry) -> Option<String> {
    let effects = rbprops_sim::effects::parse_effects(spec).ok()?;
    let models = rbprops_sim::build_models(spec, geometry, &effects).ok()?;
    let free = rbprops_sim::free_directions(&models);
    if free.is_empty() {
        return None;
    }
    let list: Vec<String> = free
        .iter()
        .map(|(s, n)| format!("set-up '{s}': {n}"))
        .collect();
    Some(format!(
        "the nominal model leaves rigid-body directions free (zero-frequency modes; {}): there its FRFs are mass lines; gravity_stiffness (the cords' pendulum stiffness) is screened for them",
        list.join(", ")
    ))
}

impl Effect for LocalEffect {
    fn id(&self) -> &'static str {
        self.kind.id()
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
    fn modify_structure(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        match self.kind {
            Kind::SensorMisorientation => {
                for (k, chans) in self.groups.iter().enumerate() {
                    let psi = Vec3::new(
                        self.values[3 * k],
                        self.values[3 * k + 1],
                        self.values[3 * k + 2],
                    );
                    let r = rodrigues(&psi);
                    for &c in chans {
                        let ch = &ctx.geometry.channels[c];
                        model.outputs[c] =
                            (r * ch.direction).transpose() * rigid_transform(&ch.position);
                    }
                }
            }
            Kind::SensorMass => {
                for (p, m) in self.points.iter().zip(&self.values) {
                    let t = rigid_transform(p);
                    model.mass += (t.transpose() * t) * *m;
                }
            }
            Kind::GravityStiffness => {
                model.stiffness += gravity_stiffness(ctx, model, &self.values)?;
                model.stiffness = (model.stiffness + model.stiffness.transpose()) * 0.5;
            }
            Kind::ResidualFlexibility => {
                // One undamped mode at f_e per excitation, unit at that excitation's
                // force: the receptance gains R_ce ω_e²/(ω_e² − ω²) ≈ R_ce (1 + ω²/ω_e²),
                // a general (any rank) residual flexibility matrix R.
                let n_ch = ctx.geometry.channels.len();
                let n_ex = ctx.geometry.excitations.len();
                let (q, zeta) = (self.values[n_ex * n_ch], self.values[n_ex * n_ch + 1]);
                let extra_hz = self.band_top_hz / q.sqrt();
                let we = std::f64::consts::TAU * extra_hz;
                for e in 0..n_ex {
                    let col = &self.values[e * n_ch..(e + 1) * n_ch];
                    if col.iter().all(|v| *v == 0.0) {
                        continue;
                    }
                    let mut at_ex = vec![0.0; n_ex];
                    at_ex[e] = 1.0;
                    model.extra_modes.push(rbprops_sim::model::ExtraMode {
                        frequency_hz: extra_hz,
                        damping_ratio: zeta,
                        at_channels: col.iter().map(|r| r * we * we).collect(),
                        at_excitations: at_ex,
                    });
                }
            }
            Kind::ForceDirection => {
                for inp in &mut model.inputs {
                    let e = &ctx.geometry.excitations[inp.excitation];
                    let d2 = tilted_direction(
                        &e.direction,
                        self.values[2 * inp.excitation],
                        self.values[2 * inp.excitation + 1],
                    );
                    inp.column = rigid_transform(&e.position).transpose() * d2;
                }
            }
            _ => {}
        }
        Ok(())
    }
    fn modify_damping(&self, ctx: &BuildContext, model: &mut DynamicModel) -> Result<(), String> {
        if self.kind == Kind::MountDashpots {
            let c = Mat3::from_diagonal(&Vec3::new(
                self.values[3 * ctx.setup_index],
                self.values[3 * ctx.setup_index + 1],
                self.values[3 * ctx.setup_index + 2],
            ));
            for s in ctx.spec.springs(ctx.setup_index) {
                let t = rigid_transform(&s.at);
                model.damping += t.transpose() * c * t;
            }
        }
        Ok(())
    }
    /// A channel's gain reaches that channel's FRFs, an excitation's its own
    /// (`transform_output`), a sensor's misorientation its channels' (their output rows),
    /// a residual flexibility `R_ce` the FRF of c and e (the `at_channels[c]` of the
    /// mode driven by e alone); everything else reaches any FRF.
    fn parameter_reach(&self, g: &Geometry) -> Vec<Reach> {
        let n = self.values.len();
        let (n_ch, n_ex) = (g.channels.len(), g.excitations.len());
        (0..n)
            .map(|i| match self.kind {
                Kind::ChannelGain if n == n_ch => Reach::Channels(vec![i]),
                Kind::SensorMisorientation if n == 3 * self.groups.len() => {
                    Reach::Channels(self.groups[i / 3].clone())
                }
                Kind::ExcitationGain if n == n_ex => Reach::Excitation(i),
                Kind::ResidualFlexibility if n == n_ch * n_ex + 2 && i < n - 2 => Reach::Cell {
                    channel: i % n_ch,
                    excitation: i / n_ch,
                },
                _ => Reach::Any,
            })
            .collect()
    }
    fn transform_output(&self, block: &mut OutputBlock) {
        let nl = block.frequency_hz.len();
        match self.kind {
            Kind::ChannelGain => {
                for (c, v) in block.values.chunks_exact_mut(nl).enumerate() {
                    let g = 1.0 + self.values[c];
                    v.iter_mut().for_each(|x| *x *= g);
                }
            }
            Kind::ExcitationGain => {
                let g = 1.0 + self.values[block.excitation];
                block.values.iter_mut().for_each(|x| *x *= g);
            }
            Kind::GlobalGain => {
                let g = 1.0 + self.values[0];
                block.values.iter_mut().for_each(|x| *x *= g);
            }
            _ => {}
        }
    }
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
            id: "transducer_highpass".into(),
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
        id: "record_truncation".into(),
        parameters: t,
    })
    .map(Some)
}

/// A warning when the spec gives no `up` but its springs say the vertical is another
/// axis: cords and air springs are far stiffer along the vertical than across it, so a
/// summed spring stiffness whose stiffest principal axis is ≥ 3× the others and more than
/// 30° from z suggests a frame with another axis up (the gravity candidates would then
/// hang their cords across the real vertical).
pub fn vertical_axis_doubt(spec: &CampaignSpec) -> Option<String> {
    if spec.up.is_some() {
        return None;
    }
    let k: Mat3 = (0..spec.setups.len())
        .flat_map(|i| spec.springs(i))
        .map(|s| s.stiffness)
        .sum();
    let eig = k.symmetric_eigen();
    let mut order: Vec<usize> = (0..3).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let (top, next) = (eig.eigenvalues[order[0]], eig.eigenvalues[order[1]]);
    let axis = eig.eigenvectors.column(order[0]).into_owned();
    let dominant = top > 0.0 && top >= 3.0 * next.max(0.0);
    (dominant && axis.z.abs() < 30f64.to_radians().cos()).then(|| {
        format!(
            "the spec gives no `up`, so gravity is taken along −z; but its springs are stiffest along ({:.2}, {:.2}, {:.2}): if that is the vertical, set `up` in the spec (gravity_stiffness, cord_mass and sensor_tilt_gravity depend on it)",
            axis.x, axis.y, axis.z
        )
    })
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
        id: "cord_mass".into(),
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
    if reparametrised("transducer_highpass") && !in_spec.contains(&"transducer_highpass") {
        out.push(transducer_highpass_candidate(geometry));
    }
    if !in_spec.contains(&"record_truncation") {
        out.push(record_truncation_candidate(spec));
    }
    out.extend(cord_mass_candidate(spec, &in_spec, &mut notes));
    if !in_spec.contains(&"added_mass") {
        out.push(added_mass_candidate());
    }
    if !in_spec.contains(&"elastic_mode") && !spec.channels().is_empty() {
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
const REPEATABLE: [&str; 2] = ["elastic_mode", "residual_flexibility"];

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

/// The local effects ([`ALL`], in order) not in the spec and not already offered by the
/// catalogue. The sensor mass is screened by its rigid-mass gauge, gravity stiffness by a
/// cord-length profile when the nominal model has free directions, the others by a score.
fn local_candidates(
    spec: &CampaignSpec,
    geometry: &Geometry,
    in_spec: &[&str],
    out: &mut Vec<Candidate>,
    notes: &mut Vec<String>,
) {
    // Free directions in the nominal model: gravity turns zero-frequency modes into
    // in-band pendulum resonances, far from linear in φ at φ = 0, so it is screened by
    // a profile over cord lengths instead of a score (see [`gravity_profile`]).
    let has_free = free_direction_note(spec, geometry).is_some();
    // A free–free body has nothing to hang from: no gravity stiffness.
    let suspended = spec
        .setups
        .iter()
        .any(|s| !s.springs.is_empty() || !s.cords.is_empty());
    for k in ALL {
        if in_spec.contains(&k.id()) || out.iter().any(|c| c.id == k.id()) {
            continue;
        }
        if k == Kind::GravityStiffness && !suspended {
            notes.push("gravity_stiffness is not screened: no set-up has springs or cords".into());
            continue;
        }
        let e = LocalEffect::neutral(k, spec, geometry);
        let n_params = e.values.len();
        out.push(Candidate {
            id: k.id().to_string(),
            title: k.title().to_string(),
            neutral: e.values(),
            scales: e.scale(spec),
            effect: Box::new(e),
            source: if rbprops_sim::effects::descriptor(k.id()).is_some() {
                "rbprops-sim (reparametrised for screening)"
            } else {
                "rbprops-check (local)"
            },
            reveal: k.reveal(),
            screening: if k == Kind::SensorMass {
                Screening::RigidMassGauge
            } else if k == Kind::GravityStiffness && has_free {
                gravity_profile(spec, n_params)
            } else {
                Screening::Score
            },
            follows: None,
        });
    }
}

/// The transducer high-pass reparametrised by inverse time constants (one per sensor), so
/// that its neutral value, no high-pass, is 0 rather than an infinite time constant.
fn transducer_highpass_candidate(geometry: &Geometry) -> Candidate {
    let (title, reveal) = describe("transducer_highpass");
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
        id: "transducer_highpass".into(),
        title: title.into(),
        effect: Box::new(Reciprocal {
            id: "transducer_highpass",
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
fn record_truncation_candidate(spec: &CampaignSpec) -> Candidate {
    let (title, reveal) = describe("record_truncation");
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
        id: "record_truncation".into(),
        title: title.into(),
        effect: Box::new(Reciprocal {
            id: "record_truncation",
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
fn cord_mass_candidate(
    spec: &CampaignSpec,
    in_spec: &[&str],
    notes: &mut Vec<String>,
) -> Option<Candidate> {
    let has_springs = spec.setups.iter().any(|s| !s.springs.is_empty());
    let cord_profile = if in_spec.contains(&"cord_mass") || !has_springs {
        Vec::new()
    } else {
        mean_cord_tension(spec)
            .map(|t| cord_grid(t, spec.frequency.start_hz, spec.frequency.stop_hz))
            .unwrap_or_default()
    };
    if !in_spec.contains(&"cord_mass") && has_springs && cord_profile.is_empty() {
        notes.push("cord_mass is not screened: the springs hold no cord tension, or no cord of plausible length and mass has a string mode below 1.2× the band's top".into());
    }
    if cord_profile.is_empty() {
        return None;
    }
    let (title, reveal) = describe("cord_mass");
    let grid = cord_profile;
    Some(Candidate {
        id: "cord_mass".into(),
        title: title.into(),
        effect: Box::new(Reciprocal {
            id: "cord_mass",
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

/// The added mass's non-rigid part (its rigid part is absorbed by the free inertia),
/// screened by a score.
fn added_mass_candidate() -> Candidate {
    let (title, reveal) = describe("added_mass");
    let e = NonRigidMass { values: [0.0; 11] };
    Candidate {
        id: "added_mass".into(),
        title: title.into(),
        neutral: e.values(),
        scales: [vec![0.05; 5], vec![0.01; 6]].concat(),
        effect: Box::new(e),
        source: "rbprops-sim (its non-rigid part; the rigid part is the free inertia's)",
        reveal,
        screening: Screening::Score,
        follows: None,
    }
}

/// An elastic mode in the band, in its in-band form (one pole, a residue per channel and
/// excitation), screened by the resonance search.
fn elastic_mode_candidate(spec: &CampaignSpec) -> Candidate {
    let (title, reveal) = describe("elastic_mode");
    let e = crate::resonance::InBandResonance::neutral(spec);
    Candidate {
        id: "elastic_mode".into(),
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
    if e.id() == "record_truncation"
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
    let parameters = if e.id() == "gravity_stiffness"
        && e.parameters()
            .first()
            .is_some_and(|p| p.name == "inverse_cord_length_per_m")
    {
        let v = e.values();
        if !(v[0] > 0.0) {
            return Err("gravity_stiffness: fitted 1/ℓ is not positive".into());
        }
        let mut t = toml::Table::new();
        let (a, b) = (
            v.get(2).copied().unwrap_or(0.0),
            v.get(3).copied().unwrap_or(0.0),
        );
        if let Some(i) = spec.setups.iter().position(|s| !s.cords.is_empty()) {
            // Hanging lengths scaled by ρ = (1/φ₁)/L̄, written as unstretched lengths
            // L₀ = ρL − T/k (tensions of the nominal body: the fitted mass moves T/k by
            // the same fraction, well below the length's standard error).
            let z = tilted_direction(&spec.up_vector(), a, b);
            let eq = hanging(spec, i, &spec.properties().mass_matrix().0, &z)?;
            let lbar = eq.lengths.iter().sum::<f64>() / eq.lengths.len() as f64;
            let rho = 1.0 / (v[0] * lbar);
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
                toml::Value::Array(vec![(1.0 / v[0]).into()]),
            );
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

/// A local effect by id with given values (for fixtures and tests: the recording side).
pub fn local_effect(
    id: &str,
    spec: &CampaignSpec,
    values: &[f64],
) -> Result<Box<dyn Effect>, String> {
    let g = spec.geometry().map_err(|e| e.to_string())?;
    let k = ALL
        .iter()
        .find(|k| k.id() == id)
        .ok_or_else(|| format!("no local effect '{id}'"))?;
    LocalEffect::neutral(*k, spec, &g).with_values(values)
}

/// Lag scan of a residual for a truncated record (`record_truncation`). The leakage of a
/// record of length T is the impulse response's tail cut off at T, which at the lines
/// f_k reads `D(f_k) = −Σ_r R_r e^{λ_r T} e^{−i2πf_kT}/(i2πf_k − λ_r) + c.c.`: a smooth
/// envelope times e^{−i2πf_kT}. The tapered lag transform of the residual of FRF b,
/// `S_b(τ) = Σ_k w_k r_{b,k} e^{+i2πf_kτ}` (Hann taper w over the lines, so a step in
/// lag is smoothed monotonically), summed as `P(τ) = Σ_b |S_b(τ)|²`, therefore steps up
/// at τ = T and decays after it. The lags of the largest local maxima of dP/dτ and of P
/// in `[tau_lo, tau_hi]` (parabolic refinement, at most `n`, at least a resolution cell
/// 1/B apart; B the bandwidth) are returned with M = ⌈(tau_hi − tau_lo) B⌉, the number
/// of independent lags scanned (the profile is Bonferroni corrected for them).
/// `rows`: (FRF index, line index, normalised residual).
pub fn delay_peaks(
    rows: &[(usize, usize, rbprops_core::c64)],
    freqs: &[f64],
    tau_lo: f64,
    tau_hi: f64,
    n: usize,
) -> (Vec<f64>, usize) {
    use rayon::prelude::*;
    use rbprops_core::c64;
    let nl = freqs.len();
    if nl < 2 || !(tau_hi > tau_lo) {
        return (Vec::new(), 0);
    }
    let band = freqs[nl - 1] - freqs[0];
    let n_frf = rows.iter().map(|r| r.0 + 1).max().unwrap_or(0);
    // Line-major (`[line][FRF]`), real and imaginary parts apart: see `lag_sums`.
    let (mut re, mut im) = (vec![0.0; n_frf * nl], vec![0.0; n_frf * nl]);
    for &(b, k, v) in rows {
        let w = 0.5 - 0.5 * (std::f64::consts::TAU * k as f64 / (nl - 1) as f64).cos();
        let x = v * w;
        (re[k * n_frf + b], im[k * n_frf + b]) = (x.re, x.im);
    }
    let step = 1.0 / (4.0 * band);
    let m = ((tau_hi - tau_lo) / step).ceil() as usize + 1;
    let p: Vec<f64> = match lag_power_by_fft(&re, &im, freqs, n_frf, tau_lo, m) {
        Some(p) => p,
        None => (0..m)
            .into_par_iter()
            .map(|j| {
                let tau = tau_lo + j as f64 * step;
                let ph: Vec<c64> = freqs
                    .iter()
                    .map(|f| c64::from_polar(1.0, std::f64::consts::TAU * f * tau))
                    .collect();
                let (sr, si) = lag_sums(&re, &im, &ph, n_frf);
                sr.iter().zip(&si).map(|(r, i)| r * r + i * i).sum()
            })
            .collect(),
    };
    let dp: Vec<f64> = (0..m)
        .map(|j| p[(j + 1).min(m - 1)] - p[j.saturating_sub(1)])
        .collect();
    let mut picks: Vec<(f64, f64)> = Vec::new();
    for series in [&dp, &p] {
        let mut maxima: Vec<(f64, f64)> = (1..m.saturating_sub(1))
            .filter(|&j| series[j] > series[j - 1] && series[j] >= series[j + 1])
            .map(|j| {
                // Parabola through the three samples around the maximum.
                let (a, b, c) = (series[j - 1], series[j], series[j + 1]);
                let den = a - 2.0 * b + c;
                let off = if den < 0.0 { 0.5 * (a - c) / den } else { 0.0 };
                (b, tau_lo + (j as f64 + off) * step)
            })
            .collect();
        maxima.sort_by(|x, y| y.0.total_cmp(&x.0));
        for (_, tau) in maxima.into_iter().take(n.div_ceil(2)) {
            if picks.iter().all(|q| (q.1 - tau).abs() > 1.0 / band) {
                picks.push((0.0, tau));
            }
        }
    }
    let independent = ((tau_hi - tau_lo) * band).ceil() as usize;
    (
        picks.into_iter().map(|q| q.1).take(n).collect(),
        independent,
    )
}

/// `P(τ_j) = Σ_b |Σ_k x_bk e^{i2πf_kτ_j}|²` at the lags `τ_j = τ_lo + j/(4B)`, j < m, by
/// one FFT per FRF, when the lines are equally spaced (`None` otherwise).
///
/// With `f_k = f_0 + kΔf` and `B = (n_l − 1)Δf`, `f_kτ_j = f_0τ_j + kΔfτ_lo + kj/N` with
/// `N = 4(n_l − 1)`: the sum is `e^{i2πf_0τ_j}` (which |·|² drops) times the inverse DFT
/// of length N of `x_bk e^{i2πkΔfτ_lo}` at j (zero-padded; periodic in j, so m > N wraps
/// as the direct sum does). The direct sum over 3 800 lags × 1 000 lines × 54 FRFs was
/// 0.4 s per screening step; this is a few milliseconds, equal to rounding
/// (`lag_power_by_fft_is_the_direct_sum`).
fn lag_power_by_fft(
    re: &[f64],
    im: &[f64],
    freqs: &[f64],
    n_frf: usize,
    tau_lo: f64,
    m: usize,
) -> Option<Vec<f64>> {
    use rbprops_core::c64;
    let nl = freqs.len();
    let df = (freqs[nl - 1] - freqs[0]) / (nl - 1) as f64;
    let uniform = freqs
        .iter()
        .enumerate()
        .all(|(k, f)| (f - (freqs[0] + k as f64 * df)).abs() <= 1e-9 * df.abs().max(f.abs()));
    if !uniform || df <= 0.0 || n_frf == 0 {
        return None;
    }
    let n = 4 * (nl - 1);
    let fft = rustfft::FftPlanner::<f64>::new().plan_fft_inverse(n);
    let shift: Vec<c64> = (0..nl)
        .map(|k| c64::from_polar(1.0, std::f64::consts::TAU * k as f64 * df * tau_lo))
        .collect();
    let mut p = vec![0.0; m];
    let mut buf = vec![c64::new(0.0, 0.0); n];
    for b in 0..n_frf {
        buf.iter_mut().for_each(|z| *z = c64::new(0.0, 0.0));
        for (k, s) in shift.iter().enumerate() {
            buf[k] = c64::new(re[k * n_frf + b], im[k * n_frf + b]) * s;
        }
        fft.process(&mut buf);
        for (j, pj) in p.iter_mut().enumerate() {
            *pj += buf[j % n].norm_sqr();
        }
    }
    Some(p)
}

rbprops_core::avx_fn! {
    /// Per FRF b, `Σ_k x_bk e_k` (the residual's lag transform at one lag; `x`
    /// line-major, `re`/`im` at `k n_frf + b`), each sum in line order from zero with
    /// `num_complex`'s product (`re = xr er − xi ei`, `im = xr ei + xi er`): bit for bit
    /// the sums of the complex values one FRF at a time, with the FRFs innermost so the
    /// loop is a vector loop.
    fn lag_sums(
        re: &[f64],
        im: &[f64],
        ph: &[rbprops_core::c64],
        n_frf: usize,
    ) -> (Vec<f64>, Vec<f64>) {
        let (mut sr, mut si) = (vec![0.0; n_frf], vec![0.0; n_frf]);
        if n_frf == 0 {
            return (sr, si);
        }
        for ((xr, xi), e) in re.chunks_exact(n_frf).zip(im.chunks_exact(n_frf)).zip(ph) {
            for (((sr, si), xr), xi) in sr.iter_mut().zip(si.iter_mut()).zip(xr).zip(xi) {
                *sr += xr * e.re - xi * e.im;
                *si += xr * e.im + xi * e.re;
            }
        }
        (sr, si)
    }
}

/// `added_mass` restricted to the complement of the rigid-body mass structure (see the
/// module docs): `A = [[a_xx, a_xy, a_xz], [a_xy, a_yy, a_yz], [a_xz, a_yz, −a_xx − a_yy]]`
/// (traceless, kg) and `B` symmetric (kg m), `C = 0`.
#[derive(Debug, Clone)]
pub struct NonRigidMass {
    /// a_xx, a_yy, a_xy, a_xz, a_yz, then b_xx, b_yy, b_zz, b_xy, b_xz, b_yz.
    values: [f64; 11],
}

impl NonRigidMass {
    fn catalogue(&self) -> rbprops_sim::effects::mass::AddedMass {
        let v = &self.values;
        let a = [
            [v[0], v[2], v[3]],
            [v[2], v[1], v[4]],
            [v[3], v[4], -v[0] - v[1]],
        ];
        let b = [[v[5], v[8], v[9]], [v[8], v[6], v[10]], [v[9], v[10], v[7]]];
        rbprops_sim::effects::mass::AddedMass {
            translational_kg: a,
            coupling_kg_m: b,
            rotational_kg_m2: [[0.0; 3]; 3],
        }
    }
}

impl Effect for NonRigidMass {
    fn id(&self) -> &'static str {
        "added_mass"
    }
    fn order(&self) -> u8 {
        0
    }
    fn parameters(&self) -> Vec<ParamInfo> {
        let info = |name: &str, unit: &'static str| ParamInfo {
            name: name.to_string(),
            unit,
            lower: f64::NEG_INFINITY,
            upper: f64::INFINITY,
            plausible: (-1.0, 1.0),
        };
        let a = ["xx", "yy", "xy", "xz", "yz"]
            .map(|k| info(&format!("translational_deviator_kg.{k}"), "kg"));
        let b = ["xx", "yy", "zz", "xy", "xz", "yz"]
            .map(|k| info(&format!("coupling_symmetric_kg_m.{k}"), "kg m"));
        a.into_iter().chain(b).collect()
    }
    fn values(&self) -> Vec<f64> {
        self.values.to_vec()
    }
    fn with_values(&self, values: &[f64]) -> Result<Box<dyn Effect>, String> {
        let values: [f64; 11] = values
            .try_into()
            .map_err(|_| format!("added_mass expects 11 values, got {}", values.len()))?;
        if values.iter().any(|x| !x.is_finite()) {
            return Err("added_mass: values must be finite".into());
        }
        Ok(Box::new(NonRigidMass { values }))
    }
    /// The catalogue's form (`translational_kg`, `coupling_kg_m`, `rotational_kg_m2`).
    fn parameters_json(&self) -> serde_json::Value {
        self.catalogue().parameters_json()
    }
    fn modify_structure(
        &self,
        _ctx: &BuildContext,
        model: &mut DynamicModel,
    ) -> Result<(), String> {
        model.mass += self.catalogue().matrix();
        Ok(())
    }
}

#[cfg(test)]
mod lag_tests {
    use super::{delay_peaks, lag_sums};
    use rbprops_core::c64;

    /// A deterministic stream in [−1, 1) (xorshift64*).
    fn uniform(state: &mut u64) -> f64 {
        *state ^= *state >> 12;
        *state ^= *state << 25;
        *state ^= *state >> 27;
        (state.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    /// The lag power by FFT equals the direct sums over the lines to rounding, on an
    /// axis that does not start at 0 Hz and over more lags than one period.
    #[test]
    fn lag_power_by_fft_is_the_direct_sum() {
        let (n_frf, nl) = (5, 37);
        let freqs: Vec<f64> = (0..nl).map(|k| 0.25 + 0.125 * k as f64).collect();
        let mut st = 11u64;
        let (mut re, mut im) = (vec![0.0; n_frf * nl], vec![0.0; n_frf * nl]);
        for v in re.iter_mut().chain(im.iter_mut()) {
            *v = uniform(&mut st);
        }
        let band = freqs[nl - 1] - freqs[0];
        let (tau_lo, step) = (0.3, 1.0 / (4.0 * band));
        let m = 4 * (nl - 1) + 17;
        let p = super::lag_power_by_fft(&re, &im, &freqs, n_frf, tau_lo, m).expect("uniform");
        let scale = p.iter().fold(0.0f64, |a, &b| a.max(b));
        for (j, pj) in p.iter().enumerate() {
            let tau = tau_lo + j as f64 * step;
            let direct: f64 = (0..n_frf)
                .map(|b| {
                    (0..nl)
                        .map(|k| {
                            c64::new(re[k * n_frf + b], im[k * n_frf + b])
                                * c64::from_polar(1.0, std::f64::consts::TAU * freqs[k] * tau)
                        })
                        .sum::<c64>()
                        .norm_sqr()
                })
                .sum();
            assert!(
                (pj - direct).abs() <= 1e-12 * scale,
                "lag {j}: {pj} vs {direct}"
            );
        }
        let mut bent = freqs.clone();
        bent[3] += 0.01;
        assert!(super::lag_power_by_fft(&re, &im, &bent, n_frf, tau_lo, m).is_none());
    }

    /// The FRFs-innermost sums are the complex sums taken one FRF at a time, bit for bit
    /// (an odd number of FRFs, so the vector loop has a remainder).
    #[test]
    fn lag_sums_are_the_per_frf_complex_sums_bit_for_bit() {
        let (n_frf, nl) = (27, 101);
        let mut st = 7u64;
        let x: Vec<c64> = (0..n_frf * nl)
            .map(|_| c64::new(uniform(&mut st), uniform(&mut st)))
            .collect(); // [frf][line]
        let ph: Vec<c64> = (0..nl)
            .map(|k| c64::from_polar(1.0, 0.37 * k as f64))
            .collect();
        let mut re = vec![0.0; n_frf * nl];
        let mut im = vec![0.0; n_frf * nl];
        for b in 0..n_frf {
            for k in 0..nl {
                re[k * n_frf + b] = x[b * nl + k].re;
                im[k * n_frf + b] = x[b * nl + k].im;
            }
        }
        let (sr, si) = lag_sums(&re, &im, &ph, n_frf);
        for b in 0..n_frf {
            let s: c64 = x[b * nl..(b + 1) * nl]
                .iter()
                .zip(&ph)
                .map(|(x, e)| x * e)
                .sum();
            assert_eq!(
                (sr[b].to_bits(), si[b].to_bits()),
                (s.re.to_bits(), s.im.to_bits()),
                "FRF {b}"
            );
        }
    }

    /// A residual that is an echo delayed by T (`e^{−i2πfT}` times a smooth amplitude, as
    /// a truncated record leaves) is found at T, within a resolution cell 1/B.
    #[test]
    fn an_echo_is_found_at_its_delay() {
        let nl = 400;
        let freqs: Vec<f64> = (0..nl).map(|k| 1.0 + 0.25 * k as f64).collect();
        let t = 1.3;
        let rows: Vec<(usize, usize, c64)> = (0..3)
            .flat_map(|b| {
                freqs.iter().enumerate().map(move |(k, f)| {
                    let a = 1.0 + 0.3 * b as f64 + 0.001 * f;
                    (b, k, c64::from_polar(a, -std::f64::consts::TAU * f * t))
                })
            })
            .collect();
        let band = freqs[nl - 1] - freqs[0];
        let (taus, m) = delay_peaks(&rows, &freqs, 0.1, 3.8, 4);
        assert!(
            taus.iter().any(|tau| (tau - t).abs() < 1.0 / band),
            "{taus:?}"
        );
        assert_eq!(m, ((3.8 - 0.1) * band).ceil() as usize);
    }
}
