"""Parameter sweeps: one scene run once per variant, each variant a Dask task.

A variant is a dict of scene overrides with dotted keys (``{"material.young_modulus":
2e4, "needle.keyframe.0.speed": 0.01}``; numeric parts index arrays of tables), the same
keys as ``needlesim sweep --vary``. Each variant runs on one CPU thread by default
(``backend="cpu"``), so a run gives bitwise the result of the same scene run alone with
``Simulation.from_dict(scene, backend="cpu")``, on whichever worker it lands.

Cores: give each Dask worker one thread (``threads_per_worker=1``) and each simulation one
thread (``threads=1``, the default); the cluster that ``sweep`` starts itself has one
worker process per core. With ``threads=k`` it starts ``cores // k`` workers, so that the
cores are used once, not oversubscribed.

Without ``dask.distributed`` installed (``pip install needlesim[dask]``) the variants run
one after another in this process, and a ``SerialSweepWarning`` says so.
"""

from __future__ import annotations

import copy
import itertools
import os
import socket
import tempfile
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, Iterable, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from ._needlesim import Simulation

__all__ = [
    "OverrideError",
    "SerialSweepWarning",
    "SweepResult",
    "apply_overrides",
    "grid",
    "load_scene",
    "sweep",
]

SceneLike = Union[str, "os.PathLike[str]", Mapping[str, Any]]


class OverrideError(ValueError):
    """A variant's key does not name a place in the scene (the message names the key)."""


class SerialSweepWarning(UserWarning):
    """``sweep`` runs the variants one after another: dask.distributed is not installed."""


def load_scene(path: Union[str, "os.PathLike[str]"]) -> Tuple[Dict[str, Any], Path]:
    """The scene file at ``path`` as a dict, and the folder its relative paths start from."""
    try:
        import tomllib  # Python 3.11+
    except ModuleNotFoundError:  # pragma: no cover - Python < 3.11
        import tomli as tomllib  # type: ignore[no-redef, import-not-found]
    path = Path(path)
    with open(path, "rb") as f:
        return tomllib.load(f), path.resolve().parent


def grid(axes: Mapping[str, Sequence[Any]]) -> List[Dict[str, Any]]:
    """Every combination of the values: ``grid({"a": [1, 2], "b": [3, 4]})`` gives four
    variants, the last key varying fastest."""
    keys = list(axes)
    for k in keys:
        if isinstance(axes[k], (str, bytes)) or len(axes[k]) == 0:
            raise ValueError(f"grid: `{k}` needs a non-empty list of values")
    return [dict(zip(keys, combo)) for combo in itertools.product(*(axes[k] for k in keys))]


def apply_overrides(scene: Mapping[str, Any], overrides: Mapping[str, Any]) -> Dict[str, Any]:
    """A deep copy of ``scene`` with each dotted key set. Every part but the last must
    exist; the last may be new (an optional key). Numeric parts index lists."""
    out = copy.deepcopy(dict(scene))
    for key, value in overrides.items():
        parts = key.split(".")
        if not key or any(p == "" for p in parts):
            raise OverrideError(f"`{key}`: empty part in the key")
        at: Any = out
        for p in parts[:-1]:
            at = _child(at, p, key)
        last = parts[-1]
        if isinstance(at, dict):
            at[last] = copy.deepcopy(value)
        elif isinstance(at, list):
            at[_index(at, last, key)] = copy.deepcopy(value)
        else:
            raise OverrideError(f"`{key}`: its parent is a plain value")
    return out


def _index(items: list, part: str, key: str) -> int:
    if not part.isdigit():
        raise OverrideError(f"`{key}`: `{part}` is not an index")
    i = int(part)
    if i >= len(items):
        raise OverrideError(f"`{key}`: index {i} past the {len(items)} entries")
    return i


def _child(at: Any, part: str, key: str) -> Any:
    if isinstance(at, dict):
        if part not in at:
            raise OverrideError(f"`{key}`: no `{part}`")
        return at[part]
    if isinstance(at, list):
        return at[_index(at, part, key)]
    raise OverrideError(f"`{key}`: `{part}` is inside a plain value")


@dataclass
class SweepResult:
    """Tidy tables (pandas), one row per variant and step (``force``), per variant,
    recorded step and node (``nodes``), and per variant (``summary``). Every table starts
    with ``variant`` (the index in the list given) and one column per override key."""

    force: Any
    nodes: Any
    summary: Any

    @property
    def failed(self) -> Any:
        """The summary rows of the variants that did not complete (``error_type``,
        ``error``)."""
        return self.summary[~self.summary["ok"]]

    def variant(self, i: int) -> Any:
        """The force history of variant ``i``."""
        return self.force[self.force["variant"] == i].reset_index(drop=True)


def sweep(
    scene: SceneLike,
    variants: Union[Sequence[Mapping[str, Any]], Mapping[str, Sequence[Any]]],
    client: Any = None,
    *,
    steps: Optional[int] = None,
    duration: Optional[float] = None,
    nodes: Optional[Sequence[int]] = None,
    every: Optional[int] = None,
    backend: str = "cpu",
    threads: Optional[int] = 1,
    files: str = "inline",
    base_dir: Optional[Union[str, "os.PathLike[str]"]] = None,
) -> SweepResult:
    """Runs ``scene`` once per variant and returns the tidy tables.

    scene: a scene file path, or a dict with the TOML keys (relative paths from
        ``base_dir``, default the working folder).
    variants: a list of override dicts, or ``{key: [values]}`` for their grid.
    client: a ``distributed.Client``, a scheduler address, ``None`` (the current default
        client, else a LocalCluster started for this call and closed after it), or
        ``"serial"`` (this process, no Dask).
    steps: steps per run (default: the scene's, ``Simulation.run_steps``).
    duration: simulated seconds per run instead of ``steps`` (``ceil(duration / dt)``
        steps, as the scene key ``run.duration``): use it when the variants change a
        ``dt = "auto"`` scene's time step (through the modulus, the density or the
        spacing).
    nodes, every: node indices whose positions are recorded every ``every`` steps
        (default: ``run.output_every``, else 100), step 0 included, in the ``nodes`` table.
    backend, threads: as in ``Simulation.from_dict``; the default is one CPU thread.
    files: ``"inline"`` (surface files referenced by ``path`` keys are read here and sent
        with each task: works on any cluster) or ``"shared"`` (paths made absolute: the
        workers must see the same file system).

    A variant that fails (a bad key, a scene error, a divergence, a lost worker) gets a
    summary row with ``ok`` False, ``error_type`` (``OverrideError``, ``ValueError``,
    ``RuntimeError``, ...) and ``error``; the other variants complete.
    """
    pd = _pandas()
    if isinstance(scene, Mapping):
        scene_dict = dict(scene)
        root = Path(base_dir if base_dir is not None else ".").resolve()
    else:
        scene_dict, root = load_scene(scene)
        if base_dir is not None:
            root = Path(base_dir).resolve()
    if isinstance(variants, Mapping):
        variants = grid(variants)
    variants = [dict(v) for v in variants]
    if files not in ("inline", "shared"):
        raise ValueError(f"files must be 'inline' or 'shared', not {files!r}")
    if nodes is not None:
        nodes = [int(i) for i in nodes]
        if any(i < 0 for i in nodes):
            raise ValueError("nodes: indices must be >= 0")
    if steps is not None and duration is not None:
        raise ValueError("give steps or duration, not both")
    if duration is not None and not (np.isfinite(duration) and duration > 0):
        raise ValueError(f"duration must be a positive time in s, not {duration!r}")
    for name, count in (("steps", steps), ("every", every)):
        if count is not None and (not isinstance(count, (int, np.integer)) or count < 1):
            raise ValueError(f"{name} must be a positive integer, not {count!r}")

    keys: List[str] = []
    for v in variants:
        keys += [k for k in v if k not in keys]
    cache: Dict[Path, bytes] = {}
    results: List[Optional[Dict[str, Any]]] = [None] * len(variants)
    tasks: List[Tuple[int, Dict[str, Any]]] = []
    for i, v in enumerate(variants):
        try:
            s = apply_overrides(scene_dict, v)
            run = s.get("run", {}) if isinstance(s.get("run"), dict) else {}
            k = every if every is not None else run.get("output_every", 100)
            if duration is not None:
                # The scene key does the counting (Simulation.run_steps, as in Rust).
                run = {key: x for key, x in run.items() if key != "steps"}
                s = {**s, "run": {**run, "duration": float(duration)}}
            s, shipped = _ship_files(s, root, files, cache)
            tasks.append(
                (
                    i,
                    {
                        "scene": s,
                        "files": shipped,
                        "base_dir": str(root),
                        "steps": steps,
                        "nodes": nodes,
                        "every": int(k),
                        "backend": backend,
                        "threads": threads,
                    },
                )
            )
        except (ValueError, OSError) as e:
            results[i] = _failure(e)

    for i, r in _execute(tasks, client, threads):
        results[i] = r
    return _tables(pd, variants, keys, results)


def _pandas() -> Any:
    try:
        import pandas
    except ModuleNotFoundError as e:
        raise ModuleNotFoundError(
            "needlesim.sweep returns pandas tables: pip install needlesim[sweep] "
            "(or needlesim[dask] for Dask as well)"
        ) from e
    return pandas


def _ship_files(
    scene: Dict[str, Any], root: Path, files: str, cache: Dict[Path, bytes]
) -> Tuple[Dict[str, Any], Dict[str, bytes]]:
    """Rewrites every string ``path`` key: absolute (shared) or ``files/<n>_<name>``
    with the bytes to send (inline)."""
    shipped: Dict[str, bytes] = {}

    def walk(node: Any) -> None:
        if isinstance(node, dict):
            for k, v in node.items():
                if k == "path" and isinstance(v, str):
                    full = (root / v).resolve()
                    if files == "shared":
                        node[k] = str(full)
                    else:
                        if full not in cache:
                            cache[full] = full.read_bytes()
                        rel = f"files/{len(shipped)}_{full.name}"
                        shipped[rel] = cache[full]
                        node[k] = rel
                else:
                    walk(v)
        elif isinstance(node, list):
            for v in node:
                walk(v)

    walk(scene)
    return scene, shipped


def _failure(e: BaseException) -> Dict[str, Any]:
    return {"ok": False, "error_type": type(e).__name__, "error": str(e)}


def run_variant(task: Mapping[str, Any]) -> Dict[str, Any]:
    """Runs one prepared variant (what each Dask task calls); never raises for a failed
    run: the error comes back in the result."""
    t0 = time.perf_counter()
    try:
        with tempfile.TemporaryDirectory(prefix="needlesim-") as tmp:
            base = task["base_dir"]
            if task["files"]:
                base = tmp
                for rel, data in task["files"].items():
                    p = Path(tmp) / rel
                    p.parent.mkdir(parents=True, exist_ok=True)
                    p.write_bytes(data)
            sim = Simulation.from_dict(
                task["scene"], backend=task["backend"], threads=task["threads"], base_dir=base
            )
        out = _run(sim, task)
    except (ValueError, RuntimeError, OSError) as e:
        out = _failure(e)
    out["wall_s"] = time.perf_counter() - t0
    out["worker"] = f"{socket.gethostname()}:{os.getpid()}"
    return out


def _run(sim: Simulation, task: Mapping[str, Any]) -> Dict[str, Any]:
    nodes = task["nodes"]
    steps, every = task["steps"], task["every"]
    if steps is None:
        steps = sim.run_steps
    rest = sim.positions
    if nodes is not None and nodes and max(nodes) >= len(rest):
        raise ValueError(f"nodes: index {max(nodes)} past the {len(rest)} nodes")
    rec_steps: List[int] = []
    rec_pos: List[np.ndarray] = []
    done = 0
    while True:
        if nodes:
            rec_steps.append(sim.steps)
            rec_pos.append(sim.positions[nodes])
        if done == steps:
            break
        n = min(every if nodes else steps, steps - done)
        sim.step(n)
        done += n
    h = sim.history()
    pos = sim.positions
    m = sim.mesh_nodes
    disp = np.linalg.norm(pos[:m] - rest[:m], axis=1)
    axial = np.asarray(h["axial"])
    return {
        "ok": True,
        "error_type": "",
        "error": "",
        "history": h,
        "nodes": list(nodes or []),
        "node_steps": np.asarray(rec_steps, dtype=np.int64),
        "node_positions": np.asarray(rec_pos).reshape(len(rec_steps), len(nodes or []), 3),
        "steps": sim.steps,
        "time_s": sim.time,
        "state": sim.puncture_state if sim.tip is not None else "",
        "depth_m": float(h["depth"][-1]) if len(axial) else float("nan"),
        "max_depth_m": float(np.max(h["depth"])) if len(axial) else float("nan"),
        "peak_axial_n": float(np.max(np.abs(axial))) if len(axial) else float("nan"),
        "final_axial_n": float(axial[-1]) if len(axial) else float("nan"),
        "active_nodes": sim.active_nodes,
        "max_displacement_m": float(disp.max()) if m else 0.0,
    }


def _execute(
    tasks: List[Tuple[int, Dict[str, Any]]], client: Any, threads: Optional[int]
) -> Iterable[Tuple[int, Dict[str, Any]]]:
    if not tasks:
        return []
    with _client(client, threads, "needlesim.sweep") as c:
        if isinstance(c, str):
            return [(i, run_variant(t)) for i, t in tasks]
        futures = c.map(run_variant, [t for _, t in tasks], pure=False)
        out = []
        try:
            for (i, _), f in zip(tasks, futures):
                try:
                    out.append((i, f.result()))
                except Exception as e:  # a lost worker, a task killed: reported, not raised
                    out.append((i, _failure(e)))
        finally:
            c.cancel(futures)
        return out


class _client:
    """The client to use: ``"serial"`` when asked for or when dask.distributed is missing
    (with a SerialSweepWarning from ``caller``), else a Dask client; closes the client
    (and its cluster) after if started here."""

    def __init__(self, client: Any, threads: Optional[int], caller: str):
        self.owned: List[Any] = []
        self.client = client
        if isinstance(client, str) and client == "serial":
            return
        try:
            import distributed
        except ModuleNotFoundError:
            if client is not None:
                raise
            warnings.warn(
                f"{caller}: dask.distributed is not installed (pip install "
                "needlesim[dask]); running the simulations one after another in this "
                "process",
                SerialSweepWarning,
                stacklevel=4,
            )
            self.client = "serial"
            return
        if client is None:
            try:
                client = distributed.default_client()
            except ValueError:
                cores = os.cpu_count() or 1
                cluster = distributed.LocalCluster(
                    n_workers=max(1, cores // max(1, threads or 1)),
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                )
                client = distributed.Client(cluster)
                self.owned = [client, cluster]
        elif isinstance(client, str):
            client = distributed.Client(client)
            self.owned = [client]
        self.client = client

    def __enter__(self) -> Any:
        return self.client

    def __exit__(self, *exc: Any) -> None:
        for o in self.owned:
            o.close()


def _tables(
    pd: Any,
    variants: Sequence[Mapping[str, Any]],
    keys: List[str],
    results: List[Optional[Dict[str, Any]]],
) -> SweepResult:
    force, nodes, summary = [], [], []
    for i, (v, r) in enumerate(zip(variants, results)):
        assert r is not None
        params = {k: v.get(k) for k in keys}
        row = {"variant": i, **params}
        for k in (
            "ok", "error_type", "error", "steps", "time_s", "state", "depth_m",
            "max_depth_m", "peak_axial_n", "final_axial_n", "active_nodes",
            "max_displacement_m", "wall_s", "worker",
        ):
            row[k] = r.get(k)
        summary.append(row)
        if not r["ok"]:
            continue
        h = r["history"]
        n = len(h["step"])
        f = pd.DataFrame(
            {
                "step": h["step"],
                "time_s": h["time"],
                "depth_m": h["depth"],
                "axial_force_n": h["axial"],
                "lateral_force_n": h["lateral"],
                "state": h["state"],
                "region": h["region"],
                "active_nodes": h["active_nodes"],
                "needle_nodes": h["needle_nodes"],
            }
        )
        for k in reversed(keys):
            f.insert(0, k, [params[k]] * n)
        f.insert(0, "variant", i)
        force.append(f)
        p = r["node_positions"]
        if p.size:
            ns, nn = p.shape[:2]
            t = pd.DataFrame(
                {
                    "step": np.repeat(r["node_steps"], nn),
                    "node": np.tile(np.asarray(r["nodes"], dtype=np.int64), ns),
                    "x": p[:, :, 0].ravel(),
                    "y": p[:, :, 1].ravel(),
                    "z": p[:, :, 2].ravel(),
                }
            )
            for k in reversed(keys):
                t.insert(0, k, [params[k]] * len(t))
            t.insert(0, "variant", i)
            nodes.append(t)
    empty_force = ["variant", *keys, "step", "time_s", "depth_m", "axial_force_n"]
    return SweepResult(
        force=pd.concat(force, ignore_index=True) if force else pd.DataFrame(columns=empty_force),
        nodes=pd.concat(nodes, ignore_index=True)
        if nodes
        else pd.DataFrame(columns=["variant", *keys, "step", "node", "x", "y", "z"]),
        summary=pd.DataFrame(summary),
    )
