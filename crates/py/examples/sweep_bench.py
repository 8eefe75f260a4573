"""Benchmark: variants per minute of needlesim.sweep, in this process and on Dask
LocalClusters of 1 and 2 workers (one thread each), on the same variants; checks that the
force histories are bitwise the same however they ran.

    python crates/py/examples/sweep_bench.py [--scene scenes/paper_insertion_lshm.toml]
                                             [--variants 8] [--steps 3000]
"""

import argparse
import time
from pathlib import Path

import needlesim

ROOT = Path(__file__).resolve().parents[3]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", default=str(ROOT / "scenes" / "paper_insertion_lshm.toml"))
    p.add_argument("--variants", type=int, default=8)
    p.add_argument("--steps", type=int, default=3000)
    p.add_argument("--workers", default="1,2")
    args = p.parse_args()
    # The CLI benchmark's variants: stiffness and friction varied.
    variants = [
        {"material.stiffness": 10.0 + 5.0 * (i // 2), "needle.friction.coefficient": 0.2 + 0.2 * (i % 2)}
        for i in range(args.variants)
    ]
    from distributed import Client, LocalCluster

    rows, forces = [], {}
    t0 = time.perf_counter()
    res = needlesim.sweep(args.scene, variants, "serial", steps=args.steps)
    rows.append(("in process (client='serial')", time.perf_counter() - t0))
    forces["serial"] = res.force
    for w in [int(x) for x in args.workers.split(",")]:
        with LocalCluster(n_workers=w, threads_per_worker=1, dashboard_address=None) as cl, \
                Client(cl) as c:
            c.wait_for_workers(w)
            t0 = time.perf_counter()
            res = needlesim.sweep(args.scene, variants, c, steps=args.steps)
            rows.append((f"Dask LocalCluster, {w} worker(s)", time.perf_counter() - t0))
            forces[w] = res.force
        assert res.summary["ok"].all(), res.failed
    same = all(f.equals(forces["serial"]) for f in forces.values())
    print(f"{args.variants} variants of {Path(args.scene).name}, {args.steps} steps each")
    print("| runner | wall (s) | variants/min | vs in process |")
    print("|---|---|---|---|")
    for name, wall in rows:
        print(f"| {name} | {wall:.1f} | {60 * args.variants / wall:.1f} | "
              f"{rows[0][1] / wall:.2f}x |")
    print(f"force histories bitwise equal across runners: {same}")
    if not same:
        raise SystemExit(1)


if __name__ == "__main__":
    main()
