#!/usr/bin/env python3
"""Finite-element reference for the circular flat-punch indentation case.

What it computes
----------------
Linear elasticity (small strain), SI units, no gravity:

* block = cube [0, 0.1]^3 m, y is up, E = 1e4 Pa, nu = 0.3;
* bottom face y = 0 clamped (u = 0);
* top face y = 0.1: rigid, bonded (no-slip) flat circular punch of radius
  a = 0.02 m centred at (x, z) = (0.05, 0.05), pressed d = 0.002 m down:
  u = (0, -d, 0) on the punch disk; the rest of the boundary is traction free.

The script solves this with scikit-fem, quadratic tetrahedra
(ElementVector(ElementTetP2)), on a sequence of refinement levels N, and
reports the punch reaction force F (the total downward force the punch must
apply, N) on every level, both as the summed internal force (K u) over the
y-DOFs of the punch and as 2 * strain energy / d.  A Richardson extrapolation
(observed order, from the three finest levels) gives the converged force and
an estimate of the remaining discretisation error.

Mesh
----
The (x, z) cross-section is a block-structured quadrilateral "O-grid" that
contains the punch rim r = a as a mesh line, so the punch boundary follows the
circle (the rim vertices lie on the circle; the punch is the inscribed polygon
with 2N sides):
  - a centre square |x-0.05|, |z-0.05| <= a/2 with (N/2) x (N/2) cells,
  - four ring blocks between that square and the circle, (N/2) cells
    tangentially x (N/4) radially, graded towards the circle,
  - four outer blocks between the circle and the sides of the cube,
    (N/2) x (N/4), graded towards the circle.
Each quadrilateral is cut into two triangles, the triangle mesh is extruded in
y with N layers graded towards the top face, and every prism is split into
three tetrahedra with a vertex-numbering rule that keeps the mesh conforming.
The grading is a power law (size ~ distance^(1/2) near the rim), which the
r^(1/2) edge singularity at the punch rim calls for.  The family is
self-similar in N, so the extrapolation in 1/N is meaningful.

Punch DOFs: every DOF (all three components) whose location (vertex or edge
midpoint) lies on the top face with sqrt((x-0.05)^2 + (z-0.05)^2) <= a
(relative tolerance 1e-9).

Solver: the Dirichlet DOFs are condensed out and the system is solved by
conjugate gradients (relative residual 1e-10) with a symmetric two-level
preconditioner: Gauss-Seidel sweeps on the P2 system plus a coarse correction
in the P1 space of the same mesh, approximated by one smoothed-aggregation AMG
V-cycle (pyamg, the six rigid-body modes as near-null space).

Outputs (relative to the repository root, i.e. ../ of this file):
  reference/indentation_fem.csv  displacement of the finest level sampled on a
                                 17 x 17 x 17 grid of the cube (header
                                 x,y,z,ux,uy,uz; x outermost, z innermost)
  reference/indentation_fem.md   description, convergence table, and the line
                                 "reaction_force_N = <value>"

How to run
----------
    python scripts/fem_indentation.py                 # levels 8,...,28
    python scripts/fem_indentation.py --levels 8,16   # quick check

N must be a multiple of 4.  Dependencies: numpy, scipy, scikit-fem, pyamg
(pip install scikit-fem pyamg).  The default levels 8,12,16,20,24,28 take
about 9-10 minutes on 2 CPU cores and about 10 GB of memory (the finest level
alone ~4 minutes); --levels 8,12,16,20,24 takes about 5 minutes and 6 GB.
"""

import argparse
import os
import sys
import time

import numpy as np
import scipy
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.optimize import brentq
from scipy.spatial import cKDTree

import skfem
from skfem import (Basis, BilinearForm, ElementTetP1, ElementTetP2,
                   ElementVector, MeshTet, asm)
from skfem.helpers import ddot, sym_grad, trace

import pyamg
from pyamg.relaxation.relaxation import gauss_seidel

# ---------------------------------------------------------------- problem data
L = 0.1                  # cube edge, m
E = 1.0e4                # Young's modulus, Pa
NU = 0.3                 # Poisson ratio
A = 0.02                 # punch radius, m
D = 0.002                # punch depth, m
XC, ZC = 0.05, 0.05      # punch centre on the top face
B_HALF = 0.5 * A         # half-side of the centre square of the O-grid
BETA = 2.0               # power-law grading exponent towards the rim / top
CG_RTOL = 1e-10

LAM = E * NU / ((1.0 + NU) * (1.0 - 2.0 * NU))
MU = E / (2.0 * (1.0 + NU))


# ------------------------------------------------------------------------ mesh
def cross_section(n):
    """Quadrilateral O-grid of the square [0, L]^2 (coordinates x, z).

    n is the level N; returns (points (2, np), quads (4, nq)), quads listed
    counter-clockwise.
    """
    nt, nr = n // 2, n // 4          # tangential cells per side, radial cells
    s = np.linspace(-1.0, 1.0, nt + 1)
    t = np.linspace(0.0, 1.0, nr + 1)
    pts, quads = [], []

    def add_block(P):
        """P: (ni+1, nj+1, 2) grid of points; appends its quads."""
        base = sum(len(p) for p in pts)
        ni, nj = P.shape[0] - 1, P.shape[1] - 1
        pts.append(P.reshape(-1, 2))
        idx = base + np.arange((ni + 1) * (nj + 1)).reshape(ni + 1, nj + 1)
        q = np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]])
        quads.append(q.reshape(4, -1))

    # centre square
    X, Z = np.meshgrid(B_HALF * s, B_HALF * s, indexing="ij")
    add_block(np.stack([X, Z], axis=-1))

    # radial blocks, one per side; in the local frame the side faces +x
    g_in = 1.0 - (1.0 - t) ** BETA   # 0 at the square, 1 at the circle
    g_out = t ** BETA                # 0 at the circle, 1 at the cube side
    c0 = np.stack([np.full_like(s, B_HALF), B_HALF * s], axis=-1)
    phi = s * np.pi / 4.0
    c1 = np.stack([A * np.cos(phi), A * np.sin(phi)], axis=-1)
    c2 = np.stack([np.full_like(s, L / 2), (L / 2) * s], axis=-1)
    for k in range(4):
        ang = k * np.pi / 2.0
        R = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
        for (ca, cb, g) in ((c0, c1, g_in), (c1, c2, g_out)):
            P = ((1.0 - g)[None, :, None] * ca[:, None, :]
                 + g[None, :, None] * cb[:, None, :])
            add_block(P @ R.T)

    p = np.vstack(pts)
    q = np.hstack(quads)
    # merge coincident nodes of neighbouring blocks
    key = np.round(p / (L * 1e-9)).astype(np.int64)
    _, first, inv = np.unique(key, axis=0, return_index=True,
                              return_inverse=True)
    inv = inv.ravel()
    p = p[first]
    q = inv[q]
    # orient every quad counter-clockwise in (x, z)
    v = p[q]                          # (4, nq, 2)
    area2 = np.sum(v[:, :, 0] * np.roll(v[:, :, 1], -1, axis=0)
                   - np.roll(v[:, :, 0], -1, axis=0) * v[:, :, 1], axis=0)
    q[:, area2 < 0] = q[::-1, area2 < 0]
    p = p + np.array([XC, ZC])
    return p.T, q


def build_mesh(n):
    """Tetrahedral mesh of the cube for level n (multiple of 4)."""
    if n % 4 != 0 or n < 4:
        raise ValueError("level N must be a positive multiple of 4")
    p2, q = cross_section(n)
    # split each quad along its shorter diagonal
    v = p2[:, q]
    d02 = np.sum((v[:, 0] - v[:, 2]) ** 2, axis=0)
    d13 = np.sum((v[:, 1] - v[:, 3]) ** 2, axis=0)
    use02 = d02 <= d13
    tri = np.hstack([
        q[[0, 1, 2]][:, use02], q[[0, 2, 3]][:, use02],
        q[[0, 1, 3]][:, ~use02], q[[1, 2, 3]][:, ~use02],
    ])
    # y levels: graded towards the top face (depth ~ t^BETA)
    ny = n
    depth = L * np.linspace(0.0, 1.0, ny + 1) ** BETA
    y = np.sort(L - depth)
    y[0], y[-1] = 0.0, L
    n2 = p2.shape[1]
    P = np.vstack([
        np.tile(p2[0], ny + 1),
        np.repeat(y, n2),
        np.tile(p2[1], ny + 1),
    ])
    # prism (a, b, c) -> (a', b', c') split with a < b < c (global numbering):
    # [a b c a'], [b c a' b'], [c a' b' c']; every quad side face is then cut
    # along the diagonal from the larger-numbered bottom vertex to the
    # smaller-numbered top vertex, identically in both neighbouring prisms.
    tri = np.sort(tri, axis=0)
    tets = []
    for j in range(ny):
        a, b, c = tri + j * n2
        a1, b1, c1 = a + n2, b + n2, c + n2
        tets += [np.stack([a, b, c, a1]), np.stack([b, c, a1, b1]),
                 np.stack([c, a1, b1, c1])]
    T = np.hstack(tets)
    # positive orientation
    x = P[:, T]
    vol6 = np.einsum("ij,ij->j", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0],
                                          axis=0), x[:, 3] - x[:, 0])
    neg = vol6 < 0
    T[1, neg], T[2, neg] = T[2, neg].copy(), T[1, neg].copy()
    if np.min(np.abs(vol6)) <= 0.0:
        raise RuntimeError("degenerate tetrahedron")
    return MeshTet(P, T)


# ---------------------------------------------------------------- FE solution
@BilinearForm
def elasticity(u, v, w):
    eps_u = sym_grad(u)
    sig = 2.0 * MU * eps_u
    tr = LAM * trace(eps_u)
    return ddot(sig, sym_grad(v)) + tr * trace(sym_grad(v))


def component_of_dofs(basis):
    comp = -np.ones(basis.N, dtype=int)
    for k in range(3):
        comp[basis.nodal_dofs[k]] = k
        comp[basis.edge_dofs[k]] = k
    assert comp.min() == 0, "unexpected DOF layout"
    return comp


def rigid_body_modes(locs, comp):
    """The six rigid-body displacement fields evaluated at DOF locations."""
    X = locs - np.array([[XC], [L / 2], [ZC]])
    Bm = np.zeros((locs.shape[1], 6))
    for k in range(3):
        Bm[comp == k, k] = 1.0
    # rotation about axis j: (e_j x X) has component i1 = -X[i2], i2 = X[i1]
    for j, (i1, i2) in enumerate(((1, 2), (2, 0), (0, 1))):
        Bm[comp == i1, 3 + j] = -X[i2, comp == i1]
        Bm[comp == i2, 3 + j] = X[i1, comp == i2]
    return Bm


def two_level_preconditioner(mesh, basis, Kc, interior, dirichlet, nu_s=3):
    """Symmetric P2 -> P1 two-level preconditioner for CG.

    Smoother: nu_s forward Gauss-Seidel sweeps before and nu_s backward sweeps
    after the coarse correction on the P1 (vertex) space of the same mesh;
    the coarse problem (the P1 stiffness matrix, which equals the Galerkin
    product P^T K P because P1 is a subspace of P2) is approximated by one
    V-cycle of smoothed-aggregation AMG (pyamg, rigid-body near null space).
    """
    basis1 = Basis(mesh, ElementVector(ElementTetP1()), intorder=1)
    K1 = asm(elasticity, basis1).tocsr()
    nv, ne = mesh.p.shape[1], mesh.edges.shape[1]
    rows, cols, vals = [], [], []
    c2f = np.empty(basis1.N, dtype=int)     # coarse DOF -> fine vertex DOF
    comp1 = np.empty(basis1.N, dtype=int)
    for k in range(3):
        c2f[basis1.nodal_dofs[k]] = basis.nodal_dofs[k]
        comp1[basis1.nodal_dofs[k]] = k
        # vertex values are copied, edge-midpoint values are averaged
        rows.append(basis.nodal_dofs[k])
        cols.append(basis1.nodal_dofs[k])
        vals.append(np.ones(nv))
        for end in (0, 1):
            rows.append(basis.edge_dofs[k])
            cols.append(basis1.nodal_dofs[k][mesh.edges[end]])
            vals.append(np.full(ne, 0.5))
    P = sp.csr_matrix((np.concatenate(vals),
                       (np.concatenate(rows), np.concatenate(cols))),
                      shape=(basis.N, basis1.N))
    fixed = np.zeros(basis.N, dtype=bool)
    fixed[dirichlet] = True
    free1 = np.nonzero(~fixed[c2f])[0]
    PI = P[interior][:, free1].tocsr()
    PIt = PI.T.tocsr()
    Ac = K1[free1][:, free1].tocsr()
    Bc = rigid_body_modes(basis1.doflocs, comp1)[free1]
    ml = pyamg.smoothed_aggregation_solver(Ac, B=Bc, max_coarse=500,
                                           coarse_solver="splu")
    Mc = ml.aspreconditioner(cycle="V")

    def apply(r):
        r = np.ascontiguousarray(r, dtype=np.float64).ravel()
        x = np.zeros_like(r)
        gauss_seidel(Kc, x, r, iterations=nu_s, sweep="forward")
        x += PI @ (Mc @ (PIt @ (r - Kc @ x)))
        gauss_seidel(Kc, x, r, iterations=nu_s, sweep="backward")
        return x

    return spla.LinearOperator(Kc.shape, matvec=apply), Ac.shape[0]


def solve_level(n, verbose=True):
    t0 = time.time()
    mesh = build_mesh(n)
    # the stiffness integrand is quadratic on affine tetrahedra: order 2 exact
    basis = Basis(mesh, ElementVector(ElementTetP2()), intorder=2)
    K = asm(elasticity, basis).tocsr()
    t_asm = time.time() - t0

    comp = component_of_dofs(basis)
    xd, yd, zd = basis.doflocs
    tol = 1e-9 * L
    bottom = np.nonzero(yd < tol)[0]
    r = np.hypot(xd - XC, zd - ZC)
    punch = np.nonzero((yd > L - tol) & (r <= A * (1.0 + 1e-9)))[0]
    punch_y = punch[comp[punch] == 1]
    dirichlet = np.union1d(bottom, punch)

    u = np.zeros(basis.N)
    u[punch_y] = -D
    interior = np.setdiff1d(np.arange(basis.N), dirichlet)
    K_I = K[interior]
    Kc = K_I[:, interior].tocsr()
    rhs = -(K_I[:, dirichlet] @ u[dirichlet])

    t1 = time.time()
    M, ncoarse = two_level_preconditioner(mesh, basis, Kc, interior, dirichlet)
    its = [0]

    def cb(_):
        its[0] += 1

    sol, info = spla.cg(Kc, rhs, rtol=CG_RTOL, atol=0.0, M=M, callback=cb,
                        maxiter=5000)
    if info != 0:
        raise RuntimeError(f"CG did not converge (info={info})")
    res = np.linalg.norm(Kc @ sol - rhs) / np.linalg.norm(rhs)
    u[interior] = sol
    t_sol = time.time() - t1

    f_int = K @ u
    F_reac = -np.sum(f_int[punch_y])                 # punch pushes down
    F_energy = float(u @ f_int) / D                  # 2 W / d
    # reaction on the bottom (should balance the punch force)
    bottom_y = bottom[comp[bottom] == 1]
    F_bottom = np.sum(f_int[bottom_y])
    out = dict(N=n, ndofs=basis.N, nfree=len(interior), nelem=mesh.t.shape[1],
               F_reac=F_reac, F_energy=F_energy, F_bottom=F_bottom,
               its=its[0], res=res, t_asm=t_asm, t_sol=t_sol,
               time=time.time() - t0, npunch=len(punch_y))
    if verbose:
        print(f"N={n:3d} elements={out['nelem']:7d} DOFs={basis.N:7d} "
              f"punch y-DOFs={len(punch_y):5d}  F_reaction={F_reac:.7f} N  "
              f"F_energy={F_energy:.7f} N  bottom={F_bottom:.7f} N  "
              f"CG its={its[0]} res={res:.1e}  assembly {t_asm:.1f} s, "
              f"solve {t_sol:.1f} s", flush=True)
    return out, basis, u


# --------------------------------------------------------------- sampling
def locate(mesh, pts):
    """Element containing each point of pts (3, n); for points on element
    faces, edges or vertices the candidate with the largest smallest
    barycentric coordinate is taken."""
    p, t = mesh.p, mesh.t

    def bary_score(pts, cand):
        x0 = p[:, t[0, cand]]                             # (3, n, k)
        J = np.stack([p[:, t[i, cand]] - x0 for i in (1, 2, 3)], axis=-1)
        rhs = np.moveaxis(pts[:, :, None] - x0, 0, -1)[..., None]
        lam = np.linalg.solve(np.moveaxis(J, 0, -2), rhs)[..., 0]
        return np.minimum(1.0 - lam.sum(-1), lam.min(-1))  # (n, k)

    tree = cKDTree(p[:, t].mean(axis=1).T)
    _, cand = tree.query(pts.T, min(40, t.shape[1]))
    score = bary_score(pts, cand)
    best = np.argmax(score, axis=1)
    rows = np.arange(pts.shape[1])
    cells, ok = cand[rows, best], score[rows, best] >= -1e-9
    # thin elements: fall back to a search over all elements
    allc = np.arange(t.shape[1])[None, :]
    for i in np.nonzero(~ok)[0]:
        sc = bary_score(pts[:, i:i + 1], allc)[0]
        if sc.max() < -1e-9:
            raise RuntimeError(f"point {pts[:, i]} not in the mesh")
        cells[i] = np.argmax(sc)
    return cells


def sample(basis, u, pts):
    """Evaluate the P2 displacement field at pts (3, n)."""
    cells = locate(basis.mesh, pts)
    Xref = basis.mapping.invF(pts[:, :, None], tind=cells)
    vals = np.zeros((3, pts.shape[1]))
    for i in range(basis.Nbfun):
        phi = basis.elem.gbasis(basis.mapping, Xref, i, tind=cells)[0].value
        vals += phi[:, :, 0] * u[basis.element_dofs[i, cells]]
    return vals


# ---------------------------------------------------------- extrapolation
def richardson(Ns, Fs):
    """F(N) = F_inf + C N^-p through three levels; returns (F_inf, p)."""
    (n1, n2, n3), (f1, f2, f3) = Ns, Fs
    ratio = (f1 - f2) / (f2 - f3)

    def g(p):
        return (n1 ** -p - n2 ** -p) / (n2 ** -p - n3 ** -p) - ratio

    try:
        p = brentq(g, 0.05, 12.0)
    except ValueError:
        return np.nan, np.nan
    C = (f2 - f3) / (n2 ** -p - n3 ** -p)
    return f3 - C * n3 ** -p, p


# ------------------------------------------------------------------- main
def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--levels", default="8,12,16,20,24,28",
                    help="comma-separated levels N (multiples of 4)")
    args = ap.parse_args()
    levels = sorted(int(s) for s in args.levels.split(","))

    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    outdir = os.path.join(root, "reference")
    os.makedirs(outdir, exist_ok=True)

    F_half = 2.0 * A * E * D / (1.0 - NU ** 2)
    print(f"scikit-fem {skfem.__version__}, scipy {scipy.__version__}, "
          f"pyamg {pyamg.__version__}")
    print(f"Boussinesq half-space (rigid circular punch): "
          f"F_half = 2 a E d / (1 - nu^2) = {F_half:.6f} N")

    t_start = time.time()
    rows = []
    for n in levels:
        out, basis, u = solve_level(n)
        rows.append(out)
    Ns = np.array([r["N"] for r in rows], dtype=float)
    Fs = np.array([r["F_energy"] for r in rows])

    # extrapolation: three finest levels, and the three before as a check
    F_inf, p_obs, F_inf_prev, p_prev = np.nan, np.nan, np.nan, np.nan
    ext = [np.nan] * len(rows)
    for i in range(2, len(rows)):
        ext[i], pi = richardson(Ns[i - 2:i + 1], Fs[i - 2:i + 1])
        rows[i]["p"] = pi
    if len(rows) >= 3:
        F_inf, p_obs = ext[-1], rows[-1]["p"]
    if len(rows) >= 4:
        F_inf_prev, p_prev = ext[-2], rows[-2]["p"]
    F_p2 = np.nan
    if len(rows) >= 2:    # the order the graded mesh should give, p = 2
        r2 = (Ns[-1] / Ns[-2]) ** 2
        F_p2 = Fs[-1] + (Fs[-1] - Fs[-2]) / (r2 - 1.0)
    if np.isfinite(F_inf):
        F_ref = F_inf
        err_fine = abs(Fs[-1] - F_inf) / abs(F_inf) * 100.0
        # uncertainty of the extrapolated value: the largest deviation of
        # the alternative extrapolations (previous triple, fixed p = 2)
        alts = [x for x in (F_inf_prev, F_p2) if np.isfinite(x)]
        err_ext = (max(abs(F_inf - x) for x in alts) / abs(F_inf) * 100.0
                   if alts else np.nan)
    else:
        F_ref, err_fine, err_ext = Fs[-1], np.nan, np.nan

    # sample the finest level
    g = np.linspace(0.0, L, 17)
    Xg, Yg, Zg = np.meshgrid(g, g, g, indexing="ij")   # x outer, z inner
    pts = np.vstack([Xg.ravel(), Yg.ravel(), Zg.ravel()])
    vals = sample(basis, u, pts)
    csv = os.path.join(outdir, "indentation_fem.csv")
    np.savetxt(csv, np.vstack([pts, vals]).T, fmt="%.6e", delimiter=",",
               header="x,y,z,ux,uy,uz", comments="")
    centre = vals[:, np.argmin(np.sum((pts - [[XC], [L], [ZC]]) ** 2, 0))]
    bottom_max = np.abs(vals[:, pts[1] == 0.0]).max()
    total = time.time() - t_start

    # report
    print()
    hdr = ("| N | elements | DOFs | F (reaction), N | F (2W/d), N | "
           "Richardson F, N | order p | CG its | time, s |")
    lines = [hdr, "|" + "---:|" * 9]
    for r, e in zip(rows, ext):
        lines.append(
            f"| {r['N']} | {r['nelem']} | {r['ndofs']} | {r['F_reac']:.6f} | "
            f"{r['F_energy']:.6f} | "
            + (f"{e:.6f}" if np.isfinite(e) else "-") + " | "
            + (f"{r['p']:.2f}" if np.isfinite(r.get('p', np.nan)) else "-")
            + f" | {r['its']} | {r['time']:.1f} |")
    table = "\n".join(lines)
    print(table)
    print(f"\nextrapolated F = {F_ref:.6f} N (order {p_obs:.2f}); finest level "
          f"differs by {err_fine:.3f} %; previous-triple extrapolation "
          f"{F_inf_prev:.6f} N, p = 2 extrapolation {F_p2:.6f} N; "
          f"uncertainty {err_ext:.3f} %")
    print(f"sampled top centre u = {centre}, max |u| on the bottom = "
          f"{bottom_max:.2e}, total time {total:.0f} s")

    fin = rows[-1]
    md = f"""# Indentation reference (scikit-fem, quadratic tetrahedra, circular punch)

reaction_force_N = {F_ref:.6f}

## Problem

Linear elasticity (small strain), SI units, no gravity. Cube [0, 0.1]^3 m,
y up, E = 1e4 Pa, nu = 0.3. Bottom face y = 0 clamped (u = 0). Top face
y = 0.1: rigid, bonded (no-slip) flat circular punch, radius a = 0.02 m,
centred at (x, z) = (0.05, 0.05), prescribed u = (0, -0.002, 0). The rest of
the boundary is traction free. F = total vertical force the punch applies (N).
Script: `scripts/fem_indentation.py`.

## Discretisation

* Element: ElementVector(ElementTetP2) (quadratic tetrahedra), stiffness
  integrated exactly (order 2 quadrature on affine tetrahedra).
* Mesh (level N): the (x, z) section is a block-structured O-grid that has
  the punch rim r = a as a mesh line (centre square of half-side a/2 with
  N/2 x N/2 cells; four ring blocks to the circle and four outer blocks to
  the cube sides, each N/2 tangential x N/4 radial cells, power-law graded
  towards the rim with exponent {BETA:g}, i.e. cell size ~ distance^(1/2)); quads
  split into triangles, extruded in y with N layers graded towards the top
  (same exponent), prisms split into 3 tetrahedra each (conforming
  vertex-numbering rule). The 2N rim vertices lie on the circle.
* Punch DOFs: all DOFs (3 components) located on the top face with
  sqrt((x-0.05)^2 + (z-0.05)^2) <= a (relative tolerance 1e-9), i.e. the
  vertices and edge midpoints of the inscribed 2N-gon and inside it.
* Solver: Dirichlet DOFs condensed; conjugate gradients, relative residual
  {CG_RTOL:g}, symmetric two-level preconditioner (3 forward / 3 backward
  Gauss-Seidel sweeps on the P2 system, coarse correction in the P1 space of
  the same mesh by one V-cycle of smoothed-aggregation AMG from pyamg with
  the 6 rigid-body modes as near-null space).
* Force: F = -sum over the punch y-DOFs of (K u) and F = u^T K u / d
  (= 2 W / d); both are listed and agree to solver accuracy.

## Convergence

{table}

Richardson extrapolation F(N) = F_inf + C N^-p through the three finest levels:
observed order p = {p_obs:.2f}, **F_inf = {F_ref:.6f} N**.
Estimated remaining discretisation error of the finest level (N = {fin['N']}):
{err_fine:.3f} % (|F_N - F_inf| / F_inf).
""" + (f"""Estimated uncertainty of the extrapolated value: {err_ext:.3f} % (largest
deviation of the alternatives: extrapolation through the previous three
levels, F = {F_inf_prev:.6f} N with p = {p_prev:.2f}; extrapolation of the two
finest levels with the order the graded mesh should give, p = 2,
F = {F_p2:.6f} N).
""" if np.isfinite(err_ext) else "") + f"""
For comparison, the Boussinesq rigid circular punch on a half-space gives
F_half = 2 a E d / (1 - nu^2) = {F_half:.6f} N (frictionless contact, infinite
body); the finite block, clamped 0.1 m = 5 a below the punch, is stiffer:
F / F_half = {F_ref / F_half:.3f}.

## Displacement field

`reference/indentation_fem.csv`: displacement (m) of the finest level
(N = {fin['N']}, {fin['ndofs']} DOFs) interpolated with the P2 basis on a
17 x 17 x 17 grid covering the cube (spacing 0.00625 m), header
`x,y,z,ux,uy,uz`, x outermost, z innermost. Checks: u at the top centre
= ({centre[0]:.3e}, {centre[1]:.6e}, {centre[2]:.3e}); max |u| on the
bottom = {bottom_max:.1e}.

## Run

Command: `python scripts/fem_indentation.py` (levels
{','.join(str(n) for n in levels)}); run time {total:.0f} s on a 2-core
machine. scikit-fem {skfem.__version__}, numpy {np.__version__},
scipy {scipy.__version__}, pyamg {pyamg.__version__}, Python
{sys.version.split()[0]}.
"""
    with open(os.path.join(outdir, "indentation_fem.md"), "w") as fh:
        fh.write(md)
    print(f"wrote {csv} and indentation_fem.md")


if __name__ == "__main__":
    main()
