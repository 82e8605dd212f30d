//! Model FRFs on the recording's frequency axis and in its channel/excitation order,
//! computed by rbprops-sim's own noise-free simulator, so that the nominal model and
//! every candidate effect are evaluated by the code that generates recordings.

use crate::error::CheckError;
use rbprops_core::{c64, FrfSet, Geometry, Quantity};
use rbprops_sim::effects::Effect;
use rbprops_sim::{CampaignSpec, SolveMethod};

/// How the recording maps onto the spec: which spec channel/excitation each recorded
/// one is, and the recording's axis and quantity.
#[derive(Debug, Clone)]
pub struct Layout {
    /// The spec's geometry (the model's channels and excitations).
    pub spec_geometry: Geometry,
    /// Recording channel i is spec channel `channel_map[i]`.
    pub channel_map: Vec<usize>,
    /// Recording excitation e is spec excitation `excitation_map[e]`.
    pub excitation_map: Vec<usize>,
    /// The recording's spectral lines (Hz).
    pub frequency_hz: Vec<f64>,
    /// What the recording's FRFs measure per newton.
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
        let channel_map: Vec<Option<usize>> = recording
            .channels
            .iter()
            .map(|c| spec_geometry.channel_index(&c.id))
            .collect();
        let excitation_map: Vec<Option<usize>> = recording
            .excitations
            .iter()
            .map(|e| spec_geometry.excitation_index(&e.id))
            .collect();
        // Every id that does not match, channels and excitations alike, in one message:
        // a spec written by hand usually misnames a whole family (`1:1` for `101x`).
        let problems: Vec<String> = [
            unmatched(
                "channels",
                recording.channels.iter().map(|c| c.id.as_str()).collect(),
                &channel_map,
                spec_geometry
                    .channels
                    .iter()
                    .map(|c| c.id.as_str())
                    .collect(),
            ),
            unmatched(
                "excitations",
                recording
                    .excitations
                    .iter()
                    .map(|e| e.id.as_str())
                    .collect(),
                &excitation_map,
                spec_geometry
                    .excitations
                    .iter()
                    .map(|e| e.id.as_str())
                    .collect(),
            ),
        ]
        .into_iter()
        .flatten()
        .collect();
        if !problems.is_empty() {
            return Err(CheckError::Mismatch(problems.join("; ")));
        }
        let channel_map: Vec<usize> = channel_map.into_iter().flatten().collect();
        let excitation_map: Vec<usize> = excitation_map.into_iter().flatten().collect();
        Ok(Layout {
            spec_geometry,
            channel_map,
            excitation_map,
            frequency_hz: frf.frequency_hz.clone(),
            quantity: frf.quantity,
        })
    }

    /// Number of spectral lines.
    pub fn n_lines(&self) -> usize {
        self.frequency_hz.len()
    }
    /// Number of complex values, excitations × channels × lines.
    pub fn n_values(&self) -> usize {
        self.channel_map.len() * self.excitation_map.len() * self.n_lines()
    }
}

/// The model's FRFs `[excitation][channel][line]` in the recording's layout, computed by
/// [`rbprops_sim::simulate::predict`] (the simulator without noise) in the recording's
/// quantity and reordered to the recording's channels and excitations.
///
/// The per-line solve is [`SolveMethod::Columns`] (one LU per line, solved for the force
/// columns only), not the simulator's default inverse: several times cheaper, and equal
/// to the simulated recordings' model to rounding (~1e-15 relative, inside the
/// model-rounding term of the noise floor), not bit for bit.
pub fn predict(
    spec: &CampaignSpec,
    layout: &Layout,
    effects: &[Box<dyn Effect>],
) -> Result<Vec<c64>, CheckError> {
    let _t = crate::prof::span(crate::prof::PREDICT);
    // Same application order as rbprops-sim's parse_effects: by `order()`, then as given.
    let mut ordered: Vec<&Box<dyn Effect>> = effects.iter().collect();
    ordered.sort_by_key(|e| e.order());
    let ordered: Vec<Box<dyn Effect>> = ordered
        .into_iter()
        .map(|e| e.with_values(&e.values()).map_err(CheckError::Model))
        .collect::<Result<_, _>>()?;
    let mut spec = std::borrow::Cow::Borrowed(spec);
    if spec.quantity != layout.quantity {
        spec.to_mut().quantity = layout.quantity;
    }
    // The 0 Hz line is never compared (the check gives it σ = 0), and a model with a free
    // rigid-body direction has no finite value there: it is not computed and reads 0.
    let skip = layout
        .frequency_hz
        .iter()
        .take_while(|&&f| f == 0.0)
        .count();
    let (frf, _) = rbprops_sim::simulate::predict(
        &spec,
        &layout.spec_geometry,
        &ordered,
        &layout.frequency_hz[skip..],
        &rbprops_sim::SimOptions {
            method: SolveMethod::Columns,
        },
    )
    .map_err(|e| CheckError::Model(e.to_string()))?;
    let nl = layout.n_lines();
    let n_rch = layout.channel_map.len();
    let in_order =
        |map: &[usize], n: usize| map.len() == n && map.iter().enumerate().all(|(i, &m)| i == m);
    // The recording's channels and excitations in the spec's order, every line
    // computed: the model's values are the recording's layout already.
    let out = if skip == 0
        && in_order(&layout.excitation_map, frf.n_excitations)
        && in_order(&layout.channel_map, frf.n_channels)
    {
        frf.values
    } else {
        // Block by block in the recording's order (excitation, then channel), the
        // skipped lines 0: each value written once.
        let mut out = Vec::with_capacity(layout.n_values());
        for &se in &layout.excitation_map {
            for &sc in &layout.channel_map {
                out.resize(out.len() + skip, c64::new(0.0, 0.0));
                out.extend_from_slice(frf.frf(se, sc));
            }
        }
        debug_assert_eq!(out.len(), n_rch * layout.excitation_map.len() * nl);
        out
    };
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

/// The recorded ids (`recorded`, mapped to the spec by `map`) that the spec lacks, as one
/// message listing them and the spec's own (`known`); `None` when every id matches.
fn unmatched(
    kind: &str,
    recorded: Vec<&str>,
    map: &[Option<usize>],
    known: Vec<&str>,
) -> Option<String> {
    const SHOWN: usize = 20;
    let missing: Vec<&str> = recorded
        .into_iter()
        .zip(map)
        .filter(|(_, m)| m.is_none())
        .map(|(id, _)| id)
        .collect();
    if missing.is_empty() {
        return None;
    }
    let list = |v: &[&str]| {
        let mut s = v
            .iter()
            .take(SHOWN)
            .map(|x| format!("'{x}'"))
            .collect::<Vec<_>>()
            .join(", ");
        if v.len() > SHOWN {
            s += &format!(" and {} more", v.len() - SHOWN);
        }
        s
    };
    Some(format!(
        "recorded {kind} not in the spec: {} (the spec has {})",
        list(&missing),
        list(&known)
    ))
}

#[cfg(test)]
mod unmatched_tests {
    use super::unmatched;

    #[test]
    fn unmatched_ids_are_listed_with_the_specs_own() {
        assert_eq!(
            unmatched(
                "channels",
                vec!["1x", "9z"],
                &[Some(0), None],
                vec!["1x", "1y"]
            ),
            Some("recorded channels not in the spec: '9z' (the spec has '1x', '1y')".into())
        );
        assert_eq!(
            unmatched("excitations", vec!["f1"], &[Some(0)], vec!["f1"]),
            None
        );
        let many: Vec<String> = (0..23).map(|i| format!("c{i}")).collect();
        let recorded: Vec<&str> = many.iter().map(String::as_str).collect();
        let msg = unmatched("channels", recorded, &[None; 23], vec!["a"]).unwrap();
        assert!(msg.contains("'c19' and 3 more (the spec has 'a')"), "{msg}");
    }
}
