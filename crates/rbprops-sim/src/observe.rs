//! The general observation of a model's FRFs: exponential window, finite record,
//! gravity in the sensor equation, transducer high-pass and masses attached during one
//! excitation ([`crate::model::Observation`], [`crate::model::ModelInput::attached_mass`],
//! [`crate::model::ModelInput::attached_stiffness`]).
//!
//! With `s = iω + σ` (σ the window decay, 0 without window), `Z(s) = K + K_a + iD + sC + s²(M + M_a)`
//! (D hysteretic damping, frequency-independent; under a window it is kept as `iD`, the
//! loss a rubber mount shows at the line's frequency)
//! and `x(s) = Z(s)⁻¹ f`, channel c of quantity order k (0 receptance, 1 mobility,
//! 2 accelerance) reads
//!
//! `y_c = h_c(s) [ S_c Y_k(s) + g_c s^{k−2} X(s) + Σ_m ψ_c ψ_e η_{m,k}(s) ]`
//!
//! where `Y_k = s^k x` for an infinite record and, for a record of length T, the finite
//! transform of the impulse response: with `(q_T, v_T)` the state at T after the unit
//! impulse (`exp(A T)` of the first-order form), the free response after T has the
//! transform `Q_T = Z(s)⁻¹[(M + M_a)(s q_T + v_T) + C q_T]`, and
//! `Y_0 = x − e^{−sT} Q_T`, `Y_1 = s x − e^{−sT}(s Q_T − q_T)`,
//! `Y_2 = s² x − e^{−sT}(s² Q_T − s q_T − v_T)` (`X = Y_0`; an extra mode likewise with its
//! scalar state). `h_c = Π sτ/(1 + sτ)` is the high-pass product of channel c.
//! The direct term of the accelerance (`S M⁻¹ f` at t = 0) is inside `s² x`.

use crate::model::{factor_batch, solve_batch, DynamicModel, ModelInput, LINES_PER_SOLVE};
use nalgebra::{SMatrix, SVector, Vector2};
use rbprops_core::{c64, Mat6, Quantity, Vec6};

type Vec6c = nalgebra::Vector6<c64>;

fn cplx6(v: &Vec6) -> Vec6c {
    v.map(|x| c64::new(x, 0.0))
}

/// State `(q, v)` at time T after a unit impulse through `f` (rigid part).
fn rigid_state_at(
    mass: &Mat6,
    stiffness: &Mat6,
    model: &DynamicModel,
    f: &Vec6,
    t: f64,
) -> Result<(Vec6, Vec6), String> {
    let minv = mass
        .try_inverse()
        .ok_or("mass matrix is singular".to_string())?;
    let mut a = SMatrix::<f64, 12, 12>::zeros();
    a.fixed_view_mut::<6, 6>(0, 6).copy_from(&Mat6::identity());
    a.fixed_view_mut::<6, 6>(6, 0)
        .copy_from(&(-minv * stiffness));
    a.fixed_view_mut::<6, 6>(6, 6)
        .copy_from(&(-minv * model.damping));
    let mut x0 = SVector::<f64, 12>::zeros();
    x0.fixed_rows_mut::<6>(6).copy_from(&(minv * f));
    let xt = finite_then(a * t, t)?.exp() * x0;
    if !xt.iter().all(|x| x.is_finite()) {
        return Err(format!("the state at T = {t} s is not finite"));
    }
    Ok((xt.fixed_rows::<6>(0).into(), xt.fixed_rows::<6>(6).into()))
}

/// Scalar state `(η, η̇)` at T of `η̈ + 2ζω η̇ + ω² η = δ(t)`.
fn mode_state_at(wm: f64, zeta: f64, t: f64) -> Result<Vector2<f64>, String> {
    let a = nalgebra::Matrix2::new(0.0, 1.0, -wm * wm, -2.0 * zeta * wm);
    Ok(finite_then(a * t, t)?.exp() * Vector2::new(0.0, 1.0))
}

/// Largest 1-norm of `A·T` handed to the matrix exponential: its tenth power stays
/// far below overflow (1e150), so the squaring count (≈ log₂ of the norm, 50 here) is
/// finite. A physical state matrix over a record is ω T ≲ 1e6.
const MAX_STATE_NORM: f64 = 1e15;

/// `A·T`, refused when an entry is not finite or its norm exceeds [`MAX_STATE_NORM`]:
/// nalgebra's matrix exponential (scaling and squaring) never returns for such a matrix
/// (a power overflows, and the squaring count `ceil(log₂ ∞)` saturates to u64::MAX), so
/// a fit that strays to such a state must get an error, not a hung evaluation (seen: a
/// record-truncation refit stuck for minutes on a stray stiffness).
fn finite_then<const N: usize>(
    at: nalgebra::SMatrix<f64, N, N>,
    t: f64,
) -> Result<nalgebra::SMatrix<f64, N, N>, String> {
    if !at.iter().all(|x| x.is_finite()) {
        return Err(format!("the state matrix over T = {t} s is not finite"));
    }
    let norm = at.column_iter().map(|c| c.abs().sum()).fold(0.0, f64::max);
    if norm > MAX_STATE_NORM {
        return Err(format!(
            "the state matrix over T = {t} s is too large to integrate (1-norm {norm:.3e})"
        ));
    }
    Ok(at)
}

/// `Y_k` from the untruncated transform `x` and, when truncated, the tail transform
/// `qt` with the state `(q0, v0)` at T and `e = e^{−sT}`.
fn derivative_transform<T>(k: i32, s: c64, x: T, tail: Option<(T, T, T, c64)>) -> T
where
    T: Clone
        + std::ops::Mul<c64, Output = T>
        + std::ops::Sub<T, Output = T>
        + std::ops::Add<T, Output = T>,
{
    let full = match k {
        0 => x,
        1 => x * s,
        _ => x * (s * s),
    };
    match tail {
        None => full,
        Some((qt, q0, v0, e)) => {
            let t = match k {
                0 => qt,
                1 => qt * s - q0,
                _ => qt * (s * s) - q0 * s - v0,
            };
            full - t * e
        }
    }
}

/// Observed FRFs of one input, `[channel][line]`, in `quantity` (see the module docs).
pub fn observed_block(
    model: &DynamicModel,
    input: &ModelInput,
    omegas: &[f64],
    quantity: Quantity,
    out: &mut [c64],
) -> Result<(), String> {
    let obs = &model.observation;
    let nl = omegas.len();
    let n_ch = model.outputs.len();
    let k = quantity.order();
    let mass = model.mass + input.attached_mass;
    let stiffness = model.stiffness + input.attached_stiffness;
    let f = input.column;
    let e = input.excitation;
    let sigma = obs.window_decay_per_s;
    if obs.record_length_s.is_some() && model.structural_damping != Mat6::zeros() {
        return Err(
            "a finite record needs the impulse response, and hysteretic damping has none: \
             record_truncation cannot be combined with hysteretic_damping"
                .into(),
        );
    }
    let rigid_tail = match obs.record_length_s {
        Some(t) => Some((t, rigid_state_at(&mass, &stiffness, model, &f, t)?)),
        None => None,
    };
    let mode_tails: Vec<Option<Vector2<f64>>> = model
        .extra_modes
        .iter()
        .map(|m| {
            obs.record_length_s
                .map(|t| mode_state_at(std::f64::consts::TAU * m.frequency_hz, m.damping_ratio, t))
                .transpose()
        })
        .collect::<Result<_, _>>()?;
    let rows: Vec<Vec6c> = model
        .outputs
        .iter()
        .map(|r| cplx6(&r.transpose()))
        .collect();
    let grows: Vec<Vec6c> = obs
        .gravity_rows
        .iter()
        .map(|r| cplx6(&r.transpose()))
        .collect();
    let (xs, qts) = responses(&mass, &stiffness, model, &f, omegas, sigma, &rigid_tail)?;
    for (l, &w) in omegas.iter().enumerate() {
        let s = c64::new(sigma, w);
        let x = xs[l];
        let tail = match (&rigid_tail, qts.get(l)) {
            (Some((t, (q0, v0))), Some(&qt)) => Some((qt, cplx6(q0), cplx6(v0), (-s * *t).exp())),
            _ => None,
        };
        let yk = derivative_transform(k, s, x, tail);
        let disp = if grows.is_empty() {
            None
        } else {
            let x0 = derivative_transform(0, s, x, tail);
            if k < 2 && s.norm() == 0.0 {
                return Err(
                    "gravity in the sensor equation makes a receptance or mobility infinite at 0 Hz: \
                     start the band above 0 Hz or simulate accelerance"
                        .into(),
                );
            }
            Some(x0 * s.powi(k - 2))
        };
        for c in 0..n_ch {
            let mut y = rows[c].dot(&yk);
            if let Some(d) = &disp {
                y += grows[c].dot(d);
            }
            for (m, st) in model.extra_modes.iter().zip(&mode_tails) {
                let wm = std::f64::consts::TAU * m.frequency_hz;
                let den = s * s + s * (2.0 * m.damping_ratio * wm) + wm * wm;
                let eta = c64::new(1.0, 0.0) / den;
                let tail = st.map(|st| {
                    let qt = (s * st[0] + st[1] + 2.0 * m.damping_ratio * wm * st[0]) / den;
                    let t = obs.record_length_s.unwrap_or(0.0);
                    (
                        qt,
                        c64::new(st[0], 0.0),
                        c64::new(st[1], 0.0),
                        (-s * t).exp(),
                    )
                });
                y += derivative_transform(k, s, eta, tail)
                    * (m.at_channels[c] * m.at_excitations[e]);
            }
            if let Some(taus) = obs.highpass_time_constants_s.get(c) {
                for &tau in taus {
                    y *= s * tau / (s * tau + 1.0);
                }
            }
            out[c * nl + l] = y;
        }
    }
    Ok(())
}

/// `x = Z(s)⁻¹ f` on every line (`s = σ + iω`) and, for a finite record (`rigid_tail`:
/// T and the state at T), the tail transform `Q_T = Z(s)⁻¹[(M + M_a)(s q_T + v_T) + C q_T]`
/// (empty without one), by the batched LU of [`crate::model::LinesLu`] (one factorisation per line
/// for both). A line whose Z is singular to working precision (see
/// [`crate::model::solve_columns`]) is an error naming its frequency.
fn responses(
    mass: &Mat6,
    stiffness: &Mat6,
    model: &DynamicModel,
    f: &Vec6,
    omegas: &[f64],
    sigma: f64,
    rigid_tail: &Option<(f64, (Vec6, Vec6))>,
) -> Result<(Vec<Vec6c>, Vec<Vec6c>), String> {
    const L: usize = LINES_PER_SOLVE;
    let fc: [c64; 6] = std::array::from_fn(|i| c64::new(f[i], 0.0));
    let mut xs = Vec::with_capacity(omegas.len());
    let mut qts = Vec::with_capacity(if rigid_tail.is_some() {
        omegas.len()
    } else {
        0
    });
    // The tail's right-hand side `(M + M_a) q_T s + ((M + M_a) v_T + C q_T)` per line.
    let tail_parts = rigid_tail
        .as_ref()
        .map(|(_, (q0, v0))| (mass * q0, mass * v0 + model.damping * q0));
    for batch in omegas.chunks(L) {
        let s: [c64; L] = std::array::from_fn(|l| c64::new(sigma, batch[l.min(batch.len() - 1)]));
        let lu = factor_batch(
            mass,
            stiffness,
            &model.damping,
            &model.structural_damping,
            &s,
        );
        let x = solve_batch(&lu, &[fc; L]);
        let qt = tail_parts.as_ref().map(|(mq, static_part)| {
            let rhs: [[c64; 6]; L] = std::array::from_fn(|l| {
                std::array::from_fn(|i| c64::new(mq[i], 0.0) * s[l] + c64::new(static_part[i], 0.0))
            });
            solve_batch(&lu, &rhs)
        });
        for l in 0..batch.len() {
            let finite = |v: &[c64; 6]| v.iter().all(|v| v.re.is_finite() && v.im.is_finite());
            if !(lu.regular[l] && finite(&x[l]) && qt.as_ref().is_none_or(|q| finite(&q[l]))) {
                return Err(format!(
                    "dynamic stiffness is singular at {:.6} Hz (s = {})",
                    batch[l] / std::f64::consts::TAU,
                    s[l]
                ));
            }
            xs.push(Vec6c::from_row_slice(&x[l]));
            if let Some(q) = &qt {
                qts.push(Vec6c::from_row_slice(&q[l]));
            }
        }
    }
    Ok((xs, qts))
}

#[cfg(test)]
mod exponential_tests {
    use super::mode_state_at;

    /// A non-finite state matrix is an error: nalgebra's exponential of such a matrix
    /// never returns (a model check's profile once hung there for half an hour).
    #[test]
    fn a_non_finite_state_is_an_error_not_a_hang() {
        for (wm, zeta, t) in [
            (f64::NAN, 0.01, 1.0),
            (f64::INFINITY, 0.01, 1.0),
            (10.0, 0.01, f64::INFINITY),
        ] {
            let e = mode_state_at(wm, zeta, t).unwrap_err();
            assert!(e.contains("not finite"), "{e}");
        }
        // Finite but huge (ω² T = 1e40): its powers overflow inside the exponential.
        let e = mode_state_at(1e20, 0.01, 1.0).unwrap_err();
        assert!(e.contains("too large"), "{e}");
        // A finite one is the impulse response: η(T) = e^{−ζωT} sin(ω_d T)/ω_d.
        let (wm, zeta, t): (f64, f64, f64) = (10.0, 0.02, 0.7);
        let wd = wm * (1.0 - zeta * zeta).sqrt();
        let x = mode_state_at(wm, zeta, t).unwrap();
        let expect = (-zeta * wm * t).exp() * (wd * t).sin() / wd;
        assert!((x[0] - expect).abs() < 1e-12, "{} vs {expect}", x[0]);
    }
}
