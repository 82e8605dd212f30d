//! Synthetic campaigns for the round-trip tests.
#![allow(dead_code)]

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rbprops_core::{
    c64, Channel, Excitation, FrfSet, Geometry, Point, Quantity, SuspensionSetup, Vec3,
};

pub struct Spec {
    /// Point ids; all points get sensors or forces.
    pub point_ids: Vec<String>,
    /// Misorient the sensors (non-orthogonal, off-axis directions).
    pub misoriented: bool,
    pub quantity: Quantity,
    pub frequency_hz: Vec<f64>,
    pub seed: u64,
}

fn unit(v: Vec3) -> Vec3 {
    v / v.norm()
}

/// Three triaxial points (ids 0..3 of `point_ids`), forces at the last point (set-up A:
/// +X and an oblique force; set-up B: -Z), random FRF values over twelve decades.
pub fn campaign(spec: &Spec) -> (Geometry, FrfSet) {
    let mut rng = ChaCha8Rng::seed_from_u64(spec.seed);
    let mut g = Geometry::default();
    for id in &spec.point_ids {
        g.points.push(Point {
            id: id.clone(),
            position: Vec3::new(
                rng.random_range(-0.5..0.5),
                rng.random_range(-0.5..0.5),
                rng.random_range(-0.5..0.5),
            ),
        });
    }
    let axes = [Vec3::x(), Vec3::y(), Vec3::z()];
    for p in g.points.iter().take(3) {
        for (k, a) in axes.iter().enumerate() {
            let d = if spec.misoriented && p.id != g.points[0].id {
                let tilt = Vec3::new(
                    rng.random_range(-0.05..0.05),
                    rng.random_range(-0.05..0.05),
                    rng.random_range(-0.05..0.05),
                );
                unit(a + tilt)
            } else if k == 1 {
                -a // a sensor mounted upside down along Y
            } else {
                *a
            };
            g.channels.push(Channel {
                id: format!("{}:{}", p.id, ["x", "y", "z"][k]),
                point: p.id.clone(),
                position: p.position,
                direction: d,
            });
        }
    }
    let fp = g.points.last().unwrap().clone();
    g.setups = vec![
        SuspensionSetup {
            id: "A".into(),
            description: "springs through the CoM".into(),
        },
        SuspensionSetup {
            id: "B".into(),
            description: String::new(),
        },
    ];
    let oblique = if spec.misoriented {
        unit(Vec3::new(0.3, -0.4, 0.866))
    } else {
        Vec3::y()
    };
    for (id, d, s) in [
        ("F1", Vec3::x(), "A"),
        ("F2", oblique, "A"),
        ("F3", -Vec3::z(), "B"),
    ] {
        g.excitations.push(Excitation {
            id: id.into(),
            point: fp.id.clone(),
            position: fp.position,
            direction: d,
            setup: s.into(),
        });
    }
    let mut frf = FrfSet::zeros(
        spec.quantity,
        spec.frequency_hz.clone(),
        g.excitations.len(),
        g.channels.len(),
    );
    for v in frf.values.iter_mut() {
        let mag = |r: &mut ChaCha8Rng| 10f64.powf(r.random_range(-9.0..3.0));
        *v = c64::new(
            rng.random_range(-1.0..1.0) * mag(&mut rng),
            rng.random_range(-1.0..1.0) * mag(&mut rng),
        );
    }
    (g, frf)
}

pub fn even_axis(n: usize, df: f64) -> Vec<f64> {
    (0..n).map(|k| k as f64 * df).collect()
}
