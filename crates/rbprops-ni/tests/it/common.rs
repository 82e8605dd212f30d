//! Test models built from rbprops-core only: a rigid body on springs, triaxial sensors,
//! forces in one or two set-ups, FRFs from the modal sum and `ModeEstimate`s made from
//! the true modes as `modal-fit` would report them.
#![allow(dead_code)]

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rbprops_core::inertia::ProductsOfInertia;
use rbprops_core::modal::modal_receptance;
use rbprops_core::records::{ModalFitRecord, ModeEstimate};
use rbprops_core::{
    c64, Excitation, FrfSet, Geometry, Mat6, Quantity, RigidBodyProperties, RigidMode,
    SuspensionSetup, Vec3, Vec6,
};

pub const ZETA: f64 = 0.01;

/// Σ T(a)ᵀ diag(k) T(a) over the spring attachment points, the same `k` at each.
pub fn spring_stiffness(points: &[Vec3], k: [f64; 3]) -> Mat6 {
    rbprops_testkit::spring_stiffness(points.iter().map(|&a| (a, k)))
}

pub use rbprops_testkit::rigid_modes;
pub use rbprops_testkit::triaxial;

pub fn force(id: &str, p: Vec3, d: Vec3, setup: &str) -> Excitation {
    Excitation {
        id: id.into(),
        point: format!("P{id}"),
        position: p,
        direction: d.normalize(),
        setup: setup.into(),
    }
}

/// A body, its geometry and the true modes of each set-up.
pub struct Model {
    pub props: RigidBodyProperties,
    pub geometry: Geometry,
    /// (set-up id, its true modes ascending).
    pub setups: Vec<(String, Vec<RigidMode>)>,
}

impl Model {
    pub fn modes_of(&self, setup: &str) -> &[RigidMode] {
        &self.setups.iter().find(|(s, _)| s == setup).unwrap().1
    }
    pub fn excitation(&self, id: &str) -> &Excitation {
        &self.geometry.excitations[self.geometry.excitation_index(id).unwrap()]
    }
    /// True participation `(f_kᵀφ_r)²` of excitation `id` in true mode `r` (0-based).
    pub fn participation(&self, id: &str, r: usize) -> f64 {
        let e = self.excitation(id);
        e.column().dot(&self.modes_of(&e.setup)[r].shape).powi(2)
    }
    /// The true mode (0-based) of `setup` nearest in frequency.
    pub fn true_mode_near(&self, setup: &str, f: f64) -> usize {
        let m = self.modes_of(setup);
        (0..m.len())
            .min_by(|&a, &b| {
                (m[a].frequency_hz - f)
                    .abs()
                    .total_cmp(&(m[b].frequency_hz - f).abs())
            })
            .unwrap()
    }
}

pub fn body(jzz: f64) -> RigidBodyProperties {
    RigidBodyProperties::from_moments_and_products(
        10.0,
        Vec3::zeros(),
        [0.5, 0.8, jzz],
        ProductsOfInertia {
            xy: 0.1,
            xz: 0.0,
            yz: 0.0,
        },
    )
}

pub fn sensors(g: &mut Geometry) {
    for (id, p) in [
        ("S1", Vec3::new(0.25, 0.0, 0.05)),
        ("S2", Vec3::new(-0.12, 0.2, 0.05)),
        ("S3", Vec3::new(-0.12, -0.2, 0.05)),
    ] {
        let (pt, ch) = triaxial(id, p);
        g.points.push(pt);
        g.channels.extend(ch);
    }
}

fn corners(dx: f64, z: f64) -> Vec<Vec3> {
    let mut v = Vec::new();
    for sx in [-1.0, 1.0] {
        for sy in [-1.0, 1.0] {
            v.push(Vec3::new(sx * 0.3 + dx, sy * 0.2, z));
        }
    }
    v
}

/// Test-Case-I-like model (paper Section 3.1): springs kx = 10, ky = 50, kz = 20 N/m at four
/// corners; set-up A in the horizontal plane through the CoM (the in-plane and
/// out-of-plane motions decouple, so each force misses some modes), set-up B in a
/// parallel plane 0.1 m below and shifted 0.05 m in x (everything couples).
/// Forces F0x, F0y, F0z at P0 = (0.2, −0.1, 0) in set-up A; F1x at S2 and F2y at S3 in B.
pub fn test_case_one() -> Model {
    let props = body(0.6);
    let k = [10.0, 50.0, 20.0];
    let ka = spring_stiffness(&corners(0.0, 0.0), k);
    let kb = spring_stiffness(&corners(0.05, -0.1), k);
    let mut g = Geometry::default();
    sensors(&mut g);
    for (id, d) in [
        ("A", "springs in the CoM plane"),
        ("B", "springs 0.1 m below"),
    ] {
        g.setups.push(SuspensionSetup {
            id: id.into(),
            description: d.into(),
        });
    }
    let p0 = Vec3::new(0.2, -0.1, 0.0);
    g.excitations.push(force("F0x", p0, Vec3::x(), "A"));
    g.excitations.push(force("F0y", p0, Vec3::y(), "A"));
    g.excitations.push(force("F0z", p0, Vec3::z(), "A"));
    g.excitations
        .push(force("F1x", Vec3::new(-0.12, 0.2, 0.05), Vec3::x(), "B"));
    g.excitations
        .push(force("F2y", Vec3::new(-0.12, -0.2, 0.05), Vec3::y(), "B"));
    g.validate().unwrap();
    Model {
        setups: vec![
            ("A".into(), rigid_modes(&props, &ka, |_| ZETA)),
            ("B".into(), rigid_modes(&props, &kb, |_| ZETA)),
        ],
        props,
        geometry: g,
    }
}

pub fn axis(f0: f64, f1: f64, df: f64) -> Vec<f64> {
    let n = ((f1 - f0) / df).round() as usize;
    (0..=n).map(|i| f0 + i as f64 * df).collect()
}

/// Receptance FRFs of every excitation from the modal sum of its set-up's modes.
pub fn frfs(model: &Model, hz: &[f64]) -> FrfSet {
    let g = &model.geometry;
    let mut s = FrfSet::zeros(
        Quantity::Receptance,
        hz.to_vec(),
        g.excitations.len(),
        g.channels.len(),
    );
    for (k, e) in g.excitations.iter().enumerate() {
        let modes = model.modes_of(&e.setup);
        let f = e.column();
        for (c, ch) in g.channels.iter().enumerate() {
            let a = ch.row();
            for (l, h) in s.frf_mut(k, c).iter_mut().enumerate() {
                *h = modal_receptance(modes, &a, &f, 2.0 * std::f64::consts::PI * hz[l]);
            }
        }
    }
    s
}

/// One standard normal (the workspace's Box–Muller, `rbprops_core::noise`).
pub use rbprops_core::noise::standard_normal as normal;

/// Adds complex Gaussian noise of `rel × |H|` per value (per-excitation seeds).
pub fn add_frf_noise(s: &mut FrfSet, rel: f64, seed: u64) {
    let nl = s.n_lines();
    for k in 0..s.n_excitations {
        let mut rng = ChaCha8Rng::seed_from_u64(seed * 1000 + k as u64);
        for c in 0..s.n_channels {
            for h in s.frf_mut(k, c).iter_mut().take(nl) {
                let sd = rel * h.norm() / std::f64::consts::SQRT_2;
                *h += c64::new(sd * normal(&mut rng), sd * normal(&mut rng));
            }
        }
    }
}

/// How `ModeEstimate`s are made from the true modes.
#[derive(Clone, Copy)]
pub struct EstimateSpec {
    /// Modes with `(f_kᵀφ)² < omit × max_r (f_kᵀφ_r)²` are not reported (modal-fit cannot see them).
    pub omit: f64,
    /// … and those below `weak × max` are flagged weak.
    pub weak: f64,
    /// Residue noise, as a fraction of the RMS residue of the excitation's strongest mode.
    pub residue_noise: f64,
    /// Relative frequency perturbation (standard deviation).
    pub frequency_noise: f64,
    pub seed: u64,
}

impl Default for EstimateSpec {
    fn default() -> Self {
        Self {
            omit: 1e-8,
            weak: 1e-4,
            residue_noise: 1e-3,
            frequency_noise: 1e-4,
            seed: 1,
        }
    }
}

/// One estimate of true mode `mode` from excitation `k`, residues `A_i = (s_iᵀφ)(f_kᵀφ)`.
pub fn estimate(
    model: &Model,
    k: usize,
    mode: &RigidMode,
    number: usize,
    noise_abs: f64,
    freq_rel: f64,
    rng: &mut ChaCha8Rng,
) -> ModeEstimate {
    let g = &model.geometry;
    let e = &g.excitations[k];
    let c = e.column().dot(&mode.shape);
    let residues = g
        .channels
        .iter()
        .map(|ch| {
            let a = (ch.row() * mode.shape)[0] * c;
            c64::new(a + noise_abs * normal(rng), noise_abs * normal(rng))
        })
        .collect();
    ModeEstimate {
        excitation: e.id.clone(),
        setup: e.setup.clone(),
        mode: number,
        frequency_hz: mode.frequency_hz * (1.0 + freq_rel * normal(rng)),
        frequency_std_hz: freq_rel * mode.frequency_hz,
        damping_ratio: mode.damping_ratio,
        damping_std: 0.0,
        residues,
        residue_std: vec![noise_abs; g.channels.len()],
        confidence: 1.0,
        mpc: 1.0,
        weak: false,
        warnings: Vec::new(),
    }
}

/// Estimates of every excitation, numbered per excitation in ascending frequency.
pub fn estimates(model: &Model, spec: EstimateSpec) -> ModalFitRecord {
    let g = &model.geometry;
    let mut rec = ModalFitRecord {
        residue_convention: "receptance modal constants".into(),
        ..Default::default()
    };
    for (k, e) in g.excitations.iter().enumerate() {
        let mut rng = ChaCha8Rng::seed_from_u64(spec.seed * 7919 + k as u64);
        let modes = model.modes_of(&e.setup);
        let part: Vec<f64> = modes
            .iter()
            .map(|m| e.column().dot(&m.shape).powi(2))
            .collect();
        let top = part.iter().copied().fold(0.0, f64::max);
        let rms_top = {
            let r = part.iter().position(|&p| p == top).unwrap();
            let c = e.column().dot(&modes[r].shape);
            let s: f64 = g
                .channels
                .iter()
                .map(|ch| ((ch.row() * modes[r].shape)[0] * c).powi(2))
                .sum();
            (s / g.channels.len() as f64).sqrt()
        };
        let mut ests: Vec<ModeEstimate> = Vec::new();
        for (r, m) in modes.iter().enumerate() {
            if part[r] < spec.omit * top {
                continue;
            }
            let mut est = estimate(
                model,
                k,
                m,
                0,
                spec.residue_noise * rms_top,
                spec.frequency_noise,
                &mut rng,
            );
            est.weak = part[r] < spec.weak * top;
            ests.push(est);
        }
        ests.sort_by(|a, b| a.frequency_hz.total_cmp(&b.frequency_hz));
        for (i, est) in ests.iter_mut().enumerate() {
            est.mode = i + 1;
        }
        rec.modes.extend(ests);
    }
    rec
}

/// MAC of two 6-vectors in the metric SᵀS of the model's channels.
pub fn mac_s(model: &Model, a: &Vec6, b: &Vec6) -> f64 {
    let w: Mat6 = model
        .geometry
        .channel_matrix()
        .iter()
        .map(|r| r.transpose() * r)
        .sum();
    rbprops_ni::mac(a, b, &w)
}
