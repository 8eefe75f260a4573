"""Richardson extrapolation shared by the reference scripts (fem_*.py)."""

import numpy as np


def richardson(h, f):
    """Fits f = F + C h^p through the last three (h, f) levels; returns (p, F).

    The order p solves (f1 - f2) / (f2 - f3) = (h1^p - h2^p) / (h2^p - h3^p), found by
    bisection on [0.05, 6].
    """
    (h1, h2, h3), (f1, f2, f3) = h[-3:], f[-3:]

    def g(p):
        return (f1 - f2) / (f2 - f3) - (h1**p - h2**p) / (h2**p - h3**p)

    lo, hi = 0.05, 6.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if np.sign(g(mid)) == np.sign(g(lo)):
            lo = mid
        else:
            hi = mid
    p = 0.5 * (lo + hi)
    c = (f2 - f3) / (h2**p - h3**p)
    return p, f3 - c * h3**p
