//! Calibration of the reported 95 % intervals through the whole pipeline:
//! `frf-sim (1 % noise) | modal-fit | ni-select | rb-solve` over N seeds of a campaign,
//! counting how often each property's interval contains the truth, for the linearised
//! propagation and for the FRF-level bootstrap (std-based `±1.96σ` and percentile
//! intervals), and printing what separates bias from spread:
//! `bias/σ` = mean error over the seeds / RMS reported σ, `sd/σ` = spread of the estimates
//! over the seeds / RMS reported σ (1 when the reported σ is right).
//!
//! cargo run --release -p rbprops-cli --example calibration -- [N=50] [example=demo] [B=100] [LINES]
//!
//! `LINES` sets the campaign's number of lines (its `lines = …`; at 102,401 lines the
//! bootstrap draws on every q-th line, `rbprops_uq::decimation`); `LINES full` draws on
//! every line for comparison.

use rbprops_cli::stages::{self, Uncertainty};
use rbprops_core::records::{InertiaEstimate, TruthRecord};
use rbprops_core::InertiaProperties;
use rbprops_formats::topics;
use rbprops_inertia::{Estimator, SolveOptions};
use rbprops_uq::{estimate_vector, BootstrapOptions, N_PROPS, PROPERTY_NAMES};

const METHODS: [&str; 2] = ["bretl_conti", "toivola_nuutila"];
const KINDS: [&str; 3] = [
    "linearised ±1.96σ",
    "bootstrap ±1.96σ",
    "bootstrap percentile",
];

#[derive(Default, Clone)]
struct Tally {
    runs: usize,
    /// [kind][property]
    covered: [[usize; N_PROPS]; 3],
    /// Per run: error (estimate − truth), linearised σ, bootstrap σ.
    rows: Vec<([f64; N_PROPS], [f64; N_PROPS], [f64; N_PROPS])>,
    rel_errors: Vec<[f64; 3]>,
    failed_replicates: usize,
    failure_reasons: Vec<String>,
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let n: u64 = args.first().map(|s| s.parse()).transpose()?.unwrap_or(50);
    let example = args.get(1).cloned().unwrap_or_else(|| "demo".into());
    let b: usize = args.get(2).map(|s| s.parse()).transpose()?.unwrap_or(100);
    let mut spec = rbprops_sim::example(&example)
        .ok_or_else(|| anyhow::anyhow!("unknown example {example}"))?
        .to_string();
    if let Some(lines) = args.get(3) {
        let lines: usize = lines.parse()?;
        let edited = spec.replace("lines = 1601", &format!("lines = {lines}"));
        anyhow::ensure!(
            edited != spec || lines == 1601,
            "{example} has no `lines = 1601`"
        );
        spec = edited;
    }
    let decimate = args.get(4).map(String::as_str) != Some("full");
    let spec = spec.as_str();
    let opts = SolveOptions {
        estimators: vec![Estimator::BretlConti, Estimator::ToivolaNuutila],
        ..Default::default()
    };
    let boot_opts = BootstrapOptions {
        replicates: b,
        decimate,
        ..Default::default()
    };
    let mut tally = vec![Tally::default(); 2];
    let t0 = std::time::Instant::now();
    let mut t_boot = 0.0;
    for seed in 1..=n {
        let (mut rec, _) = stages::simulate(spec, &example, Some(seed))?;
        stages::modal_fit(&mut rec, &Default::default(), "cal")?;
        stages::ni_select(&mut rec, &Default::default(), "cal")?;
        let mut lin_rec = rec.clone();
        stages::rb_solve(&mut lin_rec, &opts, true, "cal")?;
        let linearised: Vec<InertiaEstimate> = lin_rec.get(topics::ESTIMATES)?;
        let tb = std::time::Instant::now();
        let (_, boot) = stages::rb_solve_with(
            &mut rec,
            &opts,
            &Uncertainty::Bootstrap(boot_opts.clone()),
            true,
            "cal",
        )?;
        t_boot += tb.elapsed().as_secs_f64();
        let boot = boot.ok_or_else(|| anyhow::anyhow!("seed {seed}: the bootstrap did not run"))?;
        let truth: TruthRecord = rec.get_one(topics::TRUTH)?.unwrap();
        let tv = InertiaProperties::from_rigid_body(&truth.properties.to_properties()).to_vector();
        for e in rec.get::<InertiaEstimate>(topics::ESTIMATES)? {
            let Some(k) = METHODS.iter().position(|m| e.method == *m) else {
                continue;
            };
            let lin = linearised
                .iter()
                .find(|l| l.method == e.method && l.setup == e.setup)
                .ok_or_else(|| anyhow::anyhow!("seed {seed}: no linearised {}", e.method))?;
            let bs = boot
                .estimates
                .iter()
                .find(|x| x.method == e.method && x.setup == e.setup)
                .ok_or_else(|| anyhow::anyhow!("seed {seed}: no bootstrap of {}", e.method))?;
            let v = estimate_vector(&e);
            let sl = std_vector(lin);
            let sb = std_vector(&e);
            let t = &mut tally[k];
            t.runs += 1;
            t.failed_replicates += bs.failed;
            for r in &bs.failure_reasons {
                if t.failure_reasons.len() < 4 && !t.failure_reasons.contains(r) {
                    t.failure_reasons.push(r.clone());
                }
            }
            for i in 0..N_PROPS {
                let err = (v[i] - tv[i]).abs();
                t.covered[0][i] += (err <= rbprops_inertia::Z95 * sl[i]) as usize;
                t.covered[1][i] += (err <= rbprops_inertia::Z95 * sb[i]) as usize;
                let [lo, hi] = bs.percentile_95[i];
                t.covered[2][i] += (lo <= tv[i] && tv[i] <= hi) as usize;
            }
            t.rows.push((std::array::from_fn(|i| v[i] - tv[i]), sl, sb));
            if let Some(er) = e.errors {
                t.rel_errors.push([er.mass, er.com, er.inertia]);
            }
        }
    }
    println!(
        "{example} ({}): {n} seeds, B = {b} replicates, {:.1} s in all, bootstrap {:.3} s per run ({:.2} ms per replicate)",
        args.get(3).map_or("1601 lines".to_string(), |l| format!(
            "{l} lines{}",
            if decimate { "" } else { ", every line" }
        )),
        t0.elapsed().as_secs_f64(),
        t_boot / n as f64,
        1e3 * t_boot / (n as f64 * b as f64)
    );
    for (k, m) in METHODS.iter().enumerate() {
        let t = &tally[k];
        println!(
            "{m}: {} runs, {} failed replicates; 95 % interval coverage per property:",
            t.runs, t.failed_replicates
        );
        for r in &t.failure_reasons {
            println!("  failure: {r}");
        }
        println!(
            "  {:22} {}",
            "",
            PROPERTY_NAMES.map(|s| format!("{s:>6}")).join("")
        );
        for (q, kind) in KINDS.iter().enumerate() {
            let cells: Vec<String> = (0..N_PROPS)
                .map(|i| {
                    format!(
                        "{:>5.0}%",
                        100.0 * t.covered[q][i] as f64 / t.runs.max(1) as f64
                    )
                })
                .collect();
            println!("  {kind:22} {}", cells.join(""));
        }
        let runs = t.rows.len().max(1) as f64;
        for (label, which) in [("linearised", 1usize), ("bootstrap", 2)] {
            let mut bias = Vec::new();
            let mut spread = Vec::new();
            for i in 0..N_PROPS {
                let mean_err = t.rows.iter().map(|r| r.0[i]).sum::<f64>() / runs;
                let sd = (t
                    .rows
                    .iter()
                    .map(|r| (r.0[i] - mean_err).powi(2))
                    .sum::<f64>()
                    / (runs - 1.0).max(1.0))
                .sqrt();
                let rms_sigma = (t
                    .rows
                    .iter()
                    .map(|r| if which == 1 { r.1[i] } else { r.2[i] }.powi(2))
                    .sum::<f64>()
                    / runs)
                    .sqrt();
                bias.push(format!("{:>6.2}", mean_err / rms_sigma));
                spread.push(format!("{:>6.2}", sd / rms_sigma));
            }
            println!("  {:22} {}", format!("bias/σ ({label})"), bias.join(""));
            println!("  {:22} {}", format!("sd/σ ({label})"), spread.join(""));
        }
        let med = |i: usize| {
            let mut v: Vec<f64> = t.rel_errors.iter().map(|e| e[i]).collect();
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

fn std_vector(e: &InertiaEstimate) -> [f64; N_PROPS] {
    InertiaProperties::standard_errors_of(e).to_vector()
}
