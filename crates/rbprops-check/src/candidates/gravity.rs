//! The gravity candidate's screening form: the suspension's geometric stiffness
//! under gravity, reparametrised so that "absent" is a point of its parameter space
//! (see the local `gravity_stiffness`), its profile, and the notes on a spec
//! whose vertical or free directions are in doubt.

use super::local::tilted_direction;
use super::Screening;
use rbprops_core::{Geometry, Mat3, Mat6, Vec3};
use rbprops_sim::effects::BuildContext;
use rbprops_sim::model::DynamicModel;
use rbprops_sim::CampaignSpec;

/// Whether φ₅ is a parameter of the gravity candidate: some set-up hangs on springs
/// alone (no cords: a cord set-up's hanging equilibrium already turns its springs), and
/// the nominal model leaves no rigid direction free (springs that cannot hold the body
/// have no sagged equilibrium to turn about). Elsewhere φ₅ would have no signature.
pub(super) fn springs_can_sag(spec: &CampaignSpec, g: &Geometry) -> bool {
    spec.setups
        .iter()
        .enumerate()
        .any(|(i, s)| s.cords.is_empty() && !s.springs.is_empty() && !axial_springs_hang(spec, i))
        && free_direction_note(spec, g).is_none()
}

/// Set-up `i`'s springs are cords written as axial springs (rbprops-sim's
/// [`rbprops_sim::effects::gravity::axial_spring_cords`]): the gravity candidate hangs
/// the body on them as on cords.
fn axial_springs_hang(spec: &CampaignSpec, i: usize) -> bool {
    rbprops_sim::effects::gravity::axial_spring_cords(
        spec,
        i,
        &spec.properties().mass_matrix().0,
        rbprops_sim::effects::gravity::STANDARD_GRAVITY,
        &spec.up_vector(),
        |_| 1.0,
    )
    .is_some()
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
pub(super) fn gravity_stiffness(
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
    if let Some((cords, springs)) = rbprops_sim::effects::gravity::axial_spring_cords(
        ctx.spec,
        ctx.setup_index,
        &model.mass,
        STANDARD_GRAVITY,
        &z,
        |_| 1.0,
    ) {
        // Cords written as axial springs (vertical or splayed): hung like the set-up's
        // cords above, at 1 m (φ₁ scales the tension part to the fitted length), their
        // axes turned with the tilted vertical (φ₃, φ₄).
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
pub(super) fn hanging(
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
pub(super) fn gravity_profile(spec: &CampaignSpec, n_params: usize) -> Screening {
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
