//! From identified residues to mass-normalised rigid-body shapes about a chosen origin:
//! the least-squares rigid-body transform `q = (SᵀS)⁻¹SᵀA_r` (paper Eq. 5) and the
//! normalisation from the force geometry `φ0 = q/√(f_kᵀq)` (docs/conventions.md).

use crate::error::InertiaError;
use rbprops_core::records::{ModalFitRecord, ModeEstimate, SelectedMode};
use rbprops_core::{
    c64, mass_normalise, real_modal_constants, rigid_transform, Geometry, RigidBasis, Vec3, Vec6,
};
use serde::{Deserialize, Serialize};

/// Where the rigid-body coordinates are taken about (the paper's Origins I–III).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub enum OriginChoice {
    /// The origin of the geometry's frame.
    #[default]
    GeometryOrigin,
    /// A point given in the geometry's frame (m).
    Point([f64; 3]),
    /// The position of a channel, or of a measurement point, by id (e.g. an accelerometer).
    Channel(String),
}

/// Resolves an [`OriginChoice`] to a position in the geometry's frame.
pub fn resolve_origin(geometry: &Geometry, choice: &OriginChoice) -> Result<Vec3, InertiaError> {
    match choice {
        OriginChoice::GeometryOrigin => Ok(Vec3::zeros()),
        OriginChoice::Point(p) => {
            if p.iter().all(|x| x.is_finite()) {
                Ok(Vec3::from(*p))
            } else {
                Err(InertiaError::Origin(format!("point {p:?} is not finite")))
            }
        }
        OriginChoice::Channel(id) => {
            if let Some(c) = geometry.channels.iter().find(|c| &c.id == id) {
                Ok(c.position)
            } else if let Some(p) = geometry.point(id) {
                Ok(p.position)
            } else {
                Err(InertiaError::Origin(format!(
                    "'{id}' is neither a channel nor a point of the geometry"
                )))
            }
        }
    }
}

/// Channel rows and force columns of a geometry expressed about an origin `o`:
/// rows `sᵀT(p − o)`, columns `T(p − o)ᵀd`.
#[derive(Debug, Clone)]
pub struct RigidFrame {
    /// The origin, geometry frame (m).
    pub origin: Vec3,
    /// Channel rows `sᵀT(p − o)` about the origin, and their Gram matrix `SᵀS`.
    pub basis: RigidBasis,
    /// Force column of every geometry excitation, about the origin.
    pub forces: Vec<Vec6>,
    /// Excitation ids, geometry order.
    pub excitation_ids: Vec<String>,
    /// Channel ids, geometry order.
    pub channel_ids: Vec<String>,
}

impl RigidFrame {
    /// Builds the frame; refuses channel sets that cannot resolve all six rigid motions
    /// (collinear or only two triaxial points, …).
    pub fn new(geometry: &Geometry, origin: Vec3) -> Result<Self, InertiaError> {
        if geometry.channels.is_empty() {
            return Err(InertiaError::Geometry(
                "the geometry has no channels".into(),
            ));
        }
        let rows = geometry
            .channels
            .iter()
            .map(|c| c.direction.transpose() * rigid_transform(&(c.position - origin)))
            .collect();
        let basis = RigidBasis::new(rows).map_err(|e| InertiaError::Geometry(e.to_string()))?;
        let forces = geometry
            .excitations
            .iter()
            .map(|e| rigid_transform(&(e.position - origin)).transpose() * e.direction)
            .collect();
        Ok(Self {
            origin,
            basis,
            forces,
            excitation_ids: geometry.excitations.iter().map(|e| e.id.clone()).collect(),
            channel_ids: geometry.channels.iter().map(|c| c.id.clone()).collect(),
        })
    }

    /// Index of the excitation with this id (geometry order).
    pub fn excitation_index(&self, id: &str) -> Option<usize> {
        self.excitation_ids.iter().position(|e| e == id)
    }

    /// Rigid shape of one residue vector for excitation `k`: Eq. (5), then `φ0 = q/√(fᵀq)`.
    pub fn shape(&self, excitation: usize, residues: &[c64]) -> Result<ShapeCore, String> {
        let (a, alpha) = real_modal_constants(residues);
        let fit = self.basis.fit(&a).map_err(|e| e.to_string())?;
        let (phi0, s) = mass_normalise(&fit.q, &self.forces[excitation]).map_err(|e| {
            format!(
                "{e} (excitation '{}' does not excite this mode; choose another excitation)",
                self.excitation_ids[excitation]
            )
        })?;
        Ok(ShapeCore {
            q: fit.q,
            phi0,
            force_projection: s,
            residual: fit.residual,
            relative_residual: fit.relative_residual,
            complexity_angle_rad: alpha,
        })
    }
}

/// The numbers of one rigid-body transform.
#[derive(Debug, Clone, PartialEq)]
pub struct ShapeCore {
    /// Least-squares rigid motion `q = (SᵀS)⁻¹SᵀA` about the origin (Eq. 5), `[u; θ]`.
    pub q: Vec6,
    /// Mass-normalised shape `φ0 = q/√(f_kᵀq)` (docs/conventions.md §5).
    pub phi0: Vec6,
    /// `f_kᵀq` (1/kg) = the square of the modal participation of excitation k.
    pub force_projection: f64,
    /// Per-channel rigid-body residual `A − S q` (1/kg).
    pub residual: Vec<f64>,
    /// `‖A − Sq‖/‖A‖`: 0 for a perfectly rigid shape.
    pub relative_residual: f64,
    /// Rotation applied to bring the complex residues onto the real line (rad).
    pub complexity_angle_rad: f64,
}

/// One selected mode as the inertia stage used it (serialisable for reports).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShapeDiagnostics {
    /// Suspension set-up.
    pub setup: String,
    /// Physical mode number within the set-up.
    pub mode: usize,
    /// Excitation whose estimate was used.
    pub excitation: String,
    /// That estimate's mode number within the excitation.
    pub excitation_mode: usize,
    /// Natural frequency (Hz).
    pub frequency_hz: f64,
    /// Origin of `q` and `φ0`, geometry frame (m).
    pub origin_m: [f64; 3],
    /// Least-squares rigid motion `q = (SᵀS)⁻¹SᵀA` (Eq. 5), `[u; θ]`.
    pub q: [f64; 6],
    /// Mass-normalised shape `φ0 = q/√(fᵀq)`.
    pub phi0: [f64; 6],
    /// `f_kᵀq` (1/kg).
    pub force_projection: f64,
    /// Channel ids and the per-channel residual `A − Sq` (1/kg).
    pub channels: Vec<String>,
    /// Per-channel residual `A − Sq` (1/kg), in `channels` order.
    pub rigid_residual: Vec<f64>,
    /// `‖A − Sq‖/‖A‖`.
    pub relative_residual: f64,
    /// Rotation applied to bring the complex residues onto the real line (rad).
    pub complexity_angle_rad: f64,
}

/// A selected mode ready for the estimators.
#[derive(Debug, Clone, PartialEq)]
pub struct RigidShape {
    /// The selection this shape comes from.
    pub selected: SelectedMode,
    /// Index of the selected excitation in the geometry.
    pub excitation: usize,
    /// The selected excitation's mode estimate.
    pub estimate: ModeEstimate,
    /// The rigid-body transform of its residues.
    pub core: ShapeCore,
}

impl RigidShape {
    /// Natural angular frequency `ω_r` (rad/s).
    pub fn omega(&self) -> f64 {
        2.0 * std::f64::consts::PI * self.estimate.frequency_hz
    }

    /// The serialisable record of this shape, for reports.
    pub fn diagnostics(&self, frame: &RigidFrame) -> ShapeDiagnostics {
        let c = &self.core;
        ShapeDiagnostics {
            setup: self.selected.setup.clone(),
            mode: self.selected.mode,
            excitation: self.selected.excitation.clone(),
            excitation_mode: self.selected.excitation_mode,
            frequency_hz: self.estimate.frequency_hz,
            origin_m: frame.origin.into(),
            q: c.q.into(),
            phi0: c.phi0.into(),
            force_projection: c.force_projection,
            channels: frame.channel_ids.clone(),
            rigid_residual: c.residual.clone(),
            relative_residual: c.relative_residual,
            complexity_angle_rad: c.complexity_angle_rad,
        }
    }
}

/// Finds the [`ModeEstimate`] a selection points at and checks it fits the geometry.
pub fn find_estimate<'a>(
    frame: &RigidFrame,
    modal: &'a ModalFitRecord,
    sel: &SelectedMode,
) -> Result<(usize, &'a ModeEstimate), InertiaError> {
    let err = |reason: String| InertiaError::Mode {
        setup: sel.setup.clone(),
        mode: sel.mode,
        excitation: sel.excitation.clone(),
        reason,
    };
    let k = frame
        .excitation_index(&sel.excitation)
        .ok_or_else(|| err("the geometry has no such excitation".into()))?;
    let est = modal
        .modes
        .iter()
        .find(|m| m.excitation == sel.excitation && m.mode == sel.excitation_mode)
        .ok_or_else(|| {
            err(format!(
                "the modal fit has no mode {} for this excitation",
                sel.excitation_mode
            ))
        })?;
    if est.setup != sel.setup {
        return Err(err(format!(
            "the modal fit puts this excitation in set-up '{}'",
            est.setup
        )));
    }
    if est.residues.len() != frame.channel_ids.len() {
        return Err(err(format!(
            "{} residues for {} channels",
            est.residues.len(),
            frame.channel_ids.len()
        )));
    }
    if let Some(i) = est
        .residues
        .iter()
        .position(|z| !(z.re.is_finite() && z.im.is_finite()))
    {
        return Err(err(format!(
            "residue of channel '{}' is not finite",
            frame.channel_ids[i]
        )));
    }
    Ok((k, est))
}

/// Rigid shapes of selected modes (Eq. 5 + mass normalisation). Modes that cannot be used
/// (e.g. `f_kᵀq ≤ 0`) are returned as errors alongside, so a caller may continue without
/// them; the order of `selected` is kept.
pub fn rigid_shapes(
    frame: &RigidFrame,
    modal: &ModalFitRecord,
    selected: &[SelectedMode],
) -> (Vec<RigidShape>, Vec<InertiaError>) {
    let mut shapes = Vec::new();
    let mut errors = Vec::new();
    for sel in selected {
        let r = find_estimate(frame, modal, sel).and_then(|(k, est)| {
            frame
                .shape(k, &est.residues)
                .map(|core| RigidShape {
                    selected: sel.clone(),
                    excitation: k,
                    estimate: est.clone(),
                    core,
                })
                .map_err(|reason| InertiaError::Mode {
                    setup: sel.setup.clone(),
                    mode: sel.mode,
                    excitation: sel.excitation.clone(),
                    reason,
                })
        });
        match r {
            Ok(s) => shapes.push(s),
            Err(e) => errors.push(e),
        }
    }
    (shapes, errors)
}
