//! Fixture helpers: recordings simulated with concealed effects.
#![allow(dead_code)]

use rbprops_check::candidates::local_effect;
use rbprops_check::predict::{predict, Layout};
use rbprops_core::{FrfSet, Geometry};
use rbprops_sim::effects::Effect;
use rbprops_sim::noise::{add_noise, excitation_rng};
use rbprops_sim::CampaignSpec;

/// Test Case II with `lines` lines (0–12.5 Hz) and no noise: the nominal spec.
pub fn nominal(lines: usize) -> CampaignSpec {
    let mut s = CampaignSpec::from_toml_str(rbprops_sim::example("test-case-2").unwrap()).unwrap();
    s.frequency.lines = lines;
    s.frequency.start_hz = 0.0;
    s
}

/// The recording of `truth` (a spec, possibly with other parameter values) with the
/// given effects (id, values) switched on, and relative noise `rel` drawn exactly as
/// rbprops-sim draws it (seeded per excitation).
pub fn record(
    truth: &CampaignSpec,
    effects: &[(&str, Vec<f64>)],
    rel: f64,
    seed: u64,
) -> (Geometry, FrfSet) {
    let g = truth.geometry().unwrap();
    let effs: Vec<Box<dyn Effect>> = effects
        .iter()
        .map(|(id, v)| local_effect(id, truth, v).unwrap())
        .collect();
    let mut frf = FrfSet::zeros(
        truth.quantity,
        truth.frequency_axis(),
        g.excitations.len(),
        g.channels.len(),
    );
    let layout = Layout::new(truth, &g, &frf).unwrap();
    frf.values = predict(truth, &layout, &effs).unwrap();
    let nl = frf.n_lines();
    let block = frf.n_channels * nl;
    for e in 0..frf.n_excitations {
        let mut rng = excitation_rng(seed, e);
        add_noise(
            &mut frf.values[e * block..(e + 1) * block],
            rel,
            0.0,
            &mut rng,
        );
    }
    (g, frf)
}

/// A recording made by rbprops-sim itself from `truth` plus `[[effect]]` entries given
/// as TOML snippets (e.g. `id = "channel_gain"\ngains = { 1x = 1.03 }`).
pub fn record_sim(
    truth: &CampaignSpec,
    effects: &[&str],
    rel: f64,
    seed: u64,
) -> (Geometry, FrfSet) {
    let mut s = truth.clone();
    for e in effects {
        let wrapped = format!("[[effect]]\n{e}\n");
        #[derive(serde::Deserialize)]
        struct W {
            effect: Vec<rbprops_sim::spec::EffectSpec>,
        }
        let w: W = toml::from_str(&wrapped).unwrap();
        s.effects.extend(w.effect);
    }
    s.noise.relative = rel;
    s.noise.floor = 0.0;
    s.seed = seed;
    let sim = rbprops_sim::simulate(&s).unwrap();
    (sim.geometry, sim.frf)
}
