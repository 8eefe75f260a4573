#!/usr/bin/env python3
"""needlesim against NVIDIA Warp and Taichi on the same workload (see workload.py), in one
process tree, printed as one table with ratios.

    python3 benches/peers/run.py                 # 10k and 100k nodes, CPU
    NEEDLESIM_PEERS_1M=1 python3 benches/peers/run.py   # adds 1M nodes
    python3 benches/peers/run.py --cuda          # adds needlesim's GPU backend and the
                                                 # peers' CUDA runs (a CUDA GPU needed)
    python3 benches/peers/run.py --gpu-only --python python3 --no-install
                                                 # only the GPU rows, with an interpreter
                                                 # that already has the three packages

It makes its own virtual environment (``target/peers-venv``; ``--venv`` to move it) with
warp-lang and taichi at the versions of ``requirements.txt`` and needlesim built in
release mode (maturin), unless ``--no-install``. On a machine without a network, first
``pip download -r benches/peers/requirements.txt maturin -d WHEELS`` elsewhere and pass
``--wheels WHEELS``. Each engine runs in its own process (one thread count per process);
the table, the machine and its load before and after go to stdout and to
``target/peers/results.md`` (raw numbers in ``results.json``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def sh(cmd, env=None, capture=False):
    print("+", " ".join(map(str, cmd)), file=sys.stderr, flush=True)
    cmd = [str(c) for c in cmd]
    r = subprocess.run(cmd, env=env, text=True, capture_output=capture)
    if r.returncode != 0:
        if capture:
            sys.stderr.write(r.stdout + r.stderr)
        raise SystemExit(f"failed ({r.returncode}): {' '.join(map(str, cmd))}")
    return r.stdout if capture else None


def install(venv: Path, wheels: str | None) -> Path:
    py = venv / "bin" / "python"
    if not py.exists():
        sh([sys.executable, "-m", "venv", str(venv)])
    pip = [str(py), "-m", "pip", "install", "-q", "--disable-pip-version-check"]
    if wheels:
        pip += ["--no-index", "--find-links", wheels]
    sh(pip + ["-r", str(HERE / "requirements.txt"), "maturin>=1.5,<2"])
    env = dict(os.environ, VIRTUAL_ENV=str(venv))
    sh([str(venv / "bin" / "maturin"), "develop", "--release", "-q",
        "-m", str(ROOT / "crates/py/Cargo.toml")], env=env)
    return py


def machine() -> dict:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "load": os.getloadavg(),
            "python": platform.python_version(), "date": time.strftime("%Y-%m-%d %H:%M")}


def engine(py: Path, script: str, args: list, env: dict, keep_going: bool) -> dict | None:
    """One engine's run in its own process: its JSON result line, or None when it failed
    and `keep_going` is set (the failure is printed; the other engines still run)."""
    try:
        out = sh([str(py), str(HERE / script), *map(str, args)], env=env, capture=True)
    except SystemExit as e:
        if not keep_going:
            raise
        print(f"skipped: {e}", file=sys.stderr, flush=True)
        return None
    return json.loads(out.strip().splitlines()[-1])


def median(xs):
    s = sorted(xs)
    return s[len(s) // 2]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", default=None, help="lattice edges, e.g. 22,47 (default; 100 "
                   "is added by NEEDLESIM_PEERS_1M=1)")
    p.add_argument("--kernels", default="mass_spring,shape_matching")
    p.add_argument("--seconds", type=float, default=3.0, help="per timed repeat")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--cuda", action="store_true")
    p.add_argument("--gpu-only", action="store_true",
                   help="only needlesim's GPU backend and the peers' CUDA runs")
    p.add_argument("--keep-going", action="store_true",
                   help="an engine that fails is reported and skipped, not fatal")
    p.add_argument("--no-install", action="store_true")
    p.add_argument("--python", default=None,
                   help="interpreter that already has numpy, needlesim, warp and taichi "
                   "(implies --no-install)")
    p.add_argument("--venv", default=str(ROOT / "target" / "peers-venv"))
    p.add_argument("--wheels", default=None)
    p.add_argument("--out", default=str(ROOT / "target" / "peers"))
    a = p.parse_args()
    sizes = [int(s) for s in a.sizes.split(",")] if a.sizes else [22, 47]
    if not a.sizes and os.environ.get("NEEDLESIM_PEERS_1M"):
        sizes.append(100)
    venv = Path(a.venv)
    if a.python:
        py = Path(a.python)
    else:
        py = venv / "bin" / "python" if a.no_install else install(venv, a.wheels)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    path = os.pathsep.join(p for p in [str(HERE), os.environ.get("PYTHONPATH")] if p)
    env = dict(os.environ, PYTHONPATH=path, RAYON_NUM_THREADS="2",
               TI_LOG_LEVEL="warn")
    before = machine()
    runs = []
    threads2 = min(2, os.cpu_count() or 1)
    for kernel in a.kernels.split(","):
        for n in sizes:
            wfile = out / f"{kernel}_{n}.npz"
            engine_args = ["--seconds", a.seconds, "--repeats", a.repeats]
            try:
                sh([str(py), str(HERE / "needlesim_engine.py"), "export", kernel, n, wfile],
                   env=env)
            except SystemExit as e:
                if not a.keep_going:
                    raise
                print(f"skipped {kernel} {n}^3: {e}", file=sys.stderr, flush=True)
                continue
            jobs = [
                ("needlesim 1 thr", "needlesim_engine.py", ["time", wfile, "--threads", 1]),
                ("Warp CPU 1 thr", "warp_engine.py", [wfile, "--device", "cpu"]),
                ("Taichi 1 thr", "taichi_engine.py", [wfile, "--threads", 1]),
                (f"needlesim {threads2} thr", "needlesim_engine.py",
                 ["time", wfile, "--threads", threads2]),
                (f"Taichi {threads2} thr", "taichi_engine.py", [wfile, "--threads", threads2]),
            ]
            if a.gpu_only:
                jobs = []
            if a.cuda or a.gpu_only:
                jobs += [
                    ("needlesim GPU", "needlesim_engine.py", ["time", wfile, "--backend", "gpu"]),
                    ("Warp CUDA", "warp_engine.py", [wfile, "--device", "cuda"]),
                    ("Taichi CUDA", "taichi_engine.py", [wfile, "--arch", "cuda"]),
                ]
            for label, script, args in jobs:
                r = engine(py, script, args + engine_args, env, a.keep_going)
                if r is None:
                    continue
                r.update(kernel=kernel, nodes=n**3, label=label)
                runs.append(r)
                print(f"{kernel} {n**3} {label}: {median(r['rates']):.1f} steps/s "
                      f"(deviation {r['deviation']:.1e})", file=sys.stderr, flush=True)
    after = machine()
    report = table(runs, before, after, threads2)
    print(report)
    (out / "results.md").write_text(report)
    (out / "results.json").write_text(json.dumps({"before": before, "after": after,
                                                  "runs": runs}, indent=1))


def is_gpu(label: str) -> bool:
    """Whether a row label is a GPU run (needlesim's GPU backend, a peer's CUDA run)."""
    return "GPU" in label or "CUDA" in label


def table(runs, before, after, threads2) -> str:
    labels = []
    for r in runs:
        if r["label"] not in labels:
            labels.append(r["label"])
    versions = {r["engine"]: r["version"] for r in runs}
    gpu = int(any(is_gpu(label) for label in labels))
    lines = [
        f"Machine: {before['cpu']}, {before['cores']} cores; load average "
        f"{before['load'][0]:.2f} before, {after['load'][0]:.2f} after; {before['date']}; "
        + ", ".join(f"{k} {v}" for k, v in versions.items())
        + "".join(f"; device {d}" for d in sorted({r["device"] for r in runs
                                                  if is_gpu(r["label"])}))
        + ".",
        "Steps per second, median of the timed repeats (ratio = needlesim / best peer on the "
        "same threads; deviation = largest node distance from needlesim's one-thread result "
        "after 100 steps, over the largest displacement).",
        "",
        "| kernel | nodes | " + " | ".join(labels) + f" | ratio 1 thr | ratio {threads2} thr"
        + (" | ratio GPU" if gpu else "") + " | max deviation |",
        "|---|---:|" + "---:|" * (len(labels) + 3 + gpu),
    ]
    keys = []
    for r in runs:
        if (r["kernel"], r["nodes"]) not in keys:
            keys.append((r["kernel"], r["nodes"]))
    for kernel, nodes in keys:
        rs = {r["label"]: r for r in runs if r["kernel"] == kernel and r["nodes"] == nodes}
        rate = {k: median(r["rates"]) for k, r in rs.items()}

        def ratio(ours, peers):
            best = max((rate[p] for p in peers if p in rate), default=None)
            return f"{rate[ours] / best:.2f}x" if ours in rate and best else "-"

        cells = [f"{rate[label]:,.0f}" if label in rate else "-" for label in labels]
        r1 = ratio("needlesim 1 thr", ["Warp CPU 1 thr", "Taichi 1 thr"])
        r2 = ratio(f"needlesim {threads2} thr", [f"Taichi {threads2} thr"])
        rg = ratio("needlesim GPU", ["Warp CUDA", "Taichi CUDA"])
        dev = max(r["deviation"] for r in rs.values())
        lines.append(f"| {kernel.replace('_', ' ')} | {nodes:,} | " + " | ".join(cells)
                     + f" | {r1} | {r2}" + (f" | {rg}" if gpu else "") + f" | {dev:.1e} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
