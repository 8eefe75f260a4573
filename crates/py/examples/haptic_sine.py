"""The haptic loop driven by a simulated device: a sinusoidal insertion of the paper's
needle into its 639-node cube (4 cm in and out every 4 s) at 1 kHz on one CPU thread.
Plots the device's and the needle's positions, the force sent to the device and the
tissue's force on the needle, and the tick periods; prints the timing percentiles.

    python crates/py/examples/haptic_sine.py [--out out/python] [--seconds 4]

A real device replaces the SineDevice: leave `device` out and call
`loop.set_device(position, direction)` from the device's callback with its pose in the
scene's frame (metres), sending it `loop.force` (newtons).
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import needlesim  # noqa: E402

ROOT = Path(__file__).resolve().parents[3]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", default=str(ROOT / "scenes" / "paper_insertion_lshm.toml"))
    p.add_argument("--out", default="out/python")
    p.add_argument("--seconds", type=float, default=4.0)
    args = p.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    sim = needlesim.Simulation.from_scene(args.scene, threads=1)
    device = needlesim.SineDevice(sim.base, sim.direction, amplitude=0.04, frequency=0.25,
                                  clock="wall")
    loop = needlesim.HapticLoop(sim, rate=1000.0, max_ticks=int(args.seconds * 1000),
                                device=device)
    stats = loop.join()
    r = loop.records()
    print(f"{stats['ticks']} ticks, {stats['overruns']} overruns; period p50 "
          f"{stats['period_p50'] * 1e3:.3f} ms, p99 {stats['period_p99'] * 1e3:.3f} ms, "
          f"max {stats['period_max'] * 1e3:.3f} ms; latency p99 "
          f"{stats['latency_p99'] * 1e3:.3f} ms")

    t = r["wall"]
    x0 = r["device"][0, 0]
    fig, ax = plt.subplots(3, 1, figsize=(7, 8), sharex=False)
    ax[0].plot(t, (r["device"][:, 0] - x0) * 1e3, label="device")
    ax[0].plot(t, (r["needle"][:, 0] - x0) * 1e3, "--", label="needle (proxy)")
    inside = np.array([s == "inside" for s in r["state"]])
    if inside.any():
        ax[0].axvspan(t[inside][0], t[inside][-1], color="0.9", label="tip inside")
    ax[0].set_ylabel("base travel (mm)")
    ax[0].legend(loc="upper right")
    ax[1].plot(t, r["force"][:, 0], label="sent to the device")
    ax[1].plot(t, r["tissue"][:, 0], alpha=0.6, label="tissue on the needle")
    ax[1].set_ylabel("force along x (N)")
    ax[1].set_xlabel("wall time (s)")
    ax[1].legend(loc="upper right")
    ax[2].hist(r["period"][1:] * 1e3, bins=100, log=True)
    ax[2].axvline(1.5, color="r", lw=0.8, label="1.5 x target")
    ax[2].set_xlabel("tick period (ms)")
    ax[2].set_ylabel("ticks")
    ax[2].legend()
    fig.tight_layout()
    fig.savefig(out / "haptic_sine.png", dpi=110)
    print(f"wrote {out / 'haptic_sine.png'}")


if __name__ == "__main__":
    main()
