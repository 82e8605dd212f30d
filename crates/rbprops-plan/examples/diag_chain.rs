//! Diagnostic: where the plan's prediction and the pipeline's spread part, mode pair by
//! mode pair. For each seed the selected modes' real constants are read from the real
//! pipeline; the linearised chain `p ≈ p₀ + G (â − a)` is applied to them; the variance
//! of each property is split into mode-pair terms `2 g_r Cov(â_r, â_t) g_tᵀ` (Monte Carlo
//! against predicted).
//!
//! `cargo run --release -p rbprops-plan --example diag_chain -- SPEC|EXAMPLE SEEDS [NOISE] [PROP]`
#![allow(clippy::needless_range_loop, clippy::type_complexity)] // a diagnostic: index loops mirror the formulas

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use rbprops_core::real_modal_constants;
use rbprops_plan::estimate::properties_of_shapes;
use rbprops_plan::{evaluate, excitation_covariance, Estimator, Layout, PlanModel, PROPERTY_NAMES};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let name = args.first().map(String::as_str).unwrap_or("test-case-2");
    let seeds: u64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(50);
    let text = match rbprops_sim::example(name) {
        Some(t) => t.to_string(),
        None => std::fs::read_to_string(name).expect("spec file"),
    };
    let mut spec = rbprops_sim::CampaignSpec::from_toml_str(&text).expect("spec");
    if let Some(a) = args.get(2).and_then(|s| s.parse().ok()) {
        spec.noise.relative = a;
    }
    let prop: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(0);
    let model = PlanModel::from_spec(&spec).expect("model");
    let layout = Layout::from_spec(&spec, &model).expect("layout");
    let rows = layout.rows();
    let nc = rows.len();
    let modes = &model.setups[0].modes;
    let nm = modes.len();
    let ev = evaluate(&model, &layout, Estimator::ToivolaNuutila);
    let pred = ev.setups[0].1.as_ref().expect("observable");
    let sel: Vec<usize> = pred.selected_hits.iter().map(|s| s.unwrap()).collect();
    println!("plan selection (hit per mode): {sel:?}");
    let freqs: Vec<String> = modes
        .iter()
        .map(|m| format!("{:.4}", m.frequency_hz))
        .collect();
    if let Some((r, t, d)) = model.closest_modes(0) {
        println!(
            "modes {} Hz, damping {:.4}; closest: modes {} and {}, {d:.2} half-bandwidths",
            freqs.join(" "),
            modes[0].damping_ratio,
            r + 1,
            t + 1
        );
    }
    let data: Vec<_> = layout
        .hits
        .iter()
        .map(|h| excitation_covariance(&model, &model.setups[0], &rows, &h.column()))
        .collect();
    // Stacked true constants and predicted covariance.
    let n = nm * nc;
    let mut a0 = DVector::<f64>::zeros(n);
    let mut sigma = DMatrix::<f64>::zeros(n, n);
    for r in 0..nm {
        for i in 0..nc {
            a0[r * nc + i] = data[sel[r]].constants[r][i];
        }
        for t in 0..nm {
            if sel[r] != sel[t] {
                continue;
            }
            for i in 0..nc {
                for j in 0..nc {
                    sigma[(r * nc + i, t * nc + j)] = data[sel[r]].cov[(r * nc + i, t * nc + j)];
                }
            }
        }
    }
    // Chain a → p (plan's own nonlinear chain).
    let mut g = nalgebra::Matrix6::<f64>::zeros();
    for rw in &rows {
        g += rw.transpose() * rw;
    }
    let g_inv = g.try_inverse().unwrap();
    let chain = |a: &DVector<f64>| -> [f64; 10] {
        let phis: Vec<_> = (0..nm)
            .map(|r| {
                let f = layout.hits[sel[r]].column();
                let mut sta = rbprops_core::Vec6::zeros();
                for (i, rw) in rows.iter().enumerate() {
                    sta += rw.transpose() * a[r * nc + i];
                }
                let q = g_inv * sta;
                let s = f.dot(&q);
                q / s.abs().sqrt() * s.signum()
            })
            .collect();
        properties_of_shapes(Estimator::ToivolaNuutila, &phis).unwrap()
    };
    let mut jac = DMatrix::<f64>::zeros(10, n);
    for c in 0..n {
        let h = 1e-6 * a0.amax();
        let mut ap = a0.clone();
        let mut am = a0.clone();
        ap[c] += h;
        am[c] -= h;
        let (pp, pm) = (chain(&ap), chain(&am));
        for k in 0..10 {
            jac[(k, c)] = (pp[k] - pm[k]) / (2.0 * h);
        }
    }
    // Monte Carlo.
    let chosen_poly = std::sync::atomic::AtomicUsize::new(0);
    let runs: Vec<Option<(DVector<f64>, [f64; 10], Vec<String>)>> = (0..seeds)
        .into_par_iter()
        .map(|seed| {
            let mut s = spec.clone();
            s.seed = seed;
            let sim = rbprops_sim::simulate(&s).ok()?;
            let mut fo = rbprops_modal::FitOptions::default();
            if std::env::var("DIAG_METHOD").as_deref() == Ok("plscf") {
                fo.method = rbprops_modal::Method::Plscf;
            }
            let fit = rbprops_modal::fit_campaign(&sim.geometry, &sim.frf, &fo).ok()?;
            if fit
                .record
                .excitations
                .iter()
                .any(|e| e.method == rbprops_core::records::FitMethod::Plscf)
            {
                chosen_poly.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            }
            let sr =
                rbprops_ni::select_modes(&sim.geometry, &sim.frf, &fit.record, &Default::default())
                    .ok()?;
            let mut a = DVector::<f64>::zeros(n);
            let mut chosen = Vec::new();
            for (r, sm) in sr.record.selected.iter().enumerate() {
                chosen.push(sm.excitation.clone());
                let me = fit
                    .record
                    .modes
                    .iter()
                    .find(|e| e.excitation == sm.excitation && e.mode == sm.excitation_mode)?;
                let (c, _) = real_modal_constants(&me.residues);
                let dot: f64 = (0..nc).map(|i| c[i] * a0[r * nc + i]).sum();
                for i in 0..nc {
                    a[r * nc + i] = c[i] * dot.signum();
                }
            }
            let opts = rbprops_inertia::SolveOptions {
                estimators: vec![rbprops_inertia::Estimator::ToivolaNuutila],
                rigid_body_check: false,
                ..Default::default()
            };
            let out =
                rbprops_inertia::solve(&sim.geometry, &fit.record, &sr.record, None, &opts).ok()?;
            let p = rbprops_core::InertiaProperties::of_estimate(&out.estimates[0]).to_vector();
            Some((a, p, chosen))
        })
        .collect();
    let ok: Vec<_> = runs.iter().flatten().collect();
    let ids: Vec<&str> = layout.hits.iter().map(|h| h.id.as_str()).collect();
    let switched = ok
        .iter()
        .filter(|(_, _, c)| (0..nm).any(|r| c[r] != ids[sel[r]]))
        .count();
    println!(
        "{} of {} seeds ok; {} with a selection other than the plan's; {} fitted poly-reference",
        ok.len(),
        seeds,
        switched,
        chosen_poly.load(std::sync::atomic::Ordering::Relaxed)
    );
    let m = ok.len() as f64;
    let mean_a: DVector<f64> = ok.iter().map(|x| &x.0).sum::<DVector<f64>>() / m;
    let mut cov_mc = DMatrix::<f64>::zeros(n, n);
    for x in &ok {
        let d = &x.0 - &mean_a;
        cov_mc += &d * d.transpose();
    }
    cov_mc /= m - 1.0;
    println!("bias of constants / predicted std, largest: {:.2}", {
        let mut b: f64 = 0.0;
        for c in 0..n {
            let s = sigma[(c, c)].sqrt();
            if s > 0.0 {
                b = b.max(((mean_a[c] - a0[c]) / s).abs());
            }
        }
        b
    });
    println!("prop   pipeline MC  linear chain MC   pred    pred/pipe  lin/pipe  robust/pipe  worst seed (σ)");
    for k in 0..10 {
        let pm: f64 = ok.iter().map(|x| x.1[k]).sum::<f64>() / m;
        let ps = (ok.iter().map(|x| (x.1[k] - pm).powi(2)).sum::<f64>() / (m - 1.0)).sqrt();
        let gk = jac.row(k);
        let lin = (gk * &cov_mc * gk.transpose())[0].sqrt();
        let pr = (gk * &sigma * gk.transpose())[0].sqrt();
        // Robust spread (1.4826 × median absolute deviation) and the largest excursion:
        // heavy tails (a few seeds fitted far off) show as robust/pipe well below 1.
        let mut v: Vec<f64> = ok.iter().map(|x| x.1[k]).collect();
        v.sort_by(f64::total_cmp);
        let med = v[v.len() / 2];
        let mut dev: Vec<f64> = v.iter().map(|x| (x - med).abs()).collect();
        dev.sort_by(f64::total_cmp);
        let robust = 1.4826 * dev[dev.len() / 2];
        let worst = ok
            .iter()
            .enumerate()
            .max_by(|a, b| (a.1 .1[k] - pm).abs().total_cmp(&(b.1 .1[k] - pm).abs()))
            .map(|(s, x)| (s, (x.1[k] - pm) / pr))
            .unwrap();
        println!(
            "{:4} {:12.4e} {:12.4e} {:12.4e} {:8.3} {:8.3} {:8.3}   {} ({:+.1})",
            PROPERTY_NAMES[k],
            ps,
            lin,
            pr,
            pr / ps,
            lin / ps,
            robust / ps,
            worst.0,
            worst.1
        );
    }
    println!(
        "variance terms of {} (MC / predicted), mode pairs:",
        PROPERTY_NAMES[prop]
    );
    let gk = jac.row(prop);
    for r in 0..nm {
        for t in r..nm {
            let blk = |c: &DMatrix<f64>| {
                let gr = gk.columns(r * nc, nc);
                let gt = gk.columns(t * nc, nc);
                let v = (gr * c.view((r * nc, t * nc), (nc, nc)) * gt.transpose())[0];
                if r == t {
                    v
                } else {
                    2.0 * v
                }
            };
            println!(
                "  modes {} {} (hits {} {}): MC {:+.3e}  pred {:+.3e}",
                r + 1,
                t + 1,
                ids[sel[r]],
                ids[sel[t]],
                blk(&cov_mc),
                blk(&sigma)
            );
        }
    }
}
