//! A simulated campaign whose FRFs are made one excitation at a time, as a writer asks
//! for them ([`FrfSource`]): `frf-sim` never holds the whole set (issue 41: at 192
//! excitations × 1,601 lines the set alone is 44 MB).
//!
//! Each excitation's block is the one [`crate::simulate`] makes, bit for bit: the same
//! transfer tables (kept for the whole axis while they are small, else built again for
//! each excitation, `TABLE_LINES` lines at a time), the same [`ExcitationBlocks::fill`]
//! and the same noise stream (one per excitation, [`excitation_rng`]).

use crate::effects::Effect;
use crate::error::SimError;
use crate::noise::{add_noise, excitation_rng};
use crate::simulate::{
    build_models, check_size, omegas_of, parsed, simulated_axis, transfer_tables, truth_of,
    ExcitationBlocks, SetupModel, SimOptions, TransferTable,
};
use crate::spec::CampaignSpec;
use rbprops_core::frf::validate_frequency_axis;
use rbprops_core::records::TruthRecord;
use rbprops_core::{c64, CoreError, ExcitationFrf, FrfSet, FrfSource, Geometry, Quantity};
use std::sync::OnceLock;

/// Bytes of a set-up's transfer tables over the whole axis (six coordinates per channel
/// and line: six times an excitation's data) up to which they are kept for all its
/// excitations: at 9 channels about 9,700 lines. Above, each excitation builds them
/// again, a table per excitation instead of one per set-up: at 3 × 25,601 lines 0.27 s
/// and 21 MB against 0.22 s and 26 MB for the whole simulation (kept, they would be
/// 22 MB), at 3 × 102,401 1.3 s and 52 MB against 0.66 s and 77 MB (88 MB kept).
const KEPT_TABLE_BYTES: usize = 8 << 20;

/// A campaign simulated excitation by excitation ([`simulate_deferred`]).
#[derive(Debug)]
pub struct DeferredSimulation {
    /// The test geometry the spec describes.
    pub geometry: Geometry,
    /// The truth to compare estimates with (as [`crate::Simulation::truth`]).
    pub truth: TruthRecord,
    /// What the simulator changed or wants the user to know (a skipped 0 Hz line).
    pub notes: Vec<String>,
    spec: CampaignSpec,
    effects: Vec<Box<dyn Effect>>,
    freq: Vec<f64>,
    omegas: Vec<f64>,
    models: Vec<SetupModel>,
    /// Per set-up: its transfer tables, when kept ([`KEPT_TABLE_BYTES`]).
    tables: Vec<OnceLock<Result<Vec<TransferTable>, SimError>>>,
}

/// [`crate::simulate`] of `spec`, its FRFs made when asked for: the geometry, truth and
/// notes at once, each excitation's values (noise included) as [`FrfSource::excitation`]
/// is called, equal bit for bit to the whole simulation's.
pub fn simulate_deferred(spec: &CampaignSpec) -> Result<DeferredSimulation, SimError> {
    let (geometry, effects) = parsed(spec)?;
    let (freq, notes) = simulated_axis(spec, &geometry, &effects)?;
    check_size(&geometry, freq.len())?;
    validate_frequency_axis(&freq)?;
    let models = build_models(spec, &geometry, &effects)?;
    Ok(DeferredSimulation {
        truth: truth_of(spec, &models, &effects),
        tables: models.iter().map(|_| OnceLock::new()).collect(),
        omegas: omegas_of(&freq),
        geometry,
        notes,
        spec: spec.clone(),
        effects,
        freq,
        models,
    })
}

impl DeferredSimulation {
    /// Excitation `e`'s block `[channel][line]`, noise included.
    fn block(&self, e: usize) -> Result<Vec<c64>, SimError> {
        let options = SimOptions::default();
        let blocks = ExcitationBlocks::new(
            &self.spec,
            &self.geometry,
            &self.effects,
            (&self.freq, &self.omegas),
            &self.models,
            &options,
        )?;
        let mut values = vec![c64::new(0.0, 0.0); self.geometry.channels.len() * self.freq.len()];
        let tables = match blocks.tabled_setup(e).and_then(|si| self.kept_tables(si)) {
            Some(Ok(t)) => Some(t.as_slice()),
            Some(Err(err)) => return Err(err.clone()),
            None => None,
        };
        blocks.tabled_receptance(e, options.method, &mut values, tables)?;
        blocks.fill(e, &mut values)?;
        let mut rng = excitation_rng(self.spec.seed, e);
        add_noise(
            &mut values,
            self.spec.noise.relative,
            self.spec.noise.floor,
            &mut rng,
        );
        Ok(values)
    }

    /// Set-up `si`'s transfer tables over the whole axis, built on first use, when they
    /// are small enough to keep.
    fn kept_tables(&self, si: usize) -> Option<&Result<Vec<TransferTable>, SimError>> {
        let bytes = 6 * self.geometry.channels.len() * self.freq.len() * 16;
        (bytes <= KEPT_TABLE_BYTES).then(|| {
            self.tables[si].get_or_init(|| {
                transfer_tables(&self.models[si], &self.omegas, SimOptions::default().method)
            })
        })
    }
}

impl FrfSource for DeferredSimulation {
    fn quantity(&self) -> Quantity {
        self.spec.quantity
    }
    fn frequency_hz(&self) -> &[f64] {
        &self.freq
    }
    fn n_excitations(&self) -> usize {
        self.geometry.excitations.len()
    }
    fn n_channels(&self) -> usize {
        self.geometry.channels.len()
    }
    fn validate(&self) -> Result<(), CoreError> {
        validate_frequency_axis(&self.freq)
    }
    fn excitation(&self, e: usize) -> Result<ExcitationFrf<'_>, CoreError> {
        let id = &self.geometry.excitations[e].id;
        let values = self
            .block(e)
            .map_err(|err| CoreError::FrfSource(format!("excitation '{id}': {err}")))?;
        let set = FrfSet {
            quantity: self.spec.quantity,
            frequency_hz: self.freq.clone(),
            n_excitations: 1,
            n_channels: self.geometry.channels.len(),
            values,
        };
        set.validate()
            .map_err(|err| CoreError::FrfSource(format!("excitation '{id}': {err}")))?;
        Ok(ExcitationFrf::owned(set))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every excitation of `text`'s campaign made alone equals the whole simulation's,
    /// bit for bit, with the same truth and notes.
    fn assert_as_whole(name: &str, text: &str) {
        let spec = CampaignSpec::from_toml_str(text).unwrap();
        let whole = crate::simulate(&spec).unwrap();
        let deferred = simulate_deferred(&spec).unwrap();
        assert_eq!(deferred.truth, whole.truth, "{name}");
        assert_eq!(deferred.notes, whole.notes, "{name}");
        assert_eq!(deferred.geometry, whole.geometry, "{name}");
        assert_eq!(FrfSet::from_source(&deferred).unwrap(), whole.frf, "{name}");
    }

    /// The built-in campaigns and every effect's example (attached masses, windows,
    /// extra modes, observed blocks, output effects).
    #[test]
    fn each_excitation_alone_is_the_whole_simulation() {
        for name in crate::example_names() {
            assert_as_whole(name, crate::example(name).unwrap());
        }
        for (name, text) in crate::effect_examples() {
            assert_as_whole(name, text);
        }
    }

    /// An axis whose tables are too large to keep (20,001 lines: 17 MB at 9 channels),
    /// built again per excitation in three chunks of lines.
    #[test]
    fn tables_built_per_excitation_give_the_same_values() {
        let demo = crate::example("demo").unwrap();
        assert!(demo.contains("lines = 1601"));
        let long = demo.replace("lines = 1601", "lines = 20001");
        let spec = CampaignSpec::from_toml_str(&long).unwrap();
        let bytes = 6 * spec.geometry().unwrap().channels.len() * 20001 * 16;
        assert!(bytes > KEPT_TABLE_BYTES);
        assert_as_whole("demo at 20,001 lines", &long);
    }
}
