"""The peer-comparison workload, shared by every engine script.

An n^3 lattice cube of edge 0.1 m (density 1000 kg/m^3), K = 16 mutual nearest
neighbours, the bottom layer (z = 0) fixed, z stretched 1.2x at t = 0, dt = 1e-4 s,
gravity -9.81 m/s^2 along z, mass damping c = 30 /s taken implicitly (v <- (v + dt a) /
(1 + dt c), needlesim's integrator), float32. Two kernels:

* ``mass_spring``: k = 100 N/m at n = 22, scaled with the node mass (k ~ h^3) so that the
  highest spring frequency times dt is the same at every size, no spring damping
  (needlesim's ``mass_spring`` model). With k fixed the explicit step is not stable on
  fine lattices: at n = 47 the positions after 100 steps differed between engines by 20%
  of the displacement, and at n = 100 (1M nodes) they went non-finite (H100 run,
  2026-11-26). The cost of a step does not depend on k;
* ``shape_matching``: the paper's per-node local shape matching, k_s = 50 at n = 22 scaled
  like the springs (k_s ~ h^3), the rotation
  quaternion warm-started from the previous step with 4 iterations of Mueller et al.
  2016's extraction (needlesim's ``local_shape_matching`` with ``forces = "node"``).

The damping and the scaled stiffnesses keep every engine's state bounded over the
hundreds of thousands of steps a GPU runs in a timed repeat. Without them (H100 run,
2026-11-26) needlesim stopped the shape matching runs on its speed limit (100 m/s) after
26,100 steps at n = 22, 1,500 at n = 47 and 355 at n = 100, and the peers, which have no
such check, went on timing a diverged state. The node forces of the paper's shape
matching are not an exact gradient, so even damped the lattice keeps a bounded buzz
(largest speed about 20 m/s after 100,000 steps at n = 22, c = 30 /s, on the dev machine).

needlesim builds the scene; the peers get its arrays (rest and initial positions, inverse
masses, neighbour rows and weights) through a ``.npz`` file, so every engine steps the
same system and the results can be compared node by node.
"""

from __future__ import annotations

import json

import numpy as np

EDGE = 0.1
K = 16
DT = 1e-4
GRAVITY = (0.0, 0.0, -9.81)
STRETCH_Z = 1.2
MASS_SPRING_K = 100.0
# The lattice edge (nodes per side) at which the spring stiffness is MASS_SPRING_K.
MASS_SPRING_N = 22
SHAPE_MATCHING_K = 50.0
# Mass damping in 1/s, the same in every engine.
DAMPING = 30.0
ROTATION_ITERATIONS = 4
# Steps run from the initial state by every engine before timing; the positions after
# them are compared with needlesim's one-thread result.
CHECK_STEPS = 100
KERNELS = ("mass_spring", "shape_matching")


def size_scale(n: int) -> float:
    """Node mass on an n^3 lattice over the node mass at MASS_SPRING_N: the stiffnesses are
    scaled by it so that k / m (a squared frequency, times dt^2 what bounds an explicit
    step) is the same at every n."""
    return ((MASS_SPRING_N - 1) / (n - 1)) ** 3


def mass_spring_k(n: int) -> float:
    """Spring stiffness on an n^3 lattice (MASS_SPRING_K at MASS_SPRING_N)."""
    return MASS_SPRING_K * size_scale(n)


def shape_matching_k(n: int) -> float:
    """Shape-matching stiffness on an n^3 lattice (SHAPE_MATCHING_K at MASS_SPRING_N)."""
    return SHAPE_MATCHING_K * size_scale(n)


def damping_factor(dt: float) -> float:
    """The velocity factor 1 / (1 + dt c) of the implicit mass damping."""
    return 1.0 / (1.0 + dt * DAMPING)


def scene(kernel: str, n: int) -> dict:
    """needlesim's scene (as a dict) for `kernel` on an n x n x n lattice."""
    h = EDGE / (n - 1)
    if kernel == "mass_spring":
        material = {"model": "mass_spring", "stiffness": mass_spring_k(n),
                    "spring_damping": 0.0}
    elif kernel == "shape_matching":
        material = {
            "model": "local_shape_matching",
            "stiffness": shape_matching_k(n),
            "forces": "node",
            "rotation_iterations": ROTATION_ITERATIONS,
        }
    else:
        raise ValueError(f"unknown kernel {kernel!r}; expected one of {KERNELS}")
    return {
        "name": f"peer workload: {kernel}, {n}^3 lattice",
        "tissue": {
            "density": 1000.0,
            "neighbours": K,
            "geometry": {"kind": "box", "min": [0.0] * 3, "max": [EDGE] * 3, "spacing": h},
        },
        "material": material,
        "physics": {"dt": DT, "gravity": list(GRAVITY), "damping": DAMPING},
        "initial": {"stretch": [1.0, 1.0, STRETCH_Z]},
        "fixed": [{"name": "bottom", "axis": "z", "below": 0.5 * h}],
    }


def load(path: str) -> dict:
    """The arrays and parameters an engine needs (see ``needlesim_engine.export``)."""
    with np.load(path) as z:
        w = {k: z[k] for k in z.files}
    w["meta"] = json.loads(str(w["meta"]))
    return w


def shape_vectors(rest: np.ndarray, index: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """-(weighted centre offset of each node's rest cluster), the node itself weight 1."""
    r = rest.astype(np.float32)
    d = r[index] - r[:, None, :]
    num = (weight[..., None] * d).sum(axis=1)
    return (-(num / (1.0 + weight.sum(axis=1))[:, None])).astype(np.float32)


def deviation(x: np.ndarray, reference: np.ndarray, initial: np.ndarray) -> float:
    """Largest node distance from the reference, over the largest reference displacement."""
    moved = np.linalg.norm(reference - initial, axis=1).max()
    return float(np.linalg.norm(x - reference, axis=1).max() / moved)


def measure(run, seconds: float, repeats: int) -> list[float]:
    """Steps per second of `run(n)` (runs n steps and returns when they are done): a
    warm-up of about a quarter of `seconds`, then `repeats` timed runs of about `seconds`
    each, the step count calibrated from the warm-up."""
    import time

    n = 1
    while True:
        t0 = time.perf_counter()
        run(n)
        dt = time.perf_counter() - t0
        if dt > 0.25 * seconds or n >= 1 << 20:
            break
        n *= 2
    per_step = max(dt / n, 1e-9)
    steps = max(1, int(seconds / per_step))
    rates = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        run(steps)
        rates.append(steps / (time.perf_counter() - t0))
    return rates


def result(engine: str, version: str, device: str, threads: int, rates, dev) -> str:
    """One engine run as a JSON line for the orchestrator."""
    return json.dumps(
        {
            "engine": engine,
            "version": version,
            "device": device,
            "threads": threads,
            "rates": rates,
            "deviation": dev,
        }
    )
