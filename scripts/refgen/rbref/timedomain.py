"""The realistic FRF estimation route: impacts, time histories, FFT, H1 and coherence.

What it models, per excitation:
  - n impacts, each a half-sine force pulse f(t) = A_i sin(πt/T_p) on [0, T_p], with
    amplitude A_i = A (1 + jitter·n_i) (n_i standard normal);
  - the response of every channel, in the case's quantity, by exact modal superposition of
    the pole–residue model (rigid poles, free P/s² terms, elastic modes): each pole
    contributes ρ_r λ_r^k ∫ e^{λ_r (t − u)} f(u) du in closed form, plus the direct terms
    of s^k/(s − λ) (the sum of residues and of ρλ: the instantaneous response of an
    accelerometer to the force), and P ∫∫f for the free directions;
  - sampling at f_s over a record T = N/f_s starting at the impact (no pre-trigger), with
    NO anti-alias filter: force and response alias alike, which leaves a relative error of
    about Σ_m≥1 |F(m f_s ± f)|/|F(f)| ≈ (2 f_s T_p)⁻² in H1 (choose f_s T_p ≫ 1);
  - optional exponential window e^{−t/τ} on force AND response (so H1 → H(iω + 1/τ)
    exactly, up to aliasing and the record's truncation e^{−T/τ}), clipping of the response
    at ±clip_response (a saturated channel), white Gaussian noise on the sampled force
    (σ = force_noise, N) and response (σ = response_noise, in the quantity's unit);
  - DFT of each record, H1 = Σ_i F̄_i Y_i / Σ_i |F_i|², coherence
    γ² = |Σ F̄ Y|² / (Σ|F|² Σ|Y|²), on the bins k f_s/N inside [start_hz, stop_hz].
Hysteretic damping has no time-domain model and is refused here. Random numbers come
from numpy.random.default_rng(seed), drawn per excitation in a fixed order.
"""
import numpy as np

from .case import QUANTITY_ORDER


def _pole_response(lam, t, amp, tp):
    """∫_0^{min(t,T_p)} e^{λ(t−u)} amp sin(Ωu) du, Ω = π/T_p, for poles lam (N,), times t (L,)."""
    om = np.pi / tp
    lam = lam[:, None]
    den = lam * lam + om * om
    during = t[None, :] <= tp
    tt = np.minimum(t, tp)[None, :]
    inside = (-lam * np.sin(om * tt) - om * np.cos(om * tt) + om * np.exp(lam * tt)) / den
    after = om * (np.exp(lam * (t[None, :] - tp)) + np.exp(lam * t[None, :])) / den
    return amp * np.where(during, inside, after)


def _pulse(t, tp, deriv=0):
    """The unit half-sine, its derivative (deriv = 1) or its first/second integrals (−1, −2)."""
    om = np.pi / tp
    on = (t >= 0) & (t <= tp)
    if deriv == 0:
        return np.where(on, np.sin(om * np.minimum(t, tp)), 0.0)
    if deriv == 1:
        return np.where(on, om * np.cos(om * np.minimum(t, tp)), 0.0)
    if deriv == -1:
        return np.where(t <= tp, (1 - np.cos(om * np.minimum(t, tp))) / om, 2.0 / om)
    return np.where(t <= tp, t / om - np.sin(om * np.minimum(t, tp)) / om ** 2, (2 * t - tp) / om)


def responses(poles, lres, rres, free, extra, k, t, tp):
    """Noise-free response histories (n_ch, L) of one excitation to the unit half-sine."""
    lam = np.concatenate([poles, np.array([m for m, _ in extra], complex)])
    res = np.concatenate([lres * rres[:, 0][None, :]] + [r for _, r in extra], axis=1) if extra \
        else lres * rres[:, 0][None, :]
    conv = _pole_response(lam, t, 1.0, tp)                   # (N, L)
    y = (res * lam[None, :] ** k) @ conv                      # (n_ch, L)
    free = free[:, 0]
    if k == 0:
        y = y + free[:, None] * _pulse(t, tp, -2)[None, :]
    elif k == 1:
        y = y + (res.sum(axis=1))[:, None] * _pulse(t, tp)[None, :]
        y = y + free[:, None] * _pulse(t, tp, -1)[None, :]
    else:
        y = y + (res.sum(axis=1))[:, None] * _pulse(t, tp, 1)[None, :]
        y = y + (res * lam[None, :]).sum(axis=1)[:, None] * _pulse(t, tp)[None, :]
        y = y + free[:, None] * _pulse(t, tp)[None, :]
    return y.real


def measure(case, terms):
    """(frequency_hz, H1[e, c, l], coherence[e, c, l]) by the time-history route."""
    tm = case.time
    if case.record_s:
        raise ValueError("window.record_s: the time route's record is time.record_s")
    if any(max(s["element_losses"], default=0) > 0 for s in case.setups):
        raise ValueError("time: hysteretic damping (loss_factor) has no time-domain model")
    fs, tp = tm["sample_rate_hz"], tm["pulse_s"]
    n = int(round(tm["record_s"] * fs))
    if n < 8:
        raise ValueError("time: record_s × sample_rate_hz gives fewer than 8 samples")
    t = np.arange(n) / fs
    freq = np.fft.rfftfreq(n, 1.0 / fs)
    keep = (freq >= case.f_start - 1e-12) & (freq <= case.f_stop + 1e-12)
    if keep.sum() < 2:
        raise ValueError("time: fewer than 2 FFT bins fall inside [start_hz, stop_hz]")
    k = QUANTITY_ORDER[case.quantity]
    win = np.exp(-t / case.window_tau) if case.window_tau > 0 else np.ones(n)
    rng = np.random.default_rng(case.seed)
    n_ch = len(case.channels)
    h1 = np.empty((len(case.excitations), n_ch, keep.sum()), complex)
    coh = np.empty(h1.shape)
    force_unit = _pulse(t, tp)
    if any(c["highpass_s"] or c["delay_s"] for c in case.channels) or any(e["delay_s"] for e in case.excitations):
        raise ValueError("time: highpass_s and delays are modelled in the frequency route only")
    if terms.gravity_exc and k != 2:
        raise ValueError("time: sensor_gravity is modelled for accelerance only in the time route")
    for ei, (poles, a, b, p, extra) in enumerate(terms.per_exc):
        y_unit = responses(poles, a, b, p, extra, k, t, tp)
        if terms.gravity_exc:
            ag, pg = terms.gravity_exc[ei]
            y_unit = y_unit + responses(poles, ag, b, pg, [], 0, t, tp)
        sff = np.zeros(keep.sum())
        syy = np.zeros((n_ch, keep.sum()))
        sfy = np.zeros((n_ch, keep.sum()), complex)
        for _ in range(tm["impacts"]):
            amp = tm["amplitude_n"] * (1.0 + tm["amplitude_jitter"] * rng.standard_normal())
            f = amp * force_unit + tm["force_noise"] * rng.standard_normal(n)
            y = amp * y_unit + tm["response_noise"] * rng.standard_normal((n_ch, n))
            if tm["clip_response"] > 0:
                y = np.clip(y, -tm["clip_response"], tm["clip_response"])
            ff = np.fft.rfft(f * win)[keep]
            yy = np.fft.rfft(y * win[None, :], axis=1)[:, keep]
            sff += np.abs(ff) ** 2
            syy += np.abs(yy) ** 2
            sfy += np.conj(ff)[None, :] * yy
        h1[ei] = sfy / sff[None, :]
        coh[ei] = np.abs(sfy) ** 2 / (sff[None, :] * syy)
    return freq[keep], h1, coh
