//! Wire messages for the geometry and the FRFs (the other topics are the records of
//! `rbprops_core::records` as they are).

use crate::FormatError;
use base64::Engine;
use rbprops_core::{c64, Channel, Excitation, Geometry, Point, Quantity, SuspensionSetup, Vec3};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// A measurement point: where channels and excitations sit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct PointMsg {
    /// Point id, unique in the geometry.
    pub id: String,
    /// Position in the geometry frame (m).
    pub position_m: [f64; 3],
}

/// A response channel: unit sensing direction at a point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ChannelMsg {
    /// Channel id, unique in the geometry.
    pub id: String,
    /// Id of the point the sensor sits on.
    pub point: String,
    /// Sensor position (m).
    pub position_m: [f64; 3],
    /// Unit sensing direction in the geometry frame.
    pub direction: [f64; 3],
}

/// A force input: unit direction at a point, in a suspension set-up.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ExcitationMsg {
    /// Excitation id, unique in the geometry.
    pub id: String,
    /// Id of the point the force acts on.
    pub point: String,
    /// Id of the suspension set-up the FRFs were measured in.
    pub setup: String,
    /// Point of application (m).
    pub position_m: [f64; 3],
    /// Unit force direction in the geometry frame.
    pub direction: [f64; 3],
}

/// A suspension set-up: one way of hanging or supporting the body.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SetupMsg {
    /// Set-up id, referenced by [`ExcitationMsg::setup`].
    pub id: String,
    /// Free text, e.g. "cords at the four top corners".
    pub description: String,
}

/// The test geometry (topic `/rbprops/geometry`, one message). Right-handed frame, metres.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct GeometryMsg {
    /// Measurement points.
    pub points: Vec<PointMsg>,
    /// Response channels, in FRF order.
    pub channels: Vec<ChannelMsg>,
    /// Force inputs, in FRF order.
    pub excitations: Vec<ExcitationMsg>,
    /// Suspension set-ups the excitations refer to.
    pub setups: Vec<SetupMsg>,
}

impl GeometryMsg {
    /// The message of a [`Geometry`] (ids and vectors copied as they are).
    pub fn from_geometry(g: &Geometry) -> Self {
        let a = |v: &Vec3| [v.x, v.y, v.z];
        GeometryMsg {
            points: g
                .points
                .iter()
                .map(|p| PointMsg {
                    id: p.id.clone(),
                    position_m: a(&p.position),
                })
                .collect(),
            channels: g
                .channels
                .iter()
                .map(|c| ChannelMsg {
                    id: c.id.clone(),
                    point: c.point.clone(),
                    position_m: a(&c.position),
                    direction: a(&c.direction),
                })
                .collect(),
            excitations: g
                .excitations
                .iter()
                .map(|e| ExcitationMsg {
                    id: e.id.clone(),
                    point: e.point.clone(),
                    setup: e.setup.clone(),
                    position_m: a(&e.position),
                    direction: a(&e.direction),
                })
                .collect(),
            setups: g
                .setups
                .iter()
                .map(|s| SetupMsg {
                    id: s.id.clone(),
                    description: s.description.clone(),
                })
                .collect(),
        }
    }

    /// Converts and validates (unit directions, unique ids, known set-ups).
    pub fn to_geometry(&self) -> Result<Geometry, FormatError> {
        let v = Vec3::from;
        let g = Geometry {
            points: self
                .points
                .iter()
                .map(|p| Point {
                    id: p.id.clone(),
                    position: v(p.position_m),
                })
                .collect(),
            channels: self
                .channels
                .iter()
                .map(|c| Channel {
                    id: c.id.clone(),
                    point: c.point.clone(),
                    position: v(c.position_m),
                    direction: v(c.direction),
                })
                .collect(),
            excitations: self
                .excitations
                .iter()
                .map(|e| Excitation {
                    id: e.id.clone(),
                    point: e.point.clone(),
                    setup: e.setup.clone(),
                    position: v(e.position_m),
                    direction: v(e.direction),
                })
                .collect(),
            setups: self
                .setups
                .iter()
                .map(|s| SuspensionSetup::new(&s.id, &s.description))
                .collect(),
        };
        g.validate()
            .map_err(|e| FormatError::record("<record>", "geometry", e))?;
        Ok(g)
    }
}

/// Frequency axis and layout of the FRFs (topic `/rbprops/frf_axis`, one message).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct FrfAxisMsg {
    /// Receptance, mobility or accelerance (docs/conventions.md).
    pub quantity: Quantity,
    /// SI unit of the values (`m/N`, `m/(N s)`, `m/(N s^2)`).
    pub unit: String,
    /// Excitation ids in the order of the `/rbprops/frf` messages.
    pub excitations: Vec<String>,
    /// Channel ids in the order of each message's values.
    pub channels: Vec<String>,
    /// Frequency of every line (Hz), increasing.
    pub frequency_hz: Vec<f64>,
}

/// FRFs of one excitation (topic `/rbprops/frf`, one message per excitation).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct FrfMsg {
    /// Id of the excitation these FRFs belong to.
    pub excitation: String,
    /// Base64 of little-endian IEEE-754 f64, laid out `[channel][line][re, im]`.
    #[schemars(extend("contentEncoding" = "base64"))]
    pub values_f64le: String,
}

/// Measured ordinary coherence γ² of one excitation's FRFs (topic `/rbprops/coherence`,
/// one message per excitation that has any): the tester's quality measure per line.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct CoherenceMsg {
    /// Id of the excitation whose FRFs these coherences belong to.
    pub excitation: String,
    /// Channels with a coherence, in the FRF set's channel order.
    pub channels: Vec<String>,
    /// Base64 of little-endian IEEE-754 f64, laid out `[channel][line][γ², 0]` on the
    /// FRF set's frequency axis (the FRF layout, imaginary parts zero).
    #[schemars(extend("contentEncoding" = "base64"))]
    pub values_f64le: String,
}

/// The noise variance of every FRF line of one excitation, `σ² = E|Ĥ − H|²` in FRF
/// units squared (topic `/rbprops/frf_variance`), as the estimator knows it (H1 over
/// `n_d` averages: `|Ĥ|²(1 − γ²)/((n_d − 1)γ²)`, smoothed over neighbouring lines; see
/// docs/conventions.md). Stages use it instead of estimating the noise from the FRFs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct FrfVarianceMsg {
    /// Id of the excitation whose FRFs these variances belong to.
    pub excitation: String,
    /// Channels with a variance, in the FRF set's channel order.
    pub channels: Vec<String>,
    /// Degrees of freedom of each variance (real χ² degrees: 2(n_d − 1) per line times
    /// the lines pooled); `f64::INFINITY` written as 0 when the variance is exact.
    pub degrees_of_freedom: f64,
    /// Base64 of little-endian IEEE-754 f64, laid out `[channel][line][σ², 0]` on the
    /// FRF set's frequency axis (the FRF layout, imaginary parts zero).
    #[schemars(extend("contentEncoding" = "base64"))]
    pub values_f64le: String,
    /// The part of the error the force channel's noise puts into every FRF of this
    /// excitation alike (`frf-est`, one force channel; docs/conventions.md, FRF
    /// estimation). Absent from other writers' files and without force noise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force_noise: Option<ForceNoiseMsg>,
}

/// The force noise's error common to an excitation's FRFs, `Ĥ_c = H_c (1 + ε)`:
/// `E|ε|² = ρ²` per line and the line correlation of the window's binned noise energy
/// (`rbprops_core::CommonRelativeError`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ForceNoiseMsg {
    /// Base64 of little-endian IEEE-754 f64, `[line][ρ², 0]` on the FRF set's axis.
    #[schemars(extend("contentEncoding" = "base64"))]
    pub relative_variance_f64le: String,
    /// The bins' times (s from the pulse's centroid).
    pub window_times_s: Vec<f64>,
    /// The bins' shares of the noise energy through the force window (sum 1).
    pub window_weights: Vec<f64>,
}

/// The recorded time histories of one excitation (topic `/rbprops/time_history`, one
/// message per excitation; docs/formats.md, Time histories): the force channel and the
/// response channels, the sampling, and the records — one per hit, or one continuous
/// (throughput) record holding every hit, which `frf-est` finds by trigger.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct TimeHistoryMsg {
    /// Id of the excitation (the FRFs' excitation id).
    pub excitation: String,
    /// Id of its suspension set-up ("" for the default set-up).
    #[serde(default)]
    pub setup: String,
    /// Free text describing the set-up.
    #[serde(default)]
    pub setup_description: String,
    /// Sampling rate (Hz) of every channel.
    pub sample_rate_hz: f64,
    /// Samples per record per channel.
    pub record_samples: usize,
    /// `hits`: one record per hit; `throughput`: one continuous record with every hit.
    pub layout: String,
    /// `f32le` or `f64le`: how [`TimeRecordMsg::samples`] stores each sample.
    pub sample_format: String,
    /// The channels, the force first, then the responses; the samples of each record
    /// are in this order.
    pub channels: Vec<TimeChannelMsg>,
    /// The records, in hit order.
    pub records: Vec<TimeRecordMsg>,
}

/// One channel of a [`TimeHistoryMsg`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct TimeChannelMsg {
    /// Channel id (a response's FRF channel id; the force's is informative).
    pub id: String,
    /// Id of the measurement point ("" to name it by its node).
    #[serde(default)]
    pub point: String,
    /// Node number of the point.
    pub node: i64,
    /// Direction at the node: ±1..±3 (±X, ±Y, ±Z of the node's frame).
    pub direction: i64,
    /// `force` (the first channel only), `acceleration`, `velocity` or `displacement`.
    pub quantity: String,
    /// Units label of the samples (`N`, `m/s^2`, `g`, `mm`, …; "" for SI).
    #[serde(default)]
    pub unit: String,
    /// The node's position (m, geometry frame); absent when the geometry comes from
    /// elsewhere (`--geometry`).
    #[serde(default)]
    pub position_m: Option<[f64; 3]>,
}

/// One record of a [`TimeHistoryMsg`]: every channel's samples.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct TimeRecordMsg {
    /// Hit number (1-based; 0 for a throughput record).
    pub hit: usize,
    /// Base64 of little-endian IEEE-754 samples (f32 or f64 as the message's
    /// `sample_format`), laid out `[channel][sample]` in the message's channel order.
    #[schemars(extend("contentEncoding" = "base64"))]
    pub samples: String,
}

/// Little-endian samples `[channel][sample]` as base64, `f32le` (rounded to single
/// precision) or `f64le`, the layout of [`TimeRecordMsg::samples`].
pub fn encode_samples(channels: &[Vec<f64>], single: bool) -> String {
    let mut bytes = Vec::new();
    for c in channels {
        for &x in c {
            if single {
                bytes.extend_from_slice(&(x as f32).to_le_bytes());
            } else {
                bytes.extend_from_slice(&x.to_le_bytes());
            }
        }
    }
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

/// Inverse of [`encode_samples`]: `n_channels × n_samples` samples, else an error saying
/// how many bytes came.
pub fn decode_samples(
    s: &str,
    single: bool,
    n_channels: usize,
    n_samples: usize,
) -> Result<Vec<Vec<f64>>, String> {
    let bytes = base64::engine::general_purpose::STANDARD
        .decode(s)
        .map_err(|e| format!("samples are not valid base64: {e}"))?;
    let width = if single { 4 } else { 8 };
    let expect = n_channels
        .checked_mul(n_samples)
        .and_then(|v| v.checked_mul(width))
        .ok_or_else(|| "the declared size overflows".to_string())?;
    if bytes.len() != expect {
        return Err(format!(
            "{} bytes of samples, expected {expect} ({n_channels} channels × {n_samples} samples × {width} bytes)",
            bytes.len()
        ));
    }
    Ok(bytes
        .chunks_exact(width * n_samples.max(1))
        .take(n_channels)
        .map(|c| {
            c.chunks_exact(width)
                .map(|b| {
                    if single {
                        f32::from_le_bytes(b.try_into().expect("4 bytes")) as f64
                    } else {
                        f64::from_le_bytes(b.try_into().expect("8 bytes"))
                    }
                })
                .collect()
        })
        .collect())
}

/// Base64 of little-endian f64 `[re, im]` pairs, the layout of [`FrfMsg::values_f64le`]; exact bit for bit.
pub fn encode_values(values: &[c64]) -> String {
    let mut bytes = Vec::with_capacity(values.len() * 16);
    for v in values {
        bytes.extend_from_slice(&v.re.to_le_bytes());
        bytes.extend_from_slice(&v.im.to_le_bytes());
    }
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

/// The JSON of the [`FrfMsg`] of `excitation` with `values`, byte for byte
/// `serde_json::to_vec` of it, written straight into one buffer: the values' bytes and
/// their base64 text are never held beside it (issue 41: at 102,401 lines they are 15 and
/// 20 MB per excitation). The fields in their declared order; base64 needs no escapes.
pub fn frf_message_json(excitation: &str, values: &[c64]) -> Vec<u8> {
    use base64::Engine;
    const BLOCK: usize = 192; // values: 3,072 bytes, a multiple of 3, so 4,096 characters
    let mut out = Vec::with_capacity(values.len().div_ceil(3) * 64 + excitation.len() + 40);
    out.extend_from_slice(b"{\"excitation\":");
    serde_json::to_writer(&mut out, excitation).expect("a string serialises");
    out.extend_from_slice(b",\"values_f64le\":\"");
    let mut bytes = [0u8; BLOCK * 16];
    let mut text = [0u8; BLOCK * 16 / 3 * 4];
    for block in values.chunks(BLOCK) {
        for (v, b) in block.iter().zip(bytes.chunks_exact_mut(16)) {
            b[..8].copy_from_slice(&v.re.to_le_bytes());
            b[8..].copy_from_slice(&v.im.to_le_bytes());
        }
        let n = base64::engine::general_purpose::STANDARD
            .encode_slice(&bytes[..block.len() * 16], &mut text)
            .expect("the buffer holds a block's text");
        out.extend_from_slice(&text[..n]);
    }
    out.extend_from_slice(b"\"}");
    out
}

/// Inverse of [`encode_values`]: `expect` complex numbers, else an error saying how many bytes came.
pub fn decode_values(s: &str, expect: usize) -> Result<Vec<c64>, String> {
    // Block by block into the values: the whole text's bytes are never held beside them
    // (issue 41: at 102,401 lines an excitation's bytes are 15 MB). Any text the blocks
    // do not take cleanly (invalid base64, a wrong length) is decoded whole below, so
    // the error is the one that decoding names.
    if let Some(v) = decode_values_by_block(s, expect) {
        return Ok(v);
    }
    let bytes = base64::engine::general_purpose::STANDARD
        .decode(s)
        .map_err(|e| format!("values are not valid base64: {e}"))?;
    if bytes.len() != expect * 16 {
        return Err(format!(
            "{} bytes of values, expected {} ({} complex numbers)",
            bytes.len(),
            expect * 16,
            expect
        ));
    }
    Ok(values_of(&bytes).collect())
}

/// Little-endian `[re, im]` pairs of f64 as complex values.
fn values_of(bytes: &[u8]) -> impl Iterator<Item = c64> + '_ {
    bytes.chunks_exact(16).map(|c| {
        c64::new(
            f64::from_le_bytes(c[..8].try_into().unwrap()),
            f64::from_le_bytes(c[8..].try_into().unwrap()),
        )
    })
}

/// [`decode_values`] of valid text of exactly `expect` values, 4,096 characters (192
/// values) at a time; `None` for any other text.
fn decode_values_by_block(s: &str, expect: usize) -> Option<Vec<c64>> {
    use base64::Engine;
    const BLOCK: usize = 4096;
    let mut out = Vec::with_capacity(expect.min(s.len() / 21 + 1));
    let mut buf = [0u8; BLOCK / 4 * 3];
    for block in s.as_bytes().chunks(BLOCK) {
        let n = base64::engine::general_purpose::STANDARD
            .decode_slice(block, &mut buf)
            .ok()?;
        if n % 16 != 0 || out.len() + n / 16 > expect {
            return None;
        }
        out.extend(values_of(&buf[..n]));
    }
    (out.len() == expect).then_some(out)
}

/// Header for an FRF set with the geometry's ids.
pub fn frf_axis(frf: &dyn rbprops_core::FrfSource, geometry: &Geometry) -> FrfAxisMsg {
    FrfAxisMsg {
        quantity: frf.quantity(),
        unit: frf.quantity().unit().into(),
        excitations: geometry.excitations.iter().map(|e| e.id.clone()).collect(),
        channels: geometry.channels.iter().map(|c| c.id.clone()).collect(),
        frequency_hz: frf.frequency_hz().to_vec(),
    }
}

/// Checks that the FRF header's ids are exactly the geometry's, in order.
pub fn check_ids_match(
    axis: &FrfAxisMsg,
    geometry: &Geometry,
    file: &str,
) -> Result<(), FormatError> {
    let ge: Vec<&str> = geometry.excitations.iter().map(|e| e.id.as_str()).collect();
    let gc: Vec<&str> = geometry.channels.iter().map(|c| c.id.as_str()).collect();
    if axis
        .excitations
        .iter()
        .map(String::as_str)
        .ne(ge.iter().copied())
    {
        return Err(FormatError::record(
            file,
            "FRF axis",
            format!(
                "excitations {:?} differ from the geometry's {:?}",
                axis.excitations, ge
            ),
        ));
    }
    if axis
        .channels
        .iter()
        .map(String::as_str)
        .ne(gc.iter().copied())
    {
        return Err(FormatError::record(
            file,
            "FRF axis",
            format!(
                "channels {:?} differ from the geometry's {:?}",
                axis.channels, gc
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use base64::Engine;

    /// The block-by-block decoding gives the values of the whole-text decoding, bit for
    /// bit, for counts below, at and across the block of 192 values; and any text it does
    /// not take gives the whole-text decoding's error.
    #[test]
    fn values_decode_by_block_as_whole() {
        for n in [0usize, 1, 2, 191, 192, 193, 384, 1000] {
            let values: Vec<c64> = (0..n)
                .map(|k| c64::new((k as f64).sin() * 1e3, -(k as f64).sqrt() / 7.0))
                .collect();
            let text = encode_values(&values);
            let got = decode_values(&text, n).unwrap();
            assert_eq!(got.len(), n);
            for (a, b) in got.iter().zip(&values) {
                assert_eq!(
                    (a.re.to_bits(), a.im.to_bits()),
                    (b.re.to_bits(), b.im.to_bits())
                );
            }
            assert_eq!(decode_values_by_block(&text, n), Some(values.clone()));
            if n > 0 {
                // One value fewer or more than the text holds: the whole decoding's count.
                let e = decode_values(&text, n + 1).unwrap_err();
                assert!(e.contains(&format!("expected {}", 16 * (n + 1))), "{e}");
                assert!(decode_values(&text, n - 1).is_err());
            }
        }
        // The message written straight is serde_json's, byte for byte.
        for n in [0usize, 1, 2, 3, 191, 192, 193, 500] {
            let values: Vec<c64> = (0..n)
                .map(|k| c64::new(k as f64 * 0.37 - 3.0, (k as f64).cos()))
                .collect();
            for id in ["force1", "a \"quoted\" \\ id — ü"] {
                let msg = FrfMsg {
                    excitation: id.into(),
                    values_f64le: encode_values(&values),
                };
                assert_eq!(
                    frf_message_json(id, &values),
                    serde_json::to_vec(&msg).unwrap(),
                    "{n} values, id {id}"
                );
            }
        }
        // Invalid base64 inside the second block: the whole text's error, offset and all.
        let mut text = encode_values(&vec![c64::new(1.0, 2.0); 400]).into_bytes();
        text[5000] = b'*';
        let text = String::from_utf8(text).unwrap();
        let whole = base64::engine::general_purpose::STANDARD
            .decode(&text)
            .unwrap_err();
        assert_eq!(
            decode_values(&text, 400).unwrap_err(),
            format!("values are not valid base64: {whole}")
        );
    }
}
