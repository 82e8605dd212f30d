use crate::candidates::Candidate;
use crate::error::CheckError;
use crate::lm;
use crate::lm::{Bounds, Fit};
use crate::params::Baseline;
use crate::predict::{predict, Layout};
use crate::report::PlausibleValue;
use nalgebra::DMatrix;
use rbprops_core::c64;
use rbprops_sim::effects::{Effect, Reach};
use rbprops_sim::CampaignSpec;

/// A pass's final model: the nominal model's parameters θ and each accepted effect's φ.
/// The noise rerun of [`check`] refits every effect the first pass accepted from here
/// as well: under the re-estimated noise the baseline may drift to stand in for the
/// effect (a hanging body's mass ×4.5 for a record truncation), and from that basin the
/// effect's screening statistic and its refit from the current model see nothing.
#[derive(Debug, Clone, Default)]
pub(super) struct Prior {
    pub(super) base: Vec<f64>,
    pub(super) effects: Vec<(String, Vec<f64>)>,
}

impl Prior {
    pub(super) fn phi(&self, id: &str) -> Option<&[f64]> {
        self.effects
            .iter()
            .find(|(e, _)| e == id)
            .map(|(_, phi)| phi.as_slice())
    }

    /// θ for `active` (the last entry the effect being refitted, with its start `alpha`
    /// unless the prior has it) from the prior's θ and φ where it has them and from
    /// `current` (the current fit's θ for `active` minus its last entry) elsewhere.
    pub(super) fn start(
        &self,
        p: &Problem,
        active: &[Act],
        current: &[f64],
        alpha: &[f64],
    ) -> Vec<f64> {
        let nb = p.n_base();
        let mut t = self.base.clone();
        let mut k = nb;
        for (i, a) in active.iter().enumerate() {
            let d = a.dim();
            let fallback = if i + 1 == active.len() {
                alpha
            } else {
                &current[k..k + d]
            };
            match self.phi(&p.cands[a.c].id) {
                Some(phi) => t.extend(a.kept.iter().map(|&j| phi[j])),
                None => t.extend_from_slice(fallback),
            }
            k += d;
        }
        t
    }
}

/// An effect in the model. Its free parameters are the `kept` coordinates of φ; the
/// others stay at their neutral values (or where `held` puts them). A coordinate is
/// dropped for each exact gauge of the effect (a direction with no signature once the
/// current model's parameters are free: a common gain the mass absorbs, a rotation of a
/// force about itself), so a gauge can neither drift nor take over the inertia
/// parameters, while the kept parameters keep their own units and bounds.
#[derive(Debug, Clone)]
pub(super) struct Act {
    pub(super) c: usize,
    pub(super) kept: Vec<usize>,
    /// Unit directions in φ-space the data cannot see at first order (reported).
    pub(super) gauge: Vec<Vec<f64>>,
    /// Coordinates outside `kept` held at a value other than neutral: the effect's
    /// physical holds once accepted ([`Effect::physical_holds`]).
    pub(super) held: Vec<(usize, f64)>,
}

impl Act {
    /// Candidate `c` with the coordinates `kept` free, no gauge and nothing held.
    pub(super) fn new(c: usize, kept: Vec<usize>) -> Act {
        Act {
            c,
            kept,
            gauge: Vec::new(),
            held: Vec::new(),
        }
    }
    pub(super) fn full(c: usize, n: usize) -> Act {
        Act::new(c, (0..n).collect())
    }
    pub(super) fn dim(&self) -> usize {
        self.kept.len()
    }
    pub(super) fn phi(&self, neutral: &[f64], alpha: &[f64]) -> Vec<f64> {
        let mut phi = neutral.to_vec();
        for &(j, v) in &self.held {
            phi[j] = v;
        }
        for (&j, a) in self.kept.iter().zip(alpha) {
            phi[j] = *a;
        }
        phi
    }
}

/// The fitting problem: data, weights, parametrisation and candidates.
pub(super) struct Problem<'a> {
    pub(super) baseline: Baseline,
    pub(super) layout: &'a Layout,
    pub(super) y: &'a [c64],
    pub(super) sigma: &'a [f64],
    pub(super) used: Vec<usize>,
    /// `√2/σ` of each used value (in the order of `used`): the residual's weights,
    /// divided once rather than at every model evaluation.
    pub(super) weight: Vec<f64>,
    pub(super) fixed_effects: Vec<Box<dyn Effect>>,
    pub(super) cands: Vec<Candidate>,
    pub(super) fixed_mass: Option<f64>,
}

impl<'a> Problem<'a> {
    /// The number of candidates that are not further instances of a repeatable effect.
    pub(super) fn n_first_instances(&self) -> usize {
        self.cands.iter().filter(|c| c.follows.is_none()).count()
    }

    pub(super) fn n_base(&self) -> usize {
        self.baseline.len()
    }

    /// The physical quantities of candidate `c` at φ `phi` as a tester reads them, each
    /// with its plausible range (the effect's descriptor in rbprops-sim's registry, on
    /// its catalogue entry in the spec of the baseline parameters `theta`); empty when the
    /// effect has no ranges or no catalogue entry.
    pub(super) fn plausibility(&self, theta: &[f64], c: usize, phi: &[f64]) -> Vec<PlausibleValue> {
        let spec = self.baseline.apply(&theta[..self.n_base()]);
        let Ok(e) = self.cands[c].effect.with_values(phi) else {
            return Vec::new();
        };
        crate::candidates::catalogue_entry(e.as_ref(), &spec)
            .and_then(|entry| rbprops_sim::effects::plausibility(&entry, &spec))
            .map(|v| {
                v.into_iter()
                    .map(|q| PlausibleValue {
                        quantity: q.quantity,
                        unit: q.unit,
                        value: q.value,
                        range: q.range,
                    })
                    .collect()
            })
            .unwrap_or_default()
    }

    pub(super) fn build(
        &self,
        theta: &[f64],
        active: &[Act],
    ) -> Result<(CampaignSpec, Vec<Box<dyn Effect>>), CheckError> {
        let spec = self.baseline.apply(&theta[..self.n_base()]);
        let mut effects: Vec<Box<dyn Effect>> = self
            .fixed_effects
            .iter()
            .map(|e| e.with_values(&e.values()).map_err(CheckError::Model))
            .collect::<Result<_, _>>()?;
        let mut k = self.n_base();
        for a in active {
            let cand = &self.cands[a.c];
            let n = a.dim();
            let phi = a.phi(&cand.neutral, &theta[k..k + n]);
            effects.push(cand.effect.with_values(&phi).map_err(CheckError::Model)?);
            k += n;
        }
        Ok((spec, effects))
    }

    pub(super) fn model(&self, theta: &[f64], active: &[Act]) -> Result<Vec<c64>, CheckError> {
        let (spec, effects) = self.build(theta, active)?;
        predict(&spec, self.layout, &effects)
    }

    pub(super) fn residual(&self, theta: &[f64], active: &[Act]) -> Result<Vec<f64>, CheckError> {
        let m = self.model(theta, active)?;
        let mut r = Vec::with_capacity(2 * self.used.len());
        for (&i, &w) in self.used.iter().zip(&self.weight) {
            let d = (self.y[i] - m[i]) * w;
            r.push(d.re);
            r.push(d.im);
        }
        Ok(r)
    }

    pub(super) fn bounds(&self, active: &[Act]) -> Bounds {
        let nb = self.n_base();
        let mut lower = vec![f64::NEG_INFINITY; nb];
        let mut upper = vec![f64::INFINITY; nb];
        let mut scales = self.baseline.scales.clone();
        if let Some(m) = self.fixed_mass {
            lower[0] = m.ln();
            upper[0] = m.ln();
        }
        for a in active {
            let cand = &self.cands[a.c];
            let infos = cand.effect.parameters();
            for &j in &a.kept {
                lower.push(infos[j].lower);
                upper.push(infos[j].upper);
                scales.push(cand.scales[j]);
            }
        }
        Bounds {
            lower,
            upper,
            scales,
        }
    }

    /// The finite-difference column groups of θ for `active` (with the nominal model's
    /// parameters first when `base`): an effect parameter whose declared reach
    /// ([`Effect::parameter_reach`]) is some channels or excitations changes only the
    /// residual rows of their values; the nominal model's parameters change any row.
    pub(super) fn columns(&self, active: &[Act], base: bool) -> lm::Columns {
        let (nl, n_rch) = (self.layout.n_lines(), self.layout.channel_map.len());
        // The spec channel and excitation of each value used (rows 2k, 2k + 1).
        let cells: Vec<(usize, usize)> = self
            .used
            .iter()
            .map(|&i| {
                (
                    self.layout.channel_map[(i / nl) % n_rch],
                    self.layout.excitation_map[i / (nl * n_rch)],
                )
            })
            .collect();
        let mut rows = vec![None; if base { self.n_base() } else { 0 }];
        for a in active {
            let reach = self.cands[a.c]
                .effect
                .parameter_reach(&self.layout.spec_geometry);
            for &j in &a.kept {
                rows.push(match reach.get(j) {
                    None | Some(Reach::Any) => None,
                    Some(r) => Some(
                        cells
                            .iter()
                            .enumerate()
                            .filter(|(_, &(c, e))| r.reaches(c, e))
                            .flat_map(|(k, _)| [2 * k, 2 * k + 1])
                            .collect(),
                    ),
                });
            }
        }
        lm::Columns::grouped(rows, 2 * self.used.len())
    }

    pub(super) fn fit(
        &self,
        stage: &str,
        theta0: &[f64],
        active: &[Act],
        max_iter: usize,
    ) -> Result<Fit, CheckError> {
        let f = |t: &[f64]| self.residual(t, active);
        let b = self.bounds(active);
        let columns = self.columns(active, true);
        let mut fit = lm::fit_grouped(stage, &f, theta0, &b, max_iter, &columns)?;
        self.zero_fixed(&mut fit.jacobian);
        Ok(fit)
    }

    pub(super) fn zero_fixed(&self, j: &mut DMatrix<f64>) {
        if self.fixed_mass.is_some() {
            j.column_mut(0).fill(0.0);
        }
    }

    /// ‖y‖ in the residual's noise units (√2 |y_i| / σ_i over the lines used).
    pub(super) fn data_norm(&self) -> f64 {
        self.used
            .iter()
            .map(|&i| 2.0 * (self.y[i].norm() / self.sigma[i]).powi(2))
            .sum::<f64>()
            .sqrt()
    }

    pub(super) fn n_real(&self) -> f64 {
        2.0 * self.used.len() as f64
    }

    /// The largest over the FRFs of ‖Ŷ₁ − Ŷ₀‖/‖Ŷ₀‖ over each FRF's values used: the
    /// relative change a prediction makes to some FRF (see `RESOLUTION`).
    pub(super) fn largest_relative_change(&self, m1: &[c64], m0: &[c64]) -> f64 {
        self.largest_relative_change_in_blocks(m1, m0, self.layout.n_lines())
    }

    /// The largest over the excitations of ‖Ŷ₁ − Ŷ₀‖/‖Ŷ₀‖ over all that excitation's
    /// values used: the relative change a prediction makes to some excitation's FRFs
    /// taken together, the scale of the FRF estimator's force-noise error (which
    /// multiplies every channel of an excitation alike).
    pub(super) fn largest_relative_change_by_excitation(&self, m1: &[c64], m0: &[c64]) -> f64 {
        let block = self.layout.channel_map.len() * self.layout.n_lines();
        self.largest_relative_change_in_blocks(m1, m0, block)
    }

    /// The largest over consecutive blocks of `block` values (an FRF, an excitation) of
    /// ‖Ŷ₁ − Ŷ₀‖/‖Ŷ₀‖ over the block's values used.
    fn largest_relative_change_in_blocks(&self, m1: &[c64], m0: &[c64], block: usize) -> f64 {
        let block = block.max(1);
        let mut by_block = vec![(0.0, 0.0); self.y.len().div_ceil(block)];
        for &i in &self.used {
            let e = &mut by_block[i / block];
            e.0 += (m1[i] - m0[i]).norm_sqr();
            e.1 += m0[i].norm_sqr();
        }
        by_block
            .iter()
            .filter(|(_, d)| *d > 0.0)
            .map(|(n, d)| (n / d).sqrt())
            .fold(0.0, f64::max)
    }

    /// RMS over the values used of |Ŷ₁ − Ŷ₀|/σ_p: the change between two predictions in
    /// units of the precision floor `sigma_precision` (values with σ_p = 0, exact zeros
    /// of a model with no rounding to speak of, are left out).
    pub(super) fn change_over_floor(&self, m1: &[c64], m0: &[c64], sigma_precision: &[f64]) -> f64 {
        let (mut s, mut n) = (0.0, 0usize);
        for &i in &self.used {
            if sigma_precision[i] > 0.0 {
                s += ((m1[i] - m0[i]).norm() / sigma_precision[i]).powi(2);
                n += 1;
            }
        }
        if n == 0 {
            return 0.0;
        }
        (s / n as f64).sqrt()
    }
}

/// Orthonormal basis of the column span of `j` (columns normalised first; directions
/// with relative singular value below `tol` dropped) and those singular values
/// ([`ScaledSpan`]).
pub(super) fn span_basis(j: &DMatrix<f64>, tol: f64) -> (DMatrix<f64>, Vec<f64>) {
    let span = ScaledSpan::of(j, tol);
    (span.basis, span.singular_values)
}

/// The thin SVD of a Jacobian with unit columns, `J D⁻¹ = U S Vᵀ` (D the column norms),
/// over the directions whose singular value exceeds a tolerance: U's columns are the
/// orthonormal basis of J's span, and with S, V and D they give J's pseudo-inverse in
/// the scaled coordinates, `J⁺ = D⁻¹ V S⁻¹ Uᵀ` (the screening's chord solver).
pub(super) struct ScaledSpan {
    /// U over the kept directions (n × rank).
    pub(super) basis: DMatrix<f64>,
    /// Their singular values.
    pub(super) singular_values: Vec<f64>,
    /// `D⁻¹ V S⁻¹` over the kept directions (p × rank; a zero column of J a zero row).
    pub(super) pseudo_inverse_right: DMatrix<f64>,
}

impl ScaledSpan {
    pub(super) fn of(j: &DMatrix<f64>, tol: f64) -> Self {
        let mut js = j.clone();
        let mut norms = vec![0.0; js.ncols()];
        for (k, norm) in norms.iter_mut().enumerate() {
            *norm = js.column(k).norm();
            if *norm > 0.0 {
                js.column_mut(k).scale_mut(1.0 / *norm);
            }
        }
        let svd = lm::thin_svd(&js);
        drop(js);
        let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
            unreachable!("lm::thin_svd computes U and Vᵀ")
        };
        let keep: Vec<usize> = (0..svd.singular_values.len())
            .filter(|&k| svd.singular_values[k] > tol)
            .collect();
        let basis = if keep.len() == u.ncols() {
            u
        } else {
            DMatrix::from_fn(u.nrows(), keep.len(), |r, c| u[(r, keep[c])])
        };
        let singular_values: Vec<f64> = keep.iter().map(|&k| svd.singular_values[k]).collect();
        let pseudo_inverse_right = DMatrix::from_fn(norms.len(), keep.len(), |a, c| {
            if norms[a] > 0.0 {
                v_t[(keep[c], a)] / singular_values[c] / norms[a]
            } else {
                0.0
            }
        });
        ScaledSpan {
            basis,
            singular_values,
            pseudo_inverse_right,
        }
    }
}

/// Removes the span of `q` (orthonormal columns) from the columns of `j`: `j − q (qᵀ j)`,
/// `qᵀ j` by [`crate::lm::tr_mul`], the product subtracted in place
/// ([`crate::lm::sub_mul`]). The check's one projection: a Jacobian's columns, a
/// profile's signature and the Wald statistic's change (a vector as an n × 1 matrix).
pub(super) fn project_out(j: &DMatrix<f64>, q: &DMatrix<f64>) -> DMatrix<f64> {
    let mut out = j.clone();
    if q.ncols() > 0 {
        crate::lm::sub_mul(&mut out, q, &crate::lm::tr_mul(q, j));
    }
    out
}

pub(super) fn active_dims(active: &[Act]) -> usize {
    active.iter().map(Act::dim).sum()
}

/// The active effects without the `k`-th.
pub(super) fn without_act(active: &[Act], k: usize) -> Vec<Act> {
    active
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != k)
        .map(|(_, a)| a.clone())
        .collect()
}

/// θ without the parameters of the k-th active effect.
pub(super) fn drop_params(p: &Problem, theta: &[f64], active: &[Act], k: usize) -> Vec<f64> {
    let mut out = theta[..p.n_base()].to_vec();
    let mut off = p.n_base();
    for (i, a) in active.iter().enumerate() {
        let n = a.dim();
        if i != k {
            out.extend_from_slice(&theta[off..off + n]);
        }
        off += n;
    }
    out
}
