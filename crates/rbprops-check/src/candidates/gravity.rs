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
    rbprops_sim::effects::gravity::axial_cord_count(spec, i) > 0
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
///
/// Cords written as axial springs hang from anchors at ℓ = 1/φ₁ along their axes
/// ([`CORD_INVERSE_LENGTH`] bounds it), so `φ₁ ℓ Lat` is the cords' own tension part at
/// the fitted length, and their free lengths `ℓ − T/k + δ` carry the set-up's
/// cord-length (pose) contrasts δ ([`length_changes`] of its slot of `slots` in
/// `contrasts`, [`pose_contrasts`]):
/// at δ = 0 the body hangs in the drawn pose (the tensions of the elastic balance, and
/// then ℓ only scales `Lat`, exactly as before); unequal cords move and tilt it to the
/// equilibrium they make, as splayed cords of unequal lengths do.
pub(super) fn gravity_stiffness(
    ctx: &BuildContext,
    model: &DynamicModel,
    phi: &GravityPhi,
    slots: &[ContrastSlot],
) -> Result<Mat6, String> {
    use rbprops_sim::effects::gravity::{geometric_stiffness, Cord, STANDARD_GRAVITY};
    let z = phi.up(ctx.spec);
    if !ctx.spec.setups[ctx.setup_index].cords.is_empty() {
        let eq = hanging(ctx.spec, ctx.setup_index, &model.mass, &z)?;
        let lbar = eq.lengths.iter().sum::<f64>() / eq.lengths.len() as f64;
        let dk = eq.stiffness - ctx.spec.setup_stiffness(ctx.setup_index);
        return Ok(eq.lateral * (phi.inverse_length * lbar) + (dk - eq.lateral) * phi.load);
    }
    if let Some((cords, springs)) =
        contrasted_cords(ctx.spec, ctx.setup_index, &model.mass, phi, slots)
    {
        // Cords written as axial springs (vertical or splayed): hung like the set-up's
        // cords above, from anchors at ℓ, their free lengths changed by the set-up's
        // contrasts.
        let eq = rbprops_sim::effects::gravity::hanging_equilibrium(
            &model.mass,
            &cords,
            &springs,
            STANDARD_GRAVITY,
            &z,
        )
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
        if let Ok(eq) = hanging(ctx.spec, ctx.setup_index, &model.mass, &z) {
            let dk = eq.stiffness - ctx.spec.setup_stiffness(ctx.setup_index);
            load += (dk - kinf) * turn;
        }
    }
    Ok((k1 - kinf) * phi.inverse_length + load * phi.load)
}

/// Set-up `i`'s springs read as cords ([`rbprops_sim::effects::gravity::axial_spring_cords`]
/// for a body of mass matrix `mass` along the fitted vertical), anchored at
/// [`GravityPhi::anchor_length`], with free lengths `ℓ − T/k + δ`, δ the set-up's
/// contrasts of `slots` ([`length_changes`]); `None` when its springs are not cords.
fn contrasted_cords(
    spec: &CampaignSpec,
    i: usize,
    mass: &Mat6,
    phi: &GravityPhi,
    slots: &[ContrastSlot],
) -> Option<(
    Vec<rbprops_sim::effects::gravity::AnchoredCord>,
    Vec<rbprops_sim::suspension::Spring>,
)> {
    let ell = phi.anchor_length();
    let (mut cords, springs) = rbprops_sim::effects::gravity::axial_spring_cords(
        spec,
        i,
        mass,
        rbprops_sim::effects::gravity::STANDARD_GRAVITY,
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

/// Names of the gravity candidate's parameters (see [`gravity_stiffness`]).
pub(super) const INVERSE_LENGTH: &str = "inverse_cord_length_per_m";
pub(super) const LOAD_FACTOR: &str = "load_term_factor";
pub(super) const TILTS: [&str; 2] = ["up_tilt1_rad", "up_tilt2_rad"];
/// φ₅ (see [`gravity_stiffness`]).
pub(super) const SPRING_TURN: &str = "spring_turn_fraction";
/// What every cord-length contrast's name holds (`{set-up}.cord_length_contrast{k}_m`).
pub(super) const CONTRAST: &str = ".cord_length_contrast";

/// The gravity candidate's φ by meaning; absent parameters are 0.
#[derive(Debug, Clone, Copy)]
pub(super) struct GravityPhi<'a> {
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
pub(super) fn gravity_names(spec: &CampaignSpec, g: &Geometry) -> (Vec<String>, Vec<ContrastSlot>) {
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
pub(super) const CORD_INVERSE_LENGTH: (f64, f64) = (0.1, 20.0);

/// Where a set-up's cord-length contrasts sit in the gravity candidate's φ: set-up
/// index, first parameter, and the contrasts' patterns of free-length change (one
/// n-vector per contrast, orthonormal; see [`pose_contrasts`]).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct ContrastSlot {
    pub setup: usize,
    pub start: usize,
    pub patterns: Vec<Vec<f64>>,
}

/// The contrast slots of the set-ups whose springs are cords written as axial springs
/// (positions among the contrast parameters), and their names
/// (`{set-up}.cord_length_contrast{k}_m`).
pub(super) fn contrast_slots(spec: &CampaignSpec) -> (Vec<ContrastSlot>, Vec<String>) {
    let (mut slots, mut names) = (Vec::new(), Vec::new());
    let mass = spec.properties().mass_matrix().0;
    for (i, s) in spec.setups.iter().enumerate() {
        let Some((cords, _)) = rbprops_sim::effects::gravity::axial_spring_cords(
            spec,
            i,
            &mass,
            rbprops_sim::effects::gravity::STANDARD_GRAVITY,
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
pub(super) fn pose_contrasts(cords: &[(Vec3, Vec3)]) -> Vec<Vec<f64>> {
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
pub(super) fn length_changes(c: &[f64], patterns: &[Vec<f64>]) -> Vec<f64> {
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
pub(super) fn axial_free_lengths(
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

#[cfg(test)]
mod tests {
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
