//! The fitted FRF model the bootstrap resamples from: per excitation, the poles and
//! residues of the modal fit re-synthesised on the fit's band, and the noise model.

use crate::error::UqError;
use crate::noise::fit_channel;
use crate::scratch::SharedStore;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;
use rbprops_core::noise::NoiseModel;
use rbprops_core::records::{ExcitationFitRecord, ModalFitRecord, ModeEstimate, SelectionRecord};
use rbprops_core::{c64, CommonRelativeError, FrfSource, Geometry};
use rbprops_modal::band::BandData;
use rbprops_modal::lsfd::{self, Residuals};
use rbprops_modal::{Pole, PoleMode};
use std::borrow::Cow;
use std::sync::Arc;

/// One excitation's fitted model.
#[derive(Debug, Clone)]
pub struct ExcitationModel {
    /// Index in the geometry (and FRF set).
    pub excitation: usize,
    /// Excitation id.
    pub id: String,
    /// Its suspension set-up.
    pub setup: String,
    /// The fit's band: its lines and their quality, without its values (`channels` is
    /// empty: the measured values are read only while the model is built, `Measured`).
    /// A model that keeps its grids in a store lets the lines go too (its first line and
    /// the line quality stay).
    pub band: BandData,
    /// Channels with signal (the pole refinement uses only these, as the modal fit does).
    pub live: Vec<usize>,
    /// The poles of the record, in its mode order.
    pub poles: Vec<Pole>,
    /// `ModeEstimate.mode` of each pole.
    pub mode_numbers: Vec<usize>,
    /// Per pole: the selection takes a mode shape from it (for this excitation).
    pub selected: Vec<bool>,
    /// Noise model per channel, estimated from the fit residuals (docs/conventions.md §8).
    pub noise: Vec<NoiseModel>,
    /// Per channel, the number of misfit lines.
    pub misfit_lines: Vec<usize>,
    /// The replicates' grid (made by [`FittedModel::new`]): every `decimation`-th line of
    /// the band, the middle of each run of `decimation` lines, with the bootstrap's centre
    /// there as its channels (the modal fit's synthesis, the measured values on lines of
    /// structured misfit). Empty when the model keeps it in its store: read it with
    /// [`FittedModel::grid`].
    pub draw_band: BandData,
    /// Per channel and grid line: the standard deviation of each of the real and imaginary
    /// parts of a replicate's noise (empty when stored, as `draw_band`).
    pub draw_sd: Vec<Vec<f64>>,
    /// Lines of the replicates' grid when it is in the model's store.
    pub stored_lines: Option<usize>,
    /// Lines of the band per line of the replicates' grid.
    pub decimation: usize,
    /// Per channel: its noise comes from the given line variances (not the residuals).
    pub given_variance: Vec<bool>,
    /// The force noise's error common to every channel, drawn once per replicate on the
    /// grid ([`CommonDraw`]); None when the estimator gave none.
    pub common: Option<CommonDraw>,
}

/// What building an excitation's model reads and lets go (issue 41's memory bound: the
/// set's values are never held together).
struct Measured {
    /// The measured band values `[channel][line]`.
    values: Vec<Vec<c64>>,
    /// The bootstrap's centre `[channel][line]`: the LSFD synthesis of the measured band
    /// with the record's poles, except on lines of structured misfit where it is the
    /// measured value (so every replicate carries the misfit the data carry). Built in
    /// place from the synthesis by the noise fit, so that the band is never held three
    /// times (measured, synthesised, centre). The replicates' grid takes its values.
    centre: Vec<Vec<c64>>,
}

/// The common relative error of one excitation on the replicates' grid: its process
/// (bins merged to at most [`MAX_COMMON_TERMS`] grid-line × bin products) and the
/// standard deviation per grid line, `ρ κ` (`CommonRelativeError::run_variance_factor`:
/// a grid line stands for its run of lines).
#[derive(Debug, Clone)]
pub struct CommonDraw {
    /// The process, bins possibly merged.
    pub error: CommonRelativeError,
    /// `ρ κ` per grid line.
    pub sd: Vec<f64>,
    /// The bins' phase factors on the grid (`CommonRelativeError::phasors`), made once
    /// for every replicate.
    pub phasors: Vec<c64>,
}

/// An excitation's replicates' grid as a replicate reads it ([`FittedModel::grid`]): its
/// lines with the bootstrap's centre as channels, and the noise's standard deviations.
#[derive(Debug, Clone)]
pub struct Grid<'a> {
    /// [`ExcitationModel::draw_band`].
    pub band: Cow<'a, BandData>,
    /// [`ExcitationModel::draw_sd`].
    pub sd: Cow<'a, [Vec<f64>]>,
}

/// Most grid lines × bins of a common draw (a draw costs one complex term each).
pub const MAX_COMMON_TERMS: usize = 1 << 20;

impl ExcitationModel {
    /// Sets [`ExcitationModel::selected`]: the poles whose modes the selection takes a
    /// shape from on this excitation.
    fn mark_selected(&mut self, selection: &SelectionRecord) {
        self.selected = self
            .mode_numbers
            .iter()
            .map(|&n| {
                selection
                    .selected
                    .iter()
                    .any(|s| s.excitation == self.id && s.excitation_mode == n)
            })
            .collect();
    }

    /// The centre plus one noise draw on the replicates' grid `grid` (this excitation's,
    /// [`FittedModel::grid`]), `[channel][grid line]`,
    /// drawn channel by channel and line by line from `rng` (so a replicate's data depend
    /// only on its seed). The normals come from `rand_distr`'s ziggurat, about 4× cheaper
    /// than Box–Muller's logarithm and sine per pair: at 102,401 lines the draws were 15 %
    /// of the bootstrap's time (issue 41's bound on it).
    ///
    /// With a common error ([`ExcitationModel::common`]) one draw `ε` of it follows, after
    /// every channel's, and every channel's centre takes `H ε` more (`Ĥ = H (1 + ε)`).
    pub fn draw(&self, grid: &Grid, rng: &mut ChaCha8Rng) -> Vec<Vec<c64>> {
        let mut out: Vec<Vec<c64>> = grid
            .band
            .channels
            .iter()
            .zip(grid.sd.iter())
            .map(|(s, sd)| {
                s.iter()
                    .zip(sd)
                    .map(|(z, sd)| {
                        let (n1, n2): (f64, f64) =
                            (rng.sample(StandardNormal), rng.sample(StandardNormal));
                        z + c64::new(sd * n1, sd * n2)
                    })
                    .collect()
            })
            .collect();
        if let Some(c) = &self.common {
            let z: Vec<f64> = (0..c.error.weights.len())
                .map(|_| rng.sample(StandardNormal))
                .collect();
            let eps = c.error.draw_on(&c.phasors, &c.sd, &z);
            for (y, h) in out.iter_mut().zip(&grid.band.channels) {
                for ((y, h), e) in y.iter_mut().zip(h).zip(&eps) {
                    *y += h * e;
                }
            }
        }
        out
    }

    /// Fills the replicates' grid and noise (`prepare_draws_given`) from the `centre`
    /// (`Measured::centre`), which the grid takes: `sigma2(c, l)` is the given variance of
    /// channel c at band line l, if known.
    fn prepare_draws(
        &mut self,
        q: usize,
        given: Option<&dyn Fn(usize, usize) -> Option<f64>>,
        common: Option<&CommonRelativeError>,
        centre: Vec<Vec<c64>>,
    ) {
        let n = self.band.n_lines();
        let q = q.max(1);
        let runs: Vec<(usize, usize)> = (0..n)
            .step_by(q)
            .map(|start| (start, (start + q).min(n)))
            .collect();
        let grid: Vec<usize> = runs.iter().map(|(a, b)| a + (b - a) / 2).collect();
        let n_channels = centre.len();
        let mut draw_sd = Vec::with_capacity(n_channels);
        let mut given_variance = Vec::with_capacity(n_channels);
        for c in 0..n_channels {
            let known: Option<Vec<f64>> = given.and_then(|g| (0..n).map(|l| g(c, l)).collect());
            given_variance.push(known.is_some());
            let variance = |l: usize| match &known {
                Some(v) => v[l],
                None => self.noise[c].variance(centre[c][l]),
            };
            // One grid line stands for its run of q lines: the estimators' normal equations
            // are sums over lines, and a sum over every q-th line of noise with variance
            // (mean σ² of the run)/q has the mean and covariance of the sum over all lines
            // while the FRF and the line weights are smooth over the run (docs/results.md).
            draw_sd.push(
                runs.iter()
                    .map(|&(a, b)| {
                        let mean = (a..b).map(variance).sum::<f64>() / (b - a) as f64;
                        (mean / q as f64 / 2.0).sqrt()
                    })
                    .collect(),
            );
        }
        let pick = |v: &[f64]| -> Vec<f64> { grid.iter().map(|&l| v[l]).collect() };
        // On every line the grid's values are the centre itself: moved, not copied.
        let channels = if q == 1 {
            centre
        } else {
            centre
                .iter()
                .map(|h| grid.iter().map(|&l| h[l]).collect())
                .collect()
        };
        self.draw_band = BandData {
            quantity: self.band.quantity,
            frequency_hz: pick(&self.band.frequency_hz),
            omega: pick(&self.band.omega),
            channels,
            first_line: self.band.first_line,
            line_quality: self.band.line_quality.as_deref().map(pick),
        };
        self.draw_sd = draw_sd;
        self.decimation = q;
        self.given_variance = given_variance;
        self.common = common.map(|c| self.common_draw(c, &runs));
    }

    /// The common error on the grid: `ρ²` the mean over each run, times `κ²` of the run
    /// length at the band's line spacing; `common.relative_variance` is on the band's
    /// lines.
    fn common_draw(&self, common: &CommonRelativeError, runs: &[(usize, usize)]) -> CommonDraw {
        let f = &self.band.frequency_hz;
        let spacing = if f.len() > 1 {
            (f[f.len() - 1] - f[0]) / (f.len() - 1) as f64
        } else {
            0.0
        };
        let kappa2 = common.run_variance_factor(spacing, self.decimation);
        let sd = runs
            .iter()
            .map(|&(a, b)| {
                let mean = common.relative_variance[a..b].iter().sum::<f64>() / (b - a) as f64;
                (mean * kappa2).sqrt()
            })
            .collect();
        let max_bins = (MAX_COMMON_TERMS / runs.len().max(1)).max(1);
        let error = common.coarsened(max_bins);
        CommonDraw {
            phasors: error.phasors(&self.draw_band.frequency_hz),
            error,
            sd,
        }
    }
}

/// The FRF set's shape against the geometry's excitations and channels, and what the
/// source can check without its values (a set in memory: its values' count).
fn check_shape(geometry: &Geometry, frf: &dyn FrfSource) -> Result<(), UqError> {
    let counts = frf.n_excitations() == geometry.excitations.len()
        && frf.n_channels() == geometry.channels.len();
    let layout = frf.validate();
    if counts && layout.is_ok() {
        return Ok(());
    }
    let mut described = format!(
        "{} excitations × {} channels × {} lines",
        frf.n_excitations(),
        frf.n_channels(),
        frf.frequency_hz().len()
    );
    if let Err(e) = layout {
        described.push_str(&format!(": {e}"));
    }
    Err(UqError::Shape {
        frf: described,
        geometry: format!(
            "{} excitations × {} channels",
            geometry.excitations.len(),
            geometry.channels.len()
        ),
    })
}

/// Every excitation id of `groups` with the geometry indices of its group's excitations:
/// the modal fit weighted a pole set's lines by all of them
/// (`BandData::with_line_factors`).
fn with_group_members<'g>(
    geometry: &Geometry,
    groups: &'g [Vec<String>],
) -> Vec<(&'g String, Vec<usize>)> {
    groups
        .iter()
        .flat_map(|g| {
            let members: Vec<usize> = g
                .iter()
                .filter_map(|id| geometry.excitations.iter().position(|e| &e.id == id))
                .collect();
            g.iter().map(move |id| (id, members.clone()))
        })
        .collect()
}

/// Fewest lines per half-power half-bandwidth `ζω_n` of the narrowest mode that the
/// replicates' grid keeps. A sum over lines of a function that varies on the scale of a
/// half-bandwidth (a Lorentzian) is reproduced by every q-th line to about `e^{−2πk}`
/// with k lines per half-bandwidth (the trapezoidal rule on an analytic function): 2 leave
/// about 4·10⁻⁶, and the refinement works on such a grid as it does on the 1,601-line demo
/// (about 2 lines per half-bandwidth of its first mode), where the bootstrap is calibrated.
pub const MIN_LINES_PER_HALF_BANDWIDTH: f64 = 2.0;

/// Fewest lines of the replicates' grid, whatever the poles.
pub const MIN_GRID_LINES: usize = 400;

/// Lines of the band per line of the replicates' grid for these poles: as many as keep
/// [`MIN_LINES_PER_HALF_BANDWIDTH`] and [`MIN_GRID_LINES`] (1: every line).
pub fn decimation(poles: &[Pole], band: &BandData) -> usize {
    let n = band.n_lines();
    if n < 2 * MIN_GRID_LINES {
        return 1;
    }
    let df = (band.frequency_hz[n - 1] - band.frequency_hz[0]) / (n - 1) as f64;
    let half_bandwidth_hz = poles
        .iter()
        .map(|p| -p.0.re / std::f64::consts::TAU)
        .fold(f64::INFINITY, f64::min);
    if !(df > 0.0 && half_bandwidth_hz > 0.0 && half_bandwidth_hz.is_finite()) {
        return 1;
    }
    let q = (half_bandwidth_hz / df / MIN_LINES_PER_HALF_BANDWIDTH).floor();
    (q.min((n / MIN_GRID_LINES) as f64).max(1.0)) as usize
}

/// What the replicates are drawn from and on which lines ([`FittedModel::new`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct Draws<'a> {
    /// The FRF estimator's line variances, if known (else the residuals' noise model).
    pub line_variance: Option<&'a LineVariance>,
    /// The exponential window the FRFs were prefiltered for (the variances take its factor).
    pub window: Option<&'a rbprops_core::WindowCorrection>,
    /// Draw on every q-th line ([`decimation`]) instead of every line.
    pub decimate: bool,
    /// The modal fit's line weighting ([`crate::BootstrapOptions::fit_weighting`]).
    pub fit_weighting: Option<&'a rbprops_modal::CoherenceWeighting>,
    /// Where the grids go when the model is larger than it holds (`None`: held).
    pub scratch: Option<&'a crate::Scratch>,
}

/// The FRF estimator's variance of every FRF line (`frf-est`'s line-variance topic, or an
/// export's coherence and averages), which the bootstrap draws from instead of the
/// residuals of the fit.
#[derive(Debug, Clone, PartialEq)]
pub struct LineVariance {
    /// `σ² = E|ε|²` of every FRF value, the FRF set's layout `[excitation][channel][line]`;
    /// NaN where unknown (such a channel's noise comes from the residuals).
    pub sigma2: Vec<f64>,
    /// `Σ_m Re γ_m` over the lags a window correlates the noise of neighbouring lines by
    /// (`γ_m`, docs/conventions.md "FRF estimation"): the noise of a run of lines has this
    /// times the sum of their variances. 1 for independent lines.
    pub correlation_factor: f64,
    /// Where the variances come from, for the method text.
    pub source: String,
    /// Per excitation (the FRF set's order): the force noise's error common to its
    /// channels, `ρ²` on the set's lines, if the estimator gave it. `sigma2` holds its
    /// part as each channel sees it; the bootstrap draws this part once for all channels.
    pub common: Vec<Option<CommonRelativeError>>,
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
    /// The store of the replicates' grids when the model is too large to hold
    /// ([`Draws::scratch`]); `None`: every excitation holds its own.
    pub(crate) grids: Option<Arc<SharedStore>>,
}

impl FittedModel {
    /// Excitation `i`'s replicates' grid: held, or read from the model's store.
    pub fn grid(&self, i: usize) -> std::io::Result<Grid<'_>> {
        let e = &self.excitations[i];
        let (Some(store), Some(n)) = (&self.grids, e.stored_lines) else {
            return Ok(Grid {
                band: Cow::Borrowed(&e.draw_band),
                sd: Cow::Borrowed(&e.draw_sd),
            });
        };
        let nc = e.noise.len();
        let quality = e.band.line_quality.is_some() as usize;
        let (channels, extra) = store.channels(i, nc, n, (2 + quality + nc) * n)?;
        let mut parts = extra.chunks_exact(n.max(1)).map(<[f64]>::to_vec);
        let mut next = || parts.next().unwrap_or_default();
        let (frequency_hz, omega) = (next(), next());
        let line_quality = (quality == 1).then(&mut next);
        let sd = (0..nc).map(|_| next()).collect();
        Ok(Grid {
            band: Cow::Owned(BandData {
                quantity: e.draw_band.quantity,
                frequency_hz,
                omega,
                channels,
                first_line: e.draw_band.first_line,
                line_quality,
            }),
            sd: Cow::Owned(sd),
        })
    }
}

impl ExcitationModel {
    /// Moves the replicates' grid into `store` under `key` ([`FittedModel::grid`] reads it).
    fn store_grid(&mut self, store: &SharedStore, key: usize) -> std::io::Result<()> {
        let b = &self.draw_band;
        let mut extra: Vec<f64> = b.frequency_hz.iter().chain(&b.omega).copied().collect();
        extra.extend(b.line_quality.iter().flatten());
        extra.extend(self.draw_sd.iter().flatten());
        store.put_channels(key, &b.channels, &extra)?;
        self.stored_lines = Some(b.n_lines());
        self.draw_band = BandData {
            frequency_hz: Vec::new(),
            omega: Vec::new(),
            channels: Vec::new(),
            line_quality: None,
            quantity: b.quantity,
            first_line: b.first_line,
        };
        self.draw_sd = Vec::new();
        Ok(())
    }
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
        frf: &dyn FrfSource,
        modal: &ModalFitRecord,
        selection: &SelectionRecord,
        residual_terms: bool,
        pole_mode: Option<PoleMode>,
        draws: &Draws,
    ) -> Result<Self, UqError> {
        check_shape(geometry, frf)?;
        let (pole_mode, groups_ids) = pole_groups(geometry, modal, selection, pole_mode);
        let ids = with_group_members(geometry, &groups_ids);
        let mut groups: Vec<Vec<usize>> = Vec::new();
        let mut group_of = Vec::with_capacity(ids.len());
        for g in &groups_ids {
            let first = groups.iter().map(Vec::len).sum::<usize>();
            group_of.extend(std::iter::repeat_n(groups.len(), g.len()));
            groups.push((first..first + g.len()).collect());
        }
        let weighting = draws.fit_weighting;
        // The noise fit counts each channel's share of its group's poles, so the live
        // channels of a group of several are counted first (each band is read again
        // below); a group of one counts its own.
        let live: Vec<Option<usize>> =
            in_order(ids.par_iter().enumerate().map(|(i, (id, members))| {
                if groups[group_of[i]].len() == 1 {
                    return Ok(None);
                }
                measured_band(geometry, frf, modal, id, (weighting, members))
                    .map(|(_, _, band)| Some(live_channels(&band).len()))
            }))?;
        let group_live: Vec<Option<usize>> = groups
            .iter()
            .map(|g| g.iter().map(|&i| live[i]).sum())
            .collect();
        let axis = (
            frf.frequency_hz().len(),
            frf.n_channels(),
            frf.quantity().order(),
        );
        // The grids' values at most (every line of every model excitation): kept in a
        // store when more than the scratch holds, each as its excitation is built.
        let grids = crate::Scratch::store_for(draws.scratch, ids.len() * axis.0 * axis.1 * 24)
            .map(Arc::new);
        let build = |i: usize, id: &str, members: &[usize]| -> Result<ExcitationModel, UqError> {
            let g = group_of[i];
            let (mut e, mut measured) = excitation_model(
                geometry,
                frf,
                modal,
                id,
                residual_terms,
                (weighting, members),
            )?;
            let shared_by = group_live[g].unwrap_or(e.live.len());
            e.fit_noise(&mut measured, residual_terms, shared_by);
            let q = if draws.decimate {
                let first = ids[groups[g][0]].0;
                decimation(&record_poles(modal, first).1, &e.band)
            } else {
                1
            };
            // The replicates read only the grid (`draw_band`); the band's values go here.
            e.prepare_draws_given(q, axis, draws, measured.centre);
            if let Some(store) = &grids {
                e.store_grid(store, i)
                    .map_err(|err| UqError::Scratch(err.to_string()))?;
            }
            Ok(e)
        };
        // Every excitation's model built whole (noise, replicates' grid) and its band let
        // go before the next: the set's values are never held together (issue 41's
        // memory bound). In parallel (one group per excitation is the common case) while
        // an excitation is small (`rbprops_core::excitations_in_parallel`: a build holds
        // about four copies of its excitation at once; the noise fits of its channels
        // still run in parallel). Collected in order: the same for any thread count; the
        // first failure in that order is reported, whichever thread met it first.
        let mut excitations: Vec<ExcitationModel> = if rbprops_core::excitations_in_parallel(frf) {
            in_order(
                ids.par_iter()
                    .enumerate()
                    .map(|(i, (id, m))| build(i, id, m)),
            )?
        } else {
            ids.iter()
                .enumerate()
                .map(|(i, (id, m))| build(i, id, m))
                .collect::<Result<_, _>>()?
        };
        for e in &mut excitations {
            e.mark_selected(selection);
        }
        same_lines(&excitations, &groups)?;
        if grids.is_some() {
            // A stored model's replicates read their lines from the store (issue 41: the
            // band's lines were 25 kB an excitation at 1,601 lines, 5 MB at 192).
            for e in &mut excitations {
                e.band.frequency_hz = Vec::new();
                e.band.omega = Vec::new();
            }
        }
        Ok(Self {
            excitations,
            groups,
            pole_mode,
            residuals_enabled: residual_terms,
            grids,
        })
    }
}

/// The excitations whose poles are refitted together, as ids, and the pole mode: one
/// group per excitation the selection uses, or with shared poles (given, or inferred
/// from the record: all fitted excitations of a set-up carry bit-identical poles) every
/// fitted excitation of its set-up.
fn pole_groups(
    geometry: &Geometry,
    modal: &ModalFitRecord,
    selection: &SelectionRecord,
    pole_mode: Option<PoleMode>,
) -> (PoleMode, Vec<Vec<String>>) {
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
    (pole_mode, groups_ids)
}

/// Every excitation of a group sharing poles was fitted on its first's lines.
fn same_lines(excitations: &[ExcitationModel], groups: &[Vec<usize>]) -> Result<(), UqError> {
    for g in groups {
        let first = &excitations[g[0]];
        for &i in &g[1..] {
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
    }
    Ok(())
}

/// The results of a parallel map, collected in order; the first error in that order.
fn in_order<T: Send>(
    results: impl IndexedParallelIterator<Item = Result<T, UqError>>,
) -> Result<Vec<T>, UqError> {
    results.collect::<Vec<_>>().into_iter().collect()
}

impl ExcitationModel {
    /// Fills the replicates' grid and noise ([`Draws`]): every q-th line of the band (1:
    /// every line) with the noise of its run of q lines. A channel whose every band line
    /// has a finite variance in `draws.line_variance` (and `draws.window`: the exponential
    /// window the FRFs were prefiltered for, whose factor `|(iω/(iω + σ))^k|²` the
    /// variances take too) draws from it times its correlation factor; the others from
    /// the noise model of the residuals. `axis`: the FRF set's lines, channels and
    /// quantity order.
    fn prepare_draws_given(
        &mut self,
        q: usize,
        axis: (usize, usize, i32),
        draws: &Draws,
        centre: Vec<Vec<c64>>,
    ) {
        let Draws {
            line_variance: given,
            window,
            ..
        } = *draws;
        let (nl, nc, k) = axis;
        let prefilter = |f: f64| match window {
            Some(w) if k != 0 => {
                let w2 = (std::f64::consts::TAU * f).powi(2);
                (w2 / (w2 + w.decay_per_s().powi(2))).powi(k)
            }
            _ => 1.0,
        };
        let (ex, first_line) = (self.excitation, self.band.first_line);
        let freqs = self.band.frequency_hz.clone();
        let n_band = freqs.len();
        let lookup = given.map(|v| {
            move |c: usize, l: usize| -> Option<f64> {
                let s = v.sigma2[(ex * nc + c) * nl + first_line + l];
                s.is_finite()
                    .then(|| s * v.correlation_factor * prefilter(freqs[l]))
            }
        });
        // The common error's ρ² on the band's lines.
        let common = given
            .and_then(|v| v.common.get(ex))
            .and_then(Option::as_ref)
            .map(|c| c.on_lines(first_line..first_line + n_band));
        self.prepare_draws(
            q,
            lookup
                .as_ref()
                .map(|f| f as &dyn Fn(usize, usize) -> Option<f64>),
            common.as_ref(),
            centre,
        );
    }

    /// Noise model per channel (see [`crate::noise`]), from the residuals of the modal
    /// fit (the synthesis in `m.centre`), whose misfit lines then take the measured values.
    /// The fit's parameters per channel: 2 per mode (residue), the residual terms, and the
    /// channel's share of the 2 per mode of the poles its group estimated jointly over
    /// its `group_live` live channels. Each fit depends only on its channel.
    fn fit_noise(&mut self, m: &mut Measured, residual_terms: bool, group_live: usize) {
        let nm = self.poles.len() as f64;
        let res = Residuals::for_band(residual_terms, &self.band);
        let parameters = 2.0 * nm
            + (res.upper as usize + res.lower as usize) as f64
            + 2.0 * nm / group_live.max(1) as f64;
        let fits: Vec<_> = m
            .values
            .par_iter()
            .zip(&m.centre)
            .map(|(measured, synthesised)| fit_channel(measured, synthesised, parameters))
            .collect();
        for ((centre, measured), f) in m.centre.iter_mut().zip(&m.values).zip(&fits) {
            for ((z, h), misfit) in centre.iter_mut().zip(measured).zip(&f.misfit) {
                if *misfit {
                    *z = *h;
                }
            }
        }
        self.misfit_lines = fits
            .iter()
            .map(|f| f.misfit.iter().filter(|m| **m).count())
            .collect();
        self.noise = fits.into_iter().map(|f| f.noise).collect();
    }
}

/// The modal fit's modes of excitation `id`, in mode order, and their poles.
fn record_poles<'m>(modal: &'m ModalFitRecord, id: &str) -> (Vec<&'m ModeEstimate>, Vec<Pole>) {
    let mut modes: Vec<_> = modal.modes.iter().filter(|m| m.excitation == id).collect();
    modes.sort_by_key(|m| m.mode);
    let poles = modes
        .iter()
        .map(|m| Pole::from_modal(m.frequency_hz, m.damping_ratio))
        .collect();
    (modes, poles)
}

/// The channels with signal on `band`.
fn live_channels(band: &BandData) -> Vec<usize> {
    band.channel_rms()
        .iter()
        .enumerate()
        .filter(|(_, r)| **r > 0.0)
        .map(|(c, _)| c)
        .collect()
}

/// Excitation `id`'s geometry index, its modal-fit record and the measured lines of the
/// fit's band (weighted as the fit weighted them), checked against the record.
fn measured_band<'m>(
    geometry: &Geometry,
    frf: &dyn FrfSource,
    modal: &'m ModalFitRecord,
    id: &str,
    (weighting, members): (Option<&rbprops_modal::CoherenceWeighting>, &[usize]),
) -> Result<(usize, &'m ExcitationFitRecord, BandData), UqError> {
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
    let band = BandData::extract_from(frf, k, Some((rec.band_hz[0], rec.band_hz[1])), id)
        .map_err(|source| UqError::Modal {
            excitation: id.to_string(),
            source,
        })?
        .with_line_factors(weighting, members);
    if band.n_lines() != rec.n_lines {
        return Err(bad(format!(
            "the fit's band {:?} Hz holds {} lines of the FRF set, the modal fit used {}",
            rec.band_hz,
            band.n_lines(),
            rec.n_lines
        )));
    }
    Ok((k, rec, band))
}

fn excitation_model(
    geometry: &Geometry,
    frf: &dyn FrfSource,
    modal: &ModalFitRecord,
    id: &str,
    residual_terms: bool,
    weighting: (Option<&rbprops_modal::CoherenceWeighting>, &[usize]),
) -> Result<(ExcitationModel, Measured), UqError> {
    let bad = |reason: String| UqError::Excitation {
        excitation: id.to_string(),
        reason,
    };
    let (k, rec, mut band) = measured_band(geometry, frf, modal, id, weighting)?;
    let (modes, poles) = record_poles(modal, id);
    if modes.is_empty() {
        return Err(bad("the modal fit has no modes for it".into()));
    }
    let res = Residuals::for_band(residual_terms, &band);
    // The fit's own synthesis (the measured lines less its residuals): synthesising the
    // band again from the residues would cost as much once more.
    let synthesised = lsfd::fit_residues(&poles, &band, &band.channels, res).synthesised;
    if synthesised
        .iter()
        .flatten()
        .any(|z| !(z.re.is_finite() && z.im.is_finite()))
    {
        return Err(bad("the synthesised FRFs are not finite".into()));
    }
    let live = live_channels(&band);
    let measured = Measured {
        values: std::mem::take(&mut band.channels),
        // The synthesis; the noise fit sets its misfit lines to the measured values.
        centre: synthesised,
    };
    let model = ExcitationModel {
        excitation: k,
        id: id.to_string(),
        setup: rec.setup.clone(),
        live,
        mode_numbers: modes.iter().map(|m| m.mode).collect(),
        selected: Vec::new(),
        poles,
        noise: Vec::new(),
        misfit_lines: Vec::new(),
        draw_band: BandData {
            frequency_hz: Vec::new(),
            omega: Vec::new(),
            channels: Vec::new(),
            line_quality: None,
            quantity: band.quantity,
            first_line: band.first_line,
        },
        draw_sd: Vec::new(),
        stored_lines: None,
        decimation: 1,
        given_variance: Vec::new(),
        common: None,
        band,
    };
    Ok((model, measured))
}
