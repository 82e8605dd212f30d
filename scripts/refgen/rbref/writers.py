"""Output files: UFF 58 (via pyuff), JSON, NPZ and the truth JSON. Every writer writes to
a temporary file next to the target and renames it, so a failure leaves no partial file."""
import json
import os
import tempfile

import numpy as np

UFF_DATA_TYPE = {"receptance": 8, "mobility": 11, "accelerance": 12}
UNIT = {"receptance": "m/N", "mobility": "m/s/N", "accelerance": "m/s^2/N"}
MOTION_LABEL = {"receptance": "m", "mobility": "m/s", "accelerance": "m/s^2"}


def _atomic(path, write):
    d = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=d, prefix=".rbref-", suffix=os.path.splitext(path)[1])
    os.close(fd)
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


def _float_list(a):
    return [float(x) for x in a]


def frf_record(result):
    case = result.case
    h = result.frf
    rec = {
        "quantity": case.quantity,
        "unit": UNIT[case.quantity],
        "precision": case.precision,
        "frequency_hz": _float_list(result.frequency_hz),
        "channels": [{"id": c["id"], "point": c["point"], "position_m": c["position"].tolist(),
                      "direction": c["direction"].tolist()} for c in case.channels],
        "excitations": [{"id": e["id"], "point": e["point"], "setup": e["setup"],
                         "position_m": e["position"].tolist(), "direction": e["direction"].tolist()}
                        for e in case.excitations],
        # re/im[e][c][l], as float64 numbers (float32 data are exactly representable)
        "re": np.real(h).astype(float).tolist(),
        "im": np.imag(h).astype(float).tolist(),
    }
    if result.coherence is not None:
        rec["coherence"] = np.asarray(result.coherence, float).tolist()
    return rec


def write_json(result, path):
    def w(tmp):
        with open(tmp, "w") as fh:
            json.dump(frf_record(result), fh)
    _atomic(path, w)


def write_npz(result, path):
    case = result.case
    arrays = dict(
        frequency_hz=np.asarray(result.frequency_hz, float), frf=result.frf,
        channel_ids=np.array([c["id"] for c in case.channels]),
        channel_points=np.array([c["point"] for c in case.channels]),
        channel_positions_m=np.array([c["position"] for c in case.channels]),
        channel_directions=np.array([c["direction"] for c in case.channels]),
        excitation_ids=np.array([e["id"] for e in case.excitations]),
        excitation_points=np.array([e["point"] for e in case.excitations]),
        excitation_setups=np.array([e["setup"] for e in case.excitations]),
        excitation_positions_m=np.array([e["position"] for e in case.excitations]),
        excitation_directions=np.array([e["direction"] for e in case.excitations]),
        quantity=np.array(case.quantity))
    if result.coherence is not None:
        arrays["coherence"] = np.asarray(result.coherence)
    if result.recording is not None:
        arrays.update(recording_arrays(result))

    def w(tmp):
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
    _atomic(path, w)


def recording_arrays(result):
    """What the numpy H1 of a recording used, for a test that recomputes it: per
    (excitation, hit) the trigger sample, the force rectangle (first, last; −1 when none),
    whether the hit was averaged; and f_s, N, τ (0: none), apply_to_force."""
    rec, case = result.recording, result.case
    hits = [e["hits"] for e in rec.truth_ex]
    rect = np.array([[h["windows"]["force_rectangle"] or [-1, -1] for h in e] for e in hits], np.int64)
    return dict(
        sample_rate_hz=np.float64(rec.fs), record_samples=np.int64(rec.n_record),
        tau_s=np.float64(case.window_tau), apply_to_force=np.bool_(case.window_apply_to_force),
        trigger_samples=np.array([[h["trigger_sample"] for h in e] for e in hits], np.int64),
        force_rectangles=rect,
        hits_used=np.array([[h["accepted"] for h in e] for e in hits]),
        fft_bins=np.round(np.asarray(result.frequency_hz) * rec.n_record / rec.fs).astype(np.int64))


def write_truth(result, path):
    def w(tmp):
        with open(tmp, "w") as fh:
            json.dump(result.truth, fh, indent=1)
    _atomic(path, w)


def _axis_code(d):
    """±(k+1) when d is exactly ±axis k, else None."""
    for k in range(3):
        if abs(abs(d[k]) - 1.0) < 1e-12 and np.abs(np.delete(d, k)).max() < 1e-12:
            return int(np.sign(d[k])) * (k + 1)
    return None


def _complete_frame(rows):
    """Orthonormal rows whose first rows are the given (orthonormal) directions."""
    rows = [np.asarray(r, float) for r in rows]
    if len(rows) == 1:
        a = rows[0]
        t = np.eye(3)[np.argmin(np.abs(a))]
        b = np.cross(a, t)
        b /= np.linalg.norm(b)
        rows.append(b)
    if len(rows) == 2:
        rows.append(np.cross(rows[0], rows[1]))
    return np.array(rows[:3])


def _fits_e13(x):
    return float("%13.5e" % x) == x


class UffLayout:
    """Node labels, coordinate systems and direction codes for the nominal geometry.

    One node per geometry point (sensor or excitation point); its displacement system is
    the global one (0) when all its directions are ±X/±Y/±Z, else the frame of its triaxial
    axes (dataset 2420). A direction that is not ± an axis of its node's system gets an
    extra node at the same place with its own system (x-axis = the direction). Labels are
    the point ids when they are all positive integers, else 1, 2, … in order of appearance;
    the rbprops tags on ID line 5 keep every id."""

    def __init__(self, case):
        points = {}
        for c in case.channels:
            points.setdefault(c["point"], (c["position"], []))[1].append(c["direction"])
        for e in case.excitations:
            points.setdefault(e["point"], (e["position"], []))[1].append(e["direction"])
        ids = list(points)
        numeric = all(i.isdigit() and int(i) > 0 for i in ids)
        self.nodes = []      # (label, position, cs label)
        self.systems = []    # (label, 3x3 rows)
        self.point_node = {}
        next_label = (max(int(i) for i in ids) + 1) if numeric else len(ids) + 1
        for n, pid in enumerate(ids):
            pos, dirs = points[pid]
            label = int(pid) if numeric else n + 1
            if all(_axis_code(d) is not None for d in dirs):
                cs = 0
                rows = np.eye(3)
            else:
                tri = [c["direction"] for c in case.channels if c["point"] == pid]
                base = tri[:3] if len(tri) >= 3 and abs(np.linalg.det(np.array(tri[:3]))) > 0.999 \
                    else [d for d in dirs if _axis_code(d) is None][:1]
                rows = _complete_frame(base)
                cs = label
                self.systems.append((cs, rows))
            self.nodes.append((label, pos, cs))
            self.point_node[pid] = (label, rows)
        self._extra_next = next_label
        self.dof = {}
        for kind, items in (("ch", case.channels), ("ex", case.excitations)):
            for it in items:
                label, rows = self.point_node[it["point"]]
                code = self._code_in(rows, it["direction"])
                if code is None:
                    label = self._extra_next
                    self._extra_next += 1
                    rows = _complete_frame([it["direction"]])
                    self.systems.append((label, rows))
                    self.nodes.append((label, it["position"], label))
                    code = 1
                self.dof[(kind, it["id"])] = (label, code)

    @staticmethod
    def _code_in(rows, d):
        for k in range(3):
            dot = rows[k] @ d
            if abs(abs(dot) - 1.0) < 1e-12:
                return int(np.sign(dot)) * (k + 1)
        return None


def _header_sets(pyuff, case, lay, node_dataset):
    """164 (SI), 2420 (when a frame is not the global one), 15 or 2411 nodes."""
    sets = [pyuff.prepare_164(units_code=1, units_description="SI", temp_mode=2,
                              length=1.0, force=1.0, temp=1.0, temp_offset=273.15)]
    if lay.systems:
        sets.append(pyuff.prepare_2420(
            Part_UID=1, Part_Name="rbref", CS_sys_labels=[s[0] for s in lay.systems],
            CS_types=[0] * len(lay.systems), CS_colors=[8] * len(lay.systems),
            CS_names=[f"cs{s[0]}" for s in lay.systems],
            CS_matrices=[np.vstack([s[1], np.zeros((1, 3))]) for s in lay.systems]))
    labels = [n[0] for n in lay.nodes]
    xyz = np.array([n[1] for n in lay.nodes], float)
    use15 = node_dataset == "15" or (node_dataset == "auto" and all(_fits_e13(v) for v in xyz.ravel()))
    if use15:
        sets.append(pyuff.prepare_15(node_nums=labels, def_cs=[0] * len(labels),
                                     disp_cs=[n[2] for n in lay.nodes], color=[8] * len(labels),
                                     x=xyz[:, 0].tolist(), y=xyz[:, 1].tolist(), z=xyz[:, 2].tolist()))
    else:
        sets.append(pyuff.prepare_2411(node_nums=np.array(labels), def_cs=np.zeros(len(labels), int),
                                       disp_cs=np.array([n[2] for n in lay.nodes]),
                                       color=np.full(len(labels), 8), x=xyz[:, 0], y=xyz[:, 1], z=xyz[:, 2]))
    return sets


def write_uff(result, path, binary=False, node_dataset="auto"):
    """UFF: 164 (SI), 2420 (when needed), 15 or 2411 nodes, one 58/58b per (excitation,
    channel) in excitation-major order. Ordinates: complex single (type 5) for float32
    data, complex double (6) otherwise; even abscissa (record 7 start/step, which
    `Case.frequency_axis` made exact in E13.5). `node_dataset`: "15", "2411" or "auto"
    (15 unless a coordinate needs more than the 6 significant digits of its E13.5 field)."""
    import pyuff
    case = result.case
    lay = UffLayout(case)
    freq = np.asarray(result.frequency_hz, float)
    start, step = freq[0], (freq[1] - freq[0]) if len(freq) > 1 else 1.0
    even = _fits_e13(start) and np.allclose(start + step * np.arange(len(freq)), freq, rtol=0,
                                            atol=1e-12 * max(1.0, abs(freq[-1])))
    if even:
        step = float("%13.5e" % step)
    else:
        import sys
        print(f"warning: {path}: the frequency axis is not an even axis with start and step of 6 "
              "significant digits: written as uneven abscissae, "
              + ("in the ordinates' precision" if binary else "each with 6 significant digits (E13.5)"),
              file=sys.stderr)
    sets = _header_sets(pyuff, case, lay, node_dataset)
    single = case.precision == "float32"
    ord_type = 5 if single else 6
    setup_desc = {s["id"]: s["description"] for s in case.setups}
    records = []
    for ei, e in enumerate(case.excitations):
        rn, rd = lay.dof[("ex", e["id"])]
        for ci, c in enumerate(case.channels):
            sn, sd = lay.dof[("ch", c["id"])]
            tags = f"rbprops ch={c['id']} cp={c['point']} ex={e['id']} ep={e['point']}"
            if len(tags) > 80 or any(" " in x or "=" in x for x in (c["id"], c["point"], e["id"], e["point"])):
                tags = "NONE"
            id4 = f"setup={e['setup']} {setup_desc[e['setup']]}".strip()[:80]
            records.append(dict(
                id1=f"rbref {case.name} {c['id']}/{e['id']}"[:80], id4=id4, id5=tags,
                rsp=(sn, sd), ref=(rn, rd), data=np.asarray(result.frf[ei, ci], complex)))
    if not binary:
        for r in records:
            sets.append(pyuff.prepare_58(
                binary=0, func_type=4, ver_num=0, load_case_id=0,
                rsp_ent_name="NONE", rsp_node=r["rsp"][0], rsp_dir=r["rsp"][1], ref_ent_name="NONE",
                ref_node=r["ref"][0], ref_dir=r["ref"][1], ord_data_type=ord_type, num_pts=len(freq),
                abscissa_spacing=1 if even else 0, abscissa_min=float(start),
                abscissa_inc=float(step) if even else 0.0, z_axis_value=0.0,
                abscissa_spec_data_type=18, abscissa_len_unit_exp=0, abscissa_force_unit_exp=0,
                abscissa_temp_unit_exp=0, abscissa_axis_units_lab="Hz",
                ordinate_spec_data_type=UFF_DATA_TYPE[case.quantity], ordinate_len_unit_exp=1,
                ordinate_force_unit_exp=0, ordinate_temp_unit_exp=0,
                ordinate_axis_units_lab=MOTION_LABEL[case.quantity],
                orddenom_spec_data_type=13, orddenom_len_unit_exp=0, orddenom_force_unit_exp=1,
                orddenom_temp_unit_exp=0, orddenom_axis_units_lab="N",
                z_axis_spec_data_type=0, z_axis_len_unit_exp=0, z_axis_force_unit_exp=0,
                z_axis_temp_unit_exp=0, z_axis_axis_units_lab="NONE",
                # pyuff takes complex128; with force_double=False it writes type 5 as E13.5
                data=r["data"], x=freq, id2="NONE", id3="NONE", id1=r["id1"], id4=r["id4"], id5=r["id5"]))

    def w(tmp):
        os.remove(tmp)  # pyuff appends to an existing file
        pyuff.UFF(tmp).write_sets(sets, mode="add", force_double=not single)
        if binary:
            with open(tmp, "ab") as fh:
                for r in records:
                    fh.write(_dataset_58b(r, case.quantity, single, even, start, step, freq))
    _atomic(path, w)


def _dataset_58b(r, quantity, single, even, start, step, freq):
    """One binary dataset 58b, written here because pyuff 2.5 writes doubles whatever the
    announced type and announces half the byte count of complex data. Little-endian IEEE:
    float32 pairs for type 5, float64 pairs for type 6; an uneven axis interleaves the
    abscissa (in the ordinate's precision). Records as in the ASCII form."""
    n = len(r["data"])
    dt = np.dtype("<f4" if single else "<f8")
    if even:
        vals = np.empty(2 * n)
        vals[0::2], vals[1::2] = r["data"].real, r["data"].imag
    else:
        vals = np.empty(3 * n)
        vals[0::3], vals[1::3], vals[2::3] = freq, r["data"].real, r["data"].imag
    payload = vals.astype(dt).tobytes()
    lab = lambda spec, le, fe, lab: "%10i%5i%5i%5i %-20s %-20s\n" % (spec, le, fe, 0, "NONE", lab)
    text = ("%6i\n%6ib%6i%6i%12i%12i%6i%6i%12i%12i\n" % (-1, 58, 1, 2, 11, len(payload), 0, 0, 0, 0)
            + "".join("%-80s\n" % x for x in (r["id1"], "NONE", "NONE", r["id4"], r["id5"]))
            + "%5i%10i%5i%10i %10s%10i%4i %10s%10i%4i\n" % (4, 1, 0, 0, "NONE", r["rsp"][0], r["rsp"][1],
                                                             "NONE", r["ref"][0], r["ref"][1])
            + "%10i%10i%10i%13.5e%13.5e%13.5e\n" % (5 if single else 6, n, int(even),
                                                   start if even else 0.0, step if even else 0.0, 0.0)
            + lab(18, 0, 0, "Hz") + lab(UFF_DATA_TYPE[quantity], 1, 0, MOTION_LABEL[quantity])
            + lab(13, 0, 1, "N") + lab(0, 0, 0, "NONE"))
    return text.encode("ascii") + payload + b"%6i\n" % -1


TIME_DATA_TYPE = {"receptance": 8, "mobility": 11, "accelerance": 12}


def time_records(result, layout):
    """The UFF 58 function-type-1 records of a recording, in file order, as dicts:
    per-hit: for each excitation, for each hit 1..n, the force then every channel
    (load_case_id = hit number); throughput: for each excitation, the force then every
    channel, each the run's whole stream of n segments (load_case_id = 0)."""
    case, rec = result.case, result.recording
    lay = UffLayout(case)
    n = rec.n_record
    out = []
    for ei, e in enumerate(case.excitations):
        rn, rd = lay.dof[("ex", e["id"])]
        id4 = f"setup={e['setup']} " + next(s["description"] for s in case.setups if s["id"] == e["setup"])
        hits = range(1, case.time["impacts"] + 1) if layout == "per-hit" else [0]
        for h in hits:
            hit_tag = f" hit={h}" if h else " hits=" + str(case.time["impacts"])
            if h:
                f, y = rec.force[ei][h - 1, :n], rec.response[ei][h - 1, :, :n]
            else:
                f = rec.force[ei].reshape(-1)
                y = np.moveaxis(rec.response[ei], 1, 0).reshape(len(case.channels), -1)
            tags = f"rbprops ex={e['id']} ep={e['point']}{hit_tag}"
            what = f"hit {h}" if h else "throughput"
            out.append(dict(id1=f"rbref {case.name} force {e['id']} {what}"[:80], id4=id4.strip()[:80],
                            id5=tags if len(tags) <= 80 else "NONE", rsp=(rn, rd), ref=(rn, rd),
                            load_case=h, force=True, data=np.ascontiguousarray(f, float)))
            for ci, c in enumerate(case.channels):
                sn, sd = lay.dof[("ch", c["id"])]
                tags = f"rbprops ch={c['id']} cp={c['point']} ex={e['id']} ep={e['point']}{hit_tag}"
                if len(tags) > 80 or any(" " in x or "=" in x for x in (c["id"], c["point"], e["id"], e["point"])):
                    tags = "NONE"
                out.append(dict(id1=f"rbref {case.name} {c['id']}/{e['id']} {what}"[:80], id4=id4.strip()[:80],
                                id5=tags, rsp=(sn, sd), ref=(rn, rd), load_case=h, force=False,
                                data=np.ascontiguousarray(y[ci], float)))
    return out


def _time_labels(quantity, force):
    """(ordinate spec data type, length exp, force exp, units label)."""
    if force:
        return 13, 0, 1, "N"
    return TIME_DATA_TYPE[quantity], 1, 0, MOTION_LABEL[quantity]


def check_time_uff(result):
    """Refuses (ValueError) a recording whose time axis a UFF record 7 cannot carry exactly."""
    rec = result.recording
    if rec is None:
        raise ValueError("time-history output needs a [time] case")
    dt = 1.0 / rec.fs
    if not _fits_e13(dt):
        raise ValueError(f"time.sample_rate_hz: 1/f_s = {dt!r} s needs more than the 6 significant digits "
                         "of a UFF record 7 (E13.5); use a rate whose period fits, e.g. 256, 400, 500, 800, "
                         "1000, 1280, 1600, 2560, 3200, 6400, 12800 or 25600 Hz")


def write_time_uff(result, path, layout="per-hit", binary=False, node_dataset="auto"):
    """The time histories of a recording: UFF 164, 2420 (when needed), 15/2411 as
    write_uff, then one 58 (function type 1, real double, even abscissa from 0 s with
    step 1/f_s) per record of `time_records`. ASCII (%20.11e: the ADC's samples exactly)
    or binary 58b (little-endian float64, our own writer)."""
    import pyuff
    check_time_uff(result)
    case, rec = result.case, result.recording
    dt = 1.0 / rec.fs
    lay = UffLayout(case)
    sets = _header_sets(pyuff, case, lay, node_dataset)
    records = time_records(result, layout)
    if not binary:
        for r in records:
            spec, le, fe, lab = _time_labels(case.quantity, r["force"])
            x = np.arange(len(r["data"])) * dt
            sets.append(pyuff.prepare_58(
                binary=0, func_type=1, ver_num=0, load_case_id=int(r["load_case"]),
                rsp_ent_name="NONE", rsp_node=r["rsp"][0], rsp_dir=r["rsp"][1], ref_ent_name="NONE",
                ref_node=r["ref"][0], ref_dir=r["ref"][1], ord_data_type=4, num_pts=len(r["data"]),
                abscissa_spacing=1, abscissa_min=0.0, abscissa_inc=dt, z_axis_value=0.0,
                abscissa_spec_data_type=17, abscissa_len_unit_exp=0, abscissa_force_unit_exp=0,
                abscissa_temp_unit_exp=0, abscissa_axis_units_lab="s",
                ordinate_spec_data_type=spec, ordinate_len_unit_exp=le, ordinate_force_unit_exp=fe,
                ordinate_temp_unit_exp=0, ordinate_axis_units_lab=lab,
                orddenom_spec_data_type=0, orddenom_len_unit_exp=0, orddenom_force_unit_exp=0,
                orddenom_temp_unit_exp=0, orddenom_axis_units_lab="NONE",
                z_axis_spec_data_type=0, z_axis_len_unit_exp=0, z_axis_force_unit_exp=0,
                z_axis_temp_unit_exp=0, z_axis_axis_units_lab="NONE",
                data=r["data"], x=x, id2="NONE", id3="NONE", id1=r["id1"], id4=r["id4"], id5=r["id5"]))

    def w(tmp):
        os.remove(tmp)  # pyuff appends to an existing file
        pyuff.UFF(tmp).write_sets(sets, mode="add", force_double=True)
        if binary:
            with open(tmp, "ab") as fh:
                for r in records:
                    fh.write(_dataset_58b_time(r, case.quantity, dt))
    _atomic(path, w)


def _dataset_58b_time(r, quantity, dt):
    """One binary 58b of real float64 (type 4) time data, little-endian."""
    n = len(r["data"])
    payload = np.asarray(r["data"], "<f8").tobytes()
    spec, le, fe, lab = _time_labels(quantity, r["force"])
    line = lambda sp, l_, f_, u: "%10i%5i%5i%5i %-20s %-20s\n" % (sp, l_, f_, 0, "NONE", u)
    text = ("%6i\n%6ib%6i%6i%12i%12i%6i%6i%12i%12i\n" % (-1, 58, 1, 2, 11, len(payload), 0, 0, 0, 0)
            + "".join("%-80s\n" % x for x in (r["id1"], "NONE", "NONE", r["id4"], r["id5"]))
            + "%5i%10i%5i%10i %10s%10i%4i %10s%10i%4i\n" % (1, 1, 0, int(r["load_case"]), "NONE", r["rsp"][0],
                                                             r["rsp"][1], "NONE", r["ref"][0], r["ref"][1])
            + "%10i%10i%10i%13.5e%13.5e%13.5e\n" % (4, n, 1, 0.0, dt, 0.0)
            + line(17, 0, 0, "s") + line(spec, le, fe, lab) + line(0, 0, 0, "NONE") + line(0, 0, 0, "NONE"))
    return text.encode("ascii") + payload + b"%6i\n" % -1
