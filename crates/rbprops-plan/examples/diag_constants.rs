//! Diagnostic: predicted vs Monte Carlo spread of each excitation's real modal constants.
#![allow(
    clippy::needless_range_loop,
    clippy::redundant_closure,
    clippy::type_complexity
)] // a diagnostic: index loops mirror the formulas
use rayon::prelude::*;
use rbprops_core::real_modal_constants;
use rbprops_plan::{excitation_covariance, Layout, PlanModel};

static ONLY: std::sync::Mutex<Vec<[f64; 6]>> = std::sync::Mutex::new(Vec::new());

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let seeds: u64 = args.first().and_then(|s| s.parse().ok()).unwrap_or(50);
    let mut spec =
        rbprops_sim::CampaignSpec::from_toml_str(rbprops_sim::example("test-case-2").unwrap())
            .unwrap();
    spec.noise.relative = 0.01;
    let model = PlanModel::from_spec(&spec).unwrap();
    let layout = Layout::from_spec(&spec, &model).unwrap();
    let rows = layout.rows();
    let nc = rows.len();
    let modes = &model.setups[0].modes;
    let runs: Vec<Vec<Vec<Option<Vec<f64>>>>> = (0..seeds)
        .into_par_iter()
        .map(|seed| {
            let mut s = spec.clone();
            s.seed = seed;
            let sim = rbprops_sim::simulate(&s).unwrap();
            let fit =
                rbprops_modal::fit_campaign(&sim.geometry, &sim.frf, &Default::default()).unwrap();
            layout
                .hits
                .iter()
                .map(|h| {
                    modes
                        .iter()
                        .map(|m| {
                            fit.record
                                .modes
                                .iter()
                                .filter(|e| e.excitation == h.id)
                                .min_by(|a, b| {
                                    (a.frequency_hz - m.frequency_hz)
                                        .abs()
                                        .total_cmp(&(b.frequency_hz - m.frequency_hz).abs())
                                })
                                .filter(|e| (e.frequency_hz / m.frequency_hz - 1.0).abs() < 0.02)
                                .map(|e| real_modal_constants(&e.residues).0)
                        })
                        .collect()
                })
                .collect()
        })
        .collect();
    println!("pipeline selection seed 0: {:?}", selection_of(&spec));
    {
        let masses: Vec<(f64, f64)> = (0..seeds)
            .into_par_iter()
            .map(|seed| {
                let mut s = spec.clone();
                s.seed = seed;
                let sim = rbprops_sim::simulate(&s).unwrap();
                let fit = rbprops_modal::fit_campaign(&sim.geometry, &sim.frf, &Default::default())
                    .unwrap();
                let sel = rbprops_ni::select_modes(
                    &sim.geometry,
                    &sim.frf,
                    &fit.record,
                    &Default::default(),
                )
                .unwrap();
                let opts = rbprops_inertia::SolveOptions {
                    estimators: vec![rbprops_inertia::Estimator::ToivolaNuutila],
                    rigid_body_check: false,
                    ..Default::default()
                };
                let out =
                    rbprops_inertia::solve(&sim.geometry, &fit.record, &sel.record, None, &opts)
                        .unwrap();
                let m_pipe = out.estimates[0].mass_kg;
                // Own chain from the selected constants.
                let frame =
                    rbprops_inertia::RigidFrame::new(&sim.geometry, rbprops_core::Vec3::zeros())
                        .unwrap();
                let mut phis = Vec::new();
                for sm in &sel.record.selected {
                    let k = frame.excitation_index(&sm.excitation).unwrap();
                    let me = fit
                        .record
                        .modes
                        .iter()
                        .find(|e| e.excitation == sm.excitation && e.mode == sm.excitation_mode)
                        .unwrap();
                    phis.push(frame.shape(k, &me.residues).unwrap().phi0);
                }
                // Mass with one mode's shape replaced by the truth (sign matched), per mode.
                let truth: Vec<_> = modes.iter().map(|m| m.shape).collect();
                let mut only = [0.0; 6];
                for r in 0..6 {
                    let mut ph = truth.clone();
                    let s = if ph[r].dot(&phis[r]) < 0.0 { -1.0 } else { 1.0 };
                    ph[r] = phis[r] * s;
                    only[r] = rbprops_plan::estimate::properties_of_shapes(
                        rbprops_plan::Estimator::ToivolaNuutila,
                        &ph,
                    )
                    .unwrap()[0];
                }
                ONLY.lock().unwrap().push(only);
                let p = rbprops_plan::estimate::properties_of_shapes(
                    rbprops_plan::Estimator::ToivolaNuutila,
                    &phis,
                )
                .unwrap();
                (m_pipe, p[0])
            })
            .collect();
        let n = masses.len() as f64;
        let sd = |f: &dyn Fn(&(f64, f64)) -> f64| {
            let m = masses.iter().map(|x| f(x)).sum::<f64>() / n;
            (masses.iter().map(|x| (f(x) - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
        };
        let only = ONLY.lock().unwrap();
        for r in 0..6 {
            let v: Vec<f64> = only.iter().map(|o| o[r]).collect();
            let m = v.iter().sum::<f64>() / v.len() as f64;
            let sd =
                (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() as f64 - 1.0)).sqrt();
            println!("MC mass std from mode {} alone: {:.3e}", r + 1, sd);
        }
        println!(
            "mass std: pipeline {:.4e}, own chain on the same constants {:.4e}, max |diff| {:.3e}",
            sd(&|x| x.0),
            sd(&|x| x.1),
            masses.iter().map(|x| (x.0 - x.1).abs()).fold(0.0, f64::max)
        );
    }
    let cache = rbprops_plan::JacobianCache::default();
    let ev = rbprops_plan::evaluate(&model, &layout, rbprops_plan::Estimator::ToivolaNuutila);
    println!(
        "plan selection: {:?}",
        ev.setups[0].1.as_ref().unwrap().selected_hits
    );
    {
        // Predicted mass std from each mode alone (its selected hit's constants).
        let sel = ev.setups[0].1.as_ref().unwrap().selected_hits.clone();
        for r in 0..6 {
            let k = sel[r].unwrap();
            let mut l2 = layout.clone();
            l2.hits = vec![layout.hits[k].clone()];
            let ec =
                excitation_covariance(&model, &model.setups[0], &rows, &layout.hits[k].column());
            // a_r → φ_r → m via finite differences of the chain
            let truth: Vec<_> = modes.iter().map(|m| m.shape).collect();
            let f = layout.hits[k].column();
            let g = {
                let mut g = nalgebra::Matrix6::<f64>::zeros();
                for rw in &rows {
                    g += rw.transpose() * rw;
                }
                g.try_inverse().unwrap()
            };
            let m_of = |a: &[f64]| {
                let mut sta = rbprops_core::Vec6::zeros();
                for (i, rw) in rows.iter().enumerate() {
                    sta += rw.transpose() * a[i];
                }
                let q = g * sta;
                let phi = q / f.dot(&q).sqrt();
                let mut ph = truth.clone();
                let s = if ph[r].dot(&phi) < 0.0 { -1.0 } else { 1.0 };
                ph[r] = phi * s;
                rbprops_plan::estimate::properties_of_shapes(
                    rbprops_plan::Estimator::ToivolaNuutila,
                    &ph,
                )
                .unwrap()[0]
            };
            let a0 = ec.constants[r].clone();
            let mut grad = vec![0.0; nc];
            for i in 0..nc {
                let h = 1e-7 * a0.iter().fold(0.0f64, |x, y| x.max(y.abs()));
                let mut ap = a0.clone();
                let mut am = a0.clone();
                ap[i] += h;
                am[i] -= h;
                grad[i] = (m_of(&ap) - m_of(&am)) / (2.0 * h);
            }
            let mut v = 0.0;
            for i in 0..nc {
                for j in 0..nc {
                    v += grad[i] * grad[j] * ec.cov[(r * nc + i, r * nc + j)];
                }
            }
            println!(
                "predicted mass std from mode {} alone: {:.3e}",
                r + 1,
                v.sqrt()
            );
        }
    }
    let _ = cache;
    println!("pipeline selection seed 0: {:?}", selection_of(&spec));
    let ev = rbprops_plan::evaluate(&model, &layout, rbprops_plan::Estimator::ToivolaNuutila);
    println!(
        "plan selection: {:?}",
        ev.setups[0].1.as_ref().unwrap().selected_hits
    );
    for (k, h) in layout.hits.iter().enumerate() {
        let ec = excitation_covariance(&model, &model.setups[0], &rows, &h.column());
        for r in 0..modes.len() {
            let ok: Vec<&Vec<f64>> = runs.iter().filter_map(|run| run[k][r].as_ref()).collect();
            if ok.len() < 3 {
                println!("{} mode {}: found in {} runs", h.id, r + 1, ok.len());
                continue;
            }
            let n = ok.len() as f64;
            let mut ratios = Vec::new();
            let mut line = String::new();
            for i in 0..nc {
                let sign = if ok[0][i] * ec.constants[r][i] < 0.0 {
                    -1.0
                } else {
                    1.0
                };
                let mean = ok.iter().map(|v| sign * v[i]).sum::<f64>() / n;
                let sd = (ok.iter().map(|v| (sign * v[i] - mean).powi(2)).sum::<f64>() / (n - 1.0))
                    .sqrt();
                let pred = ec.cov[(r * nc + i, r * nc + i)].sqrt();
                ratios.push(pred / sd);
                line += &format!(" {:.2}", pred / sd);
                let _ = mean;
            }
            // Mode scale: projection of constants on the true vector.
            let a = &ec.constants[r];
            let an: f64 = a.iter().map(|x| x * x).sum::<f64>().sqrt();
            let proj: Vec<f64> = ok
                .iter()
                .map(|v| {
                    let sign = if v.iter().zip(a).map(|(x, y)| x * y).sum::<f64>() < 0.0 {
                        -1.0
                    } else {
                        1.0
                    };
                    sign * v.iter().zip(a).map(|(x, y)| x * y).sum::<f64>() / an
                })
                .collect();
            let pm = proj.iter().sum::<f64>() / n;
            let psd = (proj.iter().map(|p| (p - pm).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
            let u: Vec<f64> = a.iter().map(|x| x / an).collect();
            let mut pv = 0.0;
            for i in 0..nc {
                for j in 0..nc {
                    pv += u[i] * u[j] * ec.cov[(r * nc + i, r * nc + j)];
                }
            }
            println!("{} mode {} ({} runs, ni {:.2e}) scale pred/MC {:.2} (rel MC {:.2e}) per channel:{}", h.id, r + 1, ok.len(), ec.ni[r], pv.sqrt() / psd, psd / an, line);
        }
    }
}

#[allow(dead_code)]
pub fn selection_of(spec: &rbprops_sim::CampaignSpec) -> Vec<(usize, String, usize)> {
    let sim = rbprops_sim::simulate(spec).unwrap();
    let fit = rbprops_modal::fit_campaign(&sim.geometry, &sim.frf, &Default::default()).unwrap();
    let sel = rbprops_ni::select_modes(&sim.geometry, &sim.frf, &fit.record, &Default::default())
        .unwrap();
    sel.record
        .selected
        .iter()
        .map(|s| (s.mode, s.excitation.clone(), s.excitation_mode))
        .collect()
}
