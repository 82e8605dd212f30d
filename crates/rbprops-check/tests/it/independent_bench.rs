//! The model check on a speed-bench recording of the independent generator
//! (`fixtures/model-check/bench/`, 1000 lines × 9 × 3, 1 % noise, single precision),
//! checked as the bench does (default options, noise from the data).

use crate::bench_recording::{nominal, recording, CASES};
use rbprops_check::{check, CheckOptions};

/// `gravity-window-gain`: the body on its four springs under gravity (the nominal model
/// has none), an exponential window τ = 4 s and channel 2z's gain −5 %. The generator's
/// springs are linear springs to the ground: at the sagged equilibrium (2.4 and 1.5 mrad
/// of tilt) their stiffness axes turn with the body and couple bounce and sway by ≈14 and
/// 22 N/m, which the cords' reading of the springs cannot express; an in-band
/// `elastic_mode` used to absorb part of that misfit and the check ended at χ²/ν 1.98.
/// With the gravity candidate's φ₅ (the springs turning with the body) the three are
/// named, nothing else, χ²/ν ends in the noise band, and the fitted φ₅ and load factor
/// φ₂ are the generator's 1 within 4 SE.
///
/// Measured (release, 2 cores, session 30): `exponential_window`, `gravity_stiffness`,
/// `channel_gain`; χ²/ν 156.956 → 0.995 (band 0.968–1.050); φ₂ = 0.99905 ± 0.00069,
/// φ₅ = 1.00302 ± 0.00278, 1/ℓ = 0.0000 ± 0.0045 1/m (springs, no pendulum); 19 s.
///
/// It was an ignored study, and between sessions 28 and 30 the check lost the gravity
/// here unseen (a cord length of 15 km judged implausible, six false claims): it runs in
/// CI now, as do the bench's other two three-hit cases
/// ([`three_hit_bench_recordings_are_named_exactly`]).
#[test]
fn spring_hung_body_under_gravity_needs_no_elastic_mode() {
    let (stem, r) = named_exactly(2);
    assert_eq!(stem, "gravity-window-gain");
    let gravity = r
        .accepted
        .iter()
        .find(|a| a.id == "gravity_stiffness")
        .unwrap();
    for p in &gravity.parameters {
        eprintln!(
            "  {} = {:.5} ± {:.5} {}",
            p.name, p.value, p.standard_error, p.unit
        );
    }
    for name in ["load_term_factor", "spring_turn_fraction"] {
        let p = gravity
            .parameters
            .iter()
            .find(|p| p.name == name)
            .unwrap_or_else(|| panic!("{name} not fitted: {:?}", gravity.parameters));
        assert!(
            (p.value - 1.0).abs() <= 4.0 * p.standard_error,
            "{name} = {} ± {}, the generator's is 1",
            p.value,
            p.standard_error
        );
    }
}

/// The bench's other two three-hit recordings (`gain-orient-gauge`: channel 1y's gain,
/// sensor 2 misoriented, a 50 g gauge under force 3; `position-force-elastic`: sensor 3
/// displaced, force 2's direction off, an elastic mode at 10 Hz) name exactly their
/// three effects, nothing else, with χ²/ν in the noise band, as the bench asserts
/// (`benches/check_speed.rs`, which CI does not run).
#[test]
fn three_hit_bench_recordings_are_named_exactly() {
    for case in [0, 1] {
        named_exactly(case);
    }
}

/// Checks bench case `case` ([`CASES`]) with default options and asserts the exact set
/// named and χ²/ν in the noise band; returns the case's stem and report.
fn named_exactly(case: usize) -> (&'static str, rbprops_check::ModelCheckReport) {
    let (stem, concealed) = CASES[case];
    let (g, frf) = recording(stem);
    let t0 = std::time::Instant::now();
    let out = check(&nominal(), &g, &frf, &CheckOptions::default()).unwrap();
    crate::common::assert_improved_spec_is_the_final_model(stem, &out);
    let r = out.report;
    let mut named: Vec<&str> = r.accepted.iter().map(|a| a.id.as_str()).collect();
    for f in &r.ambiguous {
        named.extend(f.ids.iter().map(|s| s.as_str()));
    }
    eprintln!(
        "{stem}: named {named:?}; χ²/ν {:.3} → {:.3} (band {:.3}–{:.3}); {:.1} s",
        r.chi2_nu_before,
        r.chi2_nu_after,
        r.noise_band[0],
        r.noise_band[1],
        t0.elapsed().as_secs_f64()
    );
    let mut want: Vec<&str> = concealed.to_vec();
    want.sort_unstable();
    named.sort_unstable();
    assert_eq!(named, want, "{stem}: {}", r.verdict);
    crate::common::assert_chi2_in_band(stem, &r);
    (stem, r)
}
