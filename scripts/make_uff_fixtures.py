#!/usr/bin/env python3
"""Writes small UFF fixtures with the independent writer pyuff, plus JSON sidecars.

Usage (once; outputs are committed under fixtures/uff/):

    python3 -m venv /tmp/uffvenv && /tmp/uffvenv/bin/pip install pyuff numpy
    /tmp/uffvenv/bin/python scripts/make_uff_fixtures.py [out_dir]

Each `<name>.uff` gets a `<name>.json` with the exact values handed to pyuff (in the
file's units), the SI conversion factors, the expected channel/excitation ids and
global directions (computed here with numpy, independently of the Rust reader), and
the relative tolerance implied by the printed precision of the fields pyuff used.
"""
import json
import os
import sys

import numpy as np
import pyuff

OUT = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
    os.path.dirname(os.path.abspath(__file__)), "..", "fixtures", "uff")
LBF = 4.4482216152605
INCH = 0.0254
# Relative precision of the fields pyuff writes: E13.5 = 6 significant digits,
# %20.11e = 12 significant digits; binary doubles are exact.
E13 = 5e-6
E20 = 5e-12


def dof_name(node, direction):
    letter = "xyz"[abs(direction) - 1]
    return f"{node}{'-' if direction < 0 else ''}{letter}"


def frf_values(rng, n, real=False):
    re = rng.uniform(-2.0, 2.0, n) * 10.0 ** rng.integers(-6, 2, n)
    if real:
        return re
    im = rng.uniform(-2.0, 2.0, n) * 10.0 ** rng.integers(-6, 2, n)
    return re + 1j * im


def fresh(path):
    if os.path.exists(path):
        os.remove(path)
    return pyuff.UFF(path)


def frf_set(name, rng, *, nodes, responses, references, x, even, binary, ordinate,
            num_type, num_label, den_label, setups=None, real=False, force_double=True,
            extra_sets=(), pre_sets=(), node_set=2411, length_to_si=1.0, value_to_si=1.0,
            frequency_to_hz=1.0, rel_tol=E20, pos_tol=1e-15, dir_tol=1e-15,
            directions=None, quantity=None, abscissa_label="Hz"):
    """Writes one fixture and its sidecar."""
    path = os.path.join(OUT, name + ".uff")
    u = fresh(path)
    sets = list(pre_sets)
    labels = sorted(nodes)
    if node_set == 2411:
        sets.append(pyuff.prepare_2411(
            node_nums=np.array(labels), def_cs=np.zeros(len(labels), int),
            disp_cs=np.array([nodes[k][1] for k in labels]),
            color=np.full(len(labels), 8),
            x=np.array([nodes[k][0][0] for k in labels], float),
            y=np.array([nodes[k][0][1] for k in labels], float),
            z=np.array([nodes[k][0][2] for k in labels], float)))
    else:
        sets.append(pyuff.prepare_15(
            node_nums=labels, def_cs=[0] * len(labels),
            disp_cs=[nodes[k][1] for k in labels], color=[8] * len(labels),
            x=[float(nodes[k][0][0]) for k in labels],
            y=[float(nodes[k][0][1]) for k in labels],
            z=[float(nodes[k][0][2]) for k in labels]))
    frfs = []
    fid = 0
    for (rn, rd) in references:
        for (sn, sd) in responses:
            fid += 1
            data = frf_values(rng, len(x), real)
            setup = (setups or {}).get((rn, rd))
            d = pyuff.prepare_58(
                binary=int(binary), func_type=4, ver_num=0, load_case_id=0,
                rsp_ent_name="NONE", rsp_node=sn, rsp_dir=sd,
                ref_ent_name="NONE", ref_node=rn, ref_dir=rd,
                ord_data_type=ordinate, num_pts=len(x), abscissa_spacing=int(even),
                abscissa_min=float(x[0]), abscissa_inc=float(x[1] - x[0]) if even else 0.0,
                z_axis_value=0.0,
                abscissa_spec_data_type=18, abscissa_len_unit_exp=0,
                abscissa_force_unit_exp=0, abscissa_temp_unit_exp=0,
                abscissa_axis_units_lab=abscissa_label,
                ordinate_spec_data_type=num_type, ordinate_len_unit_exp=1,
                ordinate_force_unit_exp=0, ordinate_temp_unit_exp=0,
                ordinate_axis_units_lab=num_label,
                orddenom_spec_data_type=13, orddenom_len_unit_exp=0,
                orddenom_force_unit_exp=1, orddenom_temp_unit_exp=0,
                orddenom_axis_units_lab=den_label,
                z_axis_spec_data_type=0, z_axis_len_unit_exp=0, z_axis_force_unit_exp=0,
                z_axis_temp_unit_exp=0, z_axis_axis_units_lab="NONE",
                data=data, x=np.asarray(x, float), id1=f"pyuff fixture {fid}",
                id4=f"setup={setup}" if setup else "NONE")
            sets.append(d)
            arr = np.asarray(data)
            frfs.append({
                "channel": dof_name(sn, sd),
                "excitation": dof_name(rn, rd) + (f"@{setup}" if setup and setup != "A" else ""),
                "re": [float(v) for v in np.real(arr)],
                "im": [float(v) for v in (np.imag(arr) if np.iscomplexobj(arr) else np.zeros(len(arr)))],
            })
    sets.extend(extra_sets)
    u.write_sets(sets, mode="add", force_double=force_double)
    sidecar = {
        "file": name + ".uff",
        "writer": f"pyuff {pyuff.__version__}",
        "quantity": quantity,
        "value_to_si": value_to_si,
        "length_to_si": length_to_si,
        "frequency_hz": [float(f) * frequency_to_hz for f in x],
        "rel_tol": rel_tol,
        "pos_tol": pos_tol,
        "dir_tol": dir_tol,
        "nodes": {str(k): [float(c) for c in nodes[k][0]] for k in labels},
        "channels": [dof_name(n, d) for (n, d) in responses],
        "excitations": [dof_name(n, d) + (f"@{(setups or {}).get((n, d))}"
                        if (setups or {}).get((n, d), "A") != "A" else "")
                        for (n, d) in references],
        "directions": directions or {},
        "frfs": frfs,
    }
    with open(os.path.join(OUT, name + ".json"), "w") as fh:
        json.dump(sidecar, fh, indent=1)
    print("wrote", path)


def unit_axes(direction):
    v = np.zeros(3)
    v[abs(direction) - 1] = np.sign(direction)
    return v


def main():
    os.makedirs(OUT, exist_ok=True)
    rng = np.random.default_rng(20260522)
    tri = [(n, d) for n in (1, 2, 3) for d in (1, 2, 3)]

    # 1. ASCII, complex double, even spacing, SI, accelerance with units labels.
    nodes = {1: ((0.1, 0.0, 0.05), 0), 2: ((-0.05, 0.12, 0.0), 0),
             3: ((-0.04, -0.11, 0.02), 0), 4: ((0.2, 0.01, -0.03), 0)}
    refs = [(4, 1), (1, -3)]
    frf_set("ascii_complex_double_even", rng, nodes=nodes, responses=tri, references=refs,
            x=np.arange(8) * 0.5 + 1.0, even=True, binary=False, ordinate=6, num_type=12,
            num_label="m/s^2", den_label="N", quantity="accelerance", rel_tol=E20,
            directions={**{dof_name(n, d): list(unit_axes(d)) for n, d in tri},
                        **{dof_name(n, d): list(unit_axes(d)) for n, d in refs}},
            pre_sets=[pyuff.prepare_164(units_code=1, units_description="SI", temp_mode=2,
                                         length=1.0, force=1.0, temp=1.0, temp_offset=273.15)])

    # 2. ASCII, complex single, uneven spacing, inch/lbf (dataset 164 code 7), dataset 15
    #    nodes, mobility without units labels, node 2 measured in a rotated system (2420).
    c, s = np.cos(0.3), np.sin(0.3)
    rot = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # rows = local axes
    nodes = {1: ((4.0, 0.0, 2.0), 0), 2: ((-2.0, 5.0, 0.0), 7),
             3: ((-1.5, -4.5, 1.0), 0), 5: ((8.0, 0.5, -1.0), 0)}
    refs = [(5, 2)]
    dirs = {dof_name(n, d): list(unit_axes(d) if n != 2 else np.sign(d) * rot[abs(d) - 1])
            for n, d in tri}
    dirs[dof_name(5, 2)] = list(unit_axes(2))
    cs2420 = pyuff.prepare_2420(Part_UID=1, Part_Name="fixture", CS_sys_labels=[7],
                                CS_types=[0], CS_colors=[8], CS_names=["rotated 0.3 rad"],
                                CS_matrices=[np.vstack([rot, np.zeros(3)])])
    frf_set("ascii_complex_single_uneven_inch", rng, nodes=nodes, responses=tri,
            references=refs, x=np.array([0.25, 0.75, 1.5, 2.0, 3.25, 4.0, 6.5]),
            even=False, binary=False, ordinate=5, force_double=False, num_type=11,
            num_label="NONE", den_label="NONE", node_set=15, quantity="mobility",
            length_to_si=INCH, value_to_si=INCH / LBF, rel_tol=E13, pos_tol=E13,
            dir_tol=1e-15, directions=dirs,
            pre_sets=[pyuff.prepare_164(units_code=7, units_description="IN", temp_mode=2,
                                         length=1.0 / INCH, force=1.0 / LBF, temp=1.8,
                                         temp_offset=459.67), cs2420])

    # 3. Binary 58b, complex double, uneven spacing, receptance in mm/mN (code 5), node 3
    #    measured in a system from dataset 18, two set-ups, plus a coherence (skipped).
    o, px, pxz = np.array([10.0, 0, 0]), np.array([10.0, 10.0, 0]), np.array([10.0, 0, 10.0])
    ex = (px - o) / np.linalg.norm(px - o)
    v = pxz - o
    ez = v - ex * (ex @ v)
    ez /= np.linalg.norm(ez)
    ey = np.cross(ez, ex)
    rows18 = np.vstack([ex, ey, ez])
    nodes = {1: ((100.0, 0.0, 50.0), 0), 2: ((-50.0, 120.0, 0.0), 0),
             3: ((-40.0, -110.0, 20.0), 3), 6: ((0.0, 0.0, 200.0), 0)}
    refs = [(6, 3), (6, 1)]
    dirs = {dof_name(n, d): list(unit_axes(d) if n != 3 else np.sign(d) * rows18[abs(d) - 1])
            for n, d in tri}
    dirs.update({dof_name(6, 3): [0, 0, 1.0], dof_name(6, 1): [1.0, 0, 0]})
    cs18 = pyuff.prepare_18(cs_num=[3], cs_type=[0], ref_cs_num=[0], color=[1], method=[1],
                            cs_name=["rotated"], ref_o=[list(o)], x_point=[list(px)],
                            xz_point=[list(pxz)])
    coherence = pyuff.prepare_58(
        binary=1, func_type=6, rsp_ent_name="NONE", rsp_node=1, rsp_dir=1,
        ref_ent_name="NONE", ref_node=6, ref_dir=3, ord_data_type=4, num_pts=5,
        abscissa_spacing=0, abscissa_spec_data_type=18, ordinate_spec_data_type=0,
        orddenom_spec_data_type=0, z_axis_spec_data_type=0,
        data=np.linspace(0.9, 1.0, 5), x=np.array([0.5, 1.0, 2.0, 3.0, 5.0]))
    frf_set("binary_complex_double_uneven_mm", rng, nodes=nodes, responses=tri,
            references=refs, x=np.array([0.5, 1.0, 2.0, 3.0, 5.0]), even=False,
            binary=True, ordinate=6, num_type=8, num_label="NONE", den_label="NONE",
            setups={(6, 3): "A", (6, 1): "B"}, quantity="receptance", length_to_si=1e-3,
            value_to_si=1.0, rel_tol=0.0, pos_tol=1e-15, dir_tol=1e-15, directions=dirs,
            extra_sets=[coherence],
            pre_sets=[pyuff.prepare_164(units_code=5, units_description="MM", temp_mode=2,
                                         length=1000.0, force=1000.0, temp=1.0,
                                         temp_offset=273.15), cs18])

    # 4. Binary 58b, real double, even spacing, accelerance in g/N (labels), SI.
    nodes = {1: ((0.1, 0.0, 0.05), 0), 2: ((-0.05, 0.12, 0.0), 0), 3: ((-0.04, -0.11, 0.02), 0)}
    resp = [(1, 1), (2, 2), (3, -3)]
    refs = [(1, 1)]
    frf_set("binary_real_double_even_g", rng, nodes=nodes, responses=resp, references=refs,
            x=np.arange(6) * 0.25, even=True, binary=True, ordinate=4, num_type=12,
            num_label="g", den_label="N", real=True, quantity="accelerance",
            value_to_si=9.80665, rel_tol=0.0,
            directions={dof_name(n, d): list(unit_axes(d)) for n, d in resp + refs})

    # 5. An FRF whose response node has no coordinates (must be an error).
    path = os.path.join(OUT, "error_missing_node.uff")
    u = fresh(path)
    u.write_sets([
        pyuff.prepare_2411(node_nums=np.array([1]), def_cs=np.array([0]), disp_cs=np.array([0]),
                           color=np.array([8]), x=np.array([0.0]), y=np.array([0.0]),
                           z=np.array([0.0])),
        pyuff.prepare_58(binary=0, func_type=4, rsp_ent_name="NONE", rsp_node=9, rsp_dir=1,
                         ref_ent_name="NONE", ref_node=1, ref_dir=1, ord_data_type=6,
                         num_pts=3, abscissa_spacing=1, abscissa_min=1.0, abscissa_inc=1.0,
                         abscissa_spec_data_type=18, ordinate_spec_data_type=12,
                         orddenom_spec_data_type=13, z_axis_spec_data_type=0,
                         data=np.array([1 + 1j, 2, 3j]), x=np.array([1.0, 2.0, 3.0]))],
        mode="add")
    print("wrote", path)


if __name__ == "__main__":
    main()
