//! The fitted FRF model the bootstrap resamples from: per excitation, the poles and
//! residues of the modal fit re-synthesised on the fit's band, and the noise model.

use crate::error::UqError;
use crate::noise::fit_channel;
use rand_chacha::ChaCha8Rng;
use rbprops_core::noise::{standard_normal_pair, NoiseModel};
use rbprops_core::records::{ModalFitRecord, SelectionRecord};
use rbprops_core::{c64, FrfSet, Geometry};
use rbprops_modal::band::BandData;
use rbprops_modal::lsfd::{self, Residuals};
use rbprops_modal::{Pole, PoleMode};

/// One excitation's fitted model.
#[derive(Debug, Clone)]
pub struct ExcitationModel {
    /// Index in the geometry (and FRF set).
    pub excitation: usize,
    /// Excitation id.
    pub id: String,
    /// Its suspension set-up.
    pub setup: String,
    /// The measured lines of the fit's band.
    pub band: BandData,
    /// Channels with signal (the pole refinement uses only these, as the modal fit does).
    pub live: Vec<usize>,
    /// The poles of the record, in its mode order.
    pub poles: Vec<Pole>,
    /// `ModeEstimate.mode` of each pole.
    pub mode_numbers: Vec<usize>,
    /// LSFD synthesis `[channel][line]` of the measured band with these poles.
    pub synthesised: Vec<Vec<c64>>,
    /// The bootstrap's centre: the synthesis, except on lines of structured misfit where
    /// it is the measured value (so every replicate carries the misfit the data carry).
    pub centre: Vec<Vec<c64>>,
    /// Noise model per channel, estimated from the fit residuals (docs/conventions.md §8).
    pub noise: Vec<NoiseModel>,
    /// Per channel, the number of misfit lines.
    pub misfit_lines: Vec<usize>,
}

impl ExcitationModel {
    /// Synthesised FRFs plus one noise draw, `[channel][line]`, drawn channel by channel
    /// and line by line from `rng` (so a replicate's data depend only on its seed).
    pub fn draw(&self, rng: &mut ChaCha8Rng) -> Vec<Vec<c64>> {
        self.centre
            .iter()
            .zip(&self.noise)
            .map(|(s, nz)| {
                s.iter()
                    .map(|z| {
                        let (n1, n2) = standard_normal_pair(rng);
                        let sd = (nz.variance(*z) / 2.0).sqrt();
                        z + c64::new(sd * n1, sd * n2)
                    })
                    .collect()
            })
            .collect()
    }
}

/// The models of the excitations a bootstrap has to refit, grouped by shared poles.
#[derive(Debug, Clone)]
pub struct FittedModel {
    /// Every excitation that is refitted.
    pub excitations: Vec<ExcitationModel>,
    /// Indices into `excitations` that share one pole set (one per excitation for
    /// [`PoleMode::PerExcitation`], one per set-up for [`PoleMode::PerSetup`]).
    pub groups: Vec<Vec<usize>>,
    /// Whether poles are shared per excitation or per set-up.
    pub pole_mode: PoleMode,
    /// Whether the refits carry residual terms, as the measured fit did.
    pub residuals_enabled: bool,
}

/// True when every excitation of the set-up that was fitted carries the same poles: the
/// record was made with one pole set per set-up.
fn poles_shared(modal: &ModalFitRecord, ids: &[String]) -> bool {
    let poles = |id: &String| -> Vec<(u64, u64)> {
        modal
            .modes
            .iter()
            .filter(|m| &m.excitation == id)
            .map(|m| (m.frequency_hz.to_bits(), m.damping_ratio.to_bits()))
            .collect()
    };
    ids.len() > 1 && ids.windows(2).all(|w| poles(&w[0]) == poles(&w[1]))
}

impl FittedModel {
    /// Builds the model of every excitation the selection uses (and, with shared poles,
    /// of the other excitations of their set-ups). `pole_mode = None` infers it from the
    /// record: shared poles when all fitted excitations of a set-up carry bit-identical
    /// poles.
    pub fn new(
        geometry: &Geometry,
        frf: &FrfSet,
        modal: &ModalFitRecord,
        selection: &SelectionRecord,
        residual_terms: bool,
        pole_mode: Option<PoleMode>,
    ) -> Result<Self, UqError> {
        if frf.n_excitations != geometry.excitations.len()
            || frf.n_channels != geometry.channels.len()
            || frf.values.len() != frf.n_excitations * frf.n_channels * frf.n_lines()
        {
            return Err(UqError::Shape {
                frf: format!(
                    "{} excitations × {} channels × {} lines, {} values",
                    frf.n_excitations,
                    frf.n_channels,
                    frf.n_lines(),
                    frf.values.len()
                ),
                geometry: format!(
                    "{} excitations × {} channels",
                    geometry.excitations.len(),
                    geometry.channels.len()
                ),
            });
        }
        let mut used: Vec<String> = Vec::new();
        for s in &selection.selected {
            if !used.contains(&s.excitation) {
                used.push(s.excitation.clone());
            }
        }
        let fitted = |setup: &str| -> Vec<String> {
            modal
                .excitations
                .iter()
                .filter(|x| x.setup == setup && x.model_order > 0)
                .map(|x| x.excitation.clone())
                .collect()
        };
        let pole_mode = pole_mode.unwrap_or_else(|| {
            let mut setups: Vec<&str> = selection
                .selected
                .iter()
                .map(|s| s.setup.as_str())
                .collect();
            setups.dedup();
            if !setups.is_empty() && setups.iter().all(|s| poles_shared(modal, &fitted(s))) {
                PoleMode::PerSetup
            } else {
                PoleMode::PerExcitation
            }
        });
        let mut groups_ids: Vec<Vec<String>> = Vec::new();
        for id in &used {
            if groups_ids.iter().any(|g| g.contains(id)) {
                continue;
            }
            match pole_mode {
                PoleMode::PerExcitation => groups_ids.push(vec![id.clone()]),
                PoleMode::PerSetup => {
                    let setup = geometry
                        .excitations
                        .iter()
                        .find(|e| &e.id == id)
                        .map(|e| e.setup.clone())
                        .unwrap_or_default();
                    groups_ids.push(fitted(&setup));
                }
            }
        }
        let mut excitations = Vec::new();
        let mut groups = Vec::new();
        for g in &groups_ids {
            let mut idx = Vec::new();
            for id in g {
                idx.push(excitations.len());
                excitations.push(excitation_model(geometry, frf, modal, id, residual_terms)?);
            }
            let first = &excitations[idx[0]];
            for &i in &idx[1..] {
                let e: &ExcitationModel = &excitations[i];
                if e.band.frequency_hz != first.band.frequency_hz {
                    return Err(UqError::Excitation {
                        excitation: e.id.clone(),
                        reason: format!(
                            "shares its poles with '{}' but was fitted on other lines",
                            first.id
                        ),
                    });
                }
            }
            groups.push(idx);
        }
        let mut model = Self {
            excitations,
            groups,
            pole_mode,
            residuals_enabled: residual_terms,
        };
        model.fit_noise();
        Ok(model)
    }

    /// Noise model per excitation and channel (see [`crate::noise`]). The modal fit's
    /// parameters per channel: 2 per mode (residue), the residual terms, and the channel's
    /// share of the 2 per mode of the poles its group estimated jointly.
    fn fit_noise(&mut self) {
        for g in &self.groups {
            let live: usize = g.iter().map(|&i| self.excitations[i].live.len()).sum();
            for &i in g {
                let e = &mut self.excitations[i];
                let nm = e.poles.len() as f64;
                let res = Residuals::for_band(self.residuals_enabled, &e.band);
                let p = 2.0 * nm
                    + (res.upper as usize + res.lower as usize) as f64
                    + 2.0 * nm / live.max(1) as f64;
                let fits: Vec<_> = e
                    .band
                    .channels
                    .iter()
                    .zip(&e.synthesised)
                    .map(|(h, s)| fit_channel(h, s, p))
                    .collect();
                e.centre = fits
                    .iter()
                    .enumerate()
                    .map(|(c, f)| {
                        (0..e.band.n_lines())
                            .map(|l| {
                                if f.misfit[l] {
                                    e.band.channels[c][l]
                                } else {
                                    e.synthesised[c][l]
                                }
                            })
                            .collect()
                    })
                    .collect();
                e.misfit_lines = fits
                    .iter()
                    .map(|f| f.misfit.iter().filter(|m| **m).count())
                    .collect();
                e.noise = fits.into_iter().map(|f| f.noise).collect();
            }
        }
    }
}

fn excitation_model(
    geometry: &Geometry,
    frf: &FrfSet,
    modal: &ModalFitRecord,
    id: &str,
    residual_terms: bool,
) -> Result<ExcitationModel, UqError> {
    let bad = |reason: String| UqError::Excitation {
        excitation: id.to_string(),
        reason,
    };
    let k = geometry
        .excitations
        .iter()
        .position(|e| e.id == id)
        .ok_or_else(|| bad("not in the geometry".into()))?;
    let rec = modal
        .excitations
        .iter()
        .find(|x| x.excitation == id)
        .ok_or_else(|| bad("the modal fit has no record of it".into()))?;
    if rec.model_order == 0 {
        return Err(bad("its modal fit failed (model order 0)".into()));
    }
    let band = BandData::extract(frf, k, Some((rec.band_hz[0], rec.band_hz[1])), id).map_err(
        |source| UqError::Modal {
            excitation: id.to_string(),
            source,
        },
    )?;
    if band.n_lines() != rec.n_lines {
        return Err(bad(format!(
            "the fit's band {:?} Hz holds {} lines of the FRF set, the modal fit used {}",
            rec.band_hz,
            band.n_lines(),
            rec.n_lines
        )));
    }
    let mut modes: Vec<_> = modal.modes.iter().filter(|m| m.excitation == id).collect();
    modes.sort_by_key(|m| m.mode);
    if modes.is_empty() {
        return Err(bad("the modal fit has no modes for it".into()));
    }
    let poles: Vec<Pole> = modes
        .iter()
        .map(|m| Pole::from_modal(m.frequency_hz, m.damping_ratio))
        .collect();
    let res = Residuals::for_band(residual_terms, &band);
    let fit = lsfd::fit_residues(&poles, &band, &band.channels, res);
    let synthesised = lsfd::synthesise(&poles, &fit, &band);
    if synthesised
        .iter()
        .flatten()
        .any(|z| !(z.re.is_finite() && z.im.is_finite()))
    {
        return Err(bad("the synthesised FRFs are not finite".into()));
    }
    let live = band
        .channel_rms()
        .iter()
        .enumerate()
        .filter(|(_, r)| **r > 0.0)
        .map(|(c, _)| c)
        .collect();
    Ok(ExcitationModel {
        excitation: k,
        id: id.to_string(),
        setup: rec.setup.clone(),
        live,
        mode_numbers: modes.iter().map(|m| m.mode).collect(),
        poles,
        centre: synthesised.clone(),
        synthesised,
        noise: Vec::new(),
        misfit_lines: Vec::new(),
        band,
    })
}
