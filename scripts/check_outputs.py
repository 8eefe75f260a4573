#!/usr/bin/env python3
"""Reads a `needlesim run` output folder with readers that are not our writers (issue 44):

- every CSV with pandas: the expected columns, numeric columns numbers and finite, one
  needle row per step, one frame row per frame of `surface.pvd`;
- `surface.pvd` with Python's XML parser and every `.vtp` it lists with VTK's own reader
  (`vtkXMLPolyDataReader`, the `vtk` wheel): triangles that index existing points, finite
  `displacement` and `needle` point arrays of one tuple per point, the time steps those of
  `frames.csv`, the surface's largest displacement at most the tissue's, and the rest
  position (point less displacement) of every first-frame point found in every frame;
- `checkpoint.bin`, when there is one, framed as its docs say (magic, version, payload
  length, the payload's CRC-32 checked with zlib).

    python scripts/check_outputs.py OUT_DIR STEPS
"""
import pathlib
import struct
import sys
import xml.etree.ElementTree as ET
import zlib

import numpy as np
import pandas as pd


def main():
    out, steps = pathlib.Path(sys.argv[1]), int(sys.argv[2])
    needle = pd.read_csv(out / "needle_force.csv")
    want = ["step", "time_s", "depth_m", "axial_force_n", "lateral_force_n", "state"]
    missing = [c for c in want if c not in needle.columns]
    assert not missing, f"needle_force.csv lacks {missing}: {list(needle.columns)}"
    assert len(needle) == steps, f"{len(needle)} needle rows for {steps} steps"
    assert (np.diff(needle["step"]) == 1).all(), "steps are not consecutive"
    for c in ["time_s", "depth_m", "axial_force_n", "lateral_force_n"]:
        assert pd.api.types.is_float_dtype(needle[c]), f"{c} is {needle[c].dtype}"
        assert np.isfinite(needle[c]).all(), f"{c} has non-finite values"
    assert set(needle["state"]) <= {"outside", "touching", "inside"}, set(needle["state"])
    frames = pd.read_csv(out / "frames.csv")
    pvd = (out / "surface.pvd").read_text()
    assert len(frames) == pvd.count("<DataSet"), f"{len(frames)} frame rows, {pvd.count('<DataSet')} in surface.pvd"
    numeric = frames.select_dtypes("number")
    assert numeric.shape[1] == frames.shape[1], f"non-numeric frame columns: {frames.dtypes.to_dict()}"
    assert np.isfinite(numeric.to_numpy()).all(), "frames.csv has non-finite values"
    if (out / "reactions.csv").exists():
        reactions = pd.read_csv(out / "reactions.csv")
        assert len(reactions) == len(frames), "one reaction row per frame"
        assert np.isfinite(reactions.select_dtypes("number").to_numpy()).all()
    surfaces = check_surfaces(out, frames)
    checkpoint = check_checkpoint(out / "checkpoint.bin")
    print(f"outputs read with pandas {pd.__version__}: {len(needle)} needle rows, "
          f"{len(frames)} frames; with VTK {vtk_version()}: {surfaces} surface frames; "
          f"{checkpoint}")


def vtk_version() -> str:
    from vtkmodules.vtkCommonCore import vtkVersion

    return vtkVersion.GetVTKVersion()


def read_vtp(path: pathlib.Path):
    """A `.vtp` file through VTK's XML reader; VTK reports errors through its output
    window rather than exceptions, so they are collected and raised here."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkCommonCore import vtkCommand
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

    errors = []
    reader = vtkXMLPolyDataReader()
    reader.AddObserver(vtkCommand.ErrorEvent, lambda obj, event: errors.append(event))
    reader.GetExecutive().AddObserver(vtkCommand.ErrorEvent, lambda o, e: errors.append(e))
    reader.SetFileName(str(path))
    reader.Update()
    assert not errors and reader.GetErrorCode() == 0, f"VTK could not read {path}"
    poly = reader.GetOutput()
    points = vtk_to_numpy(poly.GetPoints().GetData()).astype(np.float64)
    polys = vtk_to_numpy(poly.GetPolys().GetConnectivityArray())
    offsets = vtk_to_numpy(poly.GetPolys().GetOffsetsArray())
    data = poly.GetPointData()
    arrays = {data.GetArrayName(i): vtk_to_numpy(data.GetArray(i)) for i in
              range(data.GetNumberOfArrays())}
    return points, polys, offsets, arrays


def check_surfaces(out: pathlib.Path, frames: pd.DataFrame) -> int:
    root = ET.parse(out / "surface.pvd").getroot()
    sets = root.findall("./Collection/DataSet")
    times = np.array([float(d.get("timestep")) for d in sets])
    assert np.allclose(times, frames["time_s"], rtol=1e-6, atol=1e-12), \
        "surface.pvd's time steps are not frames.csv's"
    rest0 = None
    for d, tissue_max in zip(sets, frames["max_displacement_m"]):
        path = out / d.get("file")
        points, polys, offsets, arrays = read_vtp(path)
        n = len(points)
        assert n > 0 and len(polys) > 0, f"{path}: empty surface"
        assert (np.diff(offsets) == 3).all(), f"{path}: not all cells are triangles"
        assert polys.min() >= 0 and polys.max() < n, f"{path}: a triangle indexes no point"
        for name in ("displacement", "needle"):
            assert name in arrays, f"{path}: no {name} array ({list(arrays)})"
            assert len(arrays[name]) == n, f"{path}: {name} has {len(arrays[name])} tuples"
            assert np.isfinite(arrays[name]).all(), f"{path}: {name} is not finite"
        u = arrays["displacement"].astype(np.float64)
        # frames.csv's maximum is over every tissue node, the surface's a subset; the CSV
        # keeps 7 significant digits.
        surface_max = np.linalg.norm(u, axis=1).max()
        assert surface_max <= tissue_max * (1 + 1e-6) + 1e-12, \
            f"{path}: surface displacement {surface_max} above the tissue's {tissue_max}"
        rest = points - u
        if rest0 is None:
            rest0 = rest
        else:
            # Needle splits insert points, so indices shift; every first-frame point must
            # still be there at its rest position (f32 points and displacements: a few
            # ulps of the body's size).
            from scipy.spatial import cKDTree

            tol = 1e-5 * np.abs(rest0).max()
            dev = cKDTree(rest).query(rest0)[0].max()
            assert dev <= tol, f"{path}: a first-frame point is {dev} from every rest position"
    return len(sets)


def check_checkpoint(path: pathlib.Path) -> str:
    if not path.exists():
        return "no checkpoint"
    b = path.read_bytes()
    magic = b"NEEDLESIM-CHECKPOINT\n"
    assert b.startswith(magic), f"{path}: no checkpoint magic"
    version, length, crc = struct.unpack_from("<IQI", b, len(magic))
    payload = b[len(magic) + 16:]
    assert len(payload) == length, f"{path}: payload {len(payload)} bytes, header says {length}"
    assert zlib.crc32(payload) == crc, f"{path}: payload CRC-32 differs from the header's"
    return f"checkpoint version {version}, {length} payload bytes, CRC-32 checked with zlib"


if __name__ == "__main__":
    main()
