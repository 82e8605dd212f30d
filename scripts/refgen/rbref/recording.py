"""Recorded impact tests: the time histories themselves, with the defects real tests have,
and the generator's own H1 from exactly the samples written.

What it models, per excitation (one measurement run):
  - n hits, each in its own segment of S = N + G samples (N = record_s·f_s the record,
    G = gap_s·f_s a gap after it); hit i's record is samples [iS, iS + N) of the run's
    continuous stream. Every hit starts from rest (the tester waited for the body to come
    to rest): the segment holds that hit's response only, continued through the gap, and
    the next segment starts again from rest, so the stream has a step where the previous
    tail is cut (at the start of the next pretrigger; it is the tail's size at t = N + G).
    With carry_over = true the run is instead the exact superposition of all its hits:
    each segment also holds the tails of the hits before it (carried as modal
    coefficients K e^{λ(t − t_seg)} from segment to segment), as a real continuous
    recording would; the records then start with the previous hits' residual motion.
    Either way the per-hit layout and the throughput layout carry the very same samples.
  - the first pulse starts pretrigger_s (rounded to whole samples, P) after the record's
    start, plus u/f_s with u uniform in [0, 1) when subsample_onset = true (else u = 0):
    onset o = P + u samples; the trigger sample is ⌈o⌉ (the first sample at or after the
    onset);
  - a half-sine force A_i sin(π(t − t_on)/T_p) on [t_on, t_on + T_p], A_i = A(1 + jitter·n_i);
    a double hit adds a second half-sine ratio·A_i, delay_s after the first (its pulse may
    overlap the first when delay_s < pulse_s);
  - responses by exact modal superposition (the closed forms of timedomain.responses,
    shifted to each pulse's onset, zero before it; Grid, unit_response);
  - optional anti-alias filter (anti_alias_order n, anti_alias_cutoff_hz): a Butterworth
    low-pass applied in closed form to force and responses alike (unit_response: the
    residues of H_aa·H at the structure's and the filter's poles, each convolved with the
    pulse exactly), so the only error of H1 against the FRF is the aliasing the filter
    leaves, Σ_m≠0 |H_aa F|(f + m f_s)/|H_aa F|(f) (the bound the tests check). Without
    it the samples alias as they are, ≈ 4ζ(2)(2 f_s T_p)⁻² relative: choose f_s·T_p ≫ 1;
  - analogue clipping at ±clip_response (as in the time route), then white noise
    (force_noise N, response_noise in the quantity's unit) on every sample of the stream;
  - ADC (adc_bits = 16 or 24; 0 = none, the samples stay float64): per excitation and
    channel (force included) an autoranged range R = 2^(b−1)·q, q the smallest step of the
    1-2-5 series (m·10^e, m ∈ {1, 2, 5}) with R ≥ adc_headroom × the clean peak of that
    channel over the run's hits; code = clamp(rint(x/q), −2^(b−1), 2^(b−1) − 1), sample =
    code·q computed as (code·m)/10^(−e), the float64 nearest the exact decimal, which has
    at most 8 significant digits: the UFF ASCII form (%20.11e) and binary both carry it
    exactly. A sample at −2^(b−1)·q or (2^(b−1) − 1)·q is "at the range" (clipped).
  - forced clipping: `clip = [{excitation, channel, hits, peak_over_range}]` scales the
    listed hits' amplitude so the channel's clean peak is peak_over_range × R on them (the
    tester hit harder), R from the hits forced nowhere (autorange as above);
  - random forced peaks (clip_probability p, clip_peak_over_range [lo, hi]): a hit not
    forced by `clip` is, with probability p, forced on a channel drawn uniformly among
    the force and the responses, at a peak over range uniform in [lo, hi] (lo < 1 gives
    near misses on that channel). A channel with forced hits (from `clip` or at random)
    takes its range from the hits forced nowhere; a channel without forced hits
    autoranges over all hits, so it never clips. A hit forced on one channel (hit harder)
    can therefore also clip another channel that has forced hits of its own: the truth
    counts what is in the data, always (`clipped_samples`), and names the channel the hit
    was forced on (`forced_clip_channel`).
Random numbers: numpy.random.default_rng(seed); per excitation, uniform draws (hits, 8)
then the amplitudes' standard normals (hits) replacing column 0; per hit the columns are
(amplitude, onset u, double-hit probability, delay, ratio, clip probability, clip channel,
clip peak) — drawn whatever the options, so one option does not move the others' draws;
then per hit the force noise (S) and the response noise (n_ch, S).

H1 (numpy, from the samples as written): per accepted hit, F = rfft(f·w_f), Y = rfft(y·w),
H1 = Σ F̄Y/Σ|F|², γ² = |Σ F̄Y|²/(Σ|F|² Σ|Y|²), on the bins k f_s/N in [start_hz, stop_hz].
Response window w[n] = 1 for n < n₀ (the trigger sample), e^{−(n − n₀)/(f_s τ)} from n₀
(τ = window.tau_s; none: w = 1). Force window w_f = rect·(w if window.apply_to_force,
default true, else 1), rect = 1 on samples [n₀ − round(force_pre_s f_s), n_end +
round(force_post_s f_s)] clamped to the record (n_end = ⌊end of the hit's last pulse·f_s⌋,
force_pre_s defaults to the whole pretrigger), no rectangle when force_post_s is not given.
Hits the truth marks as double or clipped (≥ 2 samples at the range on any channel) are
left out by default (time.reject).
"""
import math

import numpy as np

from .case import QUANTITY_ORDER

GRID = (1, 2, 5)


def butterworth(order, cutoff_hz):
    """Poles p_j and residues c_j of the unit-DC-gain Butterworth low-pass
    H_aa(s) = Π(−p_j)/Π(s − p_j) = Σ c_j/(s − p_j)."""
    wc = 2 * np.pi * cutoff_hz
    j = np.arange(1, order + 1)
    p = wc * np.exp(1j * np.pi * (2 * j + order - 1) / (2 * order))
    gain = np.prod(-p)
    c = np.array([gain / np.prod([p[i] - p[l] for l in range(order) if l != i]) for i in range(order)])
    return p, c


class Grid:
    """Sample times n/f_s (n < L) and E[r, m] = e^{λ_r m/f_s} for the poles of one
    excitation: a pulse starting at onset o (in samples) has e^{λ(t − t_on)} =
    E[r, n − ⌈o⌉]·e^{λ(⌈o⌉ − o)/f_s}, so the exponentials are computed once per run and
    never with a large argument."""

    def __init__(self, lam, fs, length):
        self.lam, self.fs, self.n = lam, fs, length
        self.et = np.exp((np.arange(length) / fs)[:, None] * lam[None, :])   # E transposed: row slices contiguous

    def conv(self, resk, o, tp, carry=None):
        """Re Σ_r resk[c, r] ∫ e^{λ_r(t − u)} sin(Ω(u − t_on)) du over the pulse's support
        (the closed forms of timedomain._pole_response), on the grid; zero before the
        onset o (samples). (n_ch, L). With `carry` (a list), appends K (n_ch, n_poles),
        the continuation past the grid: sample L + m gets Re Σ_r K[c, r] E[r, m]."""
        lam, fs = self.lam, self.fs
        om = np.pi / tp
        den = lam * lam + om * om
        out = np.zeros((resk.shape[0], self.n))
        n1 = int(math.ceil(o - 1e-12))
        o_end = o + tp * fs
        n2 = min(int(math.floor(o_end + 1e-12)), self.n - 1)        # last sample with t ≤ t_on + T_p
        if n1 <= n2:
            tt = (np.arange(n1, n2 + 1) - o) / fs
            tt = np.clip(tt, 0.0, tp)
            inside = (-lam[:, None] * np.sin(om * tt)[None, :] - om * np.cos(om * tt)[None, :]
                      + om * np.exp(lam[:, None] * tt[None, :])) / den[:, None]
            out[:, n1:n2 + 1] = np.einsum("cr,rl->cl", resk, inside).real
        m1 = n2 + 1
        if m1 < self.n:
            # after the pulse: Ω (e^{λ(t − T_p)} + e^{λ t})/den, t from the onset
            a = resk * (om / den * np.exp(lam * (m1 - o_end) / fs))[None, :]
            b = resk * (om / den * np.exp(lam * (n1 - o) / fs))[None, :]
            # einsum without BLAS: small products, and the same bits whatever the BLAS threads
            out[:, m1:] = (np.einsum("lr,cr->cl", self.et[:self.n - m1], a)
                           + np.einsum("lr,cr->cl", self.et[m1 - n1:self.n - n1], b)).real
        if carry is not None:
            if m1 >= self.n:
                raise ValueError("time: a pulse runs past the segment's end")
            carry.append(resk * (om / den * (np.exp(lam * (self.n - o_end) / fs)
                                             + np.exp(lam * (self.n - o) / fs)))[None, :])
        return out

    def tail(self, k):
        """Re Σ_r K[c, r] E[r, m] over the grid (m < L): a carried continuation."""
        return np.einsum("lr,cr->cl", self.et, k).real


def _pulse_deriv(t, tp, deriv):
    from .timedomain import _pulse as tp_pulse
    return np.where(t >= 0, tp_pulse(np.where(t >= 0, t, 0.0), tp, deriv), 0.0)


def unit_response(terms_e, k, grid, o, tp, aa=None, grid_f=None, carry=None):
    """Response (n_ch, L) of one excitation's terms (poles, a, b, p, extra) to a unit
    half-sine with onset o (samples). Without a filter: Σ_r ρ_r λ_r^k conv_λr plus the
    direct terms of s^k/(s − λ) and the free P/s² term (as timedomain.responses). With
    the anti-alias filter H_aa = Σ c_j/(s − p_j): the residues of H_aa(s)H(s) are
    ρ_r λ_r^k H_aa(λ_r) at the structure's poles and c_j H(p_j) at the filter's (H(p_j)
    with its direct and free terms; exact when H_aa H is strictly proper with simple
    poles: for accelerance, and for any quantity without free directions), each
    convolved with the pulse in closed form. `carry` (a dict of lists "g", "f"): the
    continuations past the grid (Grid.conv) of the structure's and the filter's poles; the
    direct terms vanish after the pulse, and free directions (whose terms do not) are
    refused by the caller for k < 2."""
    poles, a, b, p, extra = terms_e
    cg = carry["g"] if carry is not None else None
    cf = carry["f"] if carry is not None else None
    lam = np.concatenate([poles, np.array([m for m, _ in extra], complex)])
    res = np.concatenate([a * b[:, 0][None, :]] + [r for _, r in extra], axis=1) if extra \
        else a * b[:, 0][None, :]
    if aa is None:
        y = grid.conv(res * (lam ** k)[None, :], o, tp, cg)
        t = (np.arange(grid.n) - o) / grid.fs
        free = p[:, 0]
        if k == 0:
            y += free[:, None] * _pulse_deriv(t, tp, -2)[None, :]
        elif k == 1:
            y += res.sum(axis=1).real[:, None] * _pulse_deriv(t, tp, 0)[None, :]
            y += free[:, None] * _pulse_deriv(t, tp, -1)[None, :]
        else:
            y += res.sum(axis=1).real[:, None] * _pulse_deriv(t, tp, 1)[None, :]
            y += (res * lam[None, :]).sum(axis=1).real[:, None] * _pulse_deriv(t, tp, 0)[None, :]
            y += free[:, None] * _pulse_deriv(t, tp, 0)[None, :]
        return y
    from .dynamics import evaluate
    fp, fc = aa
    haa = (fc[None, :] / (lam[:, None] - fp[None, :])).sum(axis=1)
    hp = evaluate(poles, a, b, p, extra, fp)[0] * fp[None, :] ** k          # (n_ch, n_f)
    return grid.conv(res * (lam ** k * haa)[None, :], o, tp, cg) + grid_f.conv(hp * fc[None, :], o, tp, cf)


def _pulse(t, tp):
    on = (t >= 0) & (t <= tp)
    return np.where(on, np.sin(np.pi / tp * np.clip(t, 0.0, tp)), 0.0)


def adc_step(peak, bits, headroom):
    """(m, e) of the smallest q = m·10^e (m ∈ 1, 2, 5) with 2^(b−1) q ≥ headroom·peak."""
    need = headroom * max(peak, 1e-300) / 2.0 ** (bits - 1)
    e = math.floor(math.log10(need)) - 1
    while True:
        for m in GRID:
            if m * 10.0 ** e >= need * (1 - 1e-15):
                return m, e
        e += 1


def step_value(m, e):
    return m / 10.0 ** (-e) if e < 0 else float(m * 10 ** e)


def quantise(x, m, e, bits):
    """(samples, at-range mask) of x through the ADC with step m·10^e."""
    q = step_value(m, e)
    lo, hi = -(2 ** (bits - 1)), 2 ** (bits - 1) - 1
    code = np.clip(np.rint(x / q), lo, hi)
    rail = (code == lo) | (code == hi)
    val = (code * m) / 10.0 ** (-e) if e < 0 else code * (m * 10.0 ** e)
    return val, rail


class Recording:
    """fs, n_record (N), n_segment (S), pretrigger samples, channel ids; per excitation:
    force[h, S], response[h, c, S] (the written samples of each hit's segment), at_range
    masks, ranges, and the truth dict."""


def _time_params(case):
    tm = case.time
    fs = tm["sample_rate_hz"]
    n = int(round(tm["record_s"] * fs))
    pre = int(round(tm["pretrigger_s"] * fs))
    gap = int(round(tm["gap_s"] * fs)) if tm["gap_s"] is not None else int(math.ceil(1.25 * n))
    return fs, n, pre, gap


def record(case, terms):
    tm = case.time
    if case.record_s:
        raise ValueError("window.record_s: the time route's record is time.record_s")
    if any(max(s["element_losses"], default=0) > 0 for s in case.setups):
        raise ValueError("time: hysteretic damping (loss_factor) has no time-domain model")
    if any(c["highpass_s"] or c["delay_s"] for c in case.channels) or any(e["delay_s"] for e in case.excitations):
        raise ValueError("time: highpass_s and delays are modelled in the frequency route only")
    k = QUANTITY_ORDER[case.quantity]
    if terms.gravity_exc and k != 2:
        raise ValueError("time: sensor_gravity is modelled for accelerance only in the time route")
    fs, n, pre, gap = _time_params(case)
    tp = tm["pulse_s"]
    if n < 8:
        raise ValueError("time: record_s × sample_rate_hz gives fewer than 8 samples")
    if pre >= n:
        raise ValueError(f"time.pretrigger_s: {tm['pretrigger_s']} s is not inside the record ({tm['record_s']} s)")
    seg = n + gap
    nh = tm["impacts"]
    bits = tm["adc_bits"]
    n_ch = len(case.channels)
    ch_ids = [c["id"] for c in case.channels]
    ex_ids = [e["id"] for e in case.excitations]
    # explicit double hits and forced clips, per excitation
    dbl = {}
    for i, d in enumerate(tm["double"]):
        for h in d["hits"]:
            if (d["excitation"], h) in dbl:
                raise ValueError(f"time.double[{i}].hits: hit {h} of {d['excitation']} is already a double hit")
            dbl[(d["excitation"], h)] = (d["delay_s"], d["ratio"])
    clips = {}
    for i, c in enumerate(tm["clip"]):
        if bits == 0:
            raise ValueError(f"time.clip[{i}]: forced clipping needs an ADC (time.adc_bits = 16 or 24)")
        if len(c["hits"]) >= nh:
            raise ValueError(f"time.clip[{i}].hits: at least one hit must not clip (its peak sets the range)")
        clips.setdefault(c["excitation"], []).append((i, c))
    lo_d, hi_d = tm["double_delay_s"]
    lo_r, hi_r = tm["double_ratio"]
    t_seg = np.arange(seg) / fs
    carry_over = tm["carry_over"]
    k_free = [pe[3] for pe in terms.per_exc] + [pg for _, pg in terms.gravity_exc]
    if carry_over and (k < 2 or terms.gravity_exc) and any(np.any(x != 0) for x in k_free):
        raise ValueError("time.carry_over: free directions carry a growing term from hit to hit: "
                         "modelled for accelerance without sensor_gravity only")
    aa = None
    if tm["anti_alias_order"]:
        if tm["anti_alias_cutoff_hz"] >= fs / 2:
            raise ValueError(f"time.anti_alias_cutoff_hz: {tm['anti_alias_cutoff_hz']} Hz is not below "
                             f"f_s/2 = {fs / 2} Hz")
        aa = butterworth(tm["anti_alias_order"], tm["anti_alias_cutoff_hz"])
        if k < 2 and any(np.any(pe[3] != 0) for pe in terms.per_exc):
            raise ValueError("time.anti_alias_order: the filter with free directions is modelled for "
                             "accelerance only")
        if terms.gravity_exc and any(np.any(pg != 0) for _, pg in terms.gravity_exc):
            raise ValueError("time.anti_alias_order: sensor_gravity with free directions is not modelled")
    rng = np.random.default_rng(case.seed)
    rec = Recording()
    rec.fs, rec.n_record, rec.n_segment, rec.pretrigger, rec.gap = fs, n, seg, pre, gap
    rec.channel_ids, rec.bits = ch_ids, bits
    rec.force, rec.response, rec.rail_force, rec.rail_response = [], [], [], []
    truth_ex = []
    for ei, (poles, a, b, p, extra) in enumerate(terms.per_exc):
        eid = ex_ids[ei]
        draws = rng.random((nh, 8))
        draws[:, 0] = rng.standard_normal(nh)  # amplitudes from their own normal draws
        hits = []
        for h in range(nh):
            z, u, pd, dd, dr = draws[h, :5]
            amp = tm["amplitude_n"] * (1.0 + tm["amplitude_jitter"] * z)
            onset = pre + (u if tm["subsample_onset"] else 0.0)     # samples
            double = None
            if (eid, h + 1) in dbl:
                double = dbl[(eid, h + 1)]
            elif tm["double_probability"] > 0 and pd < tm["double_probability"]:
                double = (lo_d + (hi_d - lo_d) * dd, lo_r + (hi_r - lo_r) * dr)
            pulses = [(onset, 1.0)] + ([(onset + double[0] * fs, double[1])] if double else [])
            end = max(o for o, _ in pulses) + tp * fs
            if end >= n:
                raise ValueError(f"time: hit {h + 1} of {eid}: its pulse ends after the record "
                                 f"(pretrigger + delay + pulse_s ≥ record_s)")
            hits.append(dict(amp=amp, onset=onset, double=double, pulses=pulses, end=end))
        # unit-amplitude clean signals of each hit's segment
        grid = Grid(np.concatenate([poles, np.array([m for m, _ in extra], complex)]), fs, seg)
        grid_f = Grid(aa[0], fs, seg) if aa is not None else None
        f_unit = np.zeros((nh, seg))
        y_unit = np.zeros((nh, n_ch, seg))
        carries = []      # per hit: (K_structure, K_filter, K_force) of unit amplitude, or None
        for h, hit in enumerate(hits):
            kg = kf = kff = 0.0
            for o, r in hit["pulses"]:
                cr = {"g": [], "f": []} if carry_over else None
                fl = [] if carry_over else None
                if aa is None:
                    f_unit[h] += r * _pulse(t_seg - o / fs, tp)
                else:
                    f_unit[h] += r * grid_f.conv(aa[1][None, :], o, tp, fl)[0]
                y = unit_response((poles, a, b, p, extra), k, grid, o, tp, aa, grid_f, cr)
                if terms.gravity_exc:
                    ag, pg = terms.gravity_exc[ei]
                    y = y + unit_response((poles, ag, b, pg, []), 0, grid, o, tp, aa, grid_f, cr)
                y_unit[h] += r * y
                if carry_over:
                    kg = kg + r * sum(cr["g"])
                    kf = kf + r * sum(cr["f"]) if cr["f"] else kf
                    kff = kff + r * fl[0] if fl else kff
            carries.append((kg, kf, kff))
        upeak_f = np.abs(f_unit[:, :n]).max(axis=1)                 # (nh,) over the record
        upeak_y = np.abs(y_unit[:, :, :n]).max(axis=2)              # (nh, n_ch)
        amps = np.array([hit["amp"] for hit in hits])
        steps = {}
        forced = {}          # hit index → (channel index, −1 = force; peak over range)
        for i, c in clips.get(eid, []):
            ci = -1 if c["channel"] == "force" else ch_ids.index(c["channel"])
            for h in c["hits"]:
                if h - 1 in forced:
                    raise ValueError(f"time.clip[{i}].hits: hit {h} of {eid} is already forced to clip")
                forced[h - 1] = (ci, c["peak_over_range"])
        if tm["clip_probability"] > 0 and bits:
            lo_c, hi_c = tm["clip_peak_over_range"]
            for h in range(nh):
                if h not in forced and draws[h, 5] < tm["clip_probability"]:
                    ci = min(int(draws[h, 6] * (n_ch + 1)), n_ch) - 1
                    forced[h] = (ci, lo_c + (hi_c - lo_c) * draws[h, 7])
        # A channel with forced hits: its range from the hits forced nowhere (amplitudes as
        # drawn); then the forced hits' amplitudes from that range. Channels without forced
        # hits autorange below over all hits (final amplitudes) and so never clip; a hit
        # forced on one channel can clip another channel that has forced hits of its own.
        free = [h for h in range(nh) if h not in forced]
        if forced and not free:
            raise ValueError(f"time: every hit of {eid} is forced to clip: none is left to set the ranges")
        for ci in sorted({ci for ci, _ in forced.values()}):
            up = upeak_f if ci < 0 else upeak_y[:, ci]
            steps[ci] = adc_step(max(amps[h] * up[h] for h in free), bits, tm["adc_headroom"])
        for h, (ci, por) in sorted(forced.items()):
            up = upeak_f if ci < 0 else upeak_y[:, ci]
            amps[h] = 2.0 ** (bits - 1) * step_value(*steps[ci]) * por / up[h]
        if carry_over:
            # the continuous run: each segment also holds the tails of the hits before it
            y_unit *= amps[:, None, None]
            f_unit *= amps[:, None]
            cg = cf = cff = 0.0
            for h in range(nh):
                if h:
                    if np.ndim(cg):
                        y_unit[h] += grid.tail(cg)
                    if np.ndim(cf):
                        y_unit[h] += grid_f.tail(cf)
                    if np.ndim(cff):
                        f_unit[h] += grid_f.tail(cff)[0]
                kg, kf, kff = carries[h]
                cg = (cg * np.exp(grid.lam * seg / fs)[None, :] if np.ndim(cg) else 0.0) + amps[h] * kg
                if aa is not None:
                    cf = (cf * np.exp(grid_f.lam * seg / fs)[None, :] if np.ndim(cf) else 0.0) + amps[h] * kf
                    cff = (cff * np.exp(grid_f.lam * seg / fs)[None, :] if np.ndim(cff) else 0.0) + amps[h] * kff
            peak_f = np.abs(f_unit[:, :n]).max(axis=1)
            peak_y = np.abs(y_unit[:, :, :n]).max(axis=2)
            amps_signal = np.ones(nh)
        else:
            peak_f = amps * upeak_f
            peak_y = amps[:, None] * upeak_y
            amps_signal = amps
        if bits:
            for ci in [-1] + list(range(n_ch)):
                if ci not in steps:
                    pk = peak_f.max() if ci < 0 else peak_y[:, ci].max()
                    steps[ci] = adc_step(pk, bits, tm["adc_headroom"])
        force = np.empty((nh, seg))
        resp = np.empty((nh, n_ch, seg))
        rail_f = np.zeros((nh, seg), bool)
        rail_y = np.zeros((nh, n_ch, seg), bool)
        over_f = np.zeros(nh, int)
        over_y = np.zeros((nh, n_ch), int)
        for h in range(nh):
            f = amps_signal[h] * f_unit[h] + tm["force_noise"] * rng.standard_normal(seg)
            y = amps_signal[h] * y_unit[h]
            if tm["clip_response"] > 0:
                y = np.clip(y, -tm["clip_response"], tm["clip_response"])
            y = y + tm["response_noise"] * rng.standard_normal((n_ch, seg))
            if bits:
                m, e = steps[-1]
                r = 2.0 ** (bits - 1) * step_value(m, e)
                over_f[h] = int(np.count_nonzero(np.abs(f[:n]) > r))
                f, rail_f[h] = quantise(f, m, e, bits)
                for ci in range(n_ch):
                    m, e = steps[ci]
                    r = 2.0 ** (bits - 1) * step_value(m, e)
                    over_y[h, ci] = int(np.count_nonzero(np.abs(y[ci, :n]) > r))
                    y[ci], rail_y[h, ci] = quantise(y[ci], m, e, bits)
            force[h], resp[h] = f, y
        rec.force.append(force)
        rec.response.append(resp)
        rec.rail_force.append(rail_f)
        rec.rail_response.append(rail_y)
        ranges = None
        if bits:
            ranges = {"force": 2.0 ** (bits - 1) * step_value(*steps[-1]),
                      "response": [2.0 ** (bits - 1) * step_value(*steps[ci]) for ci in range(n_ch)],
                      "step_force": step_value(*steps[-1]),
                      "step_response": [step_value(*steps[ci]) for ci in range(n_ch)]}
        th = []
        for h, hit in enumerate(hits):
            cf = int(rail_f[h, :n].sum())
            cy = [int(x) for x in rail_y[h, :, :n].sum(axis=1)]
            clipped = cf >= 2 or max(cy, default=0) >= 2
            trig = int(math.ceil(hit["onset"] - 1e-9))
            d = None
            if hit["double"]:
                o2 = hit["pulses"][1][0]
                d = {"delay_s": hit["double"][0], "ratio": hit["double"][1],
                     "second_onset_s": o2 / fs, "second_onset_sample": int(math.ceil(o2 - 1e-9)),
                     "second_amplitude_n": float(amps[h] * hit["double"][1])}
            reasons = []
            if d and "double" in tm["reject"]:
                reasons.append("double")
            if clipped and "clipped" in tm["reject"]:
                reasons.append("clipped")
            th.append({
                "hit": h + 1,
                "throughput_start_sample": h * seg,
                "onset_s": hit["onset"] / fs,
                "trigger_sample": trig,
                "throughput_trigger_sample": h * seg + trig,
                "pulse_end_s": hit["end"] / fs,
                "pulse_end_sample": int(math.floor(hit["end"] + 1e-9)),
                "amplitude_n": float(amps[h]),
                "clean_peak_force_n": float(peak_f[h]),
                "clean_peak_response": [float(x) for x in peak_y[h]],
                "double": d,
                "forced_clip_channel": (("force" if forced[h][0] < 0 else ch_ids[forced[h][0]])
                                        if h in forced else None),
                "forced_peak_over_range": float(forced[h][1]) if h in forced else None,
                "clipped_samples": {"force": cf, "response": cy},
                "over_range_samples": {"force": int(over_f[h]), "response": [int(x) for x in over_y[h]]},
                "clipped": clipped,
                "accepted": not reasons,
                "reasons": reasons,
            })
        truth_ex.append({"id": eid, "adc_ranges": ranges, "hits": th})
    rec.truth_ex = truth_ex
    return rec


def windows(case, rec, ei, h):
    """(w_force, w_response, (first, last) of the force rectangle or None, n₀) of hit h."""
    fs, n = rec.fs, rec.n_record
    hit = rec.truth_ex[ei]["hits"][h]
    n0 = hit["trigger_sample"]
    idx = np.arange(n)
    tau = case.window_tau
    w = np.ones(n)
    if tau > 0:
        w = np.where(idx >= n0, np.exp(-(idx - n0) / (fs * tau)), 1.0)
    wf = w.copy() if case.window_apply_to_force else np.ones(n)
    rect = None
    if case.window_force_post is not None:
        pre = rec.pretrigger if case.window_force_pre is None else int(round(case.window_force_pre * fs))
        first = max(0, n0 - pre)
        last = min(n - 1, hit["pulse_end_sample"] + int(round(case.window_force_post * fs)))
        wf = wf * ((idx >= first) & (idx <= last))
        rect = (first, last)
    return wf, w, rect, n0


def h1(case, rec):
    """(frequency_hz, H1[e, c, l], coherence[e, c, l], used[e][h]) from the written samples."""
    fs, n = rec.fs, rec.n_record
    freq = np.fft.rfftfreq(n, 1.0 / fs)
    keep = (freq >= case.f_start - 1e-12) & (freq <= case.f_stop + 1e-12)
    if keep.sum() < 2:
        raise ValueError("time: fewer than 2 FFT bins fall inside [start_hz, stop_hz]")
    n_ex, n_ch = len(rec.force), len(rec.channel_ids)
    out = np.empty((n_ex, n_ch, keep.sum()), complex)
    coh = np.empty(out.shape)
    used = []
    for ei in range(n_ex):
        sff = np.zeros(keep.sum())
        syy = np.zeros((n_ch, keep.sum()))
        sfy = np.zeros((n_ch, keep.sum()), complex)
        u = []
        for h, hit in enumerate(rec.truth_ex[ei]["hits"]):
            wf, w, rect, n0 = windows(case, rec, ei, h)
            hit["windows"] = {"force_rectangle": list(rect) if rect else None,
                              "exponential_start_sample": n0 if case.window_tau > 0 else None}
            if not hit["accepted"]:
                continue
            u.append(h + 1)
            ff = np.fft.rfft(rec.force[ei][h, :n] * wf)[keep]
            yy = np.fft.rfft(rec.response[ei][h, :, :n] * w[None, :], axis=1)[:, keep]
            sff += np.abs(ff) ** 2
            syy += np.abs(yy) ** 2
            sfy += np.conj(ff)[None, :] * yy
        if not u:
            raise ValueError(f"time: every hit of excitation {rec.truth_ex[ei]['id']} is rejected "
                             f"({', '.join(sorted(set(r for x in rec.truth_ex[ei]['hits'] for r in x['reasons'])))}): "
                             "no H1 (set time.reject = [] to average them anyway)")
        out[ei] = sfy / sff[None, :]
        with np.errstate(invalid="ignore", divide="ignore"):
            coh[ei] = np.abs(sfy) ** 2 / (sff[None, :] * syy)
        used.append(u)
    return freq[keep], out, coh, used


def truth_record(case, rec, used):
    tm = case.time
    return {
        "sample_rate_hz": rec.fs,
        "dt_s": 1.0 / rec.fs,
        "record_samples": rec.n_record,
        "record_s": rec.n_record / rec.fs,
        "pretrigger_samples": rec.pretrigger,
        "gap_samples": rec.gap,
        "segment_samples": rec.n_segment,
        "throughput_samples": rec.n_segment * tm["impacts"],
        "impacts": tm["impacts"],
        "pulse_s": tm["pulse_s"],
        "subsample_onset": tm["subsample_onset"],
        "carry_over": tm["carry_over"],
        "adc_bits": rec.bits,
        "adc_headroom": tm["adc_headroom"] if rec.bits else None,
        "anti_alias_filter": ({"type": "butterworth", "order": tm["anti_alias_order"],
                               "cutoff_hz": tm["anti_alias_cutoff_hz"],
                               "applied_to": "force and every response channel, before the noise and the ADC"}
                              if tm["anti_alias_order"] else None),
        "force_noise": tm["force_noise"],
        "response_noise": tm["response_noise"],
        "quantity": case.quantity,
        "channels": rec.channel_ids,
        "window": {"tau_s": case.window_tau or None,
                   "response": "1 before the trigger sample n0, exp(-(n - n0)/(fs tau)) from it" if case.window_tau
                   else "none",
                   "apply_to_force": case.window_apply_to_force,
                   "force_pre_s": case.window_force_pre,
                   "force_post_s": case.window_force_post},
        "reject": list(tm["reject"]),
        "clipped_rule": ">= 2 samples at the range on any channel (force included)",
        "hits_used": {e["id"]: u for e, u in zip(rec.truth_ex, used)},
        "excitations": rec.truth_ex,
    }
