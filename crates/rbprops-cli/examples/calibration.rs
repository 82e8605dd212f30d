//! Calibration of the reported 95 % intervals through the whole pipeline:
//! `frf-sim (1 % noise) | modal-fit | ni-select | rb-solve` over N seeds of a campaign,
//! counting how often each property's interval contains the truth, and printing the
//! median relative errors.
//!
//! cargo run --release -p rbprops-cli --example calibration -- [N=50] [example=demo]

use rbprops_cli::stages;
use rbprops_core::records::{InertiaEstimate, TruthRecord};
use rbprops_formats::topics;
use rbprops_inertia::{Estimator, SolveOptions};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let n: u64 = args.first().map(|s| s.parse()).transpose()?.unwrap_or(50);
    let example = args.get(1).cloned().unwrap_or_else(|| "demo".into());
    let spec = rbprops_sim::example(&example)
        .ok_or_else(|| anyhow::anyhow!("unknown example {example}"))?;
    let names = [
        "m", "cx", "cy", "cz", "Jxx", "Jyy", "Jzz", "Jxy", "Jxz", "Jyz",
    ];
    let methods = ["bretl_conti", "toivola_nuutila"];
    let mut covered = vec![[0usize; 10]; 2];
    let mut runs = [0usize; 2];
    let mut errs: Vec<Vec<[f64; 3]>> = vec![Vec::new(); 2];
    let t0 = std::time::Instant::now();
    for seed in 1..=n {
        let (mut rec, _) = stages::simulate(spec, &example, Some(seed))?;
        stages::modal_fit(&mut rec, &Default::default(), "cal")?;
        stages::ni_select(&mut rec, &Default::default(), "cal")?;
        let opts = SolveOptions {
            estimators: vec![Estimator::BretlConti, Estimator::ToivolaNuutila],
            ..Default::default()
        };
        stages::rb_solve(&mut rec, &opts, true, "cal")?;
        let truth: TruthRecord = rec.get_one(topics::TRUTH)?.unwrap();
        let t = truth.properties;
        let tv = [
            t.mass_kg,
            t.com_m[0],
            t.com_m[1],
            t.com_m[2],
            t.inertia_cm_kg_m2[0][0],
            t.inertia_cm_kg_m2[1][1],
            t.inertia_cm_kg_m2[2][2],
            t.inertia_cm_kg_m2[0][1],
            t.inertia_cm_kg_m2[0][2],
            t.inertia_cm_kg_m2[1][2],
        ];
        for e in rec.get::<InertiaEstimate>(topics::ESTIMATES)? {
            let Some(k) = methods.iter().position(|m| *m == e.method) else {
                continue;
            };
            let j = &e.inertia_cm_kg_m2;
            let s = &e.inertia_cm_std_kg_m2;
            let v = [
                e.mass_kg, e.com_m[0], e.com_m[1], e.com_m[2], j[0][0], j[1][1], j[2][2], j[0][1],
                j[0][2], j[1][2],
            ];
            let sd = [
                e.mass_std_kg,
                e.com_std_m[0],
                e.com_std_m[1],
                e.com_std_m[2],
                s[0][0],
                s[1][1],
                s[2][2],
                s[0][1],
                s[0][2],
                s[1][2],
            ];
            runs[k] += 1;
            for i in 0..10 {
                if (v[i] - tv[i]).abs() <= 1.96 * sd[i] {
                    covered[k][i] += 1;
                }
            }
            if let Some(er) = e.errors {
                errs[k].push([er.mass, er.com, er.inertia]);
            }
        }
    }
    println!("{example}: {n} seeds, {:.1} s", t0.elapsed().as_secs_f64());
    for (k, m) in methods.iter().enumerate() {
        println!(
            "{m}: {} runs; 95 % interval coverage per property:",
            runs[k]
        );
        let line: Vec<String> = names
            .iter()
            .zip(&covered[k])
            .map(|(nm, c)| format!("{nm} {:.0} %", 100.0 * *c as f64 / runs[k].max(1) as f64))
            .collect();
        println!("  {}", line.join(", "));
        let med = |i: usize| {
            let mut v: Vec<f64> = errs[k].iter().map(|e| e[i]).collect();
            v.sort_by(f64::total_cmp);
            v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
        };
        println!(
            "  median relative errors: m {:.3} %, c {:.3} %, J {:.3} %",
            100.0 * med(0),
            100.0 * med(1),
            100.0 * med(2)
        );
    }
    Ok(())
}
