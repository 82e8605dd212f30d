//! Localisation: where the noise-normalised residual sits, by excitation × channel ×
//! frequency band, split into output-rigid / non-rigid parts (σ-weighted projection on
//! the span of the channel rows sᵀT(p)) and in-phase / quadrature parts (relative to the
//! model FRF's phase).
//!
//! A cell with n real residual entries and χ² has z = (χ² − n)/√(2n) (≈ N(0,1) under the
//! noise model); cells with z > 5 are flagged.

use crate::predict::Layout;
use rbprops_core::c64;
use serde::{Deserialize, Serialize};

/// A frequency band of the residual map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Band {
    /// Its label (`sub-suspension`, `suspension modes`, `mass line`, `upper edge`).
    pub name: String,
    /// Lower edge (Hz).
    pub from_hz: f64,
    /// Upper edge (Hz).
    pub to_hz: f64,
}

/// One cell of the residual map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ResidualCell {
    /// Excitation id.
    pub excitation: String,
    /// Channel id.
    pub channel: String,
    /// Band label.
    pub band: String,
    /// Number of real residual entries.
    pub n: usize,
    /// `χ²` of the cell's normalised residual (docs/conventions.md §8).
    pub chi2: f64,
    /// `z = (χ² − n)/√(2n)`, ≈ N(0, 1) under the noise model.
    pub z: f64,
    /// χ² of the part that is not rigid-body motion of the sensors.
    pub chi2_non_rigid: f64,
    /// χ² in phase and in quadrature with the model FRF.
    pub chi2_in_phase: f64,
    /// χ² in quadrature with the model FRF.
    pub chi2_quadrature: f64,
}

/// Totals over a group of cells (per sensor point, per excitation, per band).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ResidualTotal {
    /// Group label (sensor point, excitation or band).
    pub group: String,
    /// Number of real residual entries in the group.
    pub n: usize,
    /// `χ²/n` over the group.
    pub chi2_nu: f64,
    /// `z = (χ² − n)/√(2n)` over the group.
    pub z: f64,
    /// Fraction of χ² that is not rigid-body motion of the sensors.
    pub non_rigid_fraction: f64,
    /// Fraction of χ² in quadrature with the model FRF.
    pub quadrature_fraction: f64,
}

/// Where the normalised residual sits: by excitation × channel × band, and totals.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ResidualMap {
    /// The bands used.
    pub bands: Vec<Band>,
    /// Every cell.
    pub cells: Vec<ResidualCell>,
    /// Totals per sensor point.
    pub per_sensor: Vec<ResidualTotal>,
    /// Totals per excitation.
    pub per_excitation: Vec<ResidualTotal>,
    /// Totals per band.
    pub per_band: Vec<ResidualTotal>,
    /// Cells with z > 5, strongest first: "excitation/channel/band (z)".
    pub flagged: Vec<String>,
}

/// Bands from the model's suspension modes (lowest f_lo, highest f_hi, in Hz).
pub fn bands(f_lo: f64, f_hi: f64, axis: &[f64]) -> Vec<Band> {
    let (a, b) = (axis[0], axis[axis.len() - 1]);
    let sub = 0.7 * f_lo;
    let top = 1.5 * f_hi;
    let edge = top.max(b - 0.2 * (b - a));
    vec![
        Band {
            name: "sub-suspension".into(),
            from_hz: a,
            to_hz: sub.max(a),
        },
        Band {
            name: "suspension modes".into(),
            from_hz: sub.max(a),
            to_hz: top.min(b),
        },
        Band {
            name: "mass line".into(),
            from_hz: top.min(b),
            to_hz: edge.min(b),
        },
        Band {
            name: "upper edge".into(),
            from_hz: edge.min(b),
            to_hz: b,
        },
    ]
}

fn z(chi2: f64, n: usize) -> f64 {
    if n == 0 {
        0.0
    } else {
        (chi2 - n as f64) / (2.0 * n as f64).sqrt()
    }
}

/// χ² sums of one cell (excitation × channel × band) as the lines are added.
#[derive(Debug, Clone, Copy, Default)]
struct CellSums {
    /// Real residual entries (2 per complex line).
    n: usize,
    chi2: f64,
    non_rigid: f64,
    in_phase: f64,
    quadrature: f64,
}

/// The residual map of data `y` against model `m` with noise σ (all `[exc][ch][line]`).
pub fn residual_map(
    layout: &Layout,
    y: &[c64],
    m: &[c64],
    sigma: &[f64],
    bands: Vec<Band>,
) -> ResidualMap {
    let sums = cell_sums(layout, y, m, sigma, &bands);
    let cells = cells(layout, &bands, &sums);
    let g = &layout.spec_geometry;
    let mut points: Vec<String> = Vec::new();
    for &sc in &layout.channel_map {
        let p = &g.channels[sc].point;
        if !points.contains(p) {
            points.push(p.clone());
        }
    }
    let per_sensor = points
        .iter()
        .map(|p| {
            let chans: Vec<&str> = g
                .channels
                .iter()
                .filter(|c| &c.point == p)
                .map(|c| c.id.as_str())
                .collect();
            total(format!("sensor {p}"), &cells, |c| {
                chans.contains(&c.channel.as_str())
            })
        })
        .collect();
    let per_excitation = layout
        .excitation_map
        .iter()
        .map(|&se| {
            let id = &g.excitations[se].id;
            total(format!("excitation {id}"), &cells, |c| &c.excitation == id)
        })
        .collect();
    let per_band = bands
        .iter()
        .map(|b| total(format!("band {}", b.name), &cells, |c| c.band == b.name))
        .collect();
    let flagged = flagged(&cells);
    ResidualMap {
        bands,
        cells,
        per_sensor,
        per_excitation,
        per_band,
        flagged,
    }
}

/// The sums of every cell, indexed `[(exc · n_ch + ch) · n_bands + band]`.
fn cell_sums(
    layout: &Layout,
    y: &[c64],
    m: &[c64],
    sigma: &[f64],
    bands: &[Band],
) -> Vec<CellSums> {
    let g = &layout.spec_geometry;
    let nl = layout.n_lines();
    let nch = layout.channel_map.len();
    let nex = layout.excitation_map.len();
    let nb = bands.len();
    let band_of = |f: f64| -> usize {
        bands
            .iter()
            .position(|b| f >= b.from_hz && f < b.to_hz)
            .unwrap_or(nb - 1)
    };
    let mut sums = vec![CellSums::default(); nex * nch * nb];
    let rows: Vec<_> = layout
        .channel_map
        .iter()
        .map(|&sc| g.channels[sc].row())
        .collect();
    for e in 0..nex {
        for l in 0..nl {
            let b = band_of(layout.frequency_hz[l]);
            // Weighted residual and rows over the channels with information on this line.
            let at = |c: usize| (e * nch + c) * nl + l;
            let idx: Vec<usize> = (0..nch).filter(|&c| sigma[at(c)] > 0.0).collect();
            if idx.is_empty() {
                continue;
            }
            let rho: Vec<c64> = idx
                .iter()
                .map(|&c| (y[at(c)] - m[at(c)]) * (std::f64::consts::SQRT_2 / sigma[at(c)]))
                .collect();
            let w = nalgebra::DMatrix::from_fn(idx.len(), 6, |r, k| {
                rows[idx[r]][k] / sigma[at(idx[r])]
            });
            let rigid = rigid_part(w, &rho);
            for (r, &c) in idx.iter().enumerate() {
                let a = &mut sums[(e * nch + c) * nb + b];
                a.n += 2;
                a.chi2 += rho[r].norm_sqr();
                a.non_rigid += (rho[r] - rigid[r]).norm_sqr();
                let rot = rho[r] * unit_phase_conj(m[at(c)]);
                a.in_phase += rot.re * rot.re;
                a.quadrature += rot.im * rot.im;
            }
        }
    }
    sums
}

/// The part of the weighted residual `rho` that is rigid-body motion of the sensors: its
/// projection on the span of the weighted channel rows `w` (rank-revealing via SVD, so a
/// direction no channel sees does not count).
fn rigid_part(w: nalgebra::DMatrix<f64>, rho: &[c64]) -> Vec<c64> {
    let svd = w.svd(true, false);
    let u = svd.u.expect("requested");
    let smax = svd.singular_values.max();
    let mut rigid = vec![c64::new(0.0, 0.0); rho.len()];
    for k in (0..svd.singular_values.len()).filter(|&k| svd.singular_values[k] > 1e-9 * smax) {
        let col = u.column(k);
        let mut dot = c64::new(0.0, 0.0);
        for r in 0..rho.len() {
            dot += rho[r] * col[r];
        }
        for r in 0..rho.len() {
            rigid[r] += dot * col[r];
        }
    }
    rigid
}

/// `e^{−i arg m}`: turns a residual into the model FRF's phase frame (re in phase, im in
/// quadrature); 1 where the model is zero.
fn unit_phase_conj(m: c64) -> c64 {
    if m.norm() > 0.0 {
        m.conj() / m.norm()
    } else {
        c64::new(1.0, 0.0)
    }
}

/// The non-empty cells, excitation by channel by band.
fn cells(layout: &Layout, bands: &[Band], sums: &[CellSums]) -> Vec<ResidualCell> {
    let g = &layout.spec_geometry;
    let nch = layout.channel_map.len();
    let nb = bands.len();
    let mut cells = Vec::new();
    for (e, &se) in layout.excitation_map.iter().enumerate() {
        for (c, &sc) in layout.channel_map.iter().enumerate() {
            for (b, band) in bands.iter().enumerate() {
                let a = sums[(e * nch + c) * nb + b];
                if a.n == 0 {
                    continue;
                }
                cells.push(ResidualCell {
                    excitation: g.excitations[se].id.clone(),
                    channel: g.channels[sc].id.clone(),
                    band: band.name.clone(),
                    n: a.n,
                    chi2: a.chi2,
                    z: z(a.chi2, a.n),
                    chi2_non_rigid: a.non_rigid,
                    chi2_in_phase: a.in_phase,
                    chi2_quadrature: a.quadrature,
                });
            }
        }
    }
    cells
}

/// Totals over the cells a group selects.
fn total(
    group: String,
    cells: &[ResidualCell],
    sel: impl Fn(&ResidualCell) -> bool,
) -> ResidualTotal {
    let (mut n, mut c2, mut nr, mut q) = (0usize, 0.0, 0.0, 0.0);
    for cell in cells.iter().filter(|c| sel(c)) {
        n += cell.n;
        c2 += cell.chi2;
        nr += cell.chi2_non_rigid;
        q += cell.chi2_quadrature;
    }
    ResidualTotal {
        group,
        n,
        chi2_nu: if n > 0 { c2 / n as f64 } else { 0.0 },
        z: z(c2, n),
        non_rigid_fraction: if c2 > 0.0 { nr / c2 } else { 0.0 },
        quadrature_fraction: if c2 > 0.0 { q / c2 } else { 0.0 },
    }
}

/// The 20 strongest cells with z > 5: "excitation/channel/band (z …)".
fn flagged(cells: &[ResidualCell]) -> Vec<String> {
    let mut strong: Vec<&ResidualCell> = cells.iter().filter(|c| c.z > 5.0).collect();
    strong.sort_by(|a, b| b.z.total_cmp(&a.z));
    strong
        .iter()
        .take(20)
        .map(|c| format!("{}/{}/{} (z {:.1})", c.excitation, c.channel, c.band, c.z))
        .collect()
}
