"""Planning: which entry point brings the needle tip to a target inside the tissue, when
the tissue (and the target with it) moves as the needle pushes? A sweep of the entry
point over a line across the needle, each run a Dask task, the target node's trajectory
recorded; the miss is the closest the tip comes to the moving target, and the distance
left when the tip stops at the target's rest depth (the target has been pushed ahead).

    pip install needlesim[dask] matplotlib
    python crates/py/examples/target_sweep.py [--out out/python] [--workers 2]
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


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="out/python")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--offsets", type=int, default=11, help="entry points swept")
    args = p.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    scene, base_dir = needlesim.load_scene(SCENE)
    needle = scene["needle"]
    move = needle["keyframe"][0]
    sim = needlesim.Simulation.from_dict(scene, backend="cpu", base_dir=base_dir)
    rest, dt = sim.positions, sim.dt  # the entry point does not change dt
    # The target: the tissue node nearest the block's centre, 3 cm deep.
    target = int(np.argmin(np.linalg.norm(rest - [0.03, 0.03, 0.03], axis=1)))
    aim = rest[target]
    # An oblique insertion, 30 degrees off the entry face's normal: the dent is lopsided
    # and pushes the target sideways as well as ahead.
    angle = np.radians(30.0)
    direction = np.array([np.cos(angle), -np.sin(angle), 0.0])
    to_face = aim[0] / direction[0]  # from the entry face (x = 0) to the target
    travel_in = to_face + 0.01  # the tip goes 1 cm past the target's rest depth
    duration = (0.002 + travel_in) / move["speed"]
    entry = aim - to_face * direction
    base = entry - (needle["length"] + 0.002) * direction
    # Entry points shifted along y (across the needle's plane): 0 aims at the target's
    # rest position, the naive plan.
    ys = np.linspace(-6e-3, 6e-3, args.offsets)
    variants = [
        {
            "needle.base": [float(base[0]), float(base[1] + dy), float(base[2])],
            "needle.direction": direction.tolist(),
            "needle.keyframe.0.direction": direction.tolist(),
            "needle.keyframe.0.duration": float(duration),
        }
        for dy in ys
    ]

    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=args.workers, threads_per_worker=1,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        t0 = time.perf_counter()
        res = needlesim.sweep(scene, variants, client, base_dir=base_dir,
                              duration=duration, nodes=[target], every=20)
        wall = time.perf_counter() - t0
    if len(res.failed):
        print(res.failed[["variant", "error_type", "error"]].to_string())

    misses, planned = [], []
    t_plan = (0.002 + to_face) / move["speed"]  # the tip at the target's rest depth
    for i, v in enumerate(variants):
        tr = res.nodes[res.nodes["variant"] == i]
        t = tr["step"].to_numpy() * dt
        # The needle moves rigidly: tip = base + (length + speed t) direction.
        travel = needle["length"] + move["speed"] * np.minimum(t, duration)
        tip = np.asarray(v["needle.base"]) + travel[:, None] * direction
        pos = tr[["x", "y", "z"]].to_numpy()
        gap = np.linalg.norm(tip - pos, axis=1)
        misses.append(gap.min())
        planned.append(gap[np.argmin(abs(t - t_plan))])
    misses, planned = np.array(misses), np.array(planned)
    best = int(np.argmin(misses))
    print(f"{len(variants)} entry points in {wall:.1f} s on {args.workers} workers")
    for y, m, q in zip(ys, misses, planned):
        print(f"entry offset {y * 1e3:+6.2f} mm: closest {m * 1e3:5.2f} mm, "
              f"at the planned depth {q * 1e3:5.2f} mm")
    naive = misses[np.argmin(abs(ys))]
    print(f"best entry offset {ys[best] * 1e3:+.2f} mm: miss {misses[best] * 1e3:.2f} mm "
          f"(aimed at the rest position: {naive * 1e3:.2f} mm)")

    fig, ax = plt.subplots(figsize=(6, 3.6))
    ax.plot(ys * 1e3, misses * 1e3, "o-", label="closest approach")
    ax.plot(ys * 1e3, planned * 1e3, "s--", label="tip stopped at the target's rest depth")
    ax.axvline(0.0, color="0.6", ls=":", label="aimed at the target's rest position")
    ax.set_xlabel("entry point offset along y (mm), needle 30 degrees off the normal")
    ax.set_ylabel("tip-to-target distance (mm)")
    ax.set_title("needlesim.sweep: entry point against miss (target moves)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "target_sweep.png", dpi=120)
    print(f"wrote {out / 'target_sweep.png'}")


if __name__ == "__main__":
    main()
