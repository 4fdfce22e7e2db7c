#!/usr/bin/env python3
"""Check an am-sim HDF5 output file (and its XDMF file) with h5py, independently of the writer.

Usage: check_h5py.py RUN.h5 [--xmf RUN.xmf] [--id PARTICLE_ID] [--expected-json OUT.json]
                            [--frames N]

Checks the root attributes, every frame's datasets (types, shapes, bond indices), the
/series table against the frames, and that the XDMF file is valid XML whose every HDF
DataItem names an existing dataset with the stated dimensions and a compatible type.
Prints the temperature history of one particle (by id), the last frame's bonds (as id
pairs) and the series. With --expected-json, writes per-frame counts and field ranges for
check_paraview.py. Exits 1 on any failed check. Needs: pip install h5py numpy.
"""

import argparse
import json
import os
import sys
import xml.etree.ElementTree as ET

import h5py
import numpy as np

FAILURES = []
PASSES = [0]


def check(cond, msg):
    """Record one check; keep going so that all problems are reported."""
    if cond:
        PASSES[0] += 1
    else:
        FAILURES.append(msg)
        print(f"FAIL: {msg}", file=sys.stderr)
    return cond


def check_root(f):
    a = f.attrs
    check(a.get("format") == "am-sim", f"root format = {a.get('format')!r}")
    v = a.get("format_version")
    check(isinstance(v, np.uint32) and v == 1, f"format_version = {v!r} ({type(v).__name__}), expected uint32 1")
    check(a.get("units") == "SI", f"units = {a.get('units')!r}")
    for name in ("am_sim_version", "scene"):
        check(isinstance(a.get(name), str), f"root attribute {name} is {type(a.get(name)).__name__}, expected str")
    print(f"root: format={a['format']} v{a['format_version']} units={a['units']} "
          f"am_sim_version={a['am_sim_version']} scene={len(a['scene'])} chars")


def frame_names(f):
    return sorted(f["frames"], key=int)


def check_frame(name, g):
    """Check one frame group; return its summary or None if incomplete."""
    where = f"/frames/{name}"
    if not check("time" in g.attrs and "step" in g.attrs, f"{where}: missing time/step attribute"):
        return None
    check(g.attrs["time"].dtype == np.float64 and g.attrs["step"].dtype == np.uint64, f"{where}: time/step types")
    n = g["id"].shape[0]
    expect = {
        "id": (np.uint64, (n,)), "position": (np.float64, (n, 3)), "velocity": (np.float64, (n, 3)),
        "radius": (np.float64, (n,)), "temperature": (np.float64, (n,)), "melted": (np.uint8, (n,)),
        "melt_fraction": (np.float64, (n,)), "evaporated_mass": (np.float64, (n,)),
        "angular_velocity": (np.float64, (n, 3)), "contacts": (np.uint64, (n,)),
        "force": (np.float64, (n, 3)), "bonds": (np.uint64, None),
        "bond_overlap": (np.float64, None), "bond_force": (np.float64, None),
    }
    required = {"id", "position", "velocity", "radius"}
    for ds_name in g:
        check(ds_name in expect or ds_name == "restart", f"{where}: unexpected member {ds_name}")
    for ds_name in required:
        check(ds_name in g, f"{where}: missing {ds_name}")
    if "restart" in g:
        r = g["restart"]
        check("force" in r and r["force"].shape == (n, 3), f"{where}/restart: no force [N, 3]")
        check("bonded_ids" in r, f"{where}/restart: no bonded_ids")
    for ds_name in ("position", "velocity", "radius", "temperature", "evaporated_mass"):
        if ds_name in g:
            check(np.all(np.isfinite(g[ds_name][...])), f"{where}/{ds_name}: non-finite values")
    if "evaporated_mass" in g:
        check(np.all(g["evaporated_mass"][...] >= 0.0), f"{where}/evaporated_mass: negative values")
    b = g["bonds"].shape[0] if "bonds" in g else 0
    for ds_name, (dtype, shape) in expect.items():
        if ds_name not in g:
            continue
        ds = g[ds_name]
        if shape is None:
            shape = (b, 2) if ds_name == "bonds" else (b,)
        check(ds.dtype == dtype, f"{where}/{ds_name}: dtype {ds.dtype}, expected {np.dtype(dtype)}")
        check(ds.shape == shape, f"{where}/{ds_name}: shape {ds.shape}, expected {shape}")
        check(isinstance(ds.attrs.get("units"), str), f"{where}/{ds_name}: no units attribute")
    bonds = g["bonds"][...] if "bonds" in g else np.zeros((0, 2), dtype=np.uint64)
    if b:
        check(bonds.max() < n, f"{where}/bonds: index {bonds.max()} >= N = {n}")
        check(np.all(bonds[:, 0] != bonds[:, 1]), f"{where}/bonds: self-bond")
    ids = g["id"][...]
    check(len(np.unique(ids)) == n, f"{where}/id: duplicate ids")

    def rng(ds_name):
        if ds_name not in g or n == 0:
            return None
        v = g[ds_name][...]
        return [float(v.min()), float(v.max())]

    return {
        "name": name, "time": float(g.attrs["time"]), "step": int(g.attrs["step"]),
        "n_points": n, "n_bonds": b, "has_bonds": "bonds" in g,
        "evaporated_mass": float(g["evaporated_mass"][...].sum()) if "evaporated_mass" in g else None,
        "ranges": {k: rng(k) for k in ("radius", "temperature", "melted", "id")},
    }


def check_series(f, frames):
    s = f["series"]
    columns = ["step", "time_s", "kinetic_energy_j", "mechanical_energy_j", "contacts", "bonds", "wall_time_s"]
    for c in columns:
        if not check(c in s, f"/series/{c} missing"):
            return
    rows = s["step"].shape[0]
    for c in s:
        ds = s[c]
        check(ds.ndim == 1 and ds.maxshape == (None,) and ds.chunks is not None,
              f"/series/{c}: not a chunked unlimited 1-D dataset ({ds.shape}, {ds.maxshape}, {ds.chunks})")
        check(ds.shape[0] == rows, f"/series/{c}: {ds.shape[0]} rows, /series/step has {rows}")
        check(isinstance(ds.attrs.get("units"), str), f"/series/{c}: no units attribute")
    check(rows >= 1, "/series is empty")
    steps = s["step"][...]
    check(np.all(np.diff(steps) > 0), "/series/step not increasing")
    check(np.all(np.diff(s["time_s"][...]) > 0), "/series/time_s not increasing")
    # Where a series row and a frame share a step, they describe the same state.
    by_step = {int(st): i for i, st in enumerate(steps)}
    shared = 0
    for fr in frames:
        i = by_step.get(fr["step"])
        if i is None:
            continue
        shared += 1
        check(s["time_s"][i] == fr["time"], f"/series/time_s at step {fr['step']} != frame time")
        if fr["has_bonds"]:
            check(s["bonds"][i] == fr["n_bonds"], f"/series/bonds at step {fr['step']} = {s['bonds'][i]}, frame has {fr['n_bonds']}")
        # The vapour's mass in the series is the frame's sum, with the mass of removed particles
        # (none in the checked runs); the two sums add in different orders: 1e-12 relative.
        if fr["evaporated_mass"] is not None and "evaporated_mass_kg" in s and s["removed_particles"][i] == 0:
            series_mass = float(s["evaporated_mass_kg"][i])
            check(abs(series_mass - fr["evaporated_mass"]) <= 1e-12 * max(series_mass, 1e-300),
                  f"/series/evaporated_mass_kg at step {fr['step']} = {series_mass}, frame sums {fr['evaporated_mass']}")
    check(shared > 0, "no frame step appears in /series")
    print(f"series: {rows} rows, {len(s)} columns ({', '.join(s)}); {shared} rows at frame steps")
    show = [c for c in ("time_s", "kinetic_energy_j", "bonds", "max_temperature_k", "laser_energy_j", "evaporated_mass_kg") if c in s]
    print("  " + " ".join(f"{c:>18}" for c in show))
    for i in list(range(min(rows, 3))) + ([rows - 1] if rows > 3 else []):
        print("  " + " ".join(f"{s[c][i]:>18.6g}" for c in show))


def temperature_history(f, frames, pid):
    print(f"temperature history of particle id {pid}:")
    for fr in frames:
        g = f["frames"][fr["name"]]
        rows = np.nonzero(g["id"][...] == np.uint64(pid))[0]
        if len(rows) == 0:
            print(f"  t = {fr['time']:.6g} s: absent")
            continue
        check(len(rows) == 1, f"id {pid} appears {len(rows)} times in frame {fr['name']}")
        t = g["temperature"][rows[0]] if "temperature" in g else float("nan")
        print(f"  t = {fr['time']:.6g} s  step {fr['step']}: row {rows[0]}, T = {t:.3f} K")


def last_bonds(f, frames):
    g = f["frames"][frames[-1]["name"]]
    if "bonds" not in g:
        print("last frame: no bonds dataset (the scene has no [bond] or did not ask for it)")
        return
    bonds = g["bonds"][...]
    ids = g["id"][...]
    print(f"last frame {frames[-1]['name']}: {len(bonds)} bonds" + (", first ones as id pairs:" if len(bonds) else ""))
    for i, j in bonds[:5]:
        print(f"  rows ({i}, {j}) -> ids ({ids[i]}, {ids[j]})")


COMPATIBLE = {  # XDMF (NumberType, Precision) -> numpy dtypes the HDF5 library converts exactly
    ("Float", "8"): {np.dtype("f8")},
    ("Float", "4"): {np.dtype("f4")},
    ("Int", "8"): {np.dtype("i8"), np.dtype("u8")},  # u8 < 2**63 converts exactly
    ("Int", "4"): {np.dtype("i4")},
    ("UChar", "1"): {np.dtype("u1")},
    ("Char", "1"): {np.dtype("i1")},
}


def check_xdmf(xmf_path, frames):
    try:
        root = ET.parse(xmf_path).getroot()
    except ET.ParseError as e:
        check(False, f"{xmf_path}: invalid XML: {e}")
        return
    base = os.path.dirname(os.path.abspath(xmf_path))
    n_items = 0
    for item in root.iter("DataItem"):
        if item.get("Format") != "HDF":
            continue
        n_items += 1
        ref = item.text.strip()
        fname, _, dpath = ref.partition(":")
        dims = tuple(int(d) for d in item.get("Dimensions").split())
        key = (item.get("NumberType", "Float"), item.get("Precision", "4"))
        try:
            with h5py.File(os.path.join(base, fname), "r") as h5:
                if not check(dpath in h5, f"XDMF names missing dataset {ref}"):
                    continue
                ds = h5[dpath]
                check(ds.shape == dims, f"XDMF {ref}: Dimensions {dims}, dataset shape {ds.shape}")
                check(ds.dtype in COMPATIBLE.get(key, set()), f"XDMF {ref}: {key} for dtype {ds.dtype}")
        except OSError as e:
            check(False, f"XDMF {ref}: cannot open: {e}")
    # Structure: one particle grid per non-empty frame, one bond grid per frame with bonds.
    collections = {g.get("Name"): g for g in root.find("Domain").findall("Grid")}
    check(set(collections) == {"particles", "bonds"}, f"XDMF top-level grids {sorted(collections)}")
    for cname, key in (("particles", "n_points"), ("bonds", "n_bonds")):
        coll = collections.get(cname)
        if coll is None:
            continue
        check(coll.get("CollectionType") == "Temporal", f"XDMF {cname}: not a temporal collection")
        grids = coll.findall("Grid")
        want = [fr for fr in frames if fr[key] > 0]
        check(len(grids) == len(want), f"XDMF {cname}: {len(grids)} grids for {len(want)} frames")
        for grid, fr in zip(grids, want):
            t = float(grid.find("Time").get("Value"))
            check(t == fr["time"], f"XDMF {cname} {grid.get('Name')}: time {t} != {fr['time']}")
            topo = grid.find("Topology")
            check(int(topo.get("NumberOfElements")) == fr[key],
                  f"XDMF {grid.get('Name')}: NumberOfElements {topo.get('NumberOfElements')} != {fr[key]}")
    print(f"xdmf: {xmf_path}: {n_items} HDF data items checked")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("h5")
    ap.add_argument("--xmf", help="XDMF file to validate (default: RUN.xmf beside RUN.h5 if present)")
    ap.add_argument("--id", type=int, help="particle id whose temperature history to print")
    ap.add_argument("--expected-json", help="write frame counts and field ranges for check_paraview.py")
    ap.add_argument("--frames", type=int, help="require exactly this many complete frames")
    args = ap.parse_args()

    with h5py.File(args.h5, "r") as f:
        check_root(f)
        frames = []
        for name in frame_names(f):
            summary = check_frame(name, f["frames"][name])
            if summary:
                frames.append(summary)
        print(f"frames: {len(frames)} complete: " + ", ".join(
            f"{fr['name']} (t={fr['time']:.3g} s, N={fr['n_points']}, B={fr['n_bonds']})" for fr in frames))
        if args.frames is not None:
            check(len(frames) == args.frames, f"{len(frames)} frames, expected {args.frames}")
        check_series(f, frames)
        if frames:
            last = f["frames"][frames[-1]["name"]]
            if args.id is not None:
                pid = args.id
            elif "temperature" in last:  # the hottest particle at the end: the interesting history
                pid = int(last["id"][int(np.argmax(last["temperature"][...]))])
            else:
                pid = int(last["id"][0])
            temperature_history(f, frames, pid)
            last_bonds(f, frames)

    xmf = args.xmf or os.path.splitext(args.h5)[0] + ".xmf"
    if args.xmf or os.path.exists(xmf):
        check_xdmf(xmf, frames)
    if args.expected_json:
        with open(args.expected_json, "w") as out:
            json.dump({"frames": frames}, out, indent=1)

    print(f"check_h5py: {PASSES[0]} passed, {len(FAILURES)} failed")
    sys.exit(1 if FAILURES else 0)


if __name__ == "__main__":
    main()
