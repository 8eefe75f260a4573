#!/usr/bin/env python3
"""Zoomed plots of a needle force history around its events (issue 39: look at the whole
signal, not only at the figures an audit gives).

    python scripts/force_zoom.py OUT_DIR PNG [--window S] [--at T ...] [--title TEXT]

OUT_DIR is a `needlesim run --out` folder (its `needle_force.csv`). Without `--at` the
panels are chosen from the run itself: the first puncture, the step with the largest
high-frequency part outside the 20 ms after a puncture, the first needle node added after
the puncture, the first Tip refresh after it (the tip's material depth moving in one
step by more than ten times the tip's largest advance in a step, with no node count
change) and the first reversal from advancing to withdrawing. Rows within 20 ms of a
puncture (the state becoming inside, or the region changing inside) are not searched for
the largest buzz, as in the audit. Each panel shows, over `--window` seconds (0.1 by
default) centred on its time:

- the axial force, the tip's element (cutting or membrane) and their difference, the
  shaft's friction;
- the part above about 50 Hz as `shared/tools/force_audit.py` defines it (the force less
  its 20 ms centred moving mean), and its 20 ms RMS over the local force, in per cent;
- vertical lines at every step where the number of needle nodes changes (solid) and at
  every Tip refresh (dotted).

Needs numpy and matplotlib.
"""
import argparse
import csv
import sys

import numpy as np


def movmean(x, w):
    w = max(1, min(int(w), len(x)))
    return np.convolve(x, np.ones(w) / w, mode="same")


def load(out_dir):
    rows = list(csv.DictReader(open(f"{out_dir}/needle_force.csv")))

    def col(name, default="nan"):
        return np.array([float(r.get(name) or default) for r in rows])

    run = {
        "t": col("time_s"),
        "depth": col("depth_m"),
        "F": col("axial_force_n"),
        "tip": col("tip_force_n", "0"),
        "nodes": col("needle_nodes", "0"),
        "material": col("tissue_depth_m"),
        "inside": np.array([r["state"] == "inside" for r in rows]),
    }
    t, F = run["t"], run["F"]
    n = len(t)
    if n < 2:
        sys.exit(f"{out_dir}/needle_force.csv has {n} rows: nothing to plot")
    dt = float(np.median(np.diff(t)))
    run["dt"] = dt
    state = [r["state"] for r in rows]
    region = [r.get("region", "") for r in rows]
    run["punctures"] = [
        t[i]
        for i in range(1, n)
        if state[i] == "inside" and (state[i - 1] != "inside" or region[i] != region[i - 1])
    ]
    w20 = round(0.02 / dt)
    local = np.maximum(movmean(np.abs(F), round(0.05 / dt)), 0.1 * max(np.abs(F).max(), 1e-12))
    high = F - movmean(F, w20)
    run["high"] = high
    run["buzz"] = 100 * np.sqrt(np.maximum(movmean(high**2, w20), 0.0)) / local
    dn = np.diff(run["nodes"], prepend=run["nodes"][0])
    dm = np.abs(np.diff(run["material"], prepend=run["material"][0]))
    run["node_events"] = t[dn != 0]
    run["additions"] = t[dn > 0]
    # A Tip refresh re-places the Tip node: the tip's material depth moves in one step by
    # far more than the tip's own advance (the threshold: ten times the largest advance
    # of a step without an event, and at least 1 um).
    advance = np.abs(np.diff(run["depth"], prepend=run["depth"][0]))
    quiet = run["inside"] & (dn == 0) & np.isfinite(dm)
    floor = max(10.0 * float(np.percentile(advance[quiet], 99)) if quiet.any() else 0.0, 1e-6)
    run["refreshes"] = t[(dn == 0) & (dm > floor) & run["inside"]]
    dd = np.diff(run["depth"], prepend=run["depth"][0])
    run["reversals"] = [
        t[i] for i in range(1, n) if dd[i] < -1e-9 and np.any(dd[max(0, i - 50):i] > 1e-9)
    ]
    return run


def pick(run):
    """(label, time) of the panels the run itself suggests."""
    t = run["t"]
    out = []
    first = run["punctures"][0] if run["punctures"] else None
    if first is not None:
        out.append(("puncture", first))
    near = np.zeros(len(t), bool)
    for p in run["punctures"]:
        near |= np.abs(t - p) < 0.02
    # The audit's own exemption: the last 20 ms of a run that ends with a force on the
    # needle read a large buzz from the moving means' zero padding.
    ok = run["inside"] & ~near & (t < t[-1] - 0.02)
    if ok.any():
        i = np.argmax(np.where(ok, run["buzz"], -1.0))
        out.append((f"largest buzz ({run['buzz'][i]:.2f}%)", t[i]))
    after = first if first is not None else -np.inf
    added = [e for e in run["additions"] if e > after + 0.05]
    if added:
        out.append(("node added", added[0]))
    refreshed = [e for e in run["refreshes"] if e > after + 0.05]
    if refreshed:
        out.append(("Tip refresh", refreshed[0]))
    if run["reversals"]:
        out.append(("reversal", run["reversals"][0]))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out_dir")
    ap.add_argument("png")
    ap.add_argument("--window", type=float, default=0.1, help="seconds per panel")
    ap.add_argument("--at", type=float, action="append", help="panel centre, s (repeatable)")
    ap.add_argument("--title", default=None)
    a = ap.parse_args()
    if not a.window > 0:
        ap.error(f"--window must be a positive number of seconds, got {a.window}")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run = load(a.out_dir)
    t = run["t"]
    panels = [("at", x) for x in a.at] if a.at else pick(run)
    if not panels:
        ap.error("nothing to zoom into: the run has no puncture, node event or reversal")
    for _, x in panels:
        if not t[0] - a.window / 2 <= x <= t[-1] + a.window / 2:
            ap.error(f"--at {x:g} s is outside the run ({t[0]:g} to {t[-1]:g} s)")
    fig, axes = plt.subplots(2, len(panels), figsize=(4.2 * len(panels), 6.4), squeeze=False)
    for k, (label, centre) in enumerate(panels):
        s = np.abs(t - centre) <= a.window / 2
        top, bottom = axes[0][k], axes[1][k]
        top.plot(t[s], run["F"][s], label="axial")
        top.plot(t[s], run["tip"][s], label="tip element")
        top.plot(t[s], (run["F"] - run["tip"])[s], label="friction")
        bottom.plot(t[s], 1e3 * run["high"][s], color="C3", label="above ~50 Hz, mN")
        twin = bottom.twinx()
        twin.plot(t[s], run["buzz"][s], color="C4", lw=0.8, label="buzz %")
        twin.axhline(2.0, color="C4", ls="--", lw=0.6)
        twin.set_ylabel("buzz, % of local force", color="C4")
        for ax in (top, bottom):
            for e in run["node_events"]:
                if abs(e - centre) <= a.window / 2:
                    ax.axvline(e, color="grey", lw=0.6)
            for e in run["refreshes"]:
                if abs(e - centre) <= a.window / 2:
                    ax.axvline(e, color="grey", lw=0.6, ls=":")
            ax.grid(alpha=0.3)
        top.set_title(f"{label}, t = {centre:.3f} s" if label != "at" else f"t = {centre:.3f} s", fontsize=9)
        bottom.set_xlabel("time, s")
        if k == 0:
            top.set_ylabel("force, N")
            bottom.set_ylabel("force less its 20 ms mean, mN")
            top.legend(fontsize=7)
    fig.suptitle(a.title or a.out_dir, fontsize=10)
    fig.tight_layout()
    fig.savefig(a.png, dpi=90)


if __name__ == "__main__":
    main()
