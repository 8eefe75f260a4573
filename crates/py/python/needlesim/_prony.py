"""Prony series from a measured relaxation curve: the terms of ``viscoelastic = [...]``.

A relaxation test holds a strain (reached by a linear ramp of ``ramp`` seconds from
``t = 0``, or a step for ``ramp = 0``) and records the force. For the generalized Maxwell
material of needlesim (``needlesim_core::models::viscoelastic``) the force is

    F(t) = F0 (1 / ramp) int_0^min(t, ramp) g(t - s) ds,
    g(t) = g_inf + sum_i g_i exp(-t / tau_i),  g_inf = 1 - sum_i g_i,

with F0 the force the full strain would give at once (the instantaneous modulus). The
fit is a bounded nonlinear least squares (SciPy's trust-region reflective method) over
F0, the shares g_i and log tau_i, started from several spreads of the time constants
over the record (the problem has local minima where two terms swap or merge); the best
fit is returned. Points before the end of the ramp can be left out with ``t_min``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple

import numpy as np

__all__ = ["PronyFit", "fit_prony", "relaxation"]


def relaxation(t: np.ndarray, terms: Sequence[Tuple[float, float]], ramp: float = 0.0) -> np.ndarray:
    """The normalised response ``F(t) / F0`` of the series ``terms`` [(g, tau), ...] to a
    strain ramped over ``ramp`` s then held (``ramp = 0``: a step, ``g(t)`` itself).
    ValueError for a share outside [0, 1), shares summing to 1 or more, a time constant
    that is not a positive number, or a ramp that is negative or not finite (the scene's
    rules for ``material.viscoelastic``)."""
    for i, (g, tau) in enumerate(terms):
        if not (math.isfinite(g) and 0.0 <= g < 1.0):
            raise ValueError(f"terms[{i}]: g must lie in [0, 1), got {g!r}")
        if not (math.isfinite(tau) and tau > 0.0):
            raise ValueError(f"terms[{i}]: tau must be a positive time in s, got {tau!r}")
    if sum(g for g, _ in terms) >= 1.0:
        raise ValueError("terms: the shares g must sum to less than 1")
    if not (math.isfinite(ramp) and ramp >= 0.0):
        raise ValueError(f"ramp must be a time in s >= 0, got {ramp!r}")
    return _response(t, terms, ramp)


def _response(t: np.ndarray, terms: Sequence[Tuple[float, float]], ramp: float) -> np.ndarray:
    """``relaxation`` without the checks: the fit's trial series may sum past 1."""
    t = np.asarray(t, dtype=float)
    g_inf = 1.0 - sum(g for g, _ in terms)
    if ramp <= 0.0:
        out = np.full_like(t, g_inf)
        for g, tau in terms:
            out += g * np.exp(-t / tau)
        return out
    end = np.minimum(t, ramp)
    v = g_inf * end
    for g, tau in terms:
        v = v + g * tau * (np.exp(-(t - end) / tau) - np.exp(-t / tau))
    return v / ramp


@dataclass
class PronyFit:
    """A fitted Prony series."""

    terms: List[Tuple[float, float]]
    """(g, tau in s) of each term, by increasing tau."""
    instantaneous: float
    """F0: the force of the full strain at once (instantaneous modulus), in the data's unit."""
    rms: float
    """Root mean square residual of the fit, in the data's unit."""

    @property
    def g_inf(self) -> float:
        """The long-term share ``1 - sum g``."""
        return 1.0 - sum(g for g, _ in self.terms)

    def toml(self) -> str:
        """The ``[material]`` line: ``viscoelastic = [{ g = ..., tau = ... }, ...]``."""
        inner = ", ".join(f"{{ g = {g:.6g}, tau = {tau:.6g} }}" for g, tau in self.terms)
        return f"viscoelastic = [{inner}]"


def fit_prony(
    time: Sequence[float],
    force: Sequence[float],
    terms: int = 2,
    ramp: float = 0.0,
    t_min: Optional[float] = None,
) -> PronyFit:
    """Fits ``terms`` Prony terms (1 to 4, the kernels' bound) to the relaxation record
    ``force`` at ``time`` (s from the start of the ramp); see the module docs. The sign of
    the force does not matter. ValueError for bad input (lengths, too few points, a
    record that does not relax).
    """
    from scipy.optimize import least_squares

    t = np.asarray(time, dtype=float)
    f = np.asarray(force, dtype=float)
    if t.shape != f.shape or t.ndim != 1:
        raise ValueError(f"time and force must be 1-D of one length, got {t.shape} and {f.shape}")
    if not 1 <= terms <= 4:
        raise ValueError(f"terms must be 1 to 4 (the kernels' bound), got {terms}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(f))):
        raise ValueError("time and force must be finite")
    if t.size > 1 and not np.all(np.diff(t) > 0):
        # A reversed or repeated time axis gave a meaningless fit without a word.
        raise ValueError("time must increase strictly from sample to sample")
    if not (np.isfinite(ramp) and ramp >= 0):
        raise ValueError(f"ramp must be a finite time >= 0 in s, got {ramp}")
    if t_min is not None and not np.isfinite(t_min):
        raise ValueError(f"t_min must be a finite time in s, got {t_min}")
    start = ramp if t_min is None else t_min
    keep = t >= start
    t, f = t[keep], f[keep]
    if t.size < 2 * terms + 2:
        which = "ramp" if t_min is None else "t_min"
        raise ValueError(
            f"{t.size} points at or after {which} = {start} s: too few for {terms} terms"
        )
    sign = 1.0 if np.mean(f) >= 0 else -1.0
    f = sign * f
    if not f[0] > f[-1] > 0:
        raise ValueError("the force must relax: larger at the start than at the end, same sign")
    if not t.max() > 0:
        raise ValueError("time must reach past 0 (s from the start of the ramp)")
    # The fit runs on a record scaled to unit time and force, so that any units fit (forces
    # of 1e300 N overflowed inside scipy, a record lasting 1e-300 s met the fixed bound of
    # 1e-6 s); the result is scaled back.
    time_unit, force_unit = float(t.max()), float(f.max())
    t, f, ramp = t / time_unit, f / force_unit, ramp / time_unit
    span = (max(t.min(), 1e-6), 1.0)

    def unpack(x: np.ndarray) -> Tuple[float, List[Tuple[float, float]]]:
        return x[0], [(x[1 + 2 * i], float(np.exp(x[2 + 2 * i]))) for i in range(terms)]

    def residual(x: np.ndarray) -> np.ndarray:
        f0, series = unpack(x)
        r = f0 * _response(t, series, ramp) - f
        excess = sum(g for g, _ in series) - 0.999
        return np.append(r, 1e3 * max(excess, 0.0) * f.max())

    lo = [0.0] + [0.0, np.log(span[0] / 10)] * terms
    hi = [10 * f.max()] + [0.999, np.log(span[1] * 10)] * terms
    best = None
    for spread in (1.0, 0.5, 0.25):
        # Time constants log-spaced over the middle of the record, shares summing to 0.5.
        a, b = np.log(span[0]), np.log(span[1])
        mid, half = 0.5 * (a + b), 0.5 * (b - a) * spread
        taus = np.linspace(mid - half, mid + half, terms + 2)[1:-1] if terms > 1 else [mid]
        x0 = [f[0]] + [v for tau in taus for v in (0.5 / terms, tau)]
        r = least_squares(residual, x0, bounds=(lo, hi), x_scale="jac", max_nfev=2000)
        if best is None or r.cost < best.cost:
            best = r
    assert best is not None, "at least one start was fitted"
    f0, series = unpack(best.x)
    series.sort(key=lambda gt: gt[1])
    rms = float(np.sqrt(np.mean((f0 * _response(t, series, ramp) - f) ** 2))) * force_unit
    return PronyFit(
        terms=[(float(g), float(tau) * time_unit) for g, tau in series],
        instantaneous=float(sign * f0) * force_unit,
        rms=rms,
    )
