"""Open an am-sim XDMF file with ParaView's XDMF readers and compare what they see with h5py.

Usage: pvpython check_paraview.py RUN.xmf EXPECTED.json [--readers R1,R2] [--screenshot OUT.png]

EXPECTED.json comes from `check_h5py.py RUN.h5 --expected-json EXPECTED.json`. For each
reader (default: XDMFReader, Xdmf3ReaderS, Xdmf3ReaderT) and each frame: the time steps,
the number of particles (points) and of vertex cells, the number of bond lines (2-point
cells), the ranges of radius, temperature, melted and id (id must arrive as a 64-bit
integer, not narrowed) must match. Exits 1 on any mismatch.

Reading needs no display (plain `pvpython`). --screenshot renders the last frame and
needs an X server: run under `xvfb-run -a pvpython ...`; Debian's ParaView 5.11 crashes
with --force-offscreen-rendering (no EGL/OSMesa build).
"""

import argparse
import json
import math
import os
import sys

from paraview import servermanager as sm
from paraview import simple as pv
from vtkmodules.util.numpy_support import vtk_to_numpy

READERS = ("XDMFReader", "Xdmf3ReaderS", "Xdmf3ReaderT")
VTK_VERTEX, VTK_POLY_VERTEX, VTK_LINE, VTK_POLY_LINE = 1, 2, 3, 4

FAILURES = []
PASSES = [0]


def check(cond, msg):
    if cond:
        PASSES[0] += 1
    else:
        FAILURES.append(msg)
        print(f"FAIL: {msg}", file=sys.stderr)
    return cond


def open_reader(name, xmf):
    # Xdmf3 readers resolve "bed.h5" against a bare "bed.xmf" as "bed.xmfbed.h5" (and then
    # abort the process): always pass an absolute path.
    xmf = os.path.abspath(xmf)
    if name == "XDMFReader":  # legacy Xdmf2 reader: list property FileNames
        return pv.XDMFReader(FileNames=[xmf])
    return getattr(pv, name)(FileName=[xmf])


def leaves(data):
    """Non-empty leaf datasets of a (possibly composite) data object."""
    if not data.IsA("vtkCompositeDataSet"):
        return [data] if data.GetNumberOfPoints() else []
    out = []
    it = data.NewIterator()
    it.SkipEmptyNodesOn()
    it.InitTraversal()
    while not it.IsDoneWithTraversal():
        leaf = it.GetCurrentDataObject()
        if leaf.GetNumberOfPoints():
            out.append(leaf)
        it.GoToNextItem()
    return out


def same(a, b):
    return math.isclose(a, b, rel_tol=1e-12, abs_tol=0.0)


def check_frame(tag, data, fr):
    parts = [d for d in leaves(data) if d.GetPointData().GetArray("radius") is not None]
    bonds = [d for d in leaves(data) if d.GetPointData().GetArray("radius") is None and d.GetNumberOfCells()]
    n, b = fr["n_points"], fr["n_bonds"]
    if check(len(parts) == (1 if n else 0), f"{tag}: {len(parts)} particle blocks"):
        if parts:
            p = parts[0]
            check(p.GetNumberOfPoints() == n, f"{tag}: {p.GetNumberOfPoints()} points, expected {n}")
            check(p.GetNumberOfCells() == n, f"{tag}: {p.GetNumberOfCells()} vertex cells, expected {n}")
            types = set(vtk_to_numpy(p.GetCellTypesArray()).tolist()) if p.GetNumberOfCells() else set()
            check(types <= {VTK_VERTEX, VTK_POLY_VERTEX}, f"{tag}: particle cell types {types}")
            for field, want in fr["ranges"].items():
                arr = p.GetPointData().GetArray(field)
                if want is None:
                    check(arr is None, f"{tag}: unexpected point field {field}")
                    continue
                if not check(arr is not None, f"{tag}: point field {field} missing"):
                    continue
                got = arr.GetRange(0)
                check(same(got[0], want[0]) and same(got[1], want[1]), f"{tag}: {field} range {got}, expected {want}")
                if field == "id":
                    check(arr.GetDataTypeSize() == 8 and arr.GetDataType() != 11,
                          f"{tag}: id arrives as {arr.GetDataTypeAsString()}, expected a 64-bit integer")
    if b == 0:
        check(not bonds, f"{tag}: bond lines shown for a frame without bonds")
    elif check(len(bonds) == 1, f"{tag}: {len(bonds)} bond blocks, expected 1"):
        g = bonds[0]
        check(g.GetNumberOfCells() == b, f"{tag}: {g.GetNumberOfCells()} bond lines, expected {b}")
        types = set(vtk_to_numpy(g.GetCellTypesArray()).tolist())
        check(types <= {VTK_LINE, VTK_POLY_LINE}, f"{tag}: bond cell types {types}")
        check(all(g.GetCell(i).GetNumberOfPoints() == 2 for i in range(min(g.GetNumberOfCells(), 1000))),
              f"{tag}: bond cells without exactly 2 points")


def check_reader(name, xmf, frames):
    reader = open_reader(name, xmf)
    reader.UpdatePipelineInformation()
    times = list(reader.TimestepValues)
    want = [fr["time"] for fr in frames if fr["n_points"] or fr["n_bonds"]]
    ok = check(len(times) == len(want) and all(same(a, b) or a == b for a, b in zip(times, want)),
               f"{name}: time steps {times}, expected {want}")
    if ok:
        for fr in frames:
            if not (fr["n_points"] or fr["n_bonds"]):
                continue
            reader.UpdatePipeline(fr["time"])
            check_frame(f"{name} frame {fr['name']} t={fr['time']:.6g}", sm.Fetch(reader), fr)
    pv.Delete(reader)
    print(f"{name}: {len(times)} time steps checked")


def screenshot(xmf, frames, out):
    reader = open_reader("XDMFReader", xmf)
    reader.UpdatePipelineInformation()
    view = pv.GetActiveViewOrCreate("RenderView")
    view.ViewSize = [800, 600]
    view.ViewTime = frames[-1]["time"]
    disp = pv.Show(reader, view)
    disp.SetRepresentationType("Surface")
    disp.PointSize = 6
    disp.LineWidth = 2
    pv.ColorBy(disp, ("POINTS", "temperature"))
    view.ResetCamera()
    pv.SaveScreenshot(out, view)
    # Without this, pvpython exits with status 1 after "X Error ... GLXBadContext" under Xvfb.
    pv.Delete(view)
    del view
    print(f"screenshot: {out}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("xmf")
    ap.add_argument("expected")
    ap.add_argument("--readers", default=",".join(READERS))
    ap.add_argument("--screenshot")
    args = ap.parse_args()
    with open(args.expected) as f:
        frames = json.load(f)["frames"]
    for name in args.readers.split(","):
        try:
            check_reader(name, args.xmf, frames)
        except Exception as e:  # a reader that throws is a failed check, not a crash
            check(False, f"{name}: {type(e).__name__}: {e}")
    if args.screenshot:
        screenshot(args.xmf, frames, args.screenshot)
    print(f"check_paraview: {PASSES[0]} passed, {len(FAILURES)} failed")
    sys.exit(1 if FAILURES else 0)


if __name__ == "__main__":
    main()
