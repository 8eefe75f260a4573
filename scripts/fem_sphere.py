#!/usr/bin/env python3
"""Reference solution of the accuracy report's sphere-sag case (needlesim report).

An elastic ball of radius R = 5 cm centred at the origin (y up; E = 10 kPa, nu = 0.3,
rho = 1000 kg/m^3; linear elasticity, small strain, static) sags under its own weight,
body force rho * g with g = (0, -9.81, 0) m/s^2. Every degree of freedom located at
y <= -4 cm is held at zero displacement (all three components; this holds the spherical
cap below the plane y = -4 cm); the rest of the sphere is traction free.

Meshes: scikit-fem `MeshTet.init_ball(nrefs)` scaled by R. init_ball projects the
boundary vertices back onto the unit sphere after every refinement, so the polyhedral
boundary converges to the sphere (the quadratic elements are straight-sided: their
boundary edge midpoints lie on chords, not on the sphere). Quadratic tetrahedra,
ElementVector(ElementTetP2()); smoothed-aggregation AMG (pyamg, 3 x 3 blocks, rigid body
modes as near-null space) preconditioning CG, relative residual 1e-10. Quadrature of
order 2 (4 points) integrates every form here exactly on straight-sided P2 tetrahedra
(products of linear gradients, the quadratic shape functions, u_y).

Per level:
- mean_sag = -(integral of u_y over the mesh) / (mesh volume), the clamped cap included;
- top_sag = -u_y at (0, R, 0). That point is a vertex of every init_ball mesh (one of
  the initial octahedron's corners, kept on the sphere by the projection), so it is read
  from the vertex degree of freedom directly: no probing outside the mesh is needed;
- the support reaction (K u - f summed over the clamped y-DOFs), checked against the
  weight rho * |g| * (mesh volume).
Both sags are extrapolated to zero mesh size (h ~ R / 2^nrefs) by Richardson through the
last three levels with the observed order; where no sensible order fits (the successive
differences change sign, as they do here: the clamp acts on DOF locations, so its edge
is a staircase that falls differently on every level), the finest level is reported
instead, with the spread of the last two levels as its uncertainty. The second finest
level is also re-solved with the clamp plane moved by +-1 mm, to show how sensitive the
sags are to where the clamp edge falls. Writes, relative to the repository root:

- reference/sphere_sag_fem.csv: u_y(0, y, 0) on the finest level at 37 points
  y = linspace(-0.04, 0.05, 37), header y,uy (negative = down; interior points probed,
  the last point (0, R, 0) from its vertex DOF);
- reference/sphere_sag_fem.md: the convergence table and the lines
  `mean_sag_m = <value>` and `top_sag_m = <value>`.

Run: python scripts/fem_sphere.py [--levels 2,3,4,5]
Needs: numpy, scipy, scikit-fem, pyamg.
"""

import argparse
import platform
import time
from pathlib import Path

import numpy as np
import pyamg
import scipy
import scipy.sparse as sp
import skfem
from skfem import Basis, ElementTetP2, ElementVector, Functional, LinearForm, MeshTet, asm
from skfem.models.elasticity import lame_parameters, linear_elasticity

E, NU, RHO, G = 1e4, 0.3, 1000.0, 9.81
R, Y_CLAMP = 0.05, -0.04
CHUNK = 40000  # elements per assembly chunk (bounds the memory of the COO triplets)
INTORDER = 2  # exact on straight-sided P2 tetrahedra: every integrand here is quadratic


@LinearForm
def weight(v, w):
    return -RHO * G * v.value[1]


@Functional
def volume(w):
    return 1.0 + 0.0 * w.x[0]


@Functional
def integral_uy(w):
    return w["u"].value[1]


def build_mesh(nrefs):
    m = MeshTet.init_ball(nrefs)
    r = np.linalg.norm(m.p[:, m.boundary_nodes()], axis=0)
    assert np.allclose(r, 1.0, atol=1e-12), "init_ball left boundary vertices off the sphere"
    return MeshTet(R * m.p, m.t)


def assemble_stiffness(mesh, elem):
    lam, mu = lame_parameters(E, NU)
    form = linear_elasticity(lam, mu)
    nt = mesh.t.shape[1]
    K = None
    for s in range(0, nt, CHUNK):
        b = Basis(mesh, elem, intorder=INTORDER, elements=np.arange(s, min(s + CHUNK, nt)))
        k = asm(form, b).tocsr()
        K = k if K is None else K + k
        del b, k
    return K


def rigid_modes(x):
    """Six rigid body modes (3 translations, 3 rotations) at interleaved DOF locations."""
    n = x.shape[1]
    B = np.zeros((3 * n, 6))
    for c in range(3):
        B[c::3, c] = 1.0
    X, Y, Z = x
    B[0::3, 3], B[1::3, 3] = -Y, X   # about z
    B[1::3, 4], B[2::3, 4] = -Z, Y   # about x
    B[2::3, 5], B[0::3, 5] = -X, Z   # about y
    return B


def solve(nrefs, y_clamp=Y_CLAMP):
    t0 = time.time()
    mesh = build_mesh(nrefs)
    elem = ElementVector(ElementTetP2())
    basis = Basis(mesh, elem, intorder=INTORDER)
    ndofs = basis.N
    # ElementVector numbers the three components of a location consecutively.
    assert np.array_equal(basis.nodal_dofs, 3 * np.arange(mesh.p.shape[1]) + np.arange(3)[:, None])
    assert np.array_equal(basis.edge_dofs[1] - basis.edge_dofs[0], np.ones(basis.edge_dofs.shape[1]))
    K = assemble_stiffness(mesh, elem)
    f = asm(weight, basis)
    vol = volume.assemble(basis)
    x = basis.doflocs
    fixed = x[1] <= y_clamp + 1e-12 * R
    free = ~fixed
    # Whole locations are clamped, so the free DOFs stay in consecutive triples.
    assert np.all(free.reshape(-1, 3) == free[0::3, None])
    A = K[free][:, free].tobsr(blocksize=(3, 3))
    B = rigid_modes(x[:, free][:, 0::3])
    t_setup = time.time()
    ml = pyamg.smoothed_aggregation_solver(A, B=B, symmetry="symmetric")
    res = []
    u = np.zeros(ndofs)
    u[free] = ml.solve(f[free], tol=1e-10, accel="cg", maxiter=500, residuals=res)
    t_solve = time.time()
    relres = np.linalg.norm(f[free] - A @ u[free]) / np.linalg.norm(f[free])
    del A, ml
    r = K @ u - f  # support reactions (nonzero only on clamped DOFs, up to the residual)
    reaction = np.array([r[fixed & (np.arange(ndofs) % 3 == c)].sum() for c in range(3)])
    Wt = RHO * G * vol
    int_uy = integral_uy.assemble(basis, u=basis.interpolate(u))
    mean_sag = -int_uy / vol
    # Cross-check: f . u = rho g_y * integral(u_y) (P2 basis functions sum to one).
    assert abs(f @ u / (-RHO * G) - int_uy) <= 1e-9 * abs(int_uy)
    top = np.argmin(np.linalg.norm(mesh.p - np.array([[0.0], [R], [0.0]]), axis=0))
    assert np.linalg.norm(mesh.p[:, top] - [0.0, R, 0.0]) < 1e-14
    top_sag = -u[basis.nodal_dofs[1, top]]
    info = dict(nrefs=nrefs, ntets=mesh.t.shape[1], ndofs=ndofs, nfixed=int(fixed.sum()),
                vol=vol, weight=Wt, reaction=reaction, mean_sag=mean_sag, top_sag=top_sag,
                its=len(res) - 1, relres=relres, t_asm=t_setup - t0, t_solve=t_solve - t_setup,
                time=time.time() - t0)
    return mesh, basis, u, info


def profile(mesh, basis, u, top_sag):
    ys = np.linspace(Y_CLAMP, R, 37)
    pts = np.vstack([np.zeros_like(ys), ys, np.zeros_like(ys)])
    # (0, R, 0) lies on the boundary (a mesh vertex): probe just inside, then use the vertex value.
    pts[1, -1] = R * (1.0 - 1e-9)
    scalar = Basis(mesh, ElementTetP2())
    uy = np.asarray(scalar.probes(pts) @ np.concatenate([u[basis.nodal_dofs[1]], u[basis.edge_dofs[1]]])).ravel()
    probe_top = uy[-1]
    uy[-1] = -top_sag
    return np.column_stack([ys, uy]), probe_top


def richardson(h, f):
    """f = F + C h^p through the last three levels: (p, F), or (nan, nan) if no p > 0 fits
    (for example when the successive differences change sign)."""
    (h1, h2, h3), (f1, f2, f3) = h[-3:], f[-3:]
    q = (f1 - f2) / (f2 - f3)

    def g(p):
        return q - (h1**p - h2**p) / (h2**p - h3**p)

    lo, hi = 0.05, 8.0
    if np.sign(g(lo)) == np.sign(g(hi)):
        return float("nan"), float("nan")
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if np.sign(g(mid)) == np.sign(g(lo)):
            lo = mid
        else:
            hi = mid
    p = 0.5 * (lo + hi)
    c = (f2 - f3) / (h2**p - h3**p)
    return p, f3 - c * h3**p


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--levels", default="2,3,4,5", help="init_ball refinement counts, ascending")
    ap.add_argument("--shift-level", type=int, default=None,
                    help="level re-solved with the clamp plane moved by +-SHIFT, to measure how much the "
                         "sags depend on where the clamp edge falls (default: the second finest; -1 skips)")
    ap.add_argument("--shift", type=float, default=1e-3, help="clamp plane shift for that check, m")
    args = ap.parse_args()
    levels = [int(s) for s in args.levels.split(",")]
    root = Path(__file__).resolve().parent.parent
    (root / "reference").mkdir(exist_ok=True)
    t0 = time.time()
    rows = []
    prof = None
    for n in levels:
        mesh, basis, u, info = solve(n)
        rows.append(info)
        if n == levels[-1]:
            prof, probe_top = profile(mesh, basis, u, info["top_sag"])
        del mesh, basis, u
        rel = abs(info["reaction"][1] - info["weight"]) / info["weight"]
        print(f"nrefs={n} tets={info['ntets']} dofs={info['ndofs']} mean_sag={info['mean_sag']:.9e} "
              f"top_sag={info['top_sag']:.9e} reaction_y={info['reaction'][1]:.9e} N "
              f"weight={info['weight']:.9e} N (rel {rel:.1e}) {info['its']} its, "
              f"relres {info['relres']:.1e}, {info['time']:.1f} s (assembly {info['t_asm']:.1f} s, AMG+CG {info['t_solve']:.1f} s)", flush=True)
        assert rel < 1e-6, "support reaction does not balance the weight"
    shift_level = args.shift_level if args.shift_level is not None else (levels[-2] if len(levels) > 1 else -1)
    sens = None
    if shift_level >= 0:
        s_up = solve(shift_level, Y_CLAMP + args.shift)[3]
        s_dn = solve(shift_level, Y_CLAMP - args.shift)[3]
        sens = {k: (s_dn[k], s_up[k], (s_up[k] - s_dn[k]) / (2 * args.shift)) for k in ("mean_sag", "top_sag")}
        for k, (a, b, d) in sens.items():
            print(f"nrefs={shift_level} clamp y <= {Y_CLAMP - args.shift:g}: {k}={a:.9e}; "
                  f"y <= {Y_CLAMP + args.shift:g}: {k}={b:.9e}; d{k}/d(plane) = {d:.4e}", flush=True)
    h = np.array([R / 2.0**r["nrefs"] for r in rows])
    out = {}
    for key in ("mean_sag", "top_sag"):
        v = np.array([r[key] for r in rows])
        p, vinf = richardson(h, v) if len(rows) >= 3 else (float("nan"), float("nan"))
        sensible = np.isfinite(p) and 0.5 <= p <= 6.0
        out[key] = (p, vinf if sensible else v[-1], sensible, v[-1], np.diff(v))
        print(f"{key}: observed order p = {p:.3f}, extrapolated {vinf:.9e} m"
              + ("" if sensible else " (order not sensible: finest level reported)"), flush=True)
    np.savetxt(root / "reference/sphere_sag_fem.csv", prof, delimiter=",", fmt="%.9e",
               header="y,uy", comments="")
    fin = rows[-1]
    scale = RHO * G * R**2 / E
    vball = 4.0 / 3.0 * np.pi * R**3
    lines = [
        "# Sphere sag reference (scikit-fem, quadratic tetrahedra)",
        "",
        f"mean_sag_m = {out['mean_sag'][1]:.9e}",
        f"top_sag_m = {out['top_sag'][1]:.9e}",
        "",
        "Problem: a ball centred at the origin, y up, linear elasticity (small strain, static),",
        "sagging under its own weight (body force rho * g, g pointing down, -y).",
        "",
        "R = 0.05 m",
        "E = 10000 Pa",
        "nu = 0.3",
        "rho = 1000 kg/m^3",
        "g = 9.81 m/s^2",
        "clamp y <= -0.04 m",
        "",
        "Clamp: every degree of freedom located at y <= -0.04 m has u = 0 (all three",
        "components; the cap below the plane y = -0.04 m, vertices and edge midpoints alike,",
        "so the clamped region is resolved to within one element). The rest of the surface",
        "is traction free.",
        "mean_sag = -(integral of u_y over the mesh) / (mesh volume), the clamped cap",
        "included; top_sag = -u_y at (0, R, 0), which is a vertex of every mesh (read from",
        "its vertex DOF, no probing needed).",
        "",
        "Meshes: MeshTet.init_ball(nrefs) scaled by R (init_ball projects the boundary",
        "vertices onto the sphere after each refinement; the straight-sided quadratic",
        "elements put boundary edge midpoints on chords, so the mesh is a polyhedron",
        "inscribed in the ball). ElementVector(ElementTetP2), smoothed-aggregation AMG",
        "(pyamg, 3 x 3 blocks, rigid body modes) + CG, relative residual 1e-10; 4-point",
        "quadrature (exact for these straight-sided P2 integrands).",
        "",
        "| nrefs | h = R/2^nrefs, m | tetrahedra | DOFs | mean_sag, m | top_sag, m | CG iterations | time, s |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r, hh in zip(rows, h):
        lines.append(f"| {r['nrefs']} | {hh:.6f} | {r['ntets']} | {r['ndofs']} | {r['mean_sag']:.9e} | "
                     f"{r['top_sag']:.9e} | {r['its']} | {r['time']:.1f} |")
    lines.append("")
    for key in ("mean_sag", "top_sag"):
        p, v, ok, vfin, dv = out[key]
        if ok:
            lines.append(f"{key}: Richardson through the last three levels, observed order p = {p:.3f}, "
                         f"extrapolated {v:.9e} m; the finest level differs from it by "
                         f"{100 * abs(v - vfin) / abs(v):.3f}%.")
        else:
            lines.append(f"{key}: the last three levels give no sensible order (successive differences "
                         + ", ".join(f"{d:+.3e}" for d in dv[-2:]) + " m change sign or do not shrink); "
                         f"the value above is the finest level's, no extrapolation.")
    if len(rows) >= 2 and not all(out[k][2] for k in out):
        spread = {k: abs(rows[-1][k] - rows[-2][k]) / abs(rows[-1][k]) for k in ("mean_sag", "top_sag")}
        lines += [
            "",
            "Why the sequence is not monotone: the clamp is applied to DOF locations, and the",
            "plane y = -0.04 m cuts the init_ball meshes at a different place inside the elements",
            "on every level, so the effective clamp edge lies somewhere between the last clamped",
            "and the first free DOF, differently per level (an O(h) error whose sign changes from",
            "level to level). The last two levels differ by "
            f"{100 * spread['mean_sag']:.2f}% (mean_sag) and {100 * spread['top_sag']:.2f}% (top_sag);",
            "take that as the least uncertainty of the values above (the sensitivity below says",
            "a clamp edge off by a few tenths of a millimetre moves them by a few per cent).",
            "",
        ]
    if sens is not None:
        lines += [
            "" if lines[-1] else None,
            f"Clamp sensitivity (level nrefs = {shift_level} re-solved with the plane at "
            f"y = {Y_CLAMP - args.shift:g} and {Y_CLAMP + args.shift:g} m):",
            "",
            "| quantity | plane lowered, m | plane raised, m | d/d(plane), m per m |",
            "|---|---:|---:|---:|",
        ]
        for k, (a, b, d) in sens.items():
            lines.append(f"| {k} | {a:.9e} | {b:.9e} | {d:.4e} |")
        lines = [ln for ln in lines if ln is not None]
        d_last = {k: abs(rows[-1][k] - rows[-2][k]) for k in sens} if len(rows) >= 2 else None
        lines += [
            "",
            "Raising the clamp plane stiffens the support and lowers both sags.",
        ]
        if d_last:
            lines.append("The change between the last two levels equals moving the plane by "
                         f"{1e3 * d_last['mean_sag'] / abs(sens['mean_sag'][2]):.2f} mm (mean_sag) or "
                         f"{1e3 * d_last['top_sag'] / abs(sens['top_sag'][2]):.2f} mm (top_sag).")
    lines += [
        "",
        f"Scale check: rho g R^2 / E = {scale:.4e} m.",
        "",
        "Equilibrium check (each level; support reaction = K u - f summed over the clamped",
        "y-DOFs, weight = rho g times the mesh volume):",
        "",
        "| nrefs | mesh volume, m^3 | weight, N | reaction_y, N | relative difference | reaction_x, N | reaction_z, N |",
        "|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        rx, ry, rz = r["reaction"]
        lines.append(f"| {r['nrefs']} | {r['vol']:.9e} | {r['weight']:.9e} | {ry:.9e} | "
                     f"{abs(ry - r['weight']) / r['weight']:.1e} | {rx:.1e} | {rz:.1e} |")
    lines += [
        "",
        f"The exact ball volume is {vball:.9e} m^3 (weight {RHO * G * vball:.9e} N); the finest",
        f"mesh holds {100 * (1 - fin['vol'] / vball):.4f}% less.",
        "",
        f"reference/sphere_sag_fem.csv: u_y(0, y, 0) of the finest level (nrefs = {fin['nrefs']})",
        "at y = linspace(-0.04, 0.05, 37), negative = down; interior points probed with the",
        "P2 basis, the last point (0, R, 0) is the vertex value (probing at",
        f"(0, R (1 - 1e-9), 0) gives {probe_top:.9e} m).",
        "",
        f"Run time {time.time() - t0:.0f} s on a 2-core dev machine (24 GiB, one thread,",
        f"OMP_NUM_THREADS=1); Python {platform.python_version()}, scikit-fem {skfem.__version__},",
        f"numpy {np.__version__}, scipy {scipy.__version__}, pyamg {pyamg.__version__}.",
        "Command: `OMP_NUM_THREADS=1 python scripts/fem_sphere.py --levels "
        + ",".join(map(str, levels)) + "`" + (f" (clamp check on level {shift_level})" if sens else ""),
        "",
    ]
    (root / "reference/sphere_sag_fem.md").write_text("\n".join(lines))


if __name__ == "__main__":
    main()
