#!/usr/bin/env python3
"""Reads a `needlesim run` output folder with pandas, a reader that is not our writer
(issue 44): every CSV parses with the expected columns, numeric columns are numbers and
finite, one needle row per step, one frame row per frame of `surface.pvd`.

    python scripts/check_outputs.py OUT_DIR STEPS
"""
import pathlib
import sys

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
    print(f"outputs read with pandas {pd.__version__}: {len(needle)} needle rows, {len(frames)} frames")


if __name__ == "__main__":
    main()
