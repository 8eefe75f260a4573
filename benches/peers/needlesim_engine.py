"""needlesim on the peer workload: exports the arrays the peers step, or times itself.

    python needlesim_engine.py export KERNEL N OUT.npz
    python needlesim_engine.py time WORKLOAD.npz --threads T [--backend gpu] --seconds S
"""

from __future__ import annotations

import argparse
import json

import numpy as np

import needlesim
import workload as wl


def build(kernel: str, n: int, backend: str | None, threads: int | None):
    scene = wl.scene(kernel, n)
    sim = needlesim.Simulation.from_dict(scene, backend=backend, threads=threads)
    if sim.mesh_nodes != n**3:
        raise SystemExit(f"the lattice has {sim.mesh_nodes} nodes, expected {n ** 3}")
    return sim


def export(kernel: str, n: int, out: str) -> None:
    sim = build(kernel, n, "cpu", 1)
    index, weight = sim.neighbours()
    masses = sim.masses
    x0 = sim.positions.astype(np.float32)
    held = np.zeros(len(masses), dtype=bool)
    rest = sim.rest_positions.astype(np.float32)
    held[rest[:, 2] < 0.5 * wl.EDGE / (n - 1)] = True
    inv_mass = np.where(held, 0.0, 1.0 / masses).astype(np.float32)
    sim.step(wl.CHECK_STEPS)
    meta = {"kernel": kernel, "n": n, "k": int(index.shape[1]), "dt": sim.dt}
    np.savez(
        out,
        rest=rest,
        x0=x0,
        inv_mass=inv_mass,
        index=index.astype(np.int32),
        weight=weight.astype(np.float32),
        reference=sim.positions.astype(np.float32),
        meta=json.dumps(meta),
    )


def time(path: str, backend: str | None, threads: int, seconds: float, repeats: int) -> None:
    w = wl.load(path)
    kernel, n = w["meta"]["kernel"], w["meta"]["n"]
    sim = build(kernel, n, backend, threads if backend != "gpu" else None)
    sim.step(wl.CHECK_STEPS)
    dev = wl.deviation(sim.positions, w["reference"], w["x0"])
    rates = wl.measure(sim.step, seconds, repeats)
    device = sim.backend
    print(wl.result("needlesim", needlesim.__version__, device, threads, rates, dev))


def main() -> None:
    p = argparse.ArgumentParser()
    sub = p.add_subparsers(dest="cmd", required=True)
    e = sub.add_parser("export")
    e.add_argument("kernel")
    e.add_argument("n", type=int)
    e.add_argument("out")
    t = sub.add_parser("time")
    t.add_argument("workload")
    t.add_argument("--threads", type=int, default=1)
    t.add_argument("--backend", default="cpu")
    t.add_argument("--seconds", type=float, default=3.0)
    t.add_argument("--repeats", type=int, default=3)
    a = p.parse_args()
    if a.cmd == "export":
        export(a.kernel, a.n, a.out)
    else:
        backend = None if a.backend == "cpu" else a.backend
        time(a.workload, backend, a.threads, a.seconds, a.repeats)


if __name__ == "__main__":
    main()
