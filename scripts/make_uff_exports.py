#!/usr/bin/env python3
"""Writes UFF files shaped like commercial analyser exports, for the reader's tests.

Each file is written by the independent writer pyuff and then edited the way analysers
bend the format (units labels in Latin-1 or UTF-8, CRLF line ends, a stray line end
after binary data, blank-separated values, geometry in a separate file, node 0 with the
DOF in the names, coherence and auto-spectra next to the FRFs, a file without FRFs).
Beside each `<name>.uff` goes `<name>.json` with what the reader must return: the FRF
values pyuff was given, scaled to SI here by hand (the factors are written out below,
not taken from the reader), the frequency axis in Hz, node positions and directions
(numpy), the coherence, the relative tolerance the printed precision allows, or the
error text the reader must give.

Usage (deterministic; the outputs are committed under fixtures/uff/exports/):

    python3 scripts/make_uff_exports.py [out_dir]
"""
import json
import os
import sys

import numpy as np
import pyuff

OUT = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
    os.path.dirname(os.path.abspath(__file__)), "..", "fixtures", "uff", "exports")

# Exact definitions of the units (SI per unit).
LBF = 4.4482216152605  # N
INCH = 0.0254  # m
G0 = 9.80665  # m/s^2
# Relative precision of what pyuff prints: E13.5 (6 significant digits) for single
# precision and abscissae, %20.11e (12 digits) for double; binary doubles are exact, up
# to the rounding of one multiplication by the SI factor on either side.
E13 = 5e-6
E20 = 5e-12
BIN = 4e-16


def dof_name(node, direction):
    return f"{node}{'-' if direction < 0 else ''}{'xyz'[abs(direction) - 1]}"


def frf_values(rng, n, real=False):
    """FRF-like values spanning six decades, so fixed-width fields are exercised."""
    re = rng.uniform(-2.0, 2.0, n) * 10.0 ** rng.integers(-6, 2, n)
    if real:
        return re
    im = rng.uniform(-2.0, 2.0, n) * 10.0 ** rng.integers(-6, 2, n)
    return re + 1j * im


def fresh(path):
    if os.path.exists(path):
        os.remove(path)
    return pyuff.UFF(path)


def nodes_2411(nodes):
    labels = sorted(nodes)
    return pyuff.prepare_2411(
        node_nums=np.array(labels), def_cs=np.zeros(len(labels), int),
        disp_cs=np.array([nodes[k][1] for k in labels]), color=np.full(len(labels), 8),
        x=np.array([nodes[k][0][0] for k in labels], float),
        y=np.array([nodes[k][0][1] for k in labels], float),
        z=np.array([nodes[k][0][2] for k in labels], float))


def si164(code=1, desc="SI", length=1.0, force=1.0):
    return pyuff.prepare_164(units_code=code, units_description=desc, temp_mode=2,
                             length=length, force=force, temp=1.0, temp_offset=273.15)


def func(rsp, ref, x, data, *, binary=False, ordinate=6, func_type=4, num_type=12,
         num_label="NONE", den_type=13, den_label="NONE", even=True, id1="NONE",
         rsp_ent="NONE", ref_ent="NONE", ab_type=18, ab_label="Hz"):
    return pyuff.prepare_58(
        binary=int(binary), func_type=func_type, ver_num=0, load_case_id=0,
        rsp_ent_name=rsp_ent, rsp_node=rsp[0], rsp_dir=rsp[1],
        ref_ent_name=ref_ent, ref_node=ref[0], ref_dir=ref[1],
        ord_data_type=ordinate, num_pts=len(x), abscissa_spacing=int(even),
        abscissa_min=float(x[0]), abscissa_inc=float(x[1] - x[0]) if even else 0.0,
        z_axis_value=0.0, abscissa_spec_data_type=ab_type, abscissa_len_unit_exp=0,
        abscissa_force_unit_exp=0, abscissa_temp_unit_exp=0, abscissa_axis_units_lab=ab_label,
        ordinate_spec_data_type=num_type, ordinate_len_unit_exp=1,
        ordinate_force_unit_exp=0, ordinate_temp_unit_exp=0,
        ordinate_axis_units_lab=num_label, orddenom_spec_data_type=den_type,
        orddenom_len_unit_exp=0, orddenom_force_unit_exp=1, orddenom_temp_unit_exp=0,
        orddenom_axis_units_lab=den_label, z_axis_spec_data_type=0, z_axis_len_unit_exp=0,
        z_axis_force_unit_exp=0, z_axis_temp_unit_exp=0, z_axis_axis_units_lab="NONE",
        data=data, x=np.asarray(x, float), id1=id1)


# ---------------------------------------------------------------- byte-level edits

def split_datasets(raw):
    """Dataset byte ranges [(start, end)] of an ASCII file (end after the closing -1)."""
    lines = raw.split(b"\n")
    out, pos, start = [], 0, None
    for ln in lines:
        if ln.strip() == b"-1":
            if start is None:
                start = pos
            else:
                out.append((start, pos + len(ln) + 1))
                start = None
        pos += len(ln) + 1
    return out


def set_units_label(raw, record, label_bytes, only=None):
    """Replaces the units label (columns 48-67) of record 8, 9 or 10 of every ASCII
    dataset 58 (or those whose 1-based index among datasets 58 is in `only`)."""
    lines = raw.split(b"\n")
    k58 = 0
    for i, ln in enumerate(lines):
        if ln.rstrip() == b"    58" and i > 0 and lines[i - 1].strip() == b"-1":
            k58 += 1
            if only is not None and k58 not in only:
                continue
            j = i + record
            lines[j] = lines[j][:47] + label_bytes
    return b"\n".join(lines)


def set_ordinate_type(raw, record, data_type):
    """Sets the specific data type (columns 1-10) of record 9 or 10 in every dataset 58."""
    lines = raw.split(b"\n")
    for i, ln in enumerate(lines):
        if ln.rstrip() in (b"    58", ) or ln.startswith(b"    58b"):
            if i > 0 and lines[i - 1].strip() == b"-1":
                lines[i + record] = b"%10i" % data_type + lines[i + record][10:]
    return b"\n".join(lines)


def blank_node0(raw, id_lines=None, entities=None):
    """Record 6 response/reference node and direction set to 0 in every ASCII dataset 58;
    optionally ID line 1 / the entity names replaced (lists, one entry per dataset 58)."""
    lines = raw.split(b"\n")
    k = 0
    for i, ln in enumerate(lines):
        if ln.rstrip() == b"    58" and lines[i - 1].strip() == b"-1":
            r6 = lines[i + 6].decode()
            ftype, fid, ver, lc = r6[0:5], r6[5:15], r6[15:20], r6[20:30]
            rent, eent = r6[31:41], r6[56:66]
            if entities is not None:
                rent, eent = entities[k]
            r6 = f"{ftype}{fid}{ver}{lc} {rent:<10s}{0:10d}{0:4d} {eent:<10s}{0:10d}{0:4d}"
            lines[i + 6] = r6.encode()
            if id_lines is not None:
                lines[i + 1] = id_lines[k].encode()
            k += 1
    return b"\n".join(lines)


def write_sidecar(name, **kw):
    with open(os.path.join(OUT, name + ".json"), "w") as fh:
        json.dump({"file": name + ".uff", "writer": f"pyuff {pyuff.__version__}", **kw},
                  fh, indent=1)


def frf_entries(cells, factor):
    """Sidecar FRFs: the values handed to pyuff times the SI factor computed by hand."""
    out = []
    for (ch, ex), data in cells:
        v = np.asarray(data) * factor
        out.append({"channel": ch, "excitation": ex,
                    "re": [float(a) for a in np.real(v)],
                    "im": [float(a) for a in (np.imag(v) if np.iscomplexobj(v)
                                              else np.zeros(len(v)))]})
    return out


def write_raw(name, raw):
    with open(os.path.join(OUT, name + ".uff"), "wb") as fh:
        fh.write(raw)
    print("wrote", name)


def pyuff_bytes(sets, force_double=True):
    tmp = os.path.join(OUT, "_tmp.uff")
    u = fresh(tmp)
    u.write_sets(sets, mode="add", force_double=force_double)
    with open(tmp, "rb") as fh:
        raw = fh.read()
    os.remove(tmp)
    return raw


# ---------------------------------------------------------------- the exports

NODES = {1: ((0.1, 0.0, 0.05), 0), 2: ((-0.05, 0.125, 0.0), 0),
         3: ((-0.04, -0.11, 0.02), 0), 4: ((0.2, 0.01, -0.03), 0)}
RESP = [(1, 1), (2, 2), (3, -3)]
REFS = [(4, 1), (1, 3)]


def grid(rng, x, real=False, resp=RESP, refs=REFS):
    """One FRF per (reference, response), excitation-major."""
    return [((dof_name(*r), dof_name(*e)), frf_values(rng, len(x), real))
            for e in refs for r in resp]


def frf_sets(cells, x, resp=RESP, refs=REFS, **kw):
    out = []
    k = 0
    for e in refs:
        for r in resp:
            out.append(func(r, e, x, cells[k][1], **kw))
            k += 1
    return out


def base_sidecar(x_hz, rel, quantity="accelerance", nodes=NODES, length=1.0):
    return dict(expect="ok", quantity=quantity, frequency_hz=[float(f) for f in x_hz],
                rel_tol=rel, channels=[dof_name(*r) for r in RESP],
                excitations=[dof_name(*e) for e in REFS],
                nodes={str(k): [c * length for c in v[0]] for k, v in nodes.items()})


def label_file(name, rng, label_bytes, factor, *, record=9, ordinate=6, force_double=True,
               rel=E20, crlf=False, den_label=None, num_type=12, pre=(), length=1.0):
    """FRFs whose units label is edited to `label_bytes`; `factor` is SI per file value."""
    x = np.arange(6) * 0.5 + 1.0
    cells = grid(rng, x)
    sets = [*pre, nodes_2411(NODES)] + frf_sets(cells, x, ordinate=ordinate, num_type=num_type)
    raw = pyuff_bytes(sets, force_double=force_double)
    raw = set_units_label(raw, record, label_bytes)
    if den_label is not None:
        raw = set_units_label(raw, 10, den_label)
    if crlf:
        raw = raw.replace(b"\n", b"\r\n")
    write_raw(name, raw)
    write_sidecar(name, **base_sidecar(x, rel, length=length), frfs=frf_entries(cells, factor),
                  labels=label_bytes.decode("latin-1"))


def main():
    os.makedirs(OUT, exist_ok=True)
    rng = np.random.default_rng(20261125)

    # 1. `(1/N)*(m/s²)` with ² as the Latin-1 byte 0xB2, ASCII complex double.
    label_file("label_latin1_product", rng, b"(1/N)*(m/s\xb2)", 1.0)
    # 2. `mm/s²/N` in UTF-8 (² is two bytes, one column), ASCII complex double.
    label_file("label_utf8_mm_s2_per_n", rng, "mm/s²/N".encode(), 1e-3)
    # 3. Upper case: numerator `G`, denominator `LBF`.
    label_file("label_upper_g_lbf", rng, b"G", G0 / LBF, den_label=b"LBF")
    # 4. `in/s^2/lbf` with CRLF line ends.
    label_file("label_in_s2_lbf_crlf", rng, b"in/s^2/lbf", INCH / LBF, crlf=True)
    # 5. `(m/s2)/N`, ASCII complex single (E13.5: 6 significant digits).
    label_file("label_paren_ascii_single", rng, b"(m/s2)/N", 1.0, ordinate=5,
               force_double=False, rel=E13)
    # 6. A label that contradicts record 9: data type 12 (acceleration) but `m/s`, in an
    #    inch/pound-force file (dataset 164 code 7): record 9 wins, with a warning.
    label_file("label_contradicts_record9", rng, b"m/s", INCH / LBF,
               pre=[si164(7, "IN", 1.0 / INCH, 1.0 / LBF)], length=INCH)
    with open(os.path.join(OUT, "label_contradicts_record9.json")) as fh:
        side = json.load(fh)
    side["warnings"] = ["contradicts data type 12"]
    with open(os.path.join(OUT, "label_contradicts_record9.json"), "w") as fh:
        json.dump(side, fh, indent=1)

    # 7. `dB` with data type 0 (nothing else says what the values are): refused.
    x = np.arange(4) * 1.0 + 1.0
    cells = grid(rng, x)
    raw = pyuff_bytes([nodes_2411(NODES)] + frf_sets(cells, x, num_type=0))
    write_raw("label_db_refused", set_units_label(raw, 9, b"dB"))
    write_sidecar("label_db_refused", expect="error",
                  error_contains=["logarithmic", "nothing determines the unit"])

    # 8. Binary 58b, real double, with a stray line end (one, then two) between the data
    #    and the closing delimiter; labels `m/s^2` and `N`.
    x = np.arange(8) * 0.25
    cells = grid(rng, x, real=True)
    sets = [nodes_2411(NODES)] + frf_sets(cells, x, binary=True, ordinate=4,
                                          num_label="m/s^2", den_label="N")
    raw = pyuff_bytes(sets)
    parts = raw.split(b"    -1\n")
    # pyuff ends each 58b's data right before "    -1": add line ends there.
    out = []
    n58 = 0
    for p in parts:
        if b"    58b" in p:
            n58 += 1
            p = p + (b"\n" if n58 % 2 else b"\r\n\n")
        out.append(p)
    write_raw("binary_double_stray_line_end", b"    -1\n".join(out))
    write_sidecar("binary_double_stray_line_end", **base_sidecar(x, BIN),
                  frfs=frf_entries(cells, 1.0))

    # 9. ASCII values separated by blanks instead of in fixed columns (shortest exact
    #    decimal, three numbers a line); the count matches record 7 exactly.
    x = np.arange(5) * 2.0 + 2.0
    cells = grid(rng, x)
    raw = pyuff_bytes([nodes_2411(NODES)] + frf_sets(cells, x, num_label="m/s^2",
                                                    den_label="N"))
    lines = raw.split(b"\n")
    out, k, i = [], 0, 0
    while i < len(lines):
        out.append(lines[i])
        if lines[i].rstrip() == b"    58" and lines[i - 1].strip() == b"-1":
            out.extend(lines[i + 1:i + 12])
            nums = []
            for v in cells[k][1]:
                nums += [repr(float(v.real)), repr(float(v.imag))]
            for j in range(0, len(nums), 3):
                out.append(" ".join(nums[j:j + 3]).encode())
            k += 1
            i += 12
            while lines[i].strip() != b"-1":
                i += 1
            continue
        i += 1
    write_raw("ascii_blank_separated", b"\n".join(out))
    write_sidecar("ascii_blank_separated", **base_sidecar(x, 0.0),
                  frfs=frf_entries(cells, 1.0))

    # 10. Blank-separated values whose count does not match record 7: refused.
    good = b"\n".join(out)
    first_close = good.index(b"\n    -1\n", good.index(b"\n    58 "))
    bad = good[:first_close] + b" 0.5" + good[first_close:]
    write_raw("ascii_blank_separated_count_mismatch", bad)
    write_sidecar("ascii_blank_separated_count_mismatch", expect="error",
                  error_contains=["blank-separated", "not guessing"])

    # 11-12. Geometry and data in two files. Geometry: millimetres (164 code 5), a 2420
    #    system rotated about z by 0.3 rad and about x by 0.2 rad with an origin offset;
    #    node 2 is defined in it (dataset 15, definition system 7) and measures in it
    #    (displacement system 7); node 3 measures in a dataset 18 system.
    cz, sz, cx, sx = np.cos(0.3), np.sin(0.3), np.cos(0.2), np.sin(0.2)
    rz = np.array([[cz, sz, 0.0], [-sz, cz, 0.0], [0.0, 0.0, 1.0]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cx, sx], [0.0, -sx, cx]])
    rot = rx @ rz  # rows = local axes in global coordinates
    origin = np.array([10.0, -20.0, 5.0])  # mm
    o18, px18, pxz18 = (np.array([0.0, 0.0, 0.0]), np.array([0.0, 10.0, 0.0]),
                        np.array([0.0, 0.0, 10.0]))
    ex = (px18 - o18) / np.linalg.norm(px18 - o18)
    v = pxz18 - o18
    ez = v - ex * (ex @ v)
    ez /= np.linalg.norm(ez)
    rows18 = np.vstack([ex, np.cross(ez, ex), ez])
    local2 = np.array([50.0, 25.0, -12.5])  # node 2 in system 7, mm
    geo_nodes = {1: ([100.0, 0.0, 50.0], 0, 0), 2: (list(local2), 7, 7),
                 3: ([-40.0, -110.0, 20.0], 0, 3), 4: ([200.0, 10.0, -30.0], 0, 0),
                 9: ([0.0, 0.0, 0.0], 0, 0)}
    labels = sorted(geo_nodes)
    geo = [si164(5, "MM", 1000.0, 1000.0),
           pyuff.prepare_2420(Part_UID=1, Part_Name="split geometry", CS_sys_labels=[7],
                              CS_types=[0], CS_colors=[8], CS_names=["rotated"],
                              CS_matrices=[np.vstack([rot, origin])]),
           pyuff.prepare_18(cs_num=[3], cs_type=[0], ref_cs_num=[0], color=[1], method=[1],
                            cs_name=["side"], ref_o=[list(o18)], x_point=[list(px18)],
                            xz_point=[list(pxz18)]),
           pyuff.prepare_15(node_nums=labels, def_cs=[geo_nodes[k][1] for k in labels],
                            disp_cs=[geo_nodes[k][2] for k in labels], color=[8] * len(labels),
                            x=[geo_nodes[k][0][0] for k in labels],
                            y=[geo_nodes[k][0][1] for k in labels],
                            z=[geo_nodes[k][0][2] for k in labels])]
    write_raw("split_geometry", pyuff_bytes(geo))
    x = np.arange(6) * 0.5 + 0.5
    cells = grid(rng, x)
    write_raw("split_data", pyuff_bytes(frf_sets(cells, x, num_label="g", den_label="N")))
    pos = {k: np.array(geo_nodes[k][0]) * 1e-3 for k in labels}
    pos[2] = (rot.T @ local2 + origin) * 1e-3  # global = Rᵀ local + origin
    axes = {k: np.eye(3) for k in labels}
    axes[2] = rot
    axes[3] = rows18
    dirs = {dof_name(n, d): list(np.sign(d) * axes[n][abs(d) - 1]) for n, d in RESP + REFS}
    side = base_sidecar(x, E20)
    side["nodes"] = {str(k): [float(c) for c in pos[k]] for k in labels}
    side.update(geometry="split_geometry.uff", directions=dirs, pos_tol=E13 * 0.25,
                frfs=frf_entries(cells, G0),
                warnings=["geometry node(s) carry no FRF channel or excitation"])
    write_sidecar("split_data", **side)
    # Without the geometry the data file names the missing nodes.
    write_sidecar("split_data_alone", file="split_data.uff", expect="error",
                  error_contains=["have no coordinates: 1, 2, 3, 4", "--geometry"])

    # 13. Node 0 in record 6; the DOFs in the entity names (`Point3:-Z`) for the first
    #     reference and in ID line 1 (`Point3:-Z / Point4:+X`) for the second.
    x = np.arange(5) * 1.0 + 1.0
    cells = grid(rng, x)
    raw = pyuff_bytes([nodes_2411(NODES)] + frf_sets(cells, x, num_label="m/s^2",
                                                    den_label="N"))
    def pname(n, d):
        return f"Point{n}:{'+-'[d < 0]}{'XYZ'[abs(d) - 1]}"
    ents, ids = [], []
    for k, e in enumerate(REFS):
        for r in RESP:
            if k == 0:
                ents.append((pname(*r), pname(*e)))
                ids.append("FRF")
            else:
                ents.append(("NONE", "NONE"))
                ids.append(f"FRF {pname(*r)} / {pname(*e)}")
    write_raw("node0_dofs_in_names", blank_node0(raw, ids, ents))
    write_sidecar("node0_dofs_in_names", **base_sidecar(x, E20), frfs=frf_entries(cells, 1.0))

    # 14. Node 0 and `H1 : #  n / #  m` ID lines (no direction): DOFs from a channel map,
    #     by dataset index for the first reference and by ID text for the second.
    cells = grid(rng, x)
    raw = pyuff_bytes([nodes_2411(NODES)] + frf_sets(cells, x, num_label="m/s^2",
                                                    den_label="N"))
    ids, rows = [], []
    k = 0
    for ei, e in enumerate(REFS):
        for ri, r in enumerate(RESP):
            text = f"H1 : #{ri + 2:3d} / #{ei + 1:3d}"
            ids.append(text)
            dd = lambda d: f"{'+-'[d < 0]}{'xyz'[abs(d) - 1]}"
            key = (str(k + 2), "") if ei == 0 else ("", f'"{text}"')
            rows.append(f"{key[0]},{key[1]},FRF,{r[0]},{dd(r[1])},{e[0]},{dd(e[1])}")
            k += 1
    write_raw("node0_channel_map", blank_node0(raw, ids))
    with open(os.path.join(OUT, "node0_channel_map.csv"), "w") as fh:
        fh.write("dataset,id_line_1,function,response_point,response_direction,"
                 "reference_point,reference_direction\n" + "\n".join(rows) + "\n")
    write_sidecar("node0_channel_map", **base_sidecar(x, E20), channels_map="node0_channel_map.csv",
                  frfs=frf_entries(cells, 1.0))
    write_sidecar("node0_channel_map_without_map", file="node0_channel_map.uff",
                  expect="error", error_contains=["channel map", "H1 : #  2 / #  1"])

    # 15. FRFs (binary double, g/N) with coherence (type 6) for each pair and
    #     auto-spectra (type 2) of each response, interleaved as analysers export them.
    x = np.arange(7) * 0.5 + 0.5
    cells = grid(rng, x)
    sets = [nodes_2411(NODES)]
    coh = []
    k = 0
    for e in REFS:
        for r in RESP:
            sets.append(func(r, e, x, cells[k][1], binary=True, num_label="g", den_label="N"))
            g2 = np.round(rng.uniform(0.2, 1.0, len(x)), 6)
            coh.append({"channel": dof_name(*r), "excitation": dof_name(*e),
                        "values": [float(v) for v in g2]})
            sets.append(func(r, e, x, g2, binary=True, func_type=6, ordinate=4, num_type=0,
                             den_type=0))
            k += 1
    for r in RESP:
        sets.append(func(r, r, x, rng.uniform(1e-6, 1e-3, len(x)), binary=True,
                         func_type=2, ordinate=4, num_type=12, num_label="g^2/Hz",
                         den_type=0))
    write_raw("mixed_frf_coherence_autospectra", pyuff_bytes(sets))
    write_sidecar("mixed_frf_coherence_autospectra", **base_sidecar(x, BIN),
                  frfs=frf_entries(cells, G0), coherence=coh,
                  warnings=["3 auto spectrum (type 2)"])

    # 16. No FRF at all: time histories (type 1) and PSDs (type 9).
    t = np.arange(16) * 0.01
    sets = [nodes_2411(NODES)]
    for r in RESP[:2]:
        sets.append(func(r, (0, 0), t, rng.normal(size=len(t)), ordinate=2,
                         func_type=1, num_type=12, den_type=0, ab_type=17, ab_label="s"))
    for r in RESP:
        sets.append(func(r, r, x, rng.uniform(1e-6, 1e-3, len(x)), ordinate=4,
                         func_type=9, num_type=12, num_label="g^2/Hz", den_type=0))
    write_raw("no_frf_time_and_psd", pyuff_bytes(sets, force_double=False))
    write_sidecar("no_frf_time_and_psd", expect="error",
                  error_contains=["no FRF datasets", "time response (type 1): 2",
                                  "PSD (type 9): 3", "dataset 2411"])


if __name__ == "__main__":
    main()
