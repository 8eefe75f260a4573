"""The paper's experiment from Python: a needle moved 15 cm into a 639-node cube, then
rotated 25 degrees about z. Saves the needle force against depth and a picture of the
deformed surface with the needle.

    python crates/py/examples/paper_force.py [--scene scenes/paper_insertion_lshm.toml]
                                             [--out out/python] [--backend cpu-parallel]
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
    p.add_argument("--backend", default=None)
    p.add_argument("--steps", type=int, default=None, help="default: the scene's duration")
    args = p.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    sim = needlesim.Simulation.from_scene(args.scene, backend=args.backend)
    steps = args.steps or 4500
    sim.step(steps)
    h = sim.history()
    print(f"{sim.backend}: {steps} steps, state {sim.puncture_state}, "
          f"{sim.needle_nodes} needle nodes, axial force {sim.needle_force['axial']:.3f} N")

    # Force against depth: the straight insertion, then the rotation at full depth.
    fig, ax = plt.subplots(figsize=(8, 4.5))
    depth_mm = 1e3 * h["depth"]
    ax.plot(depth_mm, h["axial"], lw=0.8, label="axial (resists insertion > 0)")
    ax.plot(depth_mm, h["lateral"], lw=0.8, label="lateral")
    ax.set_xlabel("tip depth past first contact (mm)")
    ax.set_ylabel("force on the needle (N)")
    ax.set_title(Path(args.scene).stem)
    ax.axhline(0.0, color="grey", lw=0.5)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "needle_force_depth.png", dpi=120)
    plt.close(fig)

    # The deformed surface, coloured by displacement, with the needle and its nodes.
    verts, faces = sim.surface()
    pos, rest = sim.positions, sim.rest_positions
    tri_nodes = sim.triangles
    disp = np.linalg.norm(pos - rest, axis=1)
    fig = plt.figure(figsize=(7, 6))
    ax = fig.add_subplot(projection="3d")
    surf = ax.plot_trisurf(verts[:, 0], verts[:, 1], verts[:, 2], triangles=faces,
                           linewidth=0.1, edgecolor="k", alpha=0.35)
    surf.set_array(disp[tri_nodes].mean(axis=1))
    fig.colorbar(surf, ax=ax, shrink=0.6, label="displacement (m)")
    if sim.tip is not None:
        b, t = sim.base, sim.tip
        ax.plot([b[0], t[0]], [b[1], t[1]], [b[2], t[2]], color="crimson", lw=2)
        needle = pos[sim.mesh_nodes:]
        ax.scatter(needle[:, 0], needle[:, 1], needle[:, 2], color="crimson", s=12)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.set_title(f"t = {sim.time:.2f} s, {sim.puncture_state}")
    fig.tight_layout()
    fig.savefig(out / "deformed_surface.png", dpi=120)
    plt.close(fig)
    print(f"wrote {out / 'needle_force_depth.png'} and {out / 'deformed_surface.png'}")


if __name__ == "__main__":
    main()
