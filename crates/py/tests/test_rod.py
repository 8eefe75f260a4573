"""needlesim.flexible_needle against the Euler-Bernoulli cantilever (issue 43's first
step): a reference that is not our code."""

import math

import numpy as np
import pytest

import needlesim

# 10 cm of 22 G steel tubing: 0.718 mm outer, 0.413 mm inner diameter, E 193 GPa.
L, D, d, E = 0.1, 0.718e-3, 0.413e-3, 193e9
EI = E * math.pi / 64 * (D**4 - d**4)


def test_a_tip_force_bends_it_as_euler_bernoulli():
    p = 1e-3
    line = needlesim.flexible_needle(L, D, d, forces=[(L, p, 0.0, 0.0)])
    assert line.shape == (22, 3) and line.dtype == np.float64
    exact = p * L**3 / (3 * EI)
    # The chain's own error is 1 / (4 N^2) = 0.06% at 20 elements; 1% is the bound.
    assert line[-1, 0] == pytest.approx(exact, rel=0.01)
    assert line[0] == pytest.approx([0.0, 0.0, 0.0])


def test_a_uniform_load_bends_it_as_euler_bernoulli():
    q = 1e-2
    line = needlesim.flexible_needle(L, D, d, segments=40, per_length=(0.0, -q, 0.0))
    assert -line[-1, 1] == pytest.approx(q * L**4 / (8 * EI), rel=0.01)


def test_bad_input_names_the_key():
    with pytest.raises(ValueError, match="inner_diameter"):
        needlesim.flexible_needle(L, D, 2 * D)
    with pytest.raises(ValueError, match="segments"):
        needlesim.flexible_needle(L, D, d, segments=0)
    with pytest.raises(ValueError, match="not on the shaft"):
        needlesim.flexible_needle(L, D, d, forces=[(2 * L, 1.0, 0.0, 0.0)])
