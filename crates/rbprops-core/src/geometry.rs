//! Points, channels, excitations and the rigid-body kinematics that link them.

use crate::{CoreError, Mat3, Vec3, Vec6};
use nalgebra::{Matrix3x6, RowVector6};

/// Tolerance on `|d| - 1` for a direction to count as a unit vector.
pub const UNIT_TOLERANCE: f64 = 1e-6;

/// Cross-product matrix `[p]×`, so that `[p]× v = p × v`.
pub fn cross_matrix(p: &Vec3) -> Mat3 {
    Mat3::new(0.0, -p.z, p.y, p.z, 0.0, -p.x, -p.y, p.x, 0.0)
}

/// Rigid-body transform `T(p) = [I | -[p]×]` (docs/conventions.md; the paper's R0 rows, Eq. 3):
/// the displacement of body point `p` is `T(p) q0` for rigid motion `q0 = [u0; θ]` about O.
pub fn rigid_transform(p: &Vec3) -> Matrix3x6<f64> {
    let mut t = Matrix3x6::zeros();
    t.fixed_view_mut::<3, 3>(0, 0).copy_from(&Mat3::identity());
    t.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(-cross_matrix(p)));
    t
}

/// A named point of the test article, in the geometry's frame (m).
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    /// Unique id (sensor location name in the test).
    pub id: String,
    /// Position in the geometry's frame (m).
    pub position: Vec3,
}

/// A response channel: a unit sensing direction `s` at a point `p`. Its row is `sᵀT(p)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Channel {
    /// Unique channel id.
    pub id: String,
    /// Id of the [`Point`] it sits at.
    pub point: String,
    /// Position of the point `p` (m), copied from the point.
    pub position: Vec3,
    /// Unit sensing direction `s` in the geometry's frame.
    pub direction: Vec3,
}

impl Channel {
    /// The channels of a triaxial accelerometer at `position`, the point `point`:
    /// `{point}x`, `{point}y`, `{point}z` along the body axes.
    pub fn triaxial(point: &str, position: Vec3) -> Vec<Channel> {
        ["x", "y", "z"]
            .iter()
            .enumerate()
            .map(|(k, a)| Channel {
                id: format!("{point}{a}"),
                point: point.into(),
                position,
                direction: Vec3::from_fn(|i, _| f64::from(u8::from(i == k))),
            })
            .collect()
    }

    /// The channel's row of `S` (or R0): `sᵀ T(p)`.
    pub fn row(&self) -> RowVector6<f64> {
        self.direction.transpose() * rigid_transform(&self.position)
    }
}

/// A force input: unit direction `d` at point `p`, in one suspension set-up.
/// Its column (generalised force about O) is `T(p)ᵀ d = [d; p × d]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Excitation {
    /// Unique excitation id.
    pub id: String,
    /// Id of the [`Point`] it acts at.
    pub point: String,
    /// Position of the point `p` (m), copied from the point.
    pub position: Vec3,
    /// Unit force direction `d` in the geometry's frame.
    pub direction: Vec3,
    /// Id of the [`SuspensionSetup`] the test article hung in.
    pub setup: String,
}

impl Excitation {
    /// The force column `f = T(p)ᵀ d`.
    pub fn column(&self) -> Vec6 {
        rigid_transform(&self.position).transpose() * self.direction
    }
}

/// A suspension set-up. Modes of different set-ups are different modes.
#[derive(Debug, Clone, PartialEq)]
pub struct SuspensionSetup {
    /// Unique set-up id, referenced by [`Excitation::setup`].
    pub id: String,
    /// Free text: how the article hung (cords, springs, orientation).
    pub description: String,
}

impl SuspensionSetup {
    /// A set-up named `id`, described in words (cords, springs, orientation).
    pub fn new(id: impl Into<String>, description: impl Into<String>) -> Self {
        SuspensionSetup {
            id: id.into(),
            description: description.into(),
        }
    }
}

/// Everything the stages need to know about where things are.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Geometry {
    /// Named points of the article.
    pub points: Vec<Point>,
    /// Response channels, in the order of the FRF set's channel index.
    pub channels: Vec<Channel>,
    /// Force inputs, in the order of the FRF set's excitation index.
    pub excitations: Vec<Excitation>,
    /// Suspension set-ups the excitations refer to.
    pub setups: Vec<SuspensionSetup>,
}

fn check_unit(what: &str, d: &Vec3) -> Result<(), CoreError> {
    check_finite3(what, d)?;
    let n = d.norm();
    if (n - 1.0).abs() > UNIT_TOLERANCE {
        return Err(CoreError::NonUnitDirection {
            what: what.into(),
            dir: [d.x, d.y, d.z],
            norm: n,
        });
    }
    Ok(())
}

fn check_finite3(what: &str, v: &Vec3) -> Result<(), CoreError> {
    for x in v.iter() {
        if !x.is_finite() {
            return Err(CoreError::NonFinite {
                what: what.into(),
                value: *x,
            });
        }
    }
    Ok(())
}

fn check_unique<'a>(kind: &str, ids: impl Iterator<Item = &'a String>) -> Result<(), CoreError> {
    let mut seen = std::collections::BTreeSet::new();
    for id in ids {
        if id.is_empty() {
            return Err(CoreError::Geometry(format!("{kind} with an empty id")));
        }
        if !seen.insert(id.as_str()) {
            return Err(CoreError::Geometry(format!(
                "{kind} id '{id}' appears twice"
            )));
        }
    }
    Ok(())
}

impl Geometry {
    /// The point with this id.
    pub fn point(&self, id: &str) -> Option<&Point> {
        self.points.iter().find(|p| p.id == id)
    }
    /// Index of the channel with this id (the FRF set's channel index).
    pub fn channel_index(&self, id: &str) -> Option<usize> {
        self.channels.iter().position(|c| c.id == id)
    }
    /// Index of the excitation with this id (the FRF set's excitation index).
    pub fn excitation_index(&self, id: &str) -> Option<usize> {
        self.excitations.iter().position(|e| e.id == id)
    }

    /// Checks ids, references, finiteness and unit directions.
    pub fn validate(&self) -> Result<(), CoreError> {
        check_unique("point", self.points.iter().map(|p| &p.id))?;
        check_unique("channel", self.channels.iter().map(|c| &c.id))?;
        check_unique("excitation", self.excitations.iter().map(|e| &e.id))?;
        check_unique("set-up", self.setups.iter().map(|s| &s.id))?;
        for p in &self.points {
            check_finite3(&format!("point '{}' position", p.id), &p.position)?;
        }
        for c in &self.channels {
            check_unit(&format!("channel '{}' direction", c.id), &c.direction)?;
            check_finite3(&format!("channel '{}' position", c.id), &c.position)?;
        }
        for e in &self.excitations {
            check_unit(&format!("excitation '{}' direction", e.id), &e.direction)?;
            check_finite3(&format!("excitation '{}' position", e.id), &e.position)?;
            if !self.setups.iter().any(|s| s.id == e.setup) {
                return Err(CoreError::Geometry(format!(
                    "excitation '{}' names set-up '{}', which the geometry does not define",
                    e.id, e.setup
                )));
            }
        }
        Ok(())
    }

    /// The stacked channel rows `S` (n_channels × 6), the paper's R0 for triaxial sensors.
    pub fn channel_matrix(&self) -> Vec<RowVector6<f64>> {
        self.channels.iter().map(Channel::row).collect()
    }

    /// Points whose channels span all three directions (a triaxial measurement point).
    pub fn triaxial_points(&self) -> Vec<Vec3> {
        let mut out = Vec::new();
        let mut ids: Vec<&str> = self.channels.iter().map(|c| c.point.as_str()).collect();
        ids.sort_unstable();
        ids.dedup();
        for id in ids {
            let dirs: Vec<&Channel> = self.channels.iter().filter(|c| c.point == id).collect();
            let mut g = Mat3::zeros();
            for c in &dirs {
                g += c.direction * c.direction.transpose();
            }
            let ev = g.symmetric_eigenvalues();
            if ev.min() > 0.1 {
                out.push(dirs[0].position);
            }
        }
        out
    }

    /// Requires at least three non-collinear triaxial points, so that `SᵀS` of the
    /// rigid-body transform (paper Eq. 5) is well conditioned (Lee et al. 1999).
    pub fn check_rigid_observability(&self) -> Result<(), CoreError> {
        let pts = self.triaxial_points();
        if pts.len() < 3 {
            return Err(CoreError::Geometry(format!(
                "rigid-body motion needs at least three non-collinear triaxial points; the geometry has {}",
                pts.len()
            )));
        }
        // The largest triangle area relative to the squared spread tells collinearity.
        let centroid = pts.iter().fold(Vec3::zeros(), |a, p| a + p) / pts.len() as f64;
        let spread = pts
            .iter()
            .map(|p| (p - centroid).norm_squared())
            .sum::<f64>()
            / pts.len() as f64;
        let mut best = 0.0f64;
        for i in 0..pts.len() {
            for j in i + 1..pts.len() {
                for k in j + 1..pts.len() {
                    let a = (pts[j] - pts[i]).cross(&(pts[k] - pts[i])).norm() / 2.0;
                    best = best.max(a);
                }
            }
        }
        if spread <= 0.0 || best / spread < 1e-3 {
            return Err(CoreError::Geometry(
                "the triaxial points are collinear (or coincide): rotation about their line cannot be observed"
                    .into(),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rigid_transform_rows_match_paper_eq3() {
        let p = Vec3::new(0.3, -0.2, 0.7);
        let t = rigid_transform(&p);
        let expect = [
            [1.0, 0.0, 0.0, 0.0, p.z, -p.y],
            [0.0, 1.0, 0.0, -p.z, 0.0, p.x],
            [0.0, 0.0, 1.0, p.y, -p.x, 0.0],
        ];
        for i in 0..3 {
            for j in 0..6 {
                assert_eq!(t[(i, j)], expect[i][j]);
            }
        }
    }

    #[test]
    fn rigid_transform_is_translation_plus_rotation() {
        let p = Vec3::new(0.1, 0.2, -0.3);
        let u0 = Vec3::new(1e-3, -2e-3, 5e-4);
        let th = Vec3::new(0.01, -0.02, 0.03);
        let q = Vec6::new(u0.x, u0.y, u0.z, th.x, th.y, th.z);
        let u = rigid_transform(&p) * q;
        let expect = u0 + th.cross(&p);
        assert!((u - expect).norm() < 1e-15);
    }

    #[test]
    fn force_column_is_force_and_moment() {
        let e = Excitation {
            id: "F".into(),
            point: "P".into(),
            position: Vec3::new(0.2, 0.1, -0.4),
            direction: Vec3::new(0.0, 1.0, 0.0),
            setup: "A".into(),
        };
        let f = e.column();
        let m = e.position.cross(&e.direction);
        assert_eq!(f.fixed_rows::<3>(0).into_owned(), e.direction);
        assert!((f.fixed_rows::<3>(3).into_owned() - m).norm() < 1e-15);
    }

    #[test]
    fn observability_needs_three_noncollinear_triaxials() {
        let mut g = Geometry::default();
        g.channels
            .extend(Channel::triaxial("a", Vec3::new(0.0, 0.0, 0.0)));
        g.channels
            .extend(Channel::triaxial("b", Vec3::new(1.0, 0.0, 0.0)));
        assert!(g.check_rigid_observability().is_err());
        g.channels
            .extend(Channel::triaxial("c", Vec3::new(2.0, 0.0, 0.0)));
        let err = g.check_rigid_observability().unwrap_err().to_string();
        assert!(err.contains("collinear"), "{err}");
        g.channels
            .extend(Channel::triaxial("d", Vec3::new(0.0, 1.0, 0.0)));
        g.check_rigid_observability().unwrap();
    }

    #[test]
    fn validate_rejects_non_unit_and_dangling_setup() {
        let mut g = Geometry::default();
        g.setups.push(SuspensionSetup {
            id: "A".into(),
            description: String::new(),
        });
        g.channels.push(Channel {
            id: "c".into(),
            point: "p".into(),
            position: Vec3::zeros(),
            direction: Vec3::new(1.0, 1.0, 0.0),
        });
        assert!(matches!(
            g.validate(),
            Err(CoreError::NonUnitDirection { .. })
        ));
        g.channels[0].direction = Vec3::new(0.0, 0.0, 1.0);
        g.excitations.push(Excitation {
            id: "F".into(),
            point: "p".into(),
            position: Vec3::zeros(),
            direction: Vec3::x(),
            setup: "B".into(),
        });
        assert!(g.validate().unwrap_err().to_string().contains("set-up 'B'"));
    }
}
