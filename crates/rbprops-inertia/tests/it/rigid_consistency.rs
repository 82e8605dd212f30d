//! Rigid-body consistency check and systematic (jackknife) interval, on modal records made
//! in this test from an independent derivation (`A = (s_iᵀT(p_i)φ)(f_kᵀφ)` of the true
//! geometry, see `common`), with the systematic errors of a real test put into the *true*
//! geometry while the estimators see the nominal one, and Gaussian noise on every modal
//! constant with the standard error the record states.
//!
//! Acceptance: for each error class, either the systematic 95 % interval covers the true
//! mass and principal inertia diagonal, or the consistency warning names the right sensor,
//! channel or excitation, in ≥ 90 % of seeds; noise alone warns in ≤ 5 % of seeds. The CI
//! test runs 6 seeds per class; `study_over_100_seeds` (ignored, `--ignored --nocapture`)
//! prints the rates over 100.
use crate::common::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rbprops_core::noise::standard_normal as normal;
use rbprops_core::records::InertiaEstimate;
use rbprops_core::{c64, Geometry, Vec3};
use rbprops_inertia::*;

/// Relative standard error of each modal constant (of the mode's largest): about what
/// 1 % FRF noise gives through the modal fit.
const REL_STD: f64 = 1e-3;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Class {
    Noise,
    Misorientation,
    Position,
    Gain,
    ForceDirection,
}

fn random_axis(rng: &mut ChaCha8Rng) -> Vec3 {
    Vec3::new(normal(rng), normal(rng), normal(rng)).normalize()
}

/// The true geometry of one seed and the ids a warning should name.
fn perturbed(
    g: &Geometry,
    class: Class,
    rng: &mut ChaCha8Rng,
) -> (Geometry, Vec<f64>, Vec<String>) {
    let mut t = g.clone();
    let mut gains = vec![1.0; g.channels.len()];
    let sensors = ["A1", "A2", "A3"];
    let right = match class {
        Class::Noise => vec![],
        Class::Misorientation => {
            let s = sensors[rng.random_range(0..3)];
            let angle = (2.0 + 3.0 * rng.random::<f64>()).to_radians();
            let rot = nalgebra::Rotation3::from_axis_angle(
                &nalgebra::Unit::new_normalize(random_axis(rng)),
                angle,
            );
            for c in t.channels.iter_mut().filter(|c| c.point == s) {
                c.direction = rot * c.direction;
            }
            vec![s.to_string()]
        }
        Class::Position => {
            let s = sensors[rng.random_range(0..3)];
            let d = random_axis(rng) * (0.004 + 0.005 * rng.random::<f64>());
            for c in t.channels.iter_mut().filter(|c| c.point == s) {
                c.position += d;
            }
            vec![s.to_string()]
        }
        Class::Gain => {
            let i = rng.random_range(0..g.channels.len());
            let mut j = rng.random_range(0..g.channels.len() - 1);
            if j >= i {
                j += 1;
            }
            let mut ids = Vec::new();
            for k in [i, j] {
                gains[k] = if rng.random::<bool>() { 1.06 } else { 0.94 };
                ids.push(g.channels[k].id.clone());
                ids.push(g.channels[k].point.clone());
            }
            ids
        }
        Class::ForceDirection => {
            let k = rng.random_range(0..g.excitations.len());
            let angle = (4.0 + 4.0 * rng.random::<f64>()).to_radians();
            // About an axis normal to the force: a pure change of direction.
            let d = t.excitations[k].direction;
            let axis = d.cross(&random_axis(rng)).normalize();
            let rot =
                nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle);
            t.excitations[k].direction = rot * d;
            vec![t.excitations[k].id.clone()]
        }
    };
    (t, gains, right)
}

struct Outcome {
    warned: bool,
    named_right: bool,
    covered: bool,
}

fn run(class: Class, seed: u64) -> Outcome {
    let mut rng = ChaCha8Rng::seed_from_u64(seed * 1_000_003 + class as u64);
    let g = geometry();
    let truth = body();
    let modes = modes(&truth);
    let (gt, gains, right) = perturbed(&g, class, &mut rng);
    let mut modal = modal_record(&gt, &modes, REL_STD);
    let nch = g.channels.len();
    for m in &mut modal.modes {
        for i in 0..nch {
            let s = m.residue_std[i];
            m.residues[i] = m.residues[i] * gains[i] + c64::new(s * normal(&mut rng), 0.0);
        }
    }
    let sel = selection(&g, &modes, &[0, 1, 2, 3, 4, 5]);
    let opts = SolveOptions {
        estimators: vec![Estimator::ToivolaNuutila],
        ..Default::default()
    };
    let out = solve(&g, &modal, &sel, None, &opts).unwrap();
    let est: &InertiaEstimate = &out.estimates[0];
    let check = est.rigid_body_check.as_ref().expect("the check ran");
    let warned = !check.rigid_body_consistent;
    let warning = out
        .diagnostics
        .iter()
        .find(|d| d.kind == rbprops_core::records::DiagnosticKind::RigidBodyInconsistent)
        .map(|d| d.message.clone())
        .unwrap_or_default();
    assert_eq!(warned, !warning.is_empty());
    let named_right = warned && right.iter().any(|id| warning.contains(&format!("'{id}'")));
    let sys = est.systematic.as_ref().expect("a systematic interval");
    let j = truth.inertia_cm;
    let inside = |iv: [f64; 2], v: f64| iv[0] <= v && v <= iv[1];
    let covered = inside(sys.mass_95_kg, truth.mass)
        && (0..3).all(|k| inside(sys.inertia_cm_95_kg_m2[k][k], j[(k, k)]));
    Outcome {
        warned,
        named_right,
        covered,
    }
}

fn rates(class: Class, seeds: u64) -> (usize, usize, usize, usize) {
    let (mut ok, mut warned, mut named, mut covered) = (0, 0, 0, 0);
    for seed in 0..seeds {
        let o = run(class, seed);
        warned += o.warned as usize;
        named += o.named_right as usize;
        covered += o.covered as usize;
        ok += (o.named_right || o.covered) as usize;
    }
    (ok, warned, named, covered)
}

/// Exact data of a rigid body: consistent to the precision floor, and the warning and the
/// systematic spread are nil.
#[test]
fn exact_modes_are_consistent_with_zero_systematic_spread() {
    let g = geometry();
    let truth = body();
    let modes = modes(&truth);
    let modal = modal_record(&g, &modes, 0.0);
    let sel = selection(&g, &modes, &[0, 1, 2, 3, 4, 5]);
    let out = solve(&g, &modal, &sel, None, &SolveOptions::default()).unwrap();
    for e in out.estimates.iter().filter(|e| e.method != "mass_line") {
        assert_eq!(e.rigid_body_consistent, Some(true), "{}", e.method);
        let c = e.rigid_body_check.as_ref().unwrap();
        assert!(c.statistic < 1e-6, "{}", c.statistic);
        let s = e.systematic.as_ref().unwrap();
        assert!(s.mass_std_kg < 1e-9 * truth.mass, "{}", s.mass_std_kg);
    }
    assert!(!out
        .diagnostics
        .iter()
        .any(|d| d.kind == rbprops_core::records::DiagnosticKind::RigidBodyInconsistent));
}

/// A few seeds per class: every class meets "covered or named" in each of them, noise
/// alone never warns (its rate is ~0.1 % by construction of the threshold).
#[test]
fn systematic_errors_are_named_or_covered_on_a_few_seeds() {
    for class in [
        Class::Misorientation,
        Class::Position,
        Class::Gain,
        Class::ForceDirection,
    ] {
        let (ok, warned, named, covered) = rates(class, 6);
        assert!(
            ok >= 5,
            "{class:?}: {ok}/6 named or covered (warned {warned}, named {named}, covered {covered})"
        );
    }
    let (_, warned, _, covered) = rates(Class::Noise, 6);
    assert_eq!(warned, 0, "noise alone warned");
    assert!(
        covered >= 5,
        "noise alone: systematic interval covered {covered}/6"
    );
}

/// The acceptance study: 100 seeds per class (`cargo nextest run -p rbprops-inertia
/// --test it rigid_consistency:: --run-ignored only --no-capture`).
#[test]
#[ignore]
fn study_over_100_seeds() {
    println!("class, named-or-covered, warned, named right, covered (of 100)");
    for class in [
        Class::Noise,
        Class::Misorientation,
        Class::Position,
        Class::Gain,
        Class::ForceDirection,
    ] {
        let (ok, warned, named, covered) = rates(class, 100);
        println!("{class:?}, {ok}, {warned}, {named}, {covered}");
        if class == Class::Noise {
            assert!(warned <= 5);
        } else {
            assert!(ok >= 90, "{class:?}");
        }
    }
}
