//! Seeded synthetic SIMO data of a rigid body on springs, built only from rbprops-core
//! (the paper's Test Case II body). Used by rbprops-modal's tests, its benches and its
//! `timing` example. Pure data generation, no I/O.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rbprops_core::inertia::ProductsOfInertia;
use rbprops_core::modal::modal_receptance;
use rbprops_core::{
    c64, Channel, Excitation, FrfSet, Geometry, Mat6, Point, Quantity, RigidBodyProperties,
    RigidMode, SuspensionSetup, Vec3,
};

/// The paper's Test Case II body (m = 15.69 kg, CAD inertia) with its CoM at
/// (0.10, 0.05, 0.02) m.
pub fn test_case_body() -> RigidBodyProperties {
    RigidBodyProperties::from_moments_and_products(
        15.69,
        Vec3::new(0.10, 0.05, 0.02),
        [0.35733194, 0.39469014, 0.31706832],
        ProductsOfInertia {
            xy: 0.07722671,
            xz: -0.08736156,
            yz: -0.06919817,
        },
    )
}

/// `n` force directions spread over the sphere (a Fibonacci spiral), at the Test Case
/// body's three accelerometer points in turn: every rigid-body mode is driven by many of
/// them (the poly-reference workloads of many excitations).
pub fn fibonacci_forces(n: usize) -> Vec<(usize, Vec3)> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (2 * i + 1) as f64 / n as f64;
            let r = (1.0 - z * z).sqrt();
            let a = golden * i as f64;
            (i % 3, Vec3::new(r * a.cos(), r * a.sin(), z))
        })
        .collect()
}

/// Three triaxial accelerometers placed so that the CoM sits where Test Case II lists
/// it relative to each (mm), plus a set-up `A` and the given excitations.
pub fn test_case_geometry(body: &RigidBodyProperties, forces: &[(usize, Vec3)]) -> Geometry {
    let rel_mm = [
        [177.25, 30.40, -5.35],
        [75.45, -184.42, -61.069],
        [39.15, 86.08, 127.43],
    ];
    let mut g = Geometry::default();
    g.setups.push(SuspensionSetup {
        id: "A".into(),
        description: "four springs".into(),
    });
    for (i, r) in rel_mm.iter().enumerate() {
        let p = body.com - Vec3::new(r[0], r[1], r[2]) / 1000.0;
        let id = format!("P{}", i + 1);
        g.points.push(Point {
            id: id.clone(),
            position: p,
        });
        for (k, ax) in ["x", "y", "z"].iter().enumerate() {
            g.channels.push(Channel {
                id: format!("{id}{ax}"),
                point: id.clone(),
                position: p,
                direction: Vec3::from_fn(|j, _| if j == k { 1.0 } else { 0.0 }),
            });
        }
    }
    for (i, (pt, dir)) in forces.iter().enumerate() {
        let p = g.points[*pt].position;
        g.excitations.push(Excitation {
            id: format!("F{}", i + 1),
            point: g.points[*pt].id.clone(),
            position: p,
            direction: dir.normalize(),
            setup: "A".into(),
        });
    }
    g
}

/// Four springs (stiffness `k` along x, y, z) at the corners of a rectangle below the
/// body: `K = Σ T(a)ᵀ diag(k) T(a)`.
pub fn spring_stiffness(k: [f64; 3]) -> Mat6 {
    let corners = [
        Vec3::new(0.35, 0.25, -0.15),
        Vec3::new(-0.30, 0.25, -0.15),
        Vec3::new(-0.30, -0.20, -0.15),
        Vec3::new(0.35, -0.20, -0.15),
    ];
    crate::spring_stiffness(corners.map(|a| (a, k)))
}

/// Modes of the body on the springs with the given damping ratios (ascending frequency).
pub fn spring_modes(body: &RigidBodyProperties, k: [f64; 3], zeta: &[f64; 6]) -> Vec<RigidMode> {
    crate::rigid_modes(body, &spring_stiffness(k), |r| zeta[r])
}

/// A campaign: geometry, modes and (noise-free) FRFs.
#[derive(Debug, Clone)]
pub struct Synthetic {
    /// Points, channels, excitations and set-ups.
    pub geometry: Geometry,
    /// The true rigid-body modes (mass-normalised).
    pub modes: Vec<RigidMode>,
    /// Noise-free receptance FRFs of every excitation.
    pub frf: FrfSet,
}

impl Synthetic {
    /// Exact modal constants `A_ir = (s_iᵀφ_r)(f_kᵀφ_r)` of excitation `e`, per mode.
    pub fn true_modal_constants(&self, e: usize) -> Vec<Vec<f64>> {
        let f = self.geometry.excitations[e].column();
        self.modes
            .iter()
            .map(|m| {
                self.geometry
                    .channels
                    .iter()
                    .map(|c| m.modal_constant(&c.row(), &f))
                    .collect()
            })
            .collect()
    }

    /// Peak Norm Indicator of each mode alone for excitation `e` in the FRF quantity:
    /// `‖A_r‖ ω_r^k / (2ζ_r ω_r²)`.
    pub fn mode_peak_ni(&self, e: usize) -> Vec<f64> {
        let k = self.frf.quantity.order();
        self.true_modal_constants(e)
            .iter()
            .zip(&self.modes)
            .map(|(a, m)| {
                let w = m.omega();
                a.iter().map(|x| x * x).sum::<f64>().sqrt() * w.powi(k)
                    / (2.0 * m.damping_ratio * w * w)
            })
            .collect()
    }

    /// Indices of the modes excitation `e` excites: peak NI within `db` of its strongest.
    pub fn excited_modes(&self, e: usize, db: f64) -> Vec<usize> {
        let ni = self.mode_peak_ni(e);
        let max = ni.iter().cloned().fold(0.0, f64::max);
        (0..ni.len())
            .filter(|&r| 20.0 * (ni[r] / max).log10() > -db)
            .collect()
    }

    /// Adds complex Gaussian noise, σ = `rel` × |H| per line (re and im each σ/√2).
    pub fn with_noise(&self, rel: f64, seed: u64) -> Synthetic {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut out = self.clone();
        for v in out.frf.values.iter_mut() {
            let s = rel * v.norm() / std::f64::consts::SQRT_2;
            *v += c64::new(s * gauss(&mut rng), s * gauss(&mut rng));
        }
        out
    }
}

/// Standard normal deviate (Box–Muller). Not `rbprops_core::noise::standard_normal`: this
/// one takes `u1 = U` (floored) where the core stream takes `1 − U`, so its draws differ,
/// and the noisy fixtures built from them (the modal tests' noisy campaigns, the timing
/// example's digest) must stay as they are.
fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = rng.random::<f64>().max(f64::MIN_POSITIVE);
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// FRFs of `modes` for every excitation and channel of `geometry` on the uniform axis
/// `0, df, …, f_max` (`n_lines` lines), in `quantity`.
pub fn synthesise(
    geometry: &Geometry,
    modes: &[RigidMode],
    f_max: f64,
    n_lines: usize,
    quantity: Quantity,
) -> FrfSet {
    let df = f_max / (n_lines - 1) as f64;
    let axis: Vec<f64> = (0..n_lines).map(|l| l as f64 * df).collect();
    let mut frf = FrfSet::zeros(
        Quantity::Receptance,
        axis.clone(),
        geometry.excitations.len(),
        geometry.channels.len(),
    );
    for (e, ex) in geometry.excitations.iter().enumerate() {
        let b = ex.column();
        for (c, ch) in geometry.channels.iter().enumerate() {
            let a = ch.row();
            let h = frf.frf_mut(e, c);
            for (l, f) in axis.iter().enumerate() {
                h[l] = modal_receptance(modes, &a, &b, 2.0 * std::f64::consts::PI * f);
            }
        }
    }
    if quantity == Quantity::Receptance {
        frf
    } else {
        // Multiplying by (iω)^k is defined at 0 Hz (only the inverse is not).
        let mut out = frf.clone();
        out.quantity = quantity;
        let nl = axis.len();
        for (i, v) in out.values.iter_mut().enumerate() {
            *v *= quantity.from_receptance_factor(2.0 * std::f64::consts::PI * axis[i % nl]);
        }
        out
    }
}

/// The standard Test-Case-like campaign: Test Case II body on four springs, three
/// oblique forces at the three accelerometer points, ζ = 1–2 %.
pub fn test_case(f_max: f64, n_lines: usize, quantity: Quantity) -> Synthetic {
    let body = test_case_body();
    let forces = [
        (0, Vec3::new(1.0, 0.3, 0.2)),
        (1, Vec3::new(0.2, 1.0, -0.4)),
        (2, Vec3::new(-0.3, 0.4, 1.0)),
    ];
    let geometry = test_case_geometry(&body, &forces);
    let modes = spring_modes(
        &body,
        [60.0, 90.0, 200.0],
        &[0.012, 0.015, 0.010, 0.018, 0.014, 0.020],
    );
    let frf = synthesise(&geometry, &modes, f_max, n_lines, quantity);
    Synthetic {
        geometry,
        modes,
        frf,
    }
}

/// The bench workload: `batch` excitations, 9 channels × 4,096 lines of
/// accelerance on 0–12.5 Hz, each a copy of one of [`test_case()`]'s three excitations
/// (in turn) with its own 1 % complex noise (seed `1000 + index`). Shared by the
/// `timing` example and the criterion bench so that both measure the same data.
pub fn bench_campaign(batch: usize) -> (Geometry, FrfSet) {
    let base = test_case(12.5, 4096, Quantity::Accelerance);
    let mut geometry = base.geometry.clone();
    let per = base.frf.n_channels * base.frf.n_lines();
    let mut values = Vec::with_capacity(batch * per);
    let mut excitations = Vec::with_capacity(batch);
    for b in 0..batch {
        let noisy = base.with_noise(0.01, 1000 + b as u64);
        let e = b % base.frf.n_excitations;
        values.extend_from_slice(noisy.frf.excitation_block(e));
        let mut ex = base.geometry.excitations[e].clone();
        ex.id = format!("E{b}");
        excitations.push(ex);
    }
    geometry.excitations = excitations;
    let frf = FrfSet {
        quantity: base.frf.quantity,
        frequency_hz: base.frf.frequency_hz.clone(),
        n_excitations: batch,
        n_channels: base.frf.n_channels,
        values,
    };
    (geometry, frf)
}

/// The Test Case II body on springs with its mode shapes kept but natural frequencies
/// and damping ratios replaced (mass-normalised shapes stay valid), excited by the
/// first `n_excitations` of five oblique forces; accelerance on `0..=f_max`.
pub fn with_modes(
    f_hz: [f64; 6],
    zeta: [f64; 6],
    n_excitations: usize,
    f_max: f64,
    n_lines: usize,
) -> Synthetic {
    let body = test_case_body();
    let forces = [
        (0, Vec3::new(1.0, 0.3, 0.2)),
        (1, Vec3::new(0.2, 1.0, -0.4)),
        (2, Vec3::new(-0.3, 0.4, 1.0)),
        (0, Vec3::new(0.1, -0.5, 1.0)),
        (1, Vec3::new(1.0, -0.2, 0.6)),
    ];
    let geometry = test_case_geometry(&body, &forces[..n_excitations.min(5)]);
    let mut modes = spring_modes(&body, [60.0, 90.0, 200.0], &[0.0; 6]);
    for (i, m) in modes.iter_mut().enumerate() {
        m.frequency_hz = f_hz[i];
        m.damping_ratio = zeta[i];
    }
    let frf = synthesise(&geometry, &modes, f_max, n_lines, Quantity::Accelerance);
    Synthetic {
        geometry,
        modes,
        frf,
    }
}

/// Rigid body with two pairs of modes closer than their half-power bandwidths:
/// 0.800/0.812 Hz and 1.550/1.575 Hz (plus 2.3 and 3.1 Hz), mass-normalised shapes of
/// the Test Case II body, ζ = 1.2–1.5 %, five excitations.
pub fn close_modes(f_max: f64, n_lines: usize) -> Synthetic {
    with_modes(
        [0.800, 0.812, 1.550, 1.575, 2.3, 3.1],
        [0.015, 0.012, 0.013, 0.015, 0.014, 0.012],
        5,
        f_max,
        n_lines,
    )
}

/// Monic coefficients `c_0..c_{n−1}` of `Π (z − r)` (roots in conjugate pairs or real,
/// so the coefficients are real).
pub fn poly_from_roots(roots: &[c64]) -> Vec<f64> {
    let mut p = vec![c64::new(1.0, 0.0)];
    for r in roots {
        let mut q = vec![c64::new(0.0, 0.0); p.len() + 1];
        for (j, c) in p.iter().enumerate() {
            q[j + 1] += c;
            q[j] -= c * r;
        }
        p = q;
    }
    p[..p.len() - 1].iter().map(|c| c.re).collect()
}

/// The largest distance from a root in `a` to its nearest root in `b`.
pub fn max_nearest(a: &[c64], b: &[c64]) -> f64 {
    a.iter()
        .map(|x| {
            b.iter()
                .map(|y| (x - y).norm())
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max)
}
