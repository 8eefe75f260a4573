"""Least-squares fit of scene parameters to a measured force-against-depth curve.

The residual compares the simulated and the measured needle force, both smoothed over
depth with the same Gaussian kernel (standard deviation ``smoothing``, default 1 mm) and
sampled every ``smoothing / 2`` over the measured span; the simulated curve is its
insertion phase (the samples up to the deepest). The same smoothing on both sides leaves
no bias; it removes the step-to-step stick-slip chatter of the simulated force and the
measurement noise, and makes the residual change smoothly as the puncture moves in depth.
``smoothing=None`` compares the raw points (simulated force interpolated at the measured
depths).

Each iteration runs one batch through ``needlesim.sweep``: the current point and one
forward difference per parameter (step ``rel_step`` times the value: a secant wide enough
to step over the chatter), so a cluster runs them side by side. The optimiser is SciPy's
bounded trust-region reflective least squares on the parameters scaled to [0, 1] within
their bounds. The uncertainty is the sandwich covariance (J^T J)^-1 J^T (s^2 S S^T) J
(J^T J)^-1, with J the Jacobian at the solution, S the smoothing matrix and s^2 the
variance of the measured points about the fitted curve: it assumes independent errors and
a model that fits, so read it as a lower bound when the model is biased.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from ._sweep import OverrideError, SceneLike, _child, _client, load_scene, sweep

__all__ = ["FitError", "FitResult", "fit"]


class FitError(RuntimeError):
    """A simulation the fit needed failed, or it does not cover the measured depths."""


@dataclass
class FitResult:
    """What ``fit`` found. ``depth``, ``measured`` and ``fitted`` are the smoothed curves
    on the last stage's depth grid (the points with ``smoothing=None``); ``rms`` is their
    difference's; ``evaluations`` has every point the optimiser asked for."""

    parameters: Dict[str, float]
    stderr: Dict[str, float]
    covariance: np.ndarray
    depth: np.ndarray
    measured: np.ndarray
    fitted: np.ndarray
    rms: float
    simulations: int
    iterations: int
    success: bool
    message: str
    evaluations: Any = field(repr=False)


def fit(
    scene: SceneLike,
    measured_depth: Sequence[float],
    measured_force: Sequence[float],
    parameters: Sequence[str],
    bounds: Sequence[Tuple[float, float]],
    client: Any = None,
    *,
    x0: Optional[Sequence[float]] = None,
    steps: Optional[int] = None,
    duration: Optional[float] = None,
    force: str = "axial",
    smoothing: Optional[float] = 1e-3,
    stages: Sequence[float] = (4.0, 1.0),
    rel_step: float = 0.05,
    max_iterations: int = 15,
    backend: str = "cpu",
    threads: Optional[int] = 1,
    files: str = "inline",
    base_dir: Optional[Union[str, "os.PathLike[str]"]] = None,
) -> FitResult:
    """Fits the scene values at the dotted keys ``parameters`` (within ``bounds``, one
    (low, high) pair each) so that the simulated needle force (``force``: ``"axial"`` or
    ``"lateral"``) matches ``measured_force`` at ``measured_depth`` (m, tip depth past the
    first contact point, as in ``Simulation.history()["depth"]``).

    x0: the starting values (default: the scene's values, or the bounds' middle where the
        scene has none).
    smoothing, stages: the fit runs once per stage, each from where the last ended, with
        the kernel ``smoothing * stage`` (default 4 mm, then 1 mm): the wide kernel finds
        the valley, the narrow one the minimum (coarse to fine, as the objective is rough
        on small scales). ``max_iterations`` bounds each stage's objective batches.
    client, steps, duration, backend, threads, files, base_dir: passed to
        ``needlesim.sweep``; with ``client=None`` one cluster is started for the whole fit.
        Give ``duration`` when a parameter changes a ``dt = "auto"`` scene's time step.
    """
    try:
        from scipy.optimize import least_squares
    except ModuleNotFoundError as e:
        raise ModuleNotFoundError(
            "needlesim.fit uses SciPy: pip install needlesim[sweep] (or needlesim[dask])"
        ) from e
    import pandas as pd

    depth = np.asarray(measured_depth, dtype=float)
    meas = np.asarray(measured_force, dtype=float)
    if depth.ndim != 1 or depth.shape != meas.shape or len(depth) < 2:
        raise ValueError("measured_depth and measured_force: two 1-D arrays of one length >= 2")
    if not (np.all(np.isfinite(depth)) and np.all(np.isfinite(meas))):
        raise ValueError("measured_depth and measured_force must be finite")
    names = list(parameters)
    if not names or len(set(names)) != len(names):
        raise ValueError("parameters: one or more distinct dotted keys")
    lo, hi = _bounds(names, bounds)
    if force not in ("axial", "lateral"):
        raise ValueError(f"force must be 'axial' or 'lateral', not {force!r}")
    if smoothing is not None and not (np.isfinite(smoothing) and smoothing > 0):
        raise ValueError(f"smoothing must be a positive length in m or None, not {smoothing}")
    if not (0 < rel_step < 0.5):
        raise ValueError(f"rel_step must be in (0, 0.5), not {rel_step}")
    stages = [float(k) for k in stages] if smoothing is not None else [1.0]
    if not stages or not all(np.isfinite(k) and k > 0 for k in stages):
        raise ValueError(f"stages must be positive factors on smoothing, not {stages}")
    if int(max_iterations) < 1:
        raise ValueError("max_iterations must be >= 1")

    if isinstance(scene, Mapping):
        scene_dict = dict(scene)
    else:
        scene_dict, root = load_scene(scene)
        base_dir = base_dir if base_dir is not None else root
    start = _start(scene_dict, names, lo, hi, x0)
    targets = [_Target(depth, meas, None if smoothing is None else smoothing * k) for k in stages]

    column = "axial_force_n" if force == "axial" else "lateral_force_n"
    cache: Dict[Tuple[float, ...], Tuple[np.ndarray, List[Tuple[Any, Any]]]] = {}
    fitted: Dict[Tuple[Any, int], Tuple[np.ndarray, np.ndarray]] = {}
    evaluations: List[Dict[str, Any]] = []

    def simulate(x: np.ndarray, run_sweep: Any) -> Tuple[np.ndarray, List[Tuple[Any, Any]]]:
        """The runs at x and at one forward difference per parameter (cached)."""
        key = tuple(x)
        if key not in cache:
            h = rel_step * np.where(x != 0, np.abs(x), hi - lo)
            h = np.where(x + h <= hi, h, -h)  # step backwards at the upper bound
            points = [x] + [x + h[i] * np.eye(len(x))[i] for i in range(len(x))]
            res = run_sweep([dict(zip(names, map(float, p))) for p in points])
            bad = res.failed
            if len(bad):
                row = bad.iloc[0]
                p = dict(zip(names, map(float, points[int(row["variant"])])))
                raise FitError(f"the run at {p} failed: {row['error_type']}: {row['error']}")
            sims = []
            for i in range(len(points)):
                t = res.variant(i)
                sims.append((t["depth_m"].to_numpy(), t[column].to_numpy()))
            cache[key] = (h, sims)
        return cache[key]

    def batch(
        x: np.ndarray, target: _Target, run_sweep: Any
    ) -> Tuple[np.ndarray, np.ndarray]:
        """Residual and Jacobian at x against target (cached: least_squares asks for the
        residual and then the Jacobian at the same point)."""
        key = (tuple(x), id(target))
        if key in fitted:
            return fitted[key]
        h, sims = simulate(x, run_sweep)
        curves = [target.model(*sim) for sim in sims]
        r0 = curves[0] - target.values
        evaluations.append(
            {
                "smoothing": target.sigma,
                **dict(zip(names, map(float, x))),
                "rms": float(np.sqrt(np.mean(r0**2))),
            }
        )
        jac = np.stack([(curves[i + 1] - curves[0]) / h[i] for i in range(len(x))], axis=1)
        fitted[key] = (r0, jac)
        return r0, jac

    span = hi - lo
    to_x = lambda u: lo + np.asarray(u) * span  # noqa: E731
    x = start
    iterations = 0
    with _client(client, threads, "needlesim.fit") as c:

        def run_sweep(variants: List[Dict[str, Any]]) -> Any:
            return sweep(
                scene_dict, variants, c, steps=steps, duration=duration, backend=backend,
                threads=threads, files=files, base_dir=base_dir,
            )

        for target in targets:
            out = least_squares(
                lambda u: batch(to_x(u), target, run_sweep)[0],
                (x - lo) / span,
                jac=lambda u: batch(to_x(u), target, run_sweep)[1] * span,
                bounds=(0.0, 1.0),
                method="trf",
                x_scale="jac",
                max_nfev=int(max_iterations),
            )
            x = to_x(out.x)
            iterations += int(out.nfev)
            stopped = not out.success
        r, jac = batch(x, target, run_sweep)
        noise = target.noise(*simulate(x, run_sweep)[1][0])

    if stopped:
        warnings.warn(
            f"needlesim.fit: the last stage stopped at max_iterations={max_iterations} "
            "before converging; the parameters may still be moving and the uncertainty "
            "understates the error (raise max_iterations, or start nearer)",
            RuntimeWarning,
            stacklevel=2,
        )
    # Sandwich covariance: the smoothed residuals are S e with e the measured points'
    # errors, independent with variance `noise`, so cov(r) = noise S S^T.
    bread = np.linalg.pinv(jac.T @ jac) @ jac.T
    cov = noise * bread @ (target.smoother @ target.smoother.T) @ bread.T
    if len(target.raw_depth) <= len(x):
        cov = np.full_like(cov, np.nan)
    return FitResult(
        parameters=dict(zip(names, map(float, x))),
        stderr=dict(zip(names, map(float, np.sqrt(np.clip(np.diag(cov), 0, None))))),
        covariance=cov,
        depth=target.depth,
        measured=target.values,
        fitted=target.values + r,
        rms=float(np.sqrt(np.mean(r**2))),
        simulations=sum(len(sims) for _, sims in cache.values()),
        iterations=iterations,
        success=bool(out.success),
        message=str(out.message),
        evaluations=pd.DataFrame(evaluations),
    )


def _bounds(names: List[str], bounds: Sequence[Tuple[float, float]]) -> Tuple[np.ndarray, np.ndarray]:
    b = np.asarray(bounds, dtype=float)
    if b.shape != (len(names), 2):
        raise ValueError(f"bounds: one (low, high) pair per parameter ({len(names)})")
    for name, (l, h) in zip(names, b):
        if not (np.isfinite(l) and np.isfinite(h) and l < h):
            raise ValueError(f"bounds of `{name}`: need finite low < high, got ({l}, {h})")
    return b[:, 0], b[:, 1]


def _start(
    scene: Mapping[str, Any], names: List[str], lo: np.ndarray, hi: np.ndarray,
    x0: Optional[Sequence[float]],
) -> np.ndarray:
    if x0 is not None:
        start = np.asarray(x0, dtype=float)
        if start.shape != lo.shape:
            raise ValueError(f"x0: one value per parameter ({len(names)})")
        for name, v, l, h in zip(names, start, lo, hi):
            if not (l <= v <= h):
                raise ValueError(f"x0 of `{name}` = {v} is outside its bounds ({l}, {h})")
        return start
    start = (lo + hi) / 2
    for i, name in enumerate(names):
        at: Any = scene
        try:
            for part in name.split("."):
                at = _child(at, part, name)
        except OverrideError:
            at = None  # an optional key the scene leaves out
        if isinstance(at, (int, float)) and lo[i] <= at <= hi[i]:
            start[i] = float(at)
    return start


class _Target:
    """The measured curve as the residual compares it: smoothed on a depth grid with a
    Gaussian kernel (Nadaraya-Watson), or the points themselves (``sigma=None``)."""

    def __init__(self, depth: np.ndarray, force: np.ndarray, sigma: Optional[float]):
        order = np.argsort(depth, kind="stable")
        self.raw_depth, self.raw_force = depth[order], force[order]
        self.sigma = sigma
        lo, hi = float(self.raw_depth[0]), float(self.raw_depth[-1])
        if sigma is None:
            self.depth = self.raw_depth
            self.smoother = np.eye(len(depth))
        else:
            n = int(np.floor((hi - lo) / (sigma / 2))) + 1
            self.depth = lo + np.arange(n) * (sigma / 2)
            self.smoother = self._weights(self.raw_depth)
        self.values = self.smoother @ self.raw_force
        self.span = (lo, hi)

    def _weights(self, depth: np.ndarray) -> np.ndarray:
        assert self.sigma is not None
        k = np.exp(-0.5 * ((self.depth[:, None] - depth[None, :]) / self.sigma) ** 2)
        return k / k.sum(axis=1, keepdims=True)

    def insertion(self, depth: np.ndarray, force: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """The simulated samples up to the deepest, checked to cover the measured span."""
        if len(depth) == 0:
            raise FitError("the simulation recorded no needle force (no [needle] table?)")
        last = int(np.argmax(depth)) + 1
        depth, force = depth[:last], force[:last]
        lo, hi = self.span
        if depth.max() < hi or depth.min() > lo:
            raise FitError(
                f"the simulation spans {depth.min() * 1e3:.2f}-{depth.max() * 1e3:.2f} mm of "
                f"depth, the measured curve {lo * 1e3:.2f}-{hi * 1e3:.2f} mm: give more "
                "steps (or a longer duration)"
            )
        order = np.argsort(depth, kind="stable")
        return depth[order], force[order]

    def model(self, depth: np.ndarray, force: np.ndarray) -> np.ndarray:
        """The simulated curve as the residual compares it (over the measured span)."""
        depth, force = self.insertion(depth, force)
        if self.sigma is None:
            return np.interp(self.depth, depth, force)
        lo, hi = self.span
        keep = (depth >= lo) & (depth <= hi)
        return self._weights(depth[keep]) @ force[keep]

    def noise(self, depth: np.ndarray, force: np.ndarray) -> float:
        """Variance of the measured points about the simulated curve (unsmoothed)."""
        depth, force = self.insertion(depth, force)
        r = self.raw_force - np.interp(self.raw_depth, depth, force)
        return float(r @ r) / max(1, len(r) - 1)
