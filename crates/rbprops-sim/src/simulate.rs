//! The simulator: spec → models per set-up → FRFs (+ effects, noise) and the truth.

use crate::effects::{parse_effects, BuildContext, Effect, OutputBlock};
use crate::error::SimError;
use crate::model::{
    add_extra_receptances, modal_compliance, modal_damping_matrix, solve_columns_lines,
    DynamicModel, ModeLineFactors, ModelInput, Observation, LINES_PER_SOLVE,
};
use crate::noise::{add_noise, excitation_rng};
use crate::spec::{CampaignSpec, DampingModel};
use rayon::prelude::*;
use rbprops_core::records::{PropertiesRecord, TrueModeRecord, TrueSetupRecord, TruthRecord};
use rbprops_core::{c64, rigid_body_modes, FrfSet, Geometry, Mat6, RigidMode};

/// Largest number of complex values one simulation may produce (about 8 GB).
pub const MAX_VALUES: usize = 500_000_000;

/// How the receptance between generalised coordinates is computed per line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SolveMethod {
    /// `G = (K + iωC − ω²M)⁻¹` by LU: valid for any damping.
    #[default]
    Direct,
    /// Modal sum `G = Σ φφᵀ/(ω_r² − ω² + 2iζ_rω_rω)`: only for classical damping
    /// (refused otherwise).
    Modal,
    /// `x = Z⁻¹ f` for the set-up's force columns only, by one LU of `Z(ω)` per line
    /// ([`crate::model::solve_columns`]), then `S x`: valid for any damping, several
    /// times cheaper than [`Self::Direct`] (which forms `S G` for every coordinate) and
    /// equal to it to rounding (~1e-15 relative), not bit for bit. For a model fitter
    /// that evaluates the model many times ([`predict`]); [`simulate`] keeps `Direct`,
    /// so simulated recordings do not change. Inputs with attached mass or stiffness
    /// take the same solve with their own `Z`, and an exponential window alone the same
    /// solve at `s = σ + iω`; finite records, gravity in the sensors and filters take
    /// [`crate::observe`] as under `Direct`.
    Columns,
}

/// Options of [`simulate_with`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SimOptions {
    /// How the FRFs are solved.
    pub method: SolveMethod,
}

/// A simulated campaign.
#[derive(Debug, Clone, PartialEq)]
pub struct Simulation {
    /// The test geometry the spec describes.
    pub geometry: Geometry,
    /// The simulated FRFs, noise included.
    pub frf: FrfSet,
    /// The truth to compare estimates with: properties, true modes per set-up, effects, seed, noise.
    pub truth: TruthRecord,
    /// What the simulator changed or wants the user to know (a skipped 0 Hz line).
    pub notes: Vec<String>,
}

/// Free rigid-body directions (zero-frequency modes) per set-up: `(set-up id, count)`
/// for the set-ups that have any.
pub fn free_directions(models: &[SetupModel]) -> Vec<(String, usize)> {
    models
        .iter()
        .filter_map(|sm| {
            let n = sm.modes.iter().filter(|m| m.is_free()).count();
            (n > 0).then(|| (sm.model.setup.clone(), n))
        })
        .collect()
}

/// Simulates a campaign with the default options ([`SolveMethod::Direct`]).
pub fn simulate(spec: &CampaignSpec) -> Result<Simulation, SimError> {
    simulate_with(spec, &SimOptions::default())
}

/// A set-up's model with its true modes.
#[derive(Debug, Clone)]
pub struct SetupModel {
    /// Mass, stiffness, damping, output rows and input columns.
    pub model: DynamicModel,
    /// The set-up's true rigid-body modes, mass-normalised.
    pub modes: Vec<RigidMode>,
}

/// Builds the models of every set-up (structure effects, nominal damping, damping
/// effects) exactly as [`simulate_with`] does.
pub fn build_models(
    spec: &CampaignSpec,
    geometry: &Geometry,
    effects: &[Box<dyn Effect>],
) -> Result<Vec<SetupModel>, SimError> {
    let props = spec.properties();
    let m0 = props.mass_matrix().0;
    let outputs = geometry.channel_matrix();
    let mut out = Vec::with_capacity(spec.setups.len());
    for (si, s) in spec.setups.iter().enumerate() {
        let setup_err = |problem: String| SimError::Setup {
            setup: s.id.clone(),
            problem,
        };
        let ctx = BuildContext {
            spec,
            properties: &props,
            geometry,
            setup_index: si,
        };
        let mut model = DynamicModel {
            setup: s.id.clone(),
            mass: m0,
            stiffness: spec.setup_stiffness(si),
            damping: Mat6::zeros(),
            structural_damping: Mat6::zeros(),
            outputs: outputs.clone(),
            inputs: geometry
                .excitations
                .iter()
                .enumerate()
                .filter(|(_, e)| e.setup == s.id)
                .map(|(k, e)| ModelInput {
                    excitation: k,
                    column: e.column(),
                    point: e.position,
                    direction: e.direction,
                    attached_mass: Mat6::zeros(),
                    attached_stiffness: Mat6::zeros(),
                })
                .collect(),
            extra_modes: Vec::new(),
            observation: Default::default(),
        };
        for (i, e) in effects.iter().enumerate() {
            e.modify_structure(&ctx, &mut model)
                .map_err(|problem| effect_err(i, e.as_ref(), problem))?;
        }
        // A free direction (ω = 0) is a mode like any other: modal damping gives it none
        // (`2ζω = 0`), and the FRFs stay finite for every ω > 0 (`Z(ω)` is regular there
        // since M is positive definite); only ω = 0 is singular (see `simulate_with`).
        let undamped = rigid_body_modes(&model.mass, &model.stiffness)
            .map_err(|e| setup_err(e.to_string()))?;
        let d = &spec.damping;
        model.damping = match d.model {
            DampingModel::Modal => {
                let ratios: Vec<f64> = match (&d.ratios, d.ratio) {
                    (Some(r), _) => r.clone(),
                    (None, r) => vec![r.unwrap_or(0.0); 6],
                };
                modal_damping_matrix(&model.mass, &undamped, &ratios)
            }
            DampingModel::Proportional => {
                d.alpha.unwrap_or(0.0) * model.mass + d.beta.unwrap_or(0.0) * model.stiffness
            }
        };
        for (i, e) in effects.iter().enumerate() {
            e.modify_damping(&ctx, &mut model)
                .map_err(|problem| effect_err(i, e.as_ref(), problem))?;
        }
        let modes = model.modes().map_err(setup_err)?;
        out.push(SetupModel { model, modes });
    }
    Ok(out)
}

fn effect_err(index: usize, e: &dyn Effect, problem: String) -> SimError {
    SimError::Effect {
        index,
        id: e.id().to_string(),
        problem,
    }
}

/// Per set-up, the channel-by-coordinate receptance `P(ω) = S G(ω)` on every line,
/// stored `[channel][coordinate][line]` so an excitation's FRF is `P f` line by line.
#[derive(Debug)]
pub(crate) struct TransferTable {
    n_lines: usize,
    values: Vec<c64>,
}

impl TransferTable {
    fn build(
        sm: &SetupModel,
        omegas: &[f64],
        method: SolveMethod,
    ) -> Result<TransferTable, SimError> {
        let n_ch = sm.model.outputs.len();
        let nl = omegas.len();
        let mut values = vec![c64::new(0.0, 0.0); n_ch * 6 * nl];
        for (l, &w) in omegas.iter().enumerate() {
            let g = match method {
                SolveMethod::Direct | SolveMethod::Columns => {
                    sm.model
                        .direct_compliance(w)
                        .ok_or_else(|| SimError::Setup {
                            setup: sm.model.setup.clone(),
                            problem: format!(
                                "dynamic stiffness is singular at {:.6} Hz (an undamped resonance on a line?)",
                                w / std::f64::consts::TAU
                            ),
                        })?
                }
                SolveMethod::Modal => modal_compliance(&sm.modes, w),
            };
            for (c, row) in sm.model.outputs.iter().enumerate() {
                for j in 0..6 {
                    let mut acc = c64::new(0.0, 0.0);
                    for k in 0..6 {
                        acc += g[(k, j)] * row[k];
                    }
                    values[(c * 6 + j) * nl + l] = acc;
                }
            }
        }
        Ok(TransferTable {
            n_lines: nl,
            values,
        })
    }

    /// Receptance FRFs of all channels for force column `f` on the table's lines, written
    /// from line `first` of `out`, a `[channel][line]` block of `out_lines` lines.
    fn apply(&self, f: &rbprops_core::Vec6, out: &mut [c64], out_lines: usize, first: usize) {
        let nl = self.n_lines;
        for (c, row) in out.chunks_exact_mut(out_lines).enumerate() {
            let dst = &mut row[first..first + nl];
            dst.fill(c64::new(0.0, 0.0));
            for j in 0..6 {
                if f[j] == 0.0 {
                    continue;
                }
                let src = &self.values[(c * 6 + j) * nl..(c * 6 + j + 1) * nl];
                for (d, s) in dst.iter_mut().zip(src) {
                    *d += s * f[j];
                }
            }
        }
    }
}

/// Set-up `sm`'s transfer tables over the whole axis `omegas`, one per [`TABLE_LINES`]
/// lines (built as [`ExcitationBlocks::tabled_receptances`] builds them).
pub(crate) fn transfer_tables(
    sm: &SetupModel,
    omegas: &[f64],
    method: SolveMethod,
) -> Result<Vec<TransferTable>, SimError> {
    omegas
        .chunks(TABLE_LINES)
        .map(|lines| TransferTable::build(sm, lines, method))
        .collect()
}

/// Lines of a transfer table built at a time ([`ExcitationBlocks::tabled_receptances`]):
/// 8,192 lines of 9 channels are 7 MB.
pub(crate) const TABLE_LINES: usize = 8192;

/// Lines per parallel task of [`input_responses`].
const LINES_PER_TASK: usize = 64;

/// Whether [`SolveMethod::Columns`] serves an observation: the plain one, or an
/// exponential window alone (every FRF is then its transfer function at `s = σ + iω`).
/// Finite records, gravity in the sensors and filters take [`crate::observe`].
fn columns_serve(obs: &Observation) -> bool {
    obs.is_plain()
        || (obs.record_length_s.is_none()
            && obs.gravity_rows.is_empty()
            && obs.highpass_time_constants_s.iter().all(|v| v.is_empty()))
}

/// Receptance FRFs of a set-up's inputs by [`SolveMethod::Columns`]: `values[input]` is
/// `[channel][line]`; `s` the Laplace variables of the lines when a window shifts them
/// off the imaginary axis (`None`: `s = iω`).
struct ColumnResponses {
    values: Vec<Vec<c64>>,
    s: Option<Vec<c64>>,
}

/// Receptance FRFs `S Z(s)⁻¹ f` of each input of a set-up at the lines' `s`,
/// `[input][channel][line]` ([`SolveMethod::Columns`]): inputs that share their attached
/// mass and stiffness share one LU per line. Lines are independent, so the values do
/// not depend on the thread count.
fn input_responses(sm: &SetupModel, s: &[c64]) -> Result<Vec<Vec<c64>>, SimError> {
    let model = &sm.model;
    let n_ch = model.outputs.len();
    let nl = s.len();
    let mut out = vec![Vec::new(); model.inputs.len()];
    let mut done = vec![false; model.inputs.len()];
    for first in 0..model.inputs.len() {
        if done[first] {
            continue;
        }
        let a = &model.inputs[first];
        let group: Vec<usize> = (first..model.inputs.len())
            .filter(|&i| {
                let b = &model.inputs[i];
                b.attached_mass == a.attached_mass && b.attached_stiffness == a.attached_stiffness
            })
            .collect();
        let mass = model.mass + a.attached_mass;
        let stiffness = model.stiffness + a.attached_stiffness;
        let forces: Vec<[c64; 6]> = group
            .iter()
            .map(|&i| std::array::from_fn(|k| c64::new(model.inputs[i].column[k], 0.0)))
            .collect();
        let ng = group.len();
        // Line-major `[line][input of the group][channel]`, solved in batches of
        // `LINES_PER_SOLVE` lines (the last padded with copies of its last line).
        let mut y = vec![c64::new(0.0, 0.0); nl * ng * n_ch];
        const L: usize = LINES_PER_SOLVE;
        let ok: Vec<bool> = y
            .par_chunks_mut(L * ng * n_ch)
            .zip(s.par_chunks(L))
            .with_min_len(LINES_PER_TASK / L)
            .map_init(
                || vec![[[c64::new(0.0, 0.0); 6]; L]; ng],
                |x, (y, s)| {
                    let batch: [c64; L] = std::array::from_fn(|l| s[l.min(s.len() - 1)]);
                    let ok = solve_columns_lines(
                        &mass,
                        &stiffness,
                        &model.damping,
                        &model.structural_damping,
                        &batch,
                        &forces,
                        x,
                    );
                    for (l, y) in y.chunks_exact_mut(ng * n_ch).enumerate() {
                        for (x, y) in x.iter().zip(y.chunks_exact_mut(n_ch)) {
                            for (row, y) in model.outputs.iter().zip(y.iter_mut()) {
                                *y = (0..6).map(|k| x[l][k] * row[k]).sum();
                            }
                        }
                    }
                    ok[..s.len()].to_vec()
                },
            )
            .flatten()
            .collect();
        if let Some(l) = ok.iter().position(|ok| !ok) {
            return Err(SimError::Setup {
                setup: model.setup.clone(),
                problem: format!(
                    "dynamic stiffness is singular at {:.6} Hz (an undamped resonance on a line?)",
                    s[l].im / std::f64::consts::TAU
                ),
            });
        }
        for (g, &i) in group.iter().enumerate() {
            done[i] = true;
            let mut block = Vec::with_capacity(n_ch * nl);
            for c in 0..n_ch {
                block.extend((0..nl).map(|l| y[(l * ng + g) * n_ch + c]));
            }
            out[i] = block;
        }
    }
    Ok(out)
}

/// Noise-free FRFs of a campaign in the spec's quantity on the axis `frequency_hz`, with
/// the given (ordered, see [`parse_effects`]) effects, and the set-up models used.
/// This is [`simulate_with`] without noise: a model fitter calls it with varied effects.
/// Inputs with a plain observation use the per-set-up transfer table (`H = S G F`, then
/// output effects and the quantity factor); the others use
/// [`crate::observe::observed_block`] (window, record length, gravity in the sensors,
/// filters, attached masses), always by direct solution.
pub fn predict(
    spec: &CampaignSpec,
    geometry: &Geometry,
    effects: &[Box<dyn Effect>],
    frequency_hz: &[f64],
    options: &SimOptions,
) -> Result<(FrfSet, Vec<SetupModel>), SimError> {
    let freq = frequency_hz.to_vec();
    let n_ch = geometry.channels.len();
    let n_ex = geometry.excitations.len();
    let nl = freq.len();
    check_size(geometry, nl)?;
    let omegas = omegas_of(&freq);
    let models = build_models(spec, geometry, effects)?;
    let blocks =
        ExcitationBlocks::new(spec, geometry, effects, (&freq, &omegas), &models, options)?;
    let mut frf = FrfSet::zeros(spec.quantity, freq.clone(), n_ex, n_ch);
    let block = n_ch * nl;
    if block > 0 {
        blocks.tabled_receptances(options.method, &mut frf.values)?;
        frf.values
            .par_chunks_mut(block)
            .enumerate()
            .map(|(e, values)| blocks.fill(e, values))
            .collect::<Result<(), SimError>>()?;
    }
    Ok((frf, models))
}

/// Refuses a campaign of more than [`MAX_VALUES`] values on `nl` lines.
pub(crate) fn check_size(geometry: &Geometry, nl: usize) -> Result<(), SimError> {
    let (n_ch, n_ex) = (geometry.channels.len(), geometry.excitations.len());
    let total = n_ch.saturating_mul(n_ex).saturating_mul(nl);
    if total > MAX_VALUES {
        return Err(SimError::TooLarge(format!(
            "{n_ex} excitations × {n_ch} channels × {nl} lines = {total} values (limit {MAX_VALUES})"
        )));
    }
    Ok(())
}

/// `ω = 2πf` of every line.
pub(crate) fn omegas_of(freq: &[f64]) -> Vec<f64> {
    freq.iter().map(|f| std::f64::consts::TAU * f).collect()
}

/// The modal solve needs classical damping (modes that decouple it): refused otherwise.
fn check_classical_damping(models: &[SetupModel]) -> Result<(), SimError> {
    for sm in models {
        let coupling = sm.model.damping_coupling(&sm.modes);
        if coupling > 1e-9 {
            return Err(SimError::Setup {
                setup: sm.model.setup.clone(),
                problem: format!(
                    "damping is not classical (modal coupling {coupling:.2e}): use the direct solve"
                ),
            });
        }
    }
    Ok(())
}

/// With the column solve, each set-up's input responses where the columns serve its
/// observation, at `s = σ + iω` (σ the window's decay rate, 0 without a window).
fn column_responses(
    models: &[SetupModel],
    omegas: &[f64],
    columns: bool,
) -> Result<Vec<Option<ColumnResponses>>, SimError> {
    models
        .iter()
        .map(|sm| {
            let obs = &sm.model.observation;
            if !(columns && columns_serve(obs)) {
                return Ok(None);
            }
            let sigma = obs.window_decay_per_s;
            let s: Vec<c64> = omegas.iter().map(|&w| c64::new(sigma, w)).collect();
            Ok(Some(ColumnResponses {
                values: input_responses(sm, &s)?,
                s: (sigma != 0.0).then_some(s),
            }))
        })
        .collect()
}

/// What [`predict`] computes each excitation's block of FRFs from.
pub(crate) struct ExcitationBlocks<'a> {
    spec: &'a CampaignSpec,
    geometry: &'a Geometry,
    effects: &'a [Box<dyn Effect>],
    freq: &'a [f64],
    omegas: &'a [f64],
    /// Receptance to the spec's quantity, per line.
    factors: Vec<c64>,
    models: &'a [SetupModel],
    /// Per set-up: whether its plain inputs' receptances come from the transfer table
    /// (a plain observation, not the column solve); [`Self::tabled_receptances`] puts
    /// them in place before [`Self::fill`].
    tabled: Vec<bool>,
    /// Per set-up: the column solve's input responses.
    responses: Vec<Option<ColumnResponses>>,
    /// The set-up and input serving each excitation.
    route: Vec<(usize, usize)>,
    /// The extra modes' line factors of each set-up, computed by its first excitation
    /// that needs them and shared by the others (they do not depend on the excitation).
    line_factors: Vec<std::sync::OnceLock<ModeLineFactors>>,
}

impl<'a> ExcitationBlocks<'a> {
    /// What every excitation's block is computed from, for `models` on the lines
    /// `(freq, omegas)` (Hz, rad/s).
    pub(crate) fn new(
        spec: &'a CampaignSpec,
        geometry: &'a Geometry,
        effects: &'a [Box<dyn Effect>],
        (freq, omegas): (&'a [f64], &'a [f64]),
        models: &'a [SetupModel],
        options: &SimOptions,
    ) -> Result<Self, SimError> {
        if options.method == SolveMethod::Modal {
            check_classical_damping(models)?;
        }
        let columns = options.method == SolveMethod::Columns;
        let tabled: Vec<bool> = models
            .iter()
            .map(|sm| sm.model.observation.is_plain() && !columns)
            .collect();
        let responses = column_responses(models, omegas, columns)?;
        // Which set-up and input serve each excitation.
        let mut route = vec![(0usize, 0usize); geometry.excitations.len()];
        for (si, sm) in models.iter().enumerate() {
            for (ii, inp) in sm.model.inputs.iter().enumerate() {
                route[inp.excitation] = (si, ii);
            }
        }
        Ok(Self {
            spec,
            geometry,
            effects,
            freq,
            omegas,
            factors: omegas
                .iter()
                .map(|&w| spec.quantity.from_receptance_factor(w))
                .collect(),
            models,
            tabled,
            responses,
            route,
            line_factors: models.iter().map(|_| std::sync::OnceLock::new()).collect(),
        })
    }

    /// Whether excitation `e`'s receptances come from its set-up's transfer table: its
    /// set-up index when they do.
    pub(crate) fn tabled_setup(&self, e: usize) -> Option<usize> {
        let (si, ii) = self.route[e];
        (self.tabled[si] && self.models[si].model.inputs[ii].is_plain()).then_some(si)
    }

    /// Excitation `e`'s receptances from its set-up's transfer tables, one per
    /// [`TABLE_LINES`] lines (`tables`, as [`transfer_tables`] makes them; built here
    /// when `None`), written into its block `out` as [`Self::tabled_receptances`] writes
    /// them; nothing for an excitation the tables do not serve.
    pub(crate) fn tabled_receptance(
        &self,
        e: usize,
        method: SolveMethod,
        out: &mut [c64],
        tables: Option<&[TransferTable]>,
    ) -> Result<(), SimError> {
        let Some(si) = self.tabled_setup(e) else {
            return Ok(());
        };
        let nl = self.freq.len();
        let column = &self.models[si].model.inputs[self.route[e].1].column;
        for (t, first) in (0..nl).step_by(TABLE_LINES).enumerate() {
            match tables {
                Some(tables) => tables[t].apply(column, out, nl, first),
                None => {
                    let lines = first..(first + TABLE_LINES).min(nl);
                    let table =
                        TransferTable::build(&self.models[si], &self.omegas[lines], method)?;
                    table.apply(column, out, nl, first);
                }
            }
        }
        Ok(())
    }

    /// The receptances of every excitation served by a set-up's transfer table, written
    /// into its block of `values` (`[excitation][channel][line]`). The table is built
    /// for [`TABLE_LINES`] lines at a time, so it never holds the whole axis (six
    /// coordinates per channel: six times an excitation's data, issue 41); each line's
    /// arithmetic is the whole-axis table's, so the values are bit for bit the same.
    fn tabled_receptances(&self, method: SolveMethod, values: &mut [c64]) -> Result<(), SimError> {
        let nl = self.freq.len();
        let block = self.geometry.channels.len() * nl;
        for (si, sm) in self.models.iter().enumerate() {
            if !self.tabled[si] {
                continue;
            }
            let served = |e: usize| self.tabled_setup(e) == Some(si);
            for first in (0..nl).step_by(TABLE_LINES) {
                let lines = first..(first + TABLE_LINES).min(nl);
                let table = TransferTable::build(sm, &self.omegas[lines], method)?;
                values
                    .par_chunks_mut(block)
                    .enumerate()
                    .filter(|(e, _)| served(*e))
                    .for_each(|(e, out)| {
                        let input = &sm.model.inputs[self.route[e].1];
                        table.apply(&input.column, out, nl, first);
                    });
            }
        }
        Ok(())
    }

    /// Excitation `e`'s FRFs (channel-major, `values`): by the column solve under a
    /// window, by receptance (table or columns) then effects and the quantity factor, or
    /// by the observed block.
    pub(crate) fn fill(&self, e: usize, values: &mut [c64]) -> Result<(), SimError> {
        let (si, ii) = self.route[e];
        let sm = &self.models[si];
        let input = &sm.model.inputs[ii];
        let mut ob = OutputBlock {
            geometry: self.geometry,
            excitation: e,
            frequency_hz: self.freq,
            n_channels: self.geometry.channels.len(),
            values,
        };
        if let Some(ColumnResponses { values, s: Some(s) }) = &self.responses[si] {
            ob.values.copy_from_slice(&values[ii]);
            self.windowed(sm, s, &mut ob);
            return Ok(());
        }
        let receptance = match (&self.responses[si], self.tabled[si]) {
            (Some(responses), _) => {
                ob.values.copy_from_slice(&responses.values[ii]);
                true
            }
            (None, true) if input.is_plain() => true, // already in place
            _ => false,
        };
        if receptance {
            let modes_h = self.line_factors[si]
                .get_or_init(|| ModeLineFactors::at_iw(&sm.model.extra_modes, self.omegas));
            add_extra_receptances(&sm.model.extra_modes, e, modes_h, ob.values);
            for eff in self.effects {
                eff.transform_output(&mut ob);
            }
            let nl = self.freq.len();
            for dst in ob.values.chunks_exact_mut(nl) {
                for (d, f) in dst.iter_mut().zip(&self.factors) {
                    *d *= f;
                }
            }
            return Ok(());
        }
        crate::observe::observed_block(
            &sm.model,
            input,
            self.omegas,
            self.spec.quantity,
            ob.values,
        )
        .map_err(|problem| SimError::Setup {
            setup: sm.model.setup.clone(),
            problem: format!(
                "excitation '{}': {problem}",
                self.geometry.excitations[e].id
            ),
        })?;
        // Output effects are per-line gains, so they commute with the quantity factor.
        for eff in self.effects {
            eff.transform_output(&mut ob);
        }
        Ok(())
    }

    /// Under a window: the block holds the transfer functions at `s`; the extra modes
    /// and the output effects are added there, and `s^k` gives the quantity.
    fn windowed(&self, sm: &SetupModel, s: &[c64], ob: &mut OutputBlock) {
        let (si, _) = self.route[ob.excitation];
        let modes_h =
            self.line_factors[si].get_or_init(|| ModeLineFactors::at_s(&sm.model.extra_modes, s));
        add_extra_receptances(&sm.model.extra_modes, ob.excitation, modes_h, ob.values);
        for eff in self.effects {
            eff.transform_output(ob);
        }
        let order = self.spec.quantity.order();
        for dst in ob.values.chunks_exact_mut(self.freq.len()) {
            for (d, s) in dst.iter_mut().zip(s) {
                *d *= match order {
                    0 => c64::new(1.0, 0.0),
                    1 => *s,
                    _ => s * s,
                };
            }
        }
    }
}

/// Simulates a campaign: validates the spec, builds each set-up's model, computes the
/// FRFs `H = S (K + iωC − ω²M)⁻¹ F` in the spec's quantity (through [`predict`]), applies
/// output effects and noise, and records the truth. Excitations are computed in
/// parallel; the result is bit-identical for any number of threads.
pub fn simulate_with(spec: &CampaignSpec, options: &SimOptions) -> Result<Simulation, SimError> {
    let (geometry, effects) = parsed(spec)?;
    let (freq, notes) = simulated_axis(spec, &geometry, &effects)?;
    let (mut frf, models) = predict(spec, &geometry, &effects, &freq, options)?;
    let block = geometry.channels.len() * freq.len();
    if block > 0 {
        frf.values
            .par_chunks_mut(block)
            .enumerate()
            .for_each(|(e, values)| {
                let mut rng = excitation_rng(spec.seed, e);
                add_noise(values, spec.noise.relative, spec.noise.floor, &mut rng);
            });
    }
    frf.validate()?;
    Ok(Simulation {
        truth: truth_of(spec, &models, &effects),
        geometry,
        frf,
        notes,
    })
}

/// The spec validated, its geometry and its effects.
pub(crate) fn parsed(spec: &CampaignSpec) -> Result<(Geometry, Vec<Box<dyn Effect>>), SimError> {
    spec.validate()?;
    let geometry = spec.geometry()?;
    let effects = parse_effects(spec).map_err(|(index, problem)| SimError::Effect {
        index,
        id: spec.effects[index].id.clone(),
        problem,
    })?;
    Ok((geometry, effects))
}

/// The lines simulated, and a note when the spec's 0 Hz line is left out.
pub(crate) fn simulated_axis(
    spec: &CampaignSpec,
    geometry: &Geometry,
    effects: &[Box<dyn Effect>],
) -> Result<(Vec<f64>, Vec<String>), SimError> {
    let mut freq = spec.frequency_axis();
    let mut notes = Vec::new();
    // A free direction has no static stiffness: the receptance is infinite at 0 Hz, so
    // that line (only the first can be 0) is left out of the simulation.
    if freq.first() == Some(&0.0) {
        let free = free_directions(&build_models(spec, geometry, effects)?);
        if !free.is_empty() {
            freq.remove(0);
            let list: Vec<String> = free
                .iter()
                .map(|(s, n)| format!("set-up '{s}': {n}"))
                .collect();
            notes.push(format!(
                "the 0 Hz line is skipped: the suspension leaves rigid-body directions free ({}), whose static response is infinite; the axis starts at {} Hz",
                list.join(", "),
                freq.first().copied().unwrap_or(f64::NAN)
            ));
        }
    }
    Ok((freq, notes))
}

/// The truth of a simulated campaign: properties, true modes per set-up, effects, seed,
/// noise.
pub(crate) fn truth_of(
    spec: &CampaignSpec,
    models: &[SetupModel],
    effects: &[Box<dyn Effect>],
) -> TruthRecord {
    TruthRecord {
        campaign: spec.name.clone(),
        properties: PropertiesRecord::from_properties(&spec.properties()),
        setups: models
            .iter()
            .map(|sm| TrueSetupRecord {
                setup: sm.model.setup.clone(),
                stiffness: std::array::from_fn(|i| {
                    std::array::from_fn(|j| sm.model.stiffness[(i, j)])
                }),
                modes: sm
                    .modes
                    .iter()
                    .enumerate()
                    .map(|(r, m)| TrueModeRecord {
                        mode: r + 1,
                        frequency_hz: m.frequency_hz,
                        damping_ratio: m.damping_ratio,
                        shape: std::array::from_fn(|i| m.shape[i]),
                    })
                    .collect(),
            })
            .collect(),
        effects: effects.iter().map(|e| e.record()).collect(),
        seed: spec.seed,
        noise_relative: spec.noise.relative,
        noise_floor: spec.noise.floor,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The largest difference of two FRF sets on one axis, relative to the largest value
    /// of the first set's row (excitation and channel) it is in.
    fn worst_relative_difference(a: &FrfSet, b: &FrfSet) -> f64 {
        let nl = a.n_lines();
        let mut worst = 0.0f64;
        for (ra, rb) in a.values.chunks_exact(nl).zip(b.values.chunks_exact(nl)) {
            let scale = ra.iter().map(|v| v.norm()).fold(0.0, f64::max);
            for (x, y) in ra.iter().zip(rb) {
                worst = worst.max((x - y).norm() / scale.max(f64::MIN_POSITIVE));
            }
        }
        worst
    }

    /// The column solve agrees with the inverse to rounding on every effect fixture
    /// (Test Case II with each effect on: attached masses and stiffness, hysteretic and
    /// non-proportional damping, extra modes, output effects, an exponential window
    /// against the observed path; the other observed ones take the same path under
    /// both methods). Both are backward-stable solves of the same 6×6
    /// systems; the worst relative difference measured is 2.5e-15 of the row's
    /// largest value (hysteretic_damping, added_mass), so 1e-13 leaves room for other platforms and still fails on any
    /// wrong column, sign or attached matrix (those differ at 1e-3 and above).
    #[test]
    fn column_solve_equals_the_inverse_to_rounding() {
        // Plus a window over an extra mode, an attached mass and an output gain together
        // (the windowed column path's own extra-mode and quantity terms).
        let (_, elastic) = crate::examples::effect_examples()
            .iter()
            .find(|(n, _)| *n == "elastic_mode")
            .unwrap();
        let combined = format!(
            "{elastic}\n[[effect]]\nid = \"exponential_window\"\ndecay_per_s = 0.25\n\
             [[effect]]\nid = \"force_gauge_mass\"\nmasses_kg = {{ force2 = 0.015 }}\n"
        );
        let cases = crate::examples::effect_examples()
            .iter()
            .map(|(n, t)| (n.to_string(), t.to_string()))
            .chain([("window, elastic mode, gauge mass".to_string(), combined)]);
        for (name, text) in cases {
            let spec = CampaignSpec::from_toml_str(&text).unwrap();
            let geometry = spec.geometry().unwrap();
            let effects = parse_effects(&spec).unwrap();
            let freq: Vec<f64> = spec
                .frequency_axis()
                .into_iter()
                .filter(|&f| f > 0.0)
                .collect();
            let run = |method| {
                predict(&spec, &geometry, &effects, &freq, &SimOptions { method })
                    .unwrap()
                    .0
            };
            let worst =
                worst_relative_difference(&run(SolveMethod::Direct), &run(SolveMethod::Columns));
            assert!(worst < 1e-13, "{name}: relative difference {worst:.2e}");
            eprintln!("{name}: {worst:.1e}");
        }
    }

    /// The transfer table built [`TABLE_LINES`] lines at a time gives every line of a
    /// long axis (two whole chunks and a partial one) as the column solve does: a line
    /// written at the wrong offset or channel, or a chunk left unfilled, differs at 1e-3
    /// and above; the two backward-stable solves agree to 1e-13 of each row's largest value
    /// (see the test above).
    #[test]
    fn chunked_transfer_table_fills_every_line_of_a_long_axis() {
        let mut spec =
            CampaignSpec::from_toml_str(crate::examples::example("test-case-2").unwrap()).unwrap();
        spec.frequency.lines = 2 * TABLE_LINES + 1234;
        spec.frequency.start_hz = spec.frequency.start_hz.max(0.01);
        let geometry = spec.geometry().unwrap();
        let freq = spec.frequency_axis();
        let run = |method| {
            predict(&spec, &geometry, &[], &freq, &SimOptions { method })
                .unwrap()
                .0
        };
        let (table, columns) = (run(SolveMethod::Direct), run(SolveMethod::Columns));
        assert!(columns.values.iter().all(|v| v.norm() > 0.0));
        let worst = worst_relative_difference(&table, &columns);
        assert!(worst < 1e-13, "relative difference {worst:.2e}");
    }

    /// An undamped resonance on a line is refused by both solves, not returned as a
    /// meaningless finite value.
    #[test]
    fn column_solve_refuses_a_singular_line() {
        let mut spec =
            CampaignSpec::from_toml_str(crate::examples::example("test-case-2").unwrap()).unwrap();
        spec.damping.model = DampingModel::Modal;
        spec.damping.ratio = Some(0.0);
        spec.damping.ratios = None;
        let geometry = spec.geometry().unwrap();
        let models = build_models(&spec, &geometry, &[]).unwrap();
        let f0 = models[0].modes[2].frequency_hz;
        for method in [SolveMethod::Direct, SolveMethod::Columns] {
            let r = predict(
                &spec,
                &geometry,
                &[],
                &[0.5 * f0, f0],
                &SimOptions { method },
            );
            let Err(e) = r else {
                panic!("{method:?}: an undamped resonance on a line was solved");
            };
            assert!(e.to_string().contains("singular"), "{method:?}: {e}");
        }
    }
}
