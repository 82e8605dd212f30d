use crate::common::*;
use rbprops_check::{check, CheckOptions};

#[test]
#[ignore]
fn explore() {
    let lines: usize = std::env::var("LINES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(400);
    let eff = std::env::var("EFF").unwrap_or_default();
    let nom = nominal(lines);
    let mut truth = nom.clone();
    truth.body.mass_kg *= 1.02;
    let effects: Vec<(&str, Vec<f64>)> = match eff.as_str() {
        // The check's local gravity form (φ = 1/ℓ, load factor, tilts, spring turn); the
        // other effects through the catalogue (`s…` below).
        "gravity" => vec![("gravity_stiffness", vec![1.0, 1.0, 0.0, 0.0, 0.0])],
        _ => vec![],
    };
    let sim_eff: Vec<&str> = match eff.as_str() {
        "sgravity" => vec!["id = \"gravity_stiffness\"\ncord_length_m = [1.0]"],
        "sgain" => vec!["id = \"channel_gain\"\ngains = { 2x = 1.03, 3z = 0.98 }"],
        "smisor" => {
            vec!["id = \"sensor_misorientation\"\nrotations_rad = { 2 = [0.03, -0.02, 0.04] }"]
        }
        "ssmass" => vec!["id = \"sensor_mass\"\nmass_kg = 0.1"],
        "sglobal" => vec!["id = \"global_gain\"\ngain = 1.03"],
        "sexc" => vec!["id = \"excitation_gain\"\ngains = { force2 = 1.04 }"],
        "sdash" => vec![
            "id = \"nonproportional_damping\"\naxial_n_s_per_m = [6.0]\nlateral_n_s_per_m = [0.0]",
        ],
        "two" => vec![
            "id = \"gravity_stiffness\"\ncord_length_m = [1.0]",
            "id = \"channel_gain\"\ngains = { 2x = 1.03, 3z = 0.98 }",
        ],
        _ => vec![],
    };
    let (g, frf) = if eff.starts_with('s') || eff == "two" {
        record_sim(&truth, &sim_eff, 0.01, 7)
    } else {
        record(&truth, &effects, 0.01, 7)
    };
    let t = std::time::Instant::now();
    let out = check(&nom, &g, &frf, &CheckOptions::default()).unwrap();
    let r = &out.report;
    println!("time {:?}", t.elapsed());
    println!("{}", r.verdict);
    println!("noise {:?}", r.noise);
    for s in &r.screening {
        println!(
            "{} {} rank {}/{} score {:.1} thr {:.1} refit {:?} {:?} -> {}",
            s.step,
            s.id,
            s.rank,
            s.n_parameters,
            s.score,
            s.threshold,
            s.refit_delta_chi2,
            s.refit_delta_bic,
            s.decision
        );
    }
    for a in &r.accepted {
        println!("{} {:?}", a.id, a.parameters);
    }
    println!(
        "chi2 nominal {:.3} before {:.3} after {:.3} band {:?}",
        r.chi2_nu_nominal, r.chi2_nu_before, r.chi2_nu_after, r.noise_band
    );
    println!("flagged before {:?}", r.residuals_before.flagged);
    println!(
        "mass {} {} {}",
        r.inertia_nominal.mass_kg, r.inertia_before.mass_kg, r.inertia_after.mass_kg
    );
    println!("warnings {:?}", r.diagnostics);
}

#[test]
#[ignore]
fn explore_weighed() {
    let nom = nominal(400);
    let mut truth = nom.clone();
    truth.body.mass_kg *= 1.02;
    let (g, frf) = record_sim(&truth, &["id = \"global_gain\"\ngain = 1.04"], 0.01, 33);
    let opts = CheckOptions {
        weighed_mass_kg: Some(truth.body.mass_kg),
        ..Default::default()
    };
    let r = check(&nom, &g, &frf, &opts).unwrap().report;
    for s in &r.screening {
        println!(
            "{} {} rank {}/{} score {:.1} thr {:.1} refit {:?} {:?} -> {}",
            s.step,
            s.id,
            s.rank,
            s.n_parameters,
            s.score,
            s.threshold,
            s.refit_delta_chi2,
            s.refit_delta_bic,
            s.decision
        );
    }
    println!("{:?}", r.not_observable);
}

#[test]
#[ignore]
fn explore_predict_cost() {
    use rbprops_check::predict::{predict, Layout};
    let nom = nominal(400);
    let (g, frf) = record_sim(&nom, &[], 0.01, 1);
    let layout = Layout::new(&nom, &g, &frf).unwrap();
    let t = std::time::Instant::now();
    for _ in 0..100 {
        predict(&nom, &layout, &[]).unwrap();
    }
    println!("predict: {:?} per call", t.elapsed() / 100);
    let b = rbprops_check::params::Baseline::new(&nom);
    let t = std::time::Instant::now();
    for _ in 0..100 {
        let _ = b.apply(&b.initial());
    }
    println!("apply: {:?} per call", t.elapsed() / 100);
    let t = std::time::Instant::now();
    for _ in 0..100 {
        rbprops_sim::build_models(&nom, &layout.spec_geometry, &[]).unwrap();
    }
    println!("build_models: {:?} per call", t.elapsed() / 100);
}

/// `EFFSPEC='id = "..."\n...' cargo test -p rbprops-check --test it explore::explore_spec -- --ignored --nocapture`:
/// a concealed rbprops-sim effect at 400 lines, 1 % given noise, truth = nominal with
/// mass +2 % and vertical springs +8 %.
#[test]
#[ignore]
fn explore_spec() {
    use rbprops_check::RecordingNoise;
    let spec = std::env::var("EFFSPEC")
        .unwrap_or_default()
        .replace("\\n", "\n");
    let seed: u64 = std::env::var("SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(7);
    let nom = nominal(400);
    let mut truth = nom.clone();
    truth.body.mass_kg *= 1.02;
    for s in &mut truth.setups {
        for sp in &mut s.springs {
            if let Some(k) = &mut sp.stiffness_n_per_m {
                k[2] *= 1.08;
            }
        }
    }
    let effs: Vec<&str> = spec.split("@@").filter(|s| !s.is_empty()).collect();
    let rel: f64 = std::env::var("REL")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0.01);
    let (g, frf) = record_sim(&truth, &effs, rel, seed);
    let opts = CheckOptions {
        noise: Some(RecordingNoise::given(vec![rel; 9], vec![0.0; 9])),
        max_iterations: std::env::var("MAXIT")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(60),
        ..Default::default()
    };
    let t = std::time::Instant::now();
    let out = check(&nom, &g, &frf, &opts).unwrap();
    let r = &out.report;
    println!("time {:?}", t.elapsed());
    println!("{}", r.verdict);
    for s in &r.screening {
        println!(
            "  step {} {:28} rank {:2} score {:10.1} thr {:6.1} refit {:?} bic {:?}: {}",
            s.step,
            s.id,
            s.rank,
            s.score,
            s.threshold,
            s.refit_delta_chi2.map(|x| x.round()),
            s.refit_delta_bic.map(|x| x.round()),
            s.decision
        );
    }
    for a in &r.accepted {
        for p in &a.parameters {
            println!("  {} {} = {} ± {}", a.id, p.name, p.value, p.standard_error);
        }
    }
    for n in &r.not_observable {
        println!("  not observable {}: {}", n.id, n.reason);
    }
    let tp = truth.properties();
    println!("truth mass {} com {:?}", tp.mass, tp.com);
    println!(
        "before {:?} {:?} {:?}",
        r.inertia_before.mass_kg, r.inertia_before.com_m, r.inertia_before.moments_kg_m2
    );
    println!(
        "after  {:?} {:?} {:?}",
        r.inertia_after.mass_kg, r.inertia_after.com_m, r.inertia_after.moments_kg_m2
    );
    println!(
        "chi2 {} -> {} band {:?}",
        r.chi2_nu_before, r.chi2_nu_after, r.noise_band
    );
}
