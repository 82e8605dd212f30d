//! A per-excitation table of real values per channel and FRF line, the form of the
//! coherence (`/rbprops/coherence`) and line-variance (`/rbprops/frf_variance`) topics:
//! one message per excitation with any values, naming the channels that have them (in
//! the geometry's channel order) and their values laid out `[channel][line]` as complex
//! f64 with zero imaginary parts on the FRF set's frequency axis (`wire::encode_values`).

use anyhow::{bail, Result};
use rbprops_core::{c64, Geometry};
use rbprops_formats::wire::{decode_values, encode_values};

/// One excitation's row of the table, encoded.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// The excitation's index in the geometry.
    pub index: usize,
    /// The excitation's id.
    pub excitation: String,
    /// The ids of the channels with values, geometry order.
    pub channels: Vec<String>,
    /// Their values, `wire::encode_values` of `[channel][line]`.
    pub values_f64le: String,
}

/// The rows of the table whose values for excitation `e` and channel `c` (geometry
/// indices) are `values(e, c)` (`None`: the channel has none); excitations without any
/// channel are left out.
pub fn encode<'a>(
    geometry: &Geometry,
    mut values: impl FnMut(usize, usize) -> Option<&'a [f64]>,
) -> Vec<Row> {
    let mut rows = Vec::new();
    for (e, x) in geometry.excitations.iter().enumerate() {
        let mut channels = Vec::new();
        let mut encoded: Vec<c64> = Vec::new();
        for (c, ch) in geometry.channels.iter().enumerate() {
            if let Some(v) = values(e, c) {
                channels.push(ch.id.clone());
                encoded.extend(v.iter().map(|&g| c64::new(g, 0.0)));
            }
        }
        if !channels.is_empty() {
            rows.push(Row {
                index: e,
                excitation: x.id.clone(),
                channels,
                values_f64le: encode_values(&encoded),
            });
        }
    }
    rows
}

/// One excitation's row decoded against the geometry: the excitation's index and, per
/// channel named, its index and its `n_lines` values. Errors, prefixed by `what` (the
/// topic), name the excitation or channel the geometry lacks and a wrong number of values.
pub fn decode(
    geometry: &Geometry,
    n_lines: usize,
    what: &str,
    excitation: &str,
    channels: &[String],
    values_f64le: &str,
) -> Result<(usize, Vec<(usize, Vec<f64>)>)> {
    let at = format!("{what}, excitation '{excitation}'");
    let Some(e) = geometry.excitations.iter().position(|x| x.id == excitation) else {
        bail!("{at}: not in the geometry");
    };
    let values = decode_values(values_f64le, n_lines * channels.len())
        .map_err(|err| anyhow::anyhow!("{at}: {err}"))?;
    let mut out = Vec::with_capacity(channels.len());
    for (k, id) in channels.iter().enumerate() {
        let Some(c) = geometry.channels.iter().position(|x| &x.id == id) else {
            bail!("{at}: channel '{id}' is not in the geometry");
        };
        out.push((
            c,
            values[k * n_lines..(k + 1) * n_lines]
                .iter()
                .map(|v| v.re)
                .collect(),
        ));
    }
    Ok((e, out))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn geometry() -> Geometry {
        rbprops_testkit::synthetic::test_case(1.0, 4, rbprops_core::Quantity::Accelerance).geometry
    }

    /// What is written is read back in place, channels without values stay without, and
    /// the bytes are the f64 pairs `[channel][line][value, 0]`.
    #[test]
    fn rows_round_trip() {
        let g = geometry();
        let n = 3;
        let value = |e: usize, c: usize, l: usize| (100 * e + 10 * c + l) as f64 + 0.25;
        let table: Vec<Vec<Option<Vec<f64>>>> = (0..g.excitations.len())
            .map(|e| {
                (0..g.channels.len())
                    .map(|c| (c % 2 == e % 2).then(|| (0..n).map(|l| value(e, c, l)).collect()))
                    .collect()
            })
            .collect();
        let rows = encode(&g, |e, c| table[e][c].as_deref());
        assert_eq!(rows.len(), g.excitations.len());
        for r in &rows {
            let (e, channels) = decode(
                &g,
                n,
                "test topic",
                &r.excitation,
                &r.channels,
                &r.values_f64le,
            )
            .unwrap();
            assert_eq!(e, r.index);
            assert_eq!(channels.len(), table[e].iter().flatten().count());
            for (c, v) in channels {
                assert_eq!(Some(&v), table[e][c].as_ref());
            }
        }
        // The layout: `[channel][line][value, 0]`.
        let first = table[0].iter().flatten().next().unwrap();
        let raw =
            rbprops_formats::wire::decode_values(&rows[0].values_f64le, n * rows[0].channels.len())
                .unwrap();
        assert!(raw[..n]
            .iter()
            .zip(first)
            .all(|(v, x)| v.re == *x && v.im == 0.0));
        let e = decode(&g, n, "test topic", "nowhere", &[], "")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("test topic, excitation 'nowhere': not in the geometry"),
            "{e}"
        );
        let e = decode(
            &g,
            n + 1,
            "test topic",
            &rows[0].excitation,
            &rows[0].channels,
            &rows[0].values_f64le,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("bytes of values"), "{e}");
    }
}
