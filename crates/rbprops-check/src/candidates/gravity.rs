//! The model check's notes on a spec whose vertical or free directions are in doubt
//! (the gravity candidate's form itself is rbprops-sim's, beside its effect:
//! [`rbprops_sim::effects::gravity::screening`]).

use rbprops_core::{Geometry, Mat3};
use rbprops_sim::effects::gravity::screening::nominal_free_directions;
use rbprops_sim::CampaignSpec;

/// A warning when the nominal model leaves rigid-body directions free (zero-frequency
/// modes, e.g. cords read as axial springs, or a free–free body): their FRFs are mass
/// lines, the 0 Hz line cannot be modelled, and the gravity stiffness the cords would
/// add is screened like any candidate.
pub fn free_direction_note(spec: &CampaignSpec, geometry: &Geometry) -> Option<String> {
    let free = nominal_free_directions(spec, geometry);
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
