//! Model FRFs on the recording's frequency axis and in its channel/excitation order,
//! computed with rbprops-sim's own model builder ([`rbprops_sim::build_models`]) so that
//! the nominal model and every candidate effect are evaluated by the code that
//! generates recordings.
//!
//! Per set-up and line: `G(ω) = (K + iωC − ω²M)⁻¹`, `H_ce = s_cᵀ G f_e + Σ extra modes`,
//! then the effects' output transforms, then the quantity factor (`iω`, `−ω²`).
//! This mirrors `rbprops_sim::simulate_with` without noise (a test checks they agree);
//! it exists because the simulator's per-line transfer table is private
//! (suggested move: a public `rbprops_sim::predict(spec, geometry, effects, axis)`).

use crate::error::CheckError;
use rbprops_core::{c64, FrfSet, Geometry, Quantity};
use rbprops_sim::effects::{Effect, OutputBlock};
use rbprops_sim::CampaignSpec;

/// How the recording maps onto the spec: which spec channel/excitation each recorded
/// one is, and the recording's axis and quantity.
#[derive(Debug, Clone)]
pub struct Layout {
    pub spec_geometry: Geometry,
    /// Recording channel i is spec channel `channel_map[i]`.
    pub channel_map: Vec<usize>,
    /// Recording excitation e is spec excitation `excitation_map[e]`.
    pub excitation_map: Vec<usize>,
    pub frequency_hz: Vec<f64>,
    pub quantity: Quantity,
}

impl Layout {
    /// Matches the recording's channels and excitations to the spec's by id.
    pub fn new(
        spec: &CampaignSpec,
        recording: &Geometry,
        frf: &FrfSet,
    ) -> Result<Layout, CheckError> {
        let spec_geometry = spec
            .geometry()
            .map_err(|e| CheckError::Mismatch(format!("spec geometry: {e}")))?;
        if recording.channels.len() != frf.n_channels
            || recording.excitations.len() != frf.n_excitations
        {
            return Err(CheckError::Data(format!(
                "geometry lists {} channels × {} excitations but the FRFs hold {} × {}",
                recording.channels.len(),
                recording.excitations.len(),
                frf.n_channels,
                frf.n_excitations
            )));
        }
        let channel_map = recording
            .channels
            .iter()
            .map(|c| {
                spec_geometry.channel_index(&c.id).ok_or_else(|| {
                    CheckError::Mismatch(format!("recorded channel '{}' is not in the spec", c.id))
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let excitation_map = recording
            .excitations
            .iter()
            .map(|e| {
                spec_geometry.excitation_index(&e.id).ok_or_else(|| {
                    CheckError::Mismatch(format!(
                        "recorded excitation '{}' is not in the spec",
                        e.id
                    ))
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Layout {
            spec_geometry,
            channel_map,
            excitation_map,
            frequency_hz: frf.frequency_hz.clone(),
            quantity: frf.quantity,
        })
    }

    pub fn n_lines(&self) -> usize {
        self.frequency_hz.len()
    }
    pub fn n_values(&self) -> usize {
        self.channel_map.len() * self.excitation_map.len() * self.n_lines()
    }
}

/// The model's FRFs `[excitation][channel][line]` in the recording's layout.
pub fn predict(
    spec: &CampaignSpec,
    layout: &Layout,
    effects: &[Box<dyn Effect>],
) -> Result<Vec<c64>, CheckError> {
    // Same application order as rbprops-sim's parse_effects: by `order()`, then as given.
    let mut ordered: Vec<&Box<dyn Effect>> = effects.iter().collect();
    ordered.sort_by_key(|e| e.order());
    let ordered: Vec<Box<dyn Effect>> = ordered
        .into_iter()
        .map(|e| e.with_values(&e.values()).map_err(CheckError::Model))
        .collect::<Result<_, _>>()?;
    let effects = &ordered[..];
    let models = rbprops_sim::build_models(spec, &layout.spec_geometry, effects)
        .map_err(|e| CheckError::Model(e.to_string()))?;
    let nl = layout.n_lines();
    let n_sch = layout.spec_geometry.channels.len();
    let omegas: Vec<f64> = layout
        .frequency_hz
        .iter()
        .map(|f| std::f64::consts::TAU * f)
        .collect();
    // Which set-up model and input serve each spec excitation.
    let mut route = vec![None; layout.spec_geometry.excitations.len()];
    for (si, sm) in models.iter().enumerate() {
        for (ii, inp) in sm.model.inputs.iter().enumerate() {
            route[inp.excitation] = Some((si, ii));
        }
    }
    // Per set-up, P(ω) = S G(ω) stored [channel][coordinate][line]; built lazily.
    let mut tables: Vec<Option<Vec<c64>>> = vec![None; models.len()];
    let n_rch = layout.channel_map.len();
    let mut out = vec![c64::new(0.0, 0.0); layout.n_values()];
    let mut block = vec![c64::new(0.0, 0.0); n_sch * nl];
    for (re, &se) in layout.excitation_map.iter().enumerate() {
        let (si, ii) = route[se]
            .ok_or_else(|| CheckError::Model(format!("excitation {se} has no set-up model")))?;
        let sm = &models[si];
        if tables[si].is_none() {
            let mut t = vec![c64::new(0.0, 0.0); n_sch * 6 * nl];
            for (l, &w) in omegas.iter().enumerate() {
                let g = sm.model.direct_compliance(w).ok_or_else(|| {
                    CheckError::Model(format!(
                        "set-up '{}': dynamic stiffness singular at {:.6} Hz",
                        sm.model.setup, layout.frequency_hz[l]
                    ))
                })?;
                for (c, row) in sm.model.outputs.iter().enumerate() {
                    for j in 0..6 {
                        let mut acc = c64::new(0.0, 0.0);
                        for k in 0..6 {
                            acc += g[(k, j)] * row[k];
                        }
                        t[(c * 6 + j) * nl + l] = acc;
                    }
                }
            }
            tables[si] = Some(t);
        }
        let t = tables[si].as_ref().expect("built above");
        let f = &sm.model.inputs[ii].column;
        for (c, dst) in block.chunks_exact_mut(nl).enumerate() {
            dst.fill(c64::new(0.0, 0.0));
            for j in 0..6 {
                if f[j] == 0.0 {
                    continue;
                }
                let src = &t[(c * 6 + j) * nl..(c * 6 + j + 1) * nl];
                for (d, s) in dst.iter_mut().zip(src) {
                    *d += s * f[j];
                }
            }
            for x in &sm.model.extra_modes {
                for (d, &w) in dst.iter_mut().zip(&omegas) {
                    *d += x.receptance(c, se, w);
                }
            }
        }
        let mut ob = OutputBlock {
            excitation: se,
            frequency_hz: &layout.frequency_hz,
            n_channels: n_sch,
            values: &mut block,
        };
        for eff in effects {
            eff.transform_output(&mut ob);
        }
        for (rc, &sc) in layout.channel_map.iter().enumerate() {
            let dst = &mut out[(re * n_rch + rc) * nl..(re * n_rch + rc + 1) * nl];
            let src = &block[sc * nl..(sc + 1) * nl];
            for ((d, s), &w) in dst.iter_mut().zip(src).zip(&omegas) {
                *d = s * layout.quantity.from_receptance_factor(w);
            }
        }
    }
    if let Some(i) = out
        .iter()
        .position(|v| !(v.re.is_finite() && v.im.is_finite()))
    {
        return Err(CheckError::Model(format!(
            "non-finite model FRF at value {i}"
        )));
    }
    Ok(out)
}
