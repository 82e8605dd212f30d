//! The campaign spec: a TOML description of a simulated test (body, suspension set-ups,
//! sensors, excitations, damping, noise, effects).
//!
//! Parsing is strict (`deny_unknown_fields`); [`CampaignSpec::validate`] then checks the
//! content and reports every problem with its TOML path (array indices are 0-based),
//! e.g. `sensor[2].direction: not a unit vector (|d| = 1.41)`.

use crate::error::{SpecError, SpecIssue};
use crate::suspension::{mount_stiffness, Spring};
use rbprops_core::geometry::UNIT_TOLERANCE;
use rbprops_core::inertia::ProductsOfInertia;
use rbprops_core::{
    Channel, Excitation, Geometry, Mat3, Point, Quantity, RigidBodyProperties, SuspensionSetup,
    Vec3,
};
use serde::{Deserialize, Serialize};

/// Largest number of spectral lines a spec may ask for.
pub const MAX_LINES: usize = 10_000_000;

/// A whole simulated test campaign.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CampaignSpec {
    /// Campaign name.
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Seed of the noise generator (see [`crate::noise`]).
    #[serde(default)]
    pub seed: u64,
    /// What the FRFs measure: `receptance`, `mobility` or `accelerance`.
    pub quantity: Quantity,
    /// The frequency axis.
    pub frequency: FrequencySpec,
    /// The rigid body whose properties are to be identified.
    pub body: BodySpec,
    /// Suspension set-ups (TOML `[[setup]]`).
    #[serde(rename = "setup")]
    pub setups: Vec<SetupSpec>,
    /// Sensors, giving the response channels (TOML `[[sensor]]`).
    #[serde(rename = "sensor")]
    pub sensors: Vec<SensorSpec>,
    /// Force inputs (TOML `[[excitation]]`).
    #[serde(rename = "excitation")]
    pub excitations: Vec<ExcitationSpec>,
    /// Viscous damping of the nominal model.
    pub damping: DampingSpec,
    /// Measurement noise; none when absent.
    #[serde(default)]
    pub noise: NoiseSpec,
    /// Upward unit vector of the geometry frame (gravity acts along −`up`); +z when
    /// absent. It is the default `up` of the gravity effects ([`crate::effects::GRAVITY_EFFECTS`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub up: Option<[f64; 3]>,
    /// Effects beyond the nominal model (TOML `[[effect]]`), applied in order.
    #[serde(rename = "effect", default, skip_serializing_if = "Vec::is_empty")]
    pub effects: Vec<EffectSpec>,
}

/// Uniform frequency axis with inclusive ends: `f_l = start + l (stop − start)/(lines − 1)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrequencySpec {
    /// First line (Hz).
    pub start_hz: f64,
    /// Last line (Hz).
    pub stop_hz: f64,
    /// Number of lines (at least 2, at most [`MAX_LINES`]).
    pub lines: usize,
}

/// The rigid body: mass, CoM in the geometry frame and inertia at the CoM, given either as
/// the tensor or as moments plus CAD products (tensor entry = −product, docs/conventions.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodySpec {
    /// Mass (kg).
    pub mass_kg: f64,
    /// Centre of mass in the geometry frame (m).
    pub com_m: [f64; 3],
    /// Inertia tensor at the CoM in kg m² (symmetric positive definite); or give `moments_kg_m2`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inertia_cm_kg_m2: Option<[[f64; 3]; 3]>,
    /// Moments of inertia `J_xx, J_yy, J_zz` at the CoM, frame axes (kg m²); needs `products_kg_m2`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub moments_kg_m2: Option<[f64; 3]>,
    /// CAD products of inertia at the CoM (kg m²), given with the moments (zero for principal axes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub products_kg_m2: Option<ProductsSpec>,
}

/// Products of inertia `J_xy = ∫xy dm` etc. (CAD sense).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProductsSpec {
    /// `J_xy` (kg m²).
    pub xy: f64,
    /// `J_xz` (kg m²).
    pub xz: f64,
    /// `J_yz` (kg m²).
    pub yz: f64,
}

/// One suspension set-up: linear springs and elastic cords between body points and the
/// ground. None at all is a free–free body.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SetupSpec {
    /// Set-up id, referenced by the excitations.
    pub id: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Springs (TOML `[[setup.spring]]`).
    #[serde(rename = "spring", default)]
    pub springs: Vec<SpringSpec>,
    /// Elastic cords (TOML `[[setup.cord]]`).
    #[serde(rename = "cord", default, skip_serializing_if = "Vec::is_empty")]
    pub cords: Vec<CordSpec>,
}

/// An elastic suspension cord from the body point `at_m` to the fixed anchor `anchor_m`,
/// both in the geometry frame with the body at its reference pose (the pose the spec's
/// geometry describes). Without gravity in the model it is the axial spring
/// `k e eᵀ` at `at_m`, `e` the unit vector from `at_m` to `anchor_m` (what a tester
/// writes for a cord). With the `gravity_stiffness` effect the body hangs: the cord's
/// tension is `k (L − L₀)` at its stretched length `L`, the body moves to the static
/// equilibrium of the weight and the cords (finite rotations), and the model is
/// linearised there, tension (geometric) stiffness included
/// ([`crate::effects::gravity::hanging_equilibrium`]).
///
/// `unstretched_length_m` is the cord's free length L₀ (choice: a property of the cord
/// that does not depend on the load, so the equilibrium is well defined for any cords,
/// splayed or not; the length as it hangs is `L₀ + T/k`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CordSpec {
    /// Body attachment point (m).
    pub at_m: [f64; 3],
    /// Fixed anchor point (m).
    pub anchor_m: [f64; 3],
    /// Axial stiffness `k` (N/m).
    pub axial_stiffness_n_per_m: f64,
    /// Free length `L₀` in m (only used when the body hangs under gravity).
    pub unstretched_length_m: f64,
}

/// A spring at body point `at_m`: diagonal stiffness or a full symmetric PSD 3×3.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpringSpec {
    /// Body attachment point (m).
    pub at_m: [f64; 3],
    /// Stiffnesses along x, y, z in N/m (a diagonal `k`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness_n_per_m: Option<[f64; 3]>,
    /// Full symmetric positive semi-definite stiffness (N/m), instead of the diagonal.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness_matrix_n_per_m: Option<[[f64; 3]; 3]>,
}

/// How many channels a sensor has.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SensorKind {
    /// Three orthogonal channels.
    Triaxial,
    /// One channel along `direction`.
    Uniaxial,
}

/// A sensor. Triaxial: channels `<id>x`, `<id>y`, `<id>z` along the frame axes, or
/// `<id>:1`, `<id>:2`, `<id>:3` along the rows of `axes` when given. Uniaxial: one
/// channel `<id>` along `direction`. `channels` names them explicitly instead, one id per
/// axis in the same order (e.g. `["101x", "101y", "101z"]` as a UFF export names them).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorSpec {
    /// Sensor id, also its geometry point's id.
    pub id: String,
    /// Position in the geometry frame (m).
    pub at_m: [f64; 3],
    /// Triaxial or uniaxial.
    pub kind: SensorKind,
    /// Triaxial: the three sensing directions as rows (orthonormal); frame axes when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axes: Option<[[f64; 3]; 3]>,
    /// Uniaxial: the unit sensing direction.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub direction: Option<[f64; 3]>,
    /// Explicit channel ids, one per axis (3 for a triaxial sensor, 1 for a uniaxial).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub channels: Option<Vec<String>>,
}

/// A unit force along `direction` at `at_m`, applied with the body in set-up `setup`.
/// `point` names the geometry point (default: the excitation id); naming a sensor puts
/// the force at that sensor (a driving point), and then the positions must agree.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExcitationSpec {
    /// Excitation id.
    pub id: String,
    /// Point of application (m).
    pub at_m: [f64; 3],
    /// Unit force direction.
    pub direction: [f64; 3],
    /// Id of the set-up the body is in.
    pub setup: String,
    /// Geometry point the force acts at; the excitation id when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point: Option<String>,
}

/// How the nominal model is damped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DampingModel {
    /// Damping ratio per mode of the set-up: `C = M Φ diag(2ζ_r ω_r) Φᵀ M`.
    Modal,
    /// Rayleigh damping `C = αM + βK`; `ζ_r = α/(2ω_r) + βω_r/2`.
    Proportional,
}

/// Viscous damping of the nominal model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DampingSpec {
    /// Modal or proportional (Rayleigh).
    pub model: DampingModel,
    /// `modal`: one ratio for every mode.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ratio: Option<f64>,
    /// `modal`: six ratios, by ascending mode frequency (a free direction, at 0 Hz, takes
    /// none: `2ζω = 0`; its ratio counts again once gravity gives it a frequency).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ratios: Option<Vec<f64>>,
    /// `proportional`: mass coefficient α (1/s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alpha: Option<f64>,
    /// `proportional`: stiffness coefficient β (s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beta: Option<f64>,
}

/// Additive circular complex noise per value, `E|ε|² = relative²·|H|² + floor²` (see
/// [`rbprops_core::noise`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct NoiseSpec {
    /// Relative level: the noise's RMS as a fraction of |H|.
    #[serde(default)]
    pub relative: f64,
    /// Absolute floor: RMS of the noise independent of |H|, in FRF units.
    #[serde(default)]
    pub floor: f64,
}

/// An effect of the physics catalogue: its id and its parameters (checked by the effect).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EffectSpec {
    /// The effect's id in the catalogue ([`crate::effects`]).
    pub id: String,
    /// The effect's parameters, as the TOML entry gives them.
    #[serde(flatten)]
    pub parameters: toml::Table,
}

/// `up` as a TOML array, for an effect entry.
pub fn up_value(up: [f64; 3]) -> toml::Value {
    toml::Value::Array(up.iter().map(|&x| x.into()).collect())
}

fn v3(a: &[f64; 3]) -> Vec3 {
    Vec3::new(a[0], a[1], a[2])
}

fn m3(a: &[[f64; 3]; 3]) -> Mat3 {
    Mat3::from_fn(|r, c| a[r][c])
}

/// Collects issues while walking the spec.
#[derive(Default)]
pub(crate) struct Issues(pub Vec<SpecIssue>);

impl Issues {
    pub fn push(&mut self, path: impl Into<String>, problem: impl Into<String>) {
        self.0.push(SpecIssue {
            path: path.into(),
            problem: problem.into(),
        });
    }
    fn finite(&mut self, path: &str, xs: &[f64]) -> bool {
        if let Some(x) = xs.iter().find(|x| !x.is_finite()) {
            self.push(path, format!("value {x} is not finite"));
            false
        } else {
            true
        }
    }
    fn unit(&mut self, path: &str, d: &[f64; 3]) -> bool {
        if !self.finite(path, d) {
            return false;
        }
        let n = v3(d).norm();
        if (n - 1.0).abs() > UNIT_TOLERANCE {
            self.push(path, format!("not a unit vector (|d| = {n:.6})"));
            return false;
        }
        true
    }
    fn id(&mut self, path: &str, id: &str, seen: &mut std::collections::BTreeSet<String>) {
        if id.trim().is_empty() {
            self.push(path, "empty id");
        } else if !seen.insert(id.to_string()) {
            self.push(path, format!("id '{id}' is used twice"));
        }
    }
}

fn symmetric(a: &Mat3) -> bool {
    (a - a.transpose()).abs().max() <= 1e-9 * a.abs().max().max(f64::MIN_POSITIVE)
}

impl CampaignSpec {
    /// Parses and validates a spec.
    pub fn from_toml_str(text: &str) -> Result<CampaignSpec, SpecError> {
        let spec: CampaignSpec =
            toml::from_str(text).map_err(|e| SpecError::Toml(e.to_string()))?;
        spec.validate()?;
        Ok(spec)
    }

    /// The upward unit vector of the geometry frame (+z unless the spec says otherwise).
    pub fn up_vector(&self) -> Vec3 {
        v3(&self.up.unwrap_or([0.0, 0.0, 1.0]))
    }

    /// Same as [`Self::from_toml_str`] for raw bytes (which must be UTF-8).
    pub fn from_toml_bytes(bytes: &[u8]) -> Result<CampaignSpec, SpecError> {
        let text = std::str::from_utf8(bytes).map_err(|e| {
            SpecError::Toml(format!("not UTF-8 text (byte {}): {e}", e.valid_up_to()))
        })?;
        Self::from_toml_str(text)
    }

    /// The spec as TOML (what `frf-sim --print-spec` shows); parses back to an equal spec.
    pub fn to_toml_string(&self) -> String {
        // Every field is a plain number, string, array or table: serialisation cannot fail.
        toml::to_string(self).expect("a campaign spec always serialises to TOML")
    }

    /// Checks everything that does not need the dynamics solved; lists every problem.
    pub fn validate(&self) -> Result<(), SpecError> {
        let mut is = Issues::default();
        if self.name.trim().is_empty() {
            is.push("name", "empty campaign name");
        }
        self.check_frequency(&mut is);
        self.check_body(&mut is);
        self.check_setups(&mut is);
        let sensors_ok = self.check_sensors(&mut is);
        self.check_excitations(&mut is);
        if sensors_ok {
            if let Err(e) = self.geometry_unchecked().check_rigid_observability() {
                is.push("sensor", e.to_string());
            }
        }
        self.check_damping(&mut is);
        if !(self.noise.relative.is_finite() && self.noise.relative >= 0.0) {
            is.push(
                "noise.relative",
                format!("must be finite and ≥ 0, got {}", self.noise.relative),
            );
        }
        if let Some(up) = self.up {
            let n = v3(&up).norm();
            if !n.is_finite() || (n - 1.0).abs() > 1e-6 {
                is.push("up", format!("not a unit vector (|up| = {n:.6})"));
            }
        }
        if !(self.noise.floor.is_finite() && self.noise.floor >= 0.0) {
            is.push(
                "noise.floor",
                format!("must be finite and ≥ 0, got {}", self.noise.floor),
            );
        }
        for (i, e) in self.effects.iter().enumerate() {
            match crate::effects::parse_effect_in(e, self) {
                Err(problem) => is.push(format!("effect[{i}]"), problem),
                Ok(eff) => {
                    if let Err(problem) = eff.check(self) {
                        is.push(format!("effect[{i}] '{}'", e.id), problem);
                    }
                }
            }
        }
        if is.0.is_empty() {
            Ok(())
        } else {
            Err(SpecError::Invalid(is.0))
        }
    }

    fn check_frequency(&self, is: &mut Issues) {
        let f = &self.frequency;
        if !(f.start_hz.is_finite() && f.start_hz >= 0.0) {
            is.push(
                "frequency.start_hz",
                format!("must be finite and ≥ 0, got {}", f.start_hz),
            );
        }
        if !(f.stop_hz.is_finite() && f.stop_hz > f.start_hz) {
            is.push(
                "frequency.stop_hz",
                format!(
                    "must be finite and above start_hz ({}), got {}",
                    f.start_hz, f.stop_hz
                ),
            );
        }
        if f.lines < 2 || f.lines > MAX_LINES {
            is.push(
                "frequency.lines",
                format!("must be between 2 and {MAX_LINES}, got {}", f.lines),
            );
        }
    }

    fn check_body(&self, is: &mut Issues) -> bool {
        let b = &self.body;
        let before = is.0.len();
        if !(b.mass_kg.is_finite() && b.mass_kg > 0.0) {
            is.push(
                "body.mass_kg",
                format!("must be positive and finite, got {}", b.mass_kg),
            );
        }
        is.finite("body.com_m", &b.com_m);
        match (&b.inertia_cm_kg_m2, &b.moments_kg_m2, &b.products_kg_m2) {
            (Some(j), None, None) => {
                if is.finite("body.inertia_cm_kg_m2", j.as_flattened()) && !symmetric(&m3(j)) {
                    is.push("body.inertia_cm_kg_m2", "the tensor is not symmetric");
                }
            }
            (None, Some(m), Some(p)) => {
                is.finite("body.moments_kg_m2", m);
                is.finite("body.products_kg_m2", &[p.xy, p.xz, p.yz]);
            }
            (None, Some(_), None) => is.push(
                "body.products_kg_m2",
                "missing: give products with the moments (all zero for principal axes)",
            ),
            (None, None, Some(_)) => is.push("body.moments_kg_m2", "missing"),
            (None, None, None) => is.push(
                "body",
                "give the inertia as inertia_cm_kg_m2 or as moments_kg_m2 + products_kg_m2",
            ),
            (Some(_), _, _) => is.push(
                "body",
                "give the inertia either as inertia_cm_kg_m2 or as moments_kg_m2 + products_kg_m2, not both",
            ),
        }
        if is.0.len() > before {
            return false;
        }
        let v = self.properties().consistency_violations();
        for problem in &v {
            is.push("body", format!("inertia is not physical: {problem}"));
        }
        v.is_empty()
    }

    fn check_setups(&self, is: &mut Issues) {
        if self.setups.is_empty() {
            is.push("setup", "no suspension set-up defined");
        }
        let mut seen = Default::default();
        for (i, s) in self.setups.iter().enumerate() {
            let path = format!("setup[{i}]");
            is.id(&format!("{path}.id"), &s.id, &mut seen);
            // No spring and no cord is a free–free body: six zero-frequency modes.
            for (j, sp) in s.springs.iter().enumerate() {
                let p = format!("{path}.spring[{j}]");
                is.finite(&format!("{p}.at_m"), &sp.at_m);
                match (&sp.stiffness_n_per_m, &sp.stiffness_matrix_n_per_m) {
                    (Some(k), None) => {
                        if is.finite(&format!("{p}.stiffness_n_per_m"), k)
                            && k.iter().any(|&x| x < 0.0)
                        {
                            is.push(
                                format!("{p}.stiffness_n_per_m"),
                                format!("negative stiffness {k:?}"),
                            );
                        }
                    }
                    (None, Some(k)) => {
                        let path = format!("{p}.stiffness_matrix_n_per_m");
                        if is.finite(&path, k.as_flattened()) {
                            let k = m3(k);
                            if !symmetric(&k) {
                                is.push(path, "not symmetric");
                            } else {
                                let ev = k.symmetric_eigenvalues();
                                if ev.min() < -1e-12 * ev.abs().max() {
                                    is.push(
                                        path,
                                        format!(
                                            "not positive semi-definite (eigenvalue {:.4e})",
                                            ev.min()
                                        ),
                                    );
                                }
                            }
                        }
                    }
                    _ => is.push(
                        p,
                        "give exactly one of stiffness_n_per_m and stiffness_matrix_n_per_m",
                    ),
                }
            }
            for (j, c) in s.cords.iter().enumerate() {
                let p = format!("{path}.cord[{j}]");
                let ok = is.finite(&format!("{p}.at_m"), &c.at_m)
                    & is.finite(&format!("{p}.anchor_m"), &c.anchor_m);
                if !(c.axial_stiffness_n_per_m.is_finite() && c.axial_stiffness_n_per_m > 0.0) {
                    is.push(
                        format!("{p}.axial_stiffness_n_per_m"),
                        format!(
                            "must be positive and finite, got {}",
                            c.axial_stiffness_n_per_m
                        ),
                    );
                }
                if !(c.unstretched_length_m.is_finite() && c.unstretched_length_m > 0.0) {
                    is.push(
                        format!("{p}.unstretched_length_m"),
                        format!(
                            "must be positive and finite, got {}",
                            c.unstretched_length_m
                        ),
                    );
                }
                if ok && (v3(&c.anchor_m) - v3(&c.at_m)).norm() < 1e-9 {
                    is.push(
                        format!("{p}.anchor_m"),
                        "the anchor coincides with the attachment point: the cord has no direction",
                    );
                }
            }
            // A direction the springs leave free (vertical cords read as axial springs, a
            // free–free body) is a zero-frequency mode, not an error: the FRFs are finite
            // at every ω > 0 (see `crate::simulate`).
        }
    }

    fn check_sensors(&self, is: &mut Issues) -> bool {
        let before = is.0.len();
        if self.sensors.is_empty() {
            is.push("sensor", "no sensor defined");
        }
        let mut seen = Default::default();
        for (i, s) in self.sensors.iter().enumerate() {
            let path = format!("sensor[{i}]");
            is.id(&format!("{path}.id"), &s.id, &mut seen);
            is.finite(&format!("{path}.at_m"), &s.at_m);
            match s.kind {
                SensorKind::Triaxial => {
                    if s.direction.is_some() {
                        is.push(
                            format!("{path}.direction"),
                            "a triaxial sensor takes `axes`, not `direction`",
                        );
                    }
                    if let Some(ax) = &s.axes {
                        let mut ok = true;
                        for (k, row) in ax.iter().enumerate() {
                            ok &= is.unit(&format!("{path}.axes[{k}]"), row);
                        }
                        if ok && m3(ax).determinant().abs() < 0.5 {
                            is.push(
                                format!("{path}.axes"),
                                format!(
                                    "the three axes are nearly coplanar (det = {:.3})",
                                    m3(ax).determinant()
                                ),
                            );
                        }
                    }
                }
                SensorKind::Uniaxial => {
                    if s.axes.is_some() {
                        is.push(
                            format!("{path}.axes"),
                            "a uniaxial sensor takes `direction`, not `axes`",
                        );
                    }
                    match &s.direction {
                        Some(d) => {
                            is.unit(&format!("{path}.direction"), d);
                        }
                        None => is.push(format!("{path}.direction"), "missing"),
                    }
                }
            }
        }
        for (i, s) in self.sensors.iter().enumerate() {
            let want = match s.kind {
                SensorKind::Triaxial => 3,
                SensorKind::Uniaxial => 1,
            };
            if let Some(ids) = &s.channels {
                if ids.len() != want {
                    is.push(
                        format!("sensor[{i}].channels"),
                        format!(
                            "a {} sensor has {want} channel id(s), got {}",
                            if want == 3 { "triaxial" } else { "uniaxial" },
                            ids.len()
                        ),
                    );
                }
                if ids.iter().any(|c| c.trim().is_empty()) {
                    is.push(format!("sensor[{i}].channels"), "empty channel id");
                }
            }
        }
        let mut ch = std::collections::BTreeSet::new();
        for c in self.channels() {
            if !ch.insert(c.id.clone()) {
                is.push("sensor", format!("channel id '{}' arises twice", c.id));
            }
        }
        is.0.len() == before
    }

    fn check_excitations(&self, is: &mut Issues) {
        if self.excitations.is_empty() {
            is.push("excitation", "no excitation defined");
        }
        let mut seen = Default::default();
        for (i, e) in self.excitations.iter().enumerate() {
            let path = format!("excitation[{i}]");
            is.id(&format!("{path}.id"), &e.id, &mut seen);
            is.finite(&format!("{path}.at_m"), &e.at_m);
            is.unit(&format!("{path}.direction"), &e.direction);
            if !self.setups.iter().any(|s| s.id == e.setup) {
                let known: Vec<&str> = self.setups.iter().map(|s| s.id.as_str()).collect();
                is.push(
                    format!("{path}.setup"),
                    format!(
                        "excitation '{}': set-up '{}' is not defined (defined: {})",
                        e.id,
                        e.setup,
                        known.join(", ")
                    ),
                );
            }
            if let Some(p) = &e.point {
                if let Some(s) = self.sensors.iter().find(|s| &s.id == p) {
                    if (v3(&s.at_m) - v3(&e.at_m)).norm() > 1e-9 {
                        is.push(
                            format!("{path}.point"),
                            format!(
                                "excitation '{}' names sensor point '{p}' but at_m {:?} differs from the sensor's {:?}",
                                e.id, e.at_m, s.at_m
                            ),
                        );
                    }
                }
            }
        }
    }

    fn check_damping(&self, is: &mut Issues) {
        let d = &self.damping;
        let ratio_ok = |x: f64| x.is_finite() && (0.0..1.0).contains(&x);
        match d.model {
            DampingModel::Modal => {
                if d.alpha.is_some() || d.beta.is_some() {
                    is.push(
                        "damping",
                        "model 'modal' takes ratio or ratios, not alpha/beta",
                    );
                }
                match (d.ratio, &d.ratios) {
                    (Some(r), None) => {
                        if !ratio_ok(r) {
                            is.push("damping.ratio", format!("must be in [0, 1), got {r}"));
                        }
                    }
                    (None, Some(rs)) => {
                        if rs.len() != 6 {
                            is.push(
                                "damping.ratios",
                                format!("needs 6 ratios (one per rigid mode), got {}", rs.len()),
                            );
                        }
                        for (k, &r) in rs.iter().enumerate() {
                            if !ratio_ok(r) {
                                is.push(
                                    format!("damping.ratios[{k}]"),
                                    format!("must be in [0, 1), got {r}"),
                                );
                            }
                        }
                    }
                    _ => is.push(
                        "damping",
                        "model 'modal' needs exactly one of ratio and ratios",
                    ),
                }
            }
            DampingModel::Proportional => {
                if d.ratio.is_some() || d.ratios.is_some() {
                    is.push(
                        "damping",
                        "model 'proportional' takes alpha and beta, not ratios",
                    );
                }
                if d.alpha.is_none() && d.beta.is_none() {
                    is.push("damping", "model 'proportional' needs alpha and/or beta");
                }
                for (name, v) in [("alpha", d.alpha), ("beta", d.beta)] {
                    if let Some(x) = v {
                        if !(x.is_finite() && x >= 0.0) {
                            is.push(
                                format!("damping.{name}"),
                                format!("must be finite and ≥ 0, got {x}"),
                            );
                        }
                    }
                }
            }
        }
    }

    /// The body's inertia properties (call after validation).
    pub fn properties(&self) -> RigidBodyProperties {
        let b = &self.body;
        let com = v3(&b.com_m);
        match (&b.inertia_cm_kg_m2, &b.moments_kg_m2, &b.products_kg_m2) {
            (Some(j), _, _) => RigidBodyProperties {
                mass: b.mass_kg,
                com,
                // Symmetric within 1e-9 after validation; remove the rounding residue.
                inertia_cm: (m3(j) + m3(j).transpose()) / 2.0,
            },
            (None, Some(m), p) => {
                let p = p.unwrap_or(ProductsSpec {
                    xy: 0.0,
                    xz: 0.0,
                    yz: 0.0,
                });
                RigidBodyProperties::from_moments_and_products(
                    b.mass_kg,
                    com,
                    *m,
                    ProductsOfInertia {
                        xy: p.xy,
                        xz: p.xz,
                        yz: p.yz,
                    },
                )
            }
            (None, None, _) => RigidBodyProperties {
                mass: b.mass_kg,
                com,
                inertia_cm: Mat3::from_diagonal_element(f64::NAN),
            },
        }
    }

    /// The springs of set-up `i` as stiffness matrices: the linear springs, then each cord
    /// as its axial spring `k e eᵀ` at the reference pose (the model without gravity).
    pub fn springs(&self, i: usize) -> Vec<Spring> {
        let mut out = self.plain_springs(i);
        out.extend(self.cords(i).iter().map(|c| c.axial_spring()));
        out
    }

    /// The cords of set-up `i` (see [`CordSpec`]).
    pub fn cords(&self, i: usize) -> Vec<crate::effects::gravity::AnchoredCord> {
        self.setups[i]
            .cords
            .iter()
            .map(|c| crate::effects::gravity::AnchoredCord {
                at: v3(&c.at_m),
                anchor: v3(&c.anchor_m),
                axial_stiffness: c.axial_stiffness_n_per_m,
                unstretched_length: c.unstretched_length_m,
            })
            .collect()
    }

    /// The linear springs of set-up `i` without its cords.
    pub fn plain_springs(&self, i: usize) -> Vec<Spring> {
        self.setups[i]
            .springs
            .iter()
            .map(|s| Spring {
                at: v3(&s.at_m),
                stiffness: match (&s.stiffness_n_per_m, &s.stiffness_matrix_n_per_m) {
                    (Some(k), _) => Mat3::from_diagonal(&v3(k)),
                    (None, Some(k)) => (m3(k) + m3(k).transpose()) / 2.0,
                    (None, None) => Mat3::zeros(),
                },
            })
            .collect()
    }

    /// Mount stiffness of set-up `i` about the origin, `K = Σ T(a)ᵀ k T(a)`.
    pub fn setup_stiffness(&self, i: usize) -> rbprops_core::Mat6 {
        mount_stiffness(&self.springs(i))
    }

    /// The frequency axis (Hz), inclusive ends.
    pub fn frequency_axis(&self) -> Vec<f64> {
        let f = &self.frequency;
        let n = f.lines;
        let step = (f.stop_hz - f.start_hz) / (n.max(2) - 1) as f64;
        let mut v: Vec<f64> = (0..n).map(|l| f.start_hz + l as f64 * step).collect();
        if let Some(last) = v.last_mut() {
            *last = f.stop_hz;
        }
        v
    }

    /// Channels in spec order (sensor by sensor).
    pub fn channels(&self) -> Vec<Channel> {
        let mut out = Vec::new();
        for s in &self.sensors {
            let position = v3(&s.at_m);
            match s.kind {
                SensorKind::Triaxial => {
                    let (axes, mut names): ([[f64; 3]; 3], [String; 3]) = match &s.axes {
                        Some(a) => (*a, ["1", "2", "3"].map(|k| format!("{}:{k}", s.id))),
                        None => (
                            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                            ["x", "y", "z"].map(|k| format!("{}{k}", s.id)),
                        ),
                    };
                    if let Some(ids) = s.channels.as_ref().filter(|c| c.len() == 3) {
                        names = std::array::from_fn(|k| ids[k].clone());
                    }
                    for (a, id) in axes.iter().zip(names) {
                        out.push(Channel {
                            id,
                            point: s.id.clone(),
                            position,
                            direction: v3(a),
                        });
                    }
                }
                SensorKind::Uniaxial => out.push(Channel {
                    id: match s.channels.as_deref() {
                        Some([id]) => id.clone(),
                        _ => s.id.clone(),
                    },
                    point: s.id.clone(),
                    position,
                    direction: v3(&s.direction.unwrap_or([f64::NAN; 3])),
                }),
            }
        }
        out
    }

    fn geometry_unchecked(&self) -> Geometry {
        let mut points: Vec<Point> = self
            .sensors
            .iter()
            .map(|s| Point {
                id: s.id.clone(),
                position: v3(&s.at_m),
            })
            .collect();
        let excitations = self
            .excitations
            .iter()
            .map(|e| {
                let point = e.point.clone().unwrap_or_else(|| e.id.clone());
                if !points.iter().any(|p| p.id == point) {
                    points.push(Point {
                        id: point.clone(),
                        position: v3(&e.at_m),
                    });
                }
                Excitation {
                    id: e.id.clone(),
                    point,
                    position: v3(&e.at_m),
                    direction: v3(&e.direction),
                    setup: e.setup.clone(),
                }
            })
            .collect();
        Geometry {
            points,
            channels: self.channels(),
            excitations,
            setups: self
                .setups
                .iter()
                .map(|s| SuspensionSetup::new(&s.id, &s.description))
                .collect(),
        }
    }

    /// The geometry: sensor points, channels, excitation points and set-ups.
    pub fn geometry(&self) -> Result<Geometry, SpecError> {
        let g = self.geometry_unchecked();
        g.validate().map_err(|e| {
            SpecError::Invalid(vec![SpecIssue {
                path: "geometry".into(),
                problem: e.to_string(),
            }])
        })?;
        Ok(g)
    }
}
