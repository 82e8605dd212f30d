"""Case files: reading (TOML or JSON, optionally on top of an rbprops campaign spec),
validation with clear messages, and the resolved test article.

See README.md for the format. Every problem raises CaseError naming the file and the
path of the offending field (0-based list indices), e.g.
`case.toml: sensor[2].direction: not a unit vector (|d| = 1.41)`.
"""
import copy
import json
import os

try:
    import tomllib  # Python ≥ 3.11
except ModuleNotFoundError:  # pragma: no cover - older Pythons with the backport
    try:
        import tomli as tomllib
    except ModuleNotFoundError:
        tomllib = None

import numpy as np

from .rigid import cloud_properties, rotation, tensor_from_moments

QUANTITY_ORDER = {"receptance": 0, "mobility": 1, "accelerance": 2}
STANDARD_GRAVITY = 9.80665
CASE_ONLY = ("spec", "gravity_m_s2", "reference_point_m", "elastic_mode", "window", "output", "time",
             "sensor_gravity")


class CaseError(ValueError):
    pass


def _load_file(path):
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except OSError as e:
        raise CaseError(f"{path}: cannot read: {e.strerror}") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise CaseError(f"{path}: not UTF-8 text (byte {e.start})") from None
    try:
        if path.endswith(".json"):
            return json.loads(text)
        if tomllib is None:
            raise CaseError(f"{path}: reading TOML needs Python ≥ 3.11 (tomllib) or tomli; use JSON")
        return tomllib.loads(text)
    except json.JSONDecodeError as e:
        raise CaseError(f"{path}: {e}") from None
    except Exception as e:  # tomllib.TOMLDecodeError
        if isinstance(e, CaseError):
            raise
        raise CaseError(f"{path}: {e}") from None
        raise CaseError(f"{path}: {e}") from None


def _merge_by_id(base, over, path, src):
    """Lists of tables merged by `id`: an entry with a known id updates that entry, a new
    id is appended (in the case's order)."""
    out = [copy.deepcopy(x) for x in base]
    for i, item in enumerate(over):
        if not isinstance(item, dict) or "id" not in item:
            raise CaseError(f"{src}: {path}[{i}]: a table with an `id` is required")
        hit = [x for x in out if x.get("id") == item["id"]]
        if hit:
            hit[0].update(copy.deepcopy(item))
        else:
            out.append(copy.deepcopy(item))
    return out


def apply_setting(data, path, value, src="--set"):
    """Sets `value` at a dotted `path` of the case data, e.g. `noise.relative`,
    `sensor.2.misorientation_rad` (lists of tables — sensor, excitation, setup — are
    addressed by id, other lists by 0-based index). Missing tables are created."""
    keys = path.split(".")
    node = data
    for i, k in enumerate(keys[:-1]):
        nxt = node.get(k) if isinstance(node, dict) else None
        if isinstance(node, list):
            hit = [x for x in node if isinstance(x, dict) and str(x.get("id")) == k]
            if hit:
                node = hit[0]
                continue
            if k.isdigit() and int(k) < len(node):
                node = node[int(k)]
                continue
            raise CaseError(f"{src}: {path}: no entry with id or index {k!r} in {'.'.join(keys[:i])}")
        if nxt is None:
            node[k] = {}
            nxt = node[k]
        node = nxt
    if isinstance(node, list):
        raise CaseError(f"{src}: {path}: name an entry of the list {keys[-2]!r} by id first")
    node[keys[-1]] = value


def load(path, overrides=None, settings=()):
    """Reads a case (TOML/JSON) or a bare rbprops campaign spec; returns a Case.
    `overrides`: top-level keys replaced; `settings`: (dotted path, value) pairs applied
    after the merge with the spec (see `apply_setting`)."""
    raw = _load_file(path)
    if not isinstance(raw, dict):
        raise CaseError(f"{path}: the top level must be a table")
    data = {}
    spec_path = raw.get("spec")
    if spec_path is not None:
        if not isinstance(spec_path, str):
            raise CaseError(f"{path}: spec: must be a file name")
        full = spec_path if os.path.isabs(spec_path) else os.path.join(os.path.dirname(path), spec_path)
        data = _load_file(full)
        if data.get("effect"):
            if raw.get("spec_effects") != "ignore":
                raise CaseError(
                    f"{path}: spec '{spec_path}' lists [[effect]] entries, which are the other "
                    "simulator's catalogue: describe the physics in the case instead, or set "
                    "spec_effects = \"ignore\"")
        data.pop("effect", None)
    elif raw.get("effect"):
        raise CaseError(f"{path}: effect: [[effect]] entries are not read; describe the physics "
                        "with the case fields (README.md)")
    for key, val in raw.items():
        if key in ("spec", "spec_effects"):
            continue
        if key in ("sensor", "excitation", "setup") and key in data:
            data[key] = _merge_by_id(data[key], val, key, path)
        elif isinstance(val, dict) and isinstance(data.get(key), dict) and key not in ("body",):
            merged = copy.deepcopy(data[key])
            merged.update(val)
            data[key] = merged
        else:
            data[key] = copy.deepcopy(val)
    # A file without any case-only field is an rbprops campaign spec read as is: its
    # nominal model has no gravity (the other simulator adds gravity only as an effect).
    if not any(k in raw for k in CASE_ONLY) and "gravity_m_s2" not in data:
        data["gravity_m_s2"] = 0.0
    for key, val in (overrides or {}).items():
        data[key] = val
    for key, val in settings:
        apply_setting(data, key, val)
    return Case(data, path)


FIELDS = {
    "frequency": {"start_hz", "stop_hz", "lines"},
    "body": {"mass_kg", "com_m", "inertia_cm_kg_m2", "moments_kg_m2", "products_kg_m2", "points_m",
             "point_masses_kg"},
    "setup": {"id", "description", "spring", "cord", "dashpot", "rotational_spring", "loss_factor"},
    "rotational_spring": {"stiffness_n_m_per_rad", "stiffness_matrix_n_m_per_rad"},
    "spring": {"at_m", "anchor_m", "stiffness_n_per_m", "stiffness_matrix_n_per_m", "loss_factor"},
    "cord": {"at_m", "anchor_m", "length_m", "stiffness_n_per_m", "loss_factor"},
    "dashpot": {"at_m", "damping_n_s_per_m", "damping_matrix_n_s_per_m"},
    "sensor": {"id", "at_m", "kind", "axes", "direction", "position_error_m", "misorientation_rad",
               "gain", "gains", "mass_kg", "highpass_s", "delay_s", "delays_s"},
    "excitation": {"id", "at_m", "direction", "setup", "point", "position_error_m",
                   "direction_error_rad", "gauge_mass_kg", "stinger_lateral_n_per_m",
                   "stinger_bending_n_m_per_rad", "force_gauge_gain", "delay_s",
                   "suspension_stiffness_factor"},
    "damping": {"model", "ratio", "ratios", "alpha", "beta"},
    "noise": {"relative", "floor"},
    "elastic_mode": {"frequency_hz", "damping_ratio", "at_channels", "at_excitations", "setups"},
    "window": {"tau_s", "record_s", "force_pre_s", "force_post_s", "apply_to_force"},
    "output": {"precision"},
    "time": {"sample_rate_hz", "record_s", "pulse_s", "impacts", "force_noise", "response_noise",
             "clip_response", "amplitude_n", "amplitude_jitter", "pretrigger_s", "gap_s",
             "subsample_onset", "adc_bits", "adc_headroom", "clip", "double", "double_probability",
             "double_delay_s", "double_ratio", "reject", "anti_alias_order", "anti_alias_cutoff_hz",
             "clip_probability", "clip_peak_over_range", "carry_over"},
}
RECORDING_TIME_FIELDS = FIELDS["time"] - {"sample_rate_hz", "record_s", "pulse_s", "impacts", "force_noise",
                                          "response_noise", "clip_response", "amplitude_n",
                                          "amplitude_jitter"}
RECORDING_WINDOW_FIELDS = {"force_pre_s", "force_post_s", "apply_to_force"}
"""Fields that make a [time] case a recording (recording.py: time histories with
pretrigger, ADC, double hits, windows from the trigger); without them the time route of
timedomain.py runs as before."""
"""Known fields of each table: anything else is an error (a misspelt effect parameter
would otherwise silently vanish from the physics)."""


def _check_fields(ck, data):
    def one(tab, kind, path):
        if not isinstance(tab, dict):
            ck.fail(path, "must be a table")
        for k in tab:
            if k not in FIELDS[kind]:
                ck.fail(f"{path}.{k}", f"unknown field (known: {', '.join(sorted(FIELDS[kind]))})")

    for kind in ("frequency", "body", "damping", "noise", "window", "output", "time"):
        if kind in data:
            one(data[kind], kind, kind)
    for kind in ("setup", "sensor", "excitation", "elastic_mode"):
        items = data.get(kind, [])
        if not isinstance(items, list):
            ck.fail(kind, "must be a list of tables ([[...]])")
        for i, item in enumerate(items):
            one(item, kind, f"{kind}[{i}]")
            if kind == "setup":
                for sub in ("spring", "cord", "dashpot", "rotational_spring"):
                    for j, x in enumerate(item.get(sub, [])):
                        one(x, sub, f"{kind}[{i}].{sub}[{j}]")


class _Checker:
    def __init__(self, src):
        self.src = src

    def fail(self, path, problem):
        raise CaseError(f"{self.src}: {path}: {problem}")

    def num(self, tab, key, path, default=None, lo=None, hi=None, strict_lo=False):
        if key not in tab:
            if default is None:
                self.fail(f"{path}.{key}" if path else key, "missing")
            return default
        v = tab[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
            self.fail(f"{path}.{key}" if path else key, f"must be a finite number, got {v!r}")
        v = float(v)
        if lo is not None and (v < lo or (strict_lo and v == lo)):
            self.fail(f"{path}.{key}" if path else key, f"must be {'>' if strict_lo else '≥'} {lo}, got {v}")
        if hi is not None and v >= hi:
            self.fail(f"{path}.{key}" if path else key, f"must be < {hi}, got {v}")
        return v

    def arr(self, tab, key, path, shape, default=None):
        p = f"{path}.{key}" if path else key
        if key not in tab:
            if default is None:
                self.fail(p, "missing")
            return np.asarray(default, float)
        try:
            a = np.asarray(tab[key], float)
        except (TypeError, ValueError):
            self.fail(p, f"must be numbers of shape {shape}")
        if a.shape != shape:
            self.fail(p, f"must have shape {shape}, got {a.shape}")
        if not np.all(np.isfinite(a)):
            self.fail(p, "values must be finite")
        return a

    def unit(self, tab, key, path):
        a = self.arr(tab, key, path, (3,))
        n = np.linalg.norm(a)
        if abs(n - 1.0) > 1e-6:
            self.fail(f"{path}.{key}", f"not a unit vector (|d| = {n:.6f})")
        return a / n

    def sym_psd(self, a, path):
        if np.abs(a - a.T).max() > 1e-9 * max(np.abs(a).max(), 1e-300):
            self.fail(path, "not symmetric")
        a = 0.5 * (a + a.T)
        ev = np.linalg.eigvalsh(a)
        if ev.min() < -1e-12 * max(np.abs(ev).max(), 1e-300):
            self.fail(path, f"not positive semi-definite (eigenvalue {ev.min():.4e})")
        return a


class Case:
    """A validated test article: body, set-ups, channels, excitations and the extras."""

    def __init__(self, data, src="<case>"):
        ck = _Checker(src)
        self.src = src
        self.data = data
        known = {"name", "description", "seed", "quantity", "frequency", "body", "setup", "sensor",
                 "excitation", "damping", "noise", "up", "gravity_m_s2", "reference_point_m",
                 "elastic_mode", "window", "output", "time", "sensor_gravity"}
        for k in data:
            if k not in known:
                ck.fail(k, f"unknown field (known: {', '.join(sorted(known))})")
        _check_fields(ck, data)
        self.name = str(data.get("name", os.path.splitext(os.path.basename(src))[0]))
        self.seed = int(data.get("seed", 0))
        self.quantity = data.get("quantity", "receptance")
        if self.quantity not in QUANTITY_ORDER:
            ck.fail("quantity", f"must be one of {list(QUANTITY_ORDER)}, got {self.quantity!r}")
        self.up = ck.unit(data, "up", "") if "up" in data else np.array([0.0, 0.0, 1.0])
        self.gravity = ck.num(data, "gravity_m_s2", "", STANDARD_GRAVITY, lo=0.0)
        self.origin = ck.arr(data, "reference_point_m", "", (3,), [0.0, 0.0, 0.0])
        self.sensor_gravity = data.get("sensor_gravity", False)
        if not isinstance(self.sensor_gravity, bool):
            ck.fail("sensor_gravity", f"must be true or false, got {self.sensor_gravity!r}")
        fr = data.get("frequency")
        if not isinstance(fr, dict):
            ck.fail("frequency", "missing table [frequency] with start_hz, stop_hz, lines")
        self.f_start = ck.num(fr, "start_hz", "frequency", lo=0.0)
        self.f_stop = ck.num(fr, "stop_hz", "frequency")
        if not self.f_stop > self.f_start:
            ck.fail("frequency.stop_hz", f"must be above start_hz ({self.f_start})")
        self.lines = int(ck.num(fr, "lines", "frequency", lo=2))
        self._body(ck, data.get("body"))
        self._sensors(ck, data.get("sensor"))
        self._setups(ck, data.get("setup"))
        self._excitations(ck, data.get("excitation"))
        self._damping(ck, data.get("damping", {"model": "none"}))
        self._elastic(ck, data.get("elastic_mode", []))
        win = data.get("window", {})
        self.window_tau = ck.num(win, "tau_s", "window", 0.0, lo=0.0, strict_lo=True) if "tau_s" in win else 0.0
        self.record_s = ck.num(win, "record_s", "window", 0.0, lo=0.0, strict_lo=True) if "record_s" in win else 0.0
        self.window_force_pre = ck.num(win, "force_pre_s", "window", lo=0.0) if "force_pre_s" in win else None
        self.window_force_post = ck.num(win, "force_post_s", "window", lo=0.0) if "force_post_s" in win else None
        self.window_apply_to_force = win.get("apply_to_force", True)
        if not isinstance(self.window_apply_to_force, bool):
            ck.fail("window.apply_to_force", f"must be true or false, got {self.window_apply_to_force!r}")
        if self.window_force_pre is not None and self.window_force_post is None:
            ck.fail("window.force_pre_s", "the force window needs force_post_s too")
        noise = data.get("noise", {})
        self.noise_relative = ck.num(noise, "relative", "noise", 0.0, lo=0.0)
        self.noise_floor = ck.num(noise, "floor", "noise", 0.0, lo=0.0)
        out = data.get("output", {})
        self.precision = out.get("precision", "float64")
        if self.precision not in ("float64", "float32"):
            ck.fail("output.precision", f"must be float64 or float32, got {self.precision!r}")
        self.time = data.get("time")
        self.recording = False
        if self.time is not None:
            self.recording = bool(set(self.time) & RECORDING_TIME_FIELDS or set(win) & RECORDING_WINDOW_FIELDS)
            self._time(ck, self.time)
        elif set(win) & RECORDING_WINDOW_FIELDS:
            ck.fail("window", "force_pre_s, force_post_s and apply_to_force need a [time] table")

    # --- body ----------------------------------------------------------------------------
    def _body(self, ck, b):
        if not isinstance(b, dict):
            ck.fail("body", "missing table [body]")
        if "points_m" in b:
            pts = np.asarray(b["points_m"], float)
            if pts.ndim != 2 or pts.shape[1] != 3:
                ck.fail("body.points_m", "must be a list of [x, y, z]")
            w = ck.arr(b, "point_masses_kg", "body", (len(pts),))
            if np.any(w <= 0):
                ck.fail("body.point_masses_kg", "masses must be positive")
            for k in ("mass_kg", "com_m", "inertia_cm_kg_m2", "moments_kg_m2", "products_kg_m2"):
                if k in b:
                    ck.fail(f"body.{k}", "give the body either as points_m or as mass/CoM/inertia")
            self.body_points = (pts, w)
            self.mass, self.com, self.inertia = cloud_properties(pts, w)
            return
        self.body_points = None
        self.mass = ck.num(b, "mass_kg", "body", lo=0.0, strict_lo=True)
        self.com = ck.arr(b, "com_m", "body", (3,))
        if "inertia_cm_kg_m2" in b:
            if "moments_kg_m2" in b or "products_kg_m2" in b:
                ck.fail("body", "give the inertia either as inertia_cm_kg_m2 or as moments_kg_m2 + products_kg_m2")
            j = ck.arr(b, "inertia_cm_kg_m2", "body", (3, 3))
            j = ck.sym_psd(j, "body.inertia_cm_kg_m2")
        elif "moments_kg_m2" in b:
            mo = ck.arr(b, "moments_kg_m2", "body", (3,))
            p = b.get("products_kg_m2", {"xy": 0.0, "xz": 0.0, "yz": 0.0})
            pr = [ck.num(p, k, "body.products_kg_m2") for k in ("xy", "xz", "yz")]
            j = tensor_from_moments(mo, pr)
        else:
            ck.fail("body", "give the inertia as inertia_cm_kg_m2, moments_kg_m2 + products_kg_m2, or points_m")
        ev = np.linalg.eigvalsh(j)
        if ev.min() <= 0 or ev.max() > ev.sum() - ev.max() + 1e-12 * ev.max():
            ck.fail("body", f"inertia is not physical (principal moments {ev}: each must be positive "
                            "and at most the sum of the other two)")
        self.inertia = j

    # --- sensors -------------------------------------------------------------------------
    def _sensors(self, ck, sensors):
        if not sensors:
            ck.fail("sensor", "no sensor defined")
        self.channels = []
        self.sensor_masses = []
        seen = set()
        for i, s in enumerate(sensors):
            path = f"sensor[{i}]"
            sid = str(s.get("id", ""))
            if not sid.strip() or sid in seen:
                ck.fail(f"{path}.id", f"empty or repeated id {sid!r}")
            seen.add(sid)
            at = ck.arr(s, "at_m", path, (3,))
            kind = s.get("kind")
            dp = ck.arr(s, "position_error_m", path, (3,), [0, 0, 0])
            mis = rotation(ck.arr(s, "misorientation_rad", path, (3,), [0, 0, 0]))
            gain = ck.num(s, "gain", path, 1.0)
            mass = ck.num(s, "mass_kg", path, 0.0, lo=0.0)
            hp = s.get("highpass_s", [])
            hp = [hp] if isinstance(hp, (int, float)) and not isinstance(hp, bool) else hp
            if not isinstance(hp, list) or not all(isinstance(x, (int, float)) and x > 0 for x in hp):
                ck.fail(f"{path}.highpass_s", "must be a positive time constant or a list of them (s)")
            if "delay_s" in s and "delays_s" in s:
                ck.fail(path, "give delay_s (all channels) or delays_s (per axis), not both")
            delay = ck.num(s, "delay_s", path, 0.0, lo=0.0)
            delays = ck.arr(s, "delays_s", path, (3,)) if "delays_s" in s else None
            if kind != "triaxial" and delays is not None:
                ck.fail(f"{path}.delays_s", "per-axis delays are for triaxial sensors (use delay_s)")
            filt = dict(highpass_s=[float(x) for x in hp], delay_s=delay)
            if mass > 0:
                self.sensor_masses.append((at + dp, mass))
            if kind == "triaxial":
                if "direction" in s:
                    ck.fail(f"{path}.direction", "a triaxial sensor takes `axes`, not `direction`")
                if "axes" in s:
                    ax = ck.arr(s, "axes", path, (3, 3))
                    for k in range(3):
                        ck.unit({"a": ax[k]}, "a", f"{path}.axes[{k}]")
                    if abs(np.linalg.det(ax)) < 0.5:
                        ck.fail(f"{path}.axes", "the three axes are nearly coplanar")
                    names = [f"{sid}:{k}" for k in (1, 2, 3)]
                else:
                    ax = np.eye(3)
                    names = [f"{sid}{k}" for k in "xyz"]
                gains = s.get("gains")
                if gains is not None:
                    gains = ck.arr(s, "gains", path, (3,))
                else:
                    gains = [gain] * 3
                for k in range(3):
                    if delays is not None:
                        filt = dict(filt, delay_s=float(delays[k]))
                    self.channels.append(dict(id=names[k], point=sid, position=at, direction=ax[k],
                                              true_position=at + dp, true_direction=mis @ ax[k],
                                              gain=float(gains[k]), **filt))
            elif kind == "uniaxial":
                if "axes" in s:
                    ck.fail(f"{path}.axes", "a uniaxial sensor takes `direction`, not `axes`")
                d = ck.unit(s, "direction", path)
                self.channels.append(dict(id=sid, point=sid, position=at, direction=d,
                                          true_position=at + dp, true_direction=mis @ d, gain=gain, **filt))
            else:
                ck.fail(f"{path}.kind", f"must be 'triaxial' or 'uniaxial', got {kind!r}")
        self.sensor_points = {str(s["id"]): np.asarray(s["at_m"], float) for s in sensors}

    # --- set-ups -------------------------------------------------------------------------
    def _setups(self, ck, setups):
        if not setups:
            ck.fail("setup", "no suspension set-up defined")
        self.setups = []
        seen = set()
        for i, s in enumerate(setups):
            path = f"setup[{i}]"
            sid = str(s.get("id", ""))
            if not sid.strip() or sid in seen:
                ck.fail(f"{path}.id", f"empty or repeated id {sid!r}")
            seen.add(sid)
            springs, cords, dashpots, spring_eta, cord_eta = [], [], [], [], []
            for j, sp in enumerate(s.get("spring", [])):
                p = f"{path}.spring[{j}]"
                at = ck.arr(sp, "at_m", p, (3,))
                if ("stiffness_n_per_m" in sp) == ("stiffness_matrix_n_per_m" in sp):
                    ck.fail(p, "give exactly one of stiffness_n_per_m and stiffness_matrix_n_per_m")
                if "stiffness_n_per_m" in sp:
                    kd = ck.arr(sp, "stiffness_n_per_m", p, (3,))
                    if np.any(kd < 0):
                        ck.fail(f"{p}.stiffness_n_per_m", f"negative stiffness {kd.tolist()}")
                    k = np.diag(kd)
                else:
                    k = ck.sym_psd(ck.arr(sp, "stiffness_matrix_n_per_m", p, (3, 3)), f"{p}.stiffness_matrix_n_per_m")
                anchor = ck.arr(sp, "anchor_m", p, (3,), at)
                springs.append((at, anchor, k))
                spring_eta.append(ck.num(sp, "loss_factor", p, -1.0) if "loss_factor" in sp else None)
            for j, c in enumerate(s.get("cord", [])):
                p = f"{path}.cord[{j}]"
                at = ck.arr(c, "at_m", p, (3,))
                anchor = ck.arr(c, "anchor_m", p, (3,))
                l0 = ck.num(c, "length_m", p, lo=0.0, strict_lo=True)
                k = ck.num(c, "stiffness_n_per_m", p, lo=0.0, strict_lo=True)
                cords.append((at, anchor, l0, k))
                cord_eta.append(ck.num(c, "loss_factor", p, lo=0.0) if "loss_factor" in c else None)
            for j, d in enumerate(s.get("dashpot", [])):
                p = f"{path}.dashpot[{j}]"
                at = ck.arr(d, "at_m", p, (3,))
                if ("damping_n_s_per_m" in d) == ("damping_matrix_n_s_per_m" in d):
                    ck.fail(p, "give exactly one of damping_n_s_per_m and damping_matrix_n_s_per_m")
                if "damping_n_s_per_m" in d:
                    cd = ck.arr(d, "damping_n_s_per_m", p, (3,))
                    if np.any(cd < 0):
                        ck.fail(f"{p}.damping_n_s_per_m", "negative damping")
                    c = np.diag(cd)
                else:
                    c = ck.sym_psd(ck.arr(d, "damping_matrix_n_s_per_m", p, (3, 3)), f"{p}.damping_matrix_n_s_per_m")
                dashpots.append((at, c))
            rotational = []
            for j, r in enumerate(s.get("rotational_spring", [])):
                p = f"{path}.rotational_spring[{j}]"
                if ("stiffness_n_m_per_rad" in r) == ("stiffness_matrix_n_m_per_rad" in r):
                    ck.fail(p, "give exactly one of stiffness_n_m_per_rad and stiffness_matrix_n_m_per_rad")
                if "stiffness_n_m_per_rad" in r:
                    kr = ck.arr(r, "stiffness_n_m_per_rad", p, (3,))
                    if np.any(kr < 0):
                        ck.fail(f"{p}.stiffness_n_m_per_rad", "negative stiffness")
                    rotational.append(np.diag(kr))
                else:
                    rotational.append(ck.sym_psd(ck.arr(r, "stiffness_matrix_n_m_per_rad", p, (3, 3)),
                                                 f"{p}.stiffness_matrix_n_m_per_rad"))
            eta = ck.num(s, "loss_factor", path, 0.0, lo=0.0)
            for j, e in enumerate(spring_eta):
                if e is not None and e < 0:
                    ck.fail(f"{path}.spring[{j}].loss_factor", f"must be ≥ 0, got {e}")
            # Element loss factors default to the set-up's.
            losses = [eta if e is None else e for e in spring_eta] + [eta if e is None else e for e in cord_eta]
            self.setups.append(dict(id=sid, description=str(s.get("description", "")), springs=springs,
                                    cords=cords, dashpots=dashpots, rotational=rotational, loss_factor=eta,
                                    element_losses=losses))

    # --- excitations ---------------------------------------------------------------------
    def _excitations(self, ck, exc):
        if not exc:
            ck.fail("excitation", "no excitation defined")
        ids = {s["id"] for s in self.setups}
        self.excitations = []
        seen = set()
        for i, e in enumerate(exc):
            path = f"excitation[{i}]"
            eid = str(e.get("id", ""))
            if not eid.strip() or eid in seen:
                ck.fail(f"{path}.id", f"empty or repeated id {eid!r}")
            seen.add(eid)
            at = ck.arr(e, "at_m", path, (3,))
            d = ck.unit(e, "direction", path)
            setup = str(e.get("setup", self.setups[0]["id"] if len(self.setups) == 1 else ""))
            if setup not in ids:
                ck.fail(f"{path}.setup", f"set-up {setup!r} is not defined (defined: {', '.join(sorted(ids))})")
            dp = ck.arr(e, "position_error_m", path, (3,), [0, 0, 0])
            rot = rotation(ck.arr(e, "direction_error_rad", path, (3,), [0, 0, 0]))
            point = str(e.get("point", eid))
            if point in self.sensor_points and np.abs(self.sensor_points[point] - at).max() > 1e-9:
                ck.fail(f"{path}.point", f"names sensor point {point!r} but at_m differs from the sensor's")
            self.excitations.append(dict(
                id=eid, point=point, position=at, direction=d, setup=setup, true_position=at + dp,
                true_direction=rot @ d, gauge_mass=ck.num(e, "gauge_mass_kg", path, 0.0, lo=0.0),
                stinger_lateral=ck.num(e, "stinger_lateral_n_per_m", path, 0.0, lo=0.0),
                stinger_bending=ck.num(e, "stinger_bending_n_m_per_rad", path, 0.0, lo=0.0),
                force_gauge_gain=ck.num(e, "force_gauge_gain", path, 1.0, lo=0.0, strict_lo=True),
                delay_s=ck.num(e, "delay_s", path, 0.0, lo=0.0),
                stiffness_factor=ck.num(e, "suspension_stiffness_factor", path, 1.0, lo=0.0, strict_lo=True)))

    # --- damping -------------------------------------------------------------------------
    def _damping(self, ck, d):
        model = d.get("model", "none")
        self.damping_model = model
        self.modal_ratios = None
        self.alpha = self.beta = 0.0
        if model == "modal":
            if ("ratio" in d) == ("ratios" in d):
                ck.fail("damping", "model 'modal' needs exactly one of ratio and ratios")
            if "ratio" in d:
                self.modal_ratios = [ck.num(d, "ratio", "damping", lo=0.0, hi=1.0)] * 6
            else:
                r = ck.arr(d, "ratios", "damping", (6,))
                if np.any(r < 0) or np.any(r >= 1):
                    ck.fail("damping.ratios", "each ratio must be in [0, 1)")
                self.modal_ratios = list(r)
        elif model == "proportional":
            self.alpha = ck.num(d, "alpha", "damping", 0.0, lo=0.0)
            self.beta = ck.num(d, "beta", "damping", 0.0, lo=0.0)
        elif model != "none":
            ck.fail("damping.model", f"must be 'modal', 'proportional' or 'none', got {model!r}")

    def _elastic(self, ck, modes):
        self.elastic_modes = []
        ch = [c["id"] for c in self.channels]
        ex = [e["id"] for e in self.excitations]
        for i, m in enumerate(modes):
            path = f"elastic_mode[{i}]"
            f = ck.num(m, "frequency_hz", path, lo=0.0, strict_lo=True)
            z = ck.num(m, "damping_ratio", path, lo=0.0, hi=1.0)
            shapes = []
            for key, names in (("at_channels", ch), ("at_excitations", ex)):
                v = m.get(key, {})
                if not isinstance(v, dict):
                    ck.fail(f"{path}.{key}", "must be a table {id = value} (mass-normalised, 1/√kg)")
                for k in v:
                    if k not in names:
                        what = "channel" if key == "at_channels" else "excitation"
                        ck.fail(f"{path}.{key}.{k}", f"no such {what} (known: {', '.join(names)})")
                shapes.append(np.array([float(v.get(n, 0.0)) for n in names]))
            setups = m.get("setups", [s["id"] for s in self.setups])
            self.elastic_modes.append(dict(frequency_hz=f, damping_ratio=z, at_channels=shapes[0],
                                           at_excitations=shapes[1], setups=list(setups)))

    def _time(self, ck, t):
        p = "time"
        self.time = dict(
            sample_rate_hz=ck.num(t, "sample_rate_hz", p, lo=0.0, strict_lo=True),
            record_s=ck.num(t, "record_s", p, lo=0.0, strict_lo=True),
            pulse_s=ck.num(t, "pulse_s", p, lo=0.0, strict_lo=True),
            impacts=int(ck.num(t, "impacts", p, 1, lo=1)),
            force_noise=ck.num(t, "force_noise", p, 0.0, lo=0.0),
            response_noise=ck.num(t, "response_noise", p, 0.0, lo=0.0),
            clip_response=ck.num(t, "clip_response", p, 0.0, lo=0.0),
            amplitude_n=ck.num(t, "amplitude_n", p, 100.0, lo=0.0, strict_lo=True),
            amplitude_jitter=ck.num(t, "amplitude_jitter", p, 0.0, lo=0.0),
        )
        self._recording_fields(ck, t)

    def _recording_fields(self, ck, t):
        p = "time"
        tm = self.time
        tm["pretrigger_s"] = ck.num(t, "pretrigger_s", p, 0.0, lo=0.0)
        tm["gap_s"] = ck.num(t, "gap_s", p, lo=0.0) if "gap_s" in t else None
        for key in ("subsample_onset", "carry_over"):
            tm[key] = t.get(key, False)
            if not isinstance(tm[key], bool):
                ck.fail(f"{p}.{key}", f"must be true or false, got {tm[key]!r}")
        bits = t.get("adc_bits", 0)
        if isinstance(bits, bool) or bits not in (0, 16, 24):
            ck.fail(f"{p}.adc_bits", f"must be 0 (no ADC), 16 or 24, got {bits!r}")
        tm["adc_bits"] = int(bits)
        tm["adc_headroom"] = ck.num(t, "adc_headroom", p, 1.5, lo=1.0)
        order = t.get("anti_alias_order", 0)
        if isinstance(order, bool) or not isinstance(order, int) or not 0 <= order <= 16:
            ck.fail(f"{p}.anti_alias_order", f"must be an integer 0 (no filter) .. 16, got {order!r}")
        tm["anti_alias_order"] = order
        tm["anti_alias_cutoff_hz"] = ck.num(t, "anti_alias_cutoff_hz", p, 0.4 * tm["sample_rate_hz"],
                                           lo=0.0, strict_lo=True)
        tm["double_probability"] = ck.num(t, "double_probability", p, 0.0, lo=0.0)
        if tm["double_probability"] > 1:
            ck.fail(f"{p}.double_probability", f"must be ≤ 1, got {tm['double_probability']}")
        tm["clip_probability"] = ck.num(t, "clip_probability", p, 0.0, lo=0.0)
        if tm["clip_probability"] > 1:
            ck.fail(f"{p}.clip_probability", f"must be ≤ 1, got {tm['clip_probability']}")
        if tm["clip_probability"] > 0 and not tm["adc_bits"]:
            ck.fail(f"{p}.clip_probability", "forced clipping needs an ADC (time.adc_bits = 16 or 24)")
        for key, dflt in (("double_delay_s", [0.0005, 0.02]), ("double_ratio", [0.05, 0.5]),
                          ("clip_peak_over_range", [1.0, 2.0])):
            a = ck.arr(t, key, p, (2,), dflt)
            if not (0 < a[0] <= a[1]):
                ck.fail(f"{p}.{key}", f"must be [low, high] with 0 < low ≤ high, got {a.tolist()}")
            tm[key] = [float(a[0]), float(a[1])]
        reject = t.get("reject", ["double", "clipped"])
        if not isinstance(reject, list) or any(r not in ("double", "clipped") for r in reject):
            ck.fail(f"{p}.reject", f"must be a list of \"double\", \"clipped\", got {reject!r}")
        tm["reject"] = list(reject)
        ex = [e["id"] for e in self.excitations]
        ch = [c["id"] for c in self.channels]
        n_hits = tm["impacts"]

        def hits(tab, path):
            h = tab.get("hits")
            if not isinstance(h, list) or not h or any(isinstance(x, bool) or not isinstance(x, int) for x in h):
                ck.fail(f"{path}.hits", f"must be a non-empty list of hit numbers (1..{n_hits}), got {h!r}")
            for x in h:
                if not 1 <= x <= n_hits:
                    ck.fail(f"{path}.hits", f"hit {x} is not in 1..{n_hits} (hits are numbered from 1)")
            if len(set(h)) != len(h):
                ck.fail(f"{path}.hits", "a hit is listed twice")
            return list(h)

        def excitation(tab, path):
            e = tab.get("excitation")
            if e not in ex:
                ck.fail(f"{path}.excitation", f"no such excitation {e!r} (known: {', '.join(ex)})")
            return e

        tm["double"] = []
        for i, d in enumerate(t.get("double", [])):
            path = f"{p}.double[{i}]"
            if not isinstance(d, dict):
                ck.fail(path, "must be a table {excitation, hits, delay_s, ratio}")
            for k in d:
                if k not in ("excitation", "hits", "delay_s", "ratio"):
                    ck.fail(f"{path}.{k}", "unknown field (known: delay_s, excitation, hits, ratio)")
            tm["double"].append(dict(excitation=excitation(d, path), hits=hits(d, path),
                                     delay_s=ck.num(d, "delay_s", path, lo=0.0, strict_lo=True),
                                     ratio=ck.num(d, "ratio", path, lo=0.0, strict_lo=True)))
        tm["clip"] = []
        for i, c in enumerate(t.get("clip", [])):
            path = f"{p}.clip[{i}]"
            if not isinstance(c, dict):
                ck.fail(path, "must be a table {excitation, channel, hits, peak_over_range}")
            for k in c:
                if k not in ("excitation", "channel", "hits", "peak_over_range"):
                    ck.fail(f"{path}.{k}", "unknown field (known: channel, excitation, hits, peak_over_range)")
            chan = c.get("channel")
            if chan != "force" and chan not in ch:
                ck.fail(f"{path}.channel", f"no such channel {chan!r} (known: force, {', '.join(ch)})")
            por = ck.num(c, "peak_over_range", path, lo=1.0, strict_lo=True)
            tm["clip"].append(dict(excitation=excitation(c, path), channel=chan, hits=hits(c, path),
                                   peak_over_range=por))

    def frequency_axis(self):
        """f_l = start + l·step, with start and step rounded to the 6 significant digits a
        UFF 58 record 7 (E13.5) holds, so the file carries the exact axis computed on."""
        step = (self.f_stop - self.f_start) / (self.lines - 1)
        start = float("%.5e" % self.f_start)
        step = float("%.5e" % step)
        return start + step * np.arange(self.lines)
