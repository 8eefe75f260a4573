"""Calibration: fit the Young's modulus, the shaft friction and the puncture force of the
gel phantom (scenes/phantom_insertion.toml) to a force-against-depth curve, on Dask.

The "measured" curve is made by the simulator itself at known values, plus 0.02 N of
Gaussian noise, so the fit's answer can be checked. Replace `depth, force` with your
load-cell record (tip depth past the first contact in m, axial force in N).

    pip install needlesim[dask] matplotlib
    python crates/py/examples/fit_phantom.py [--out out/python] [--workers 2]
"""

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import needlesim  # noqa: E402

ROOT = Path(__file__).resolve().parents[3]
SCENE = ROOT / "scenes" / "phantom_insertion.toml"
TRUTH = {
    "material.young_modulus": 2.0e4,  # Pa
    "needle.friction.coefficient": 0.3,  # on a grip of 150 N/m: 45 N/m of shaft
    "needle.puncture_force": 1.0,  # N
}
BOUNDS = [(5e3, 8e4), (0.05, 1.0), (0.3, 3.0)]
START = [3e4, 0.2, 1.5]
DURATION = 2.0  # s: 4 cm at 2 cm/s; dt = "auto" changes with E, so time, not steps


def synthetic(seed: int):
    r = needlesim.sweep(SCENE, [TRUTH], "serial", duration=DURATION).variant(0)
    d, f = r["depth_m"].to_numpy(), r["axial_force_n"].to_numpy()
    keep = slice(0, int(np.argmax(d)) + 1)
    depth = np.arange(0.0, 0.035, 1e-4)
    noise = np.random.default_rng(seed).normal(0.0, 0.02, depth.size)
    return depth, np.interp(depth, d[keep], f[keep]) + noise


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="out/python")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--seed", type=int, default=1)
    args = p.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    depth, force = synthetic(args.seed)
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=args.workers, threads_per_worker=1,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        t0 = time.perf_counter()
        res = needlesim.fit(SCENE, depth, force, list(TRUTH), BOUNDS, client,
                            x0=START, duration=DURATION)
        wall = time.perf_counter() - t0
    print(f"{res.simulations} simulations, {res.iterations} batches, {wall:.1f} s "
          f"on {args.workers} workers; smoothed rms {res.rms * 1e3:.1f} mN")
    print(f"{'parameter':30s} {'start':>10s} {'fitted':>10s} {'+-':>9s} {'truth':>10s} {'error':>7s}")
    for (k, t), s in zip(TRUTH.items(), START):
        v, e = res.parameters[k], res.stderr[k]
        print(f"{k:30s} {s:10.4g} {v:10.4g} {e:9.2g} {t:10.4g} {100 * (v / t - 1):6.2f}%")

    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(depth * 1e3, force, ".", ms=2, color="0.6", label="measured (synthetic + noise)")
    ax.plot(res.depth * 1e3, res.measured, "k-", lw=1.5, label="measured, smoothed")
    ax.plot(res.depth * 1e3, res.fitted, "r--", lw=1.5, label="fitted, smoothed")
    ax.set_xlabel("depth past first contact (mm)")
    ax.set_ylabel("axial needle force (N)")
    ax.set_title("needlesim.fit: E {:.0f} Pa, friction {:.3f}, puncture {:.2f} N".format(
        *res.parameters.values()))
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "fit_phantom.png", dpi=120)
    print(f"wrote {out / 'fit_phantom.png'}")


if __name__ == "__main__":
    main()
