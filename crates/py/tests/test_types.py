"""Typed results and cheap reads (issue 44, item 5): the puncture state enum, the needle
force and history records, neighbours without a rebuild, several arrays in one read, and
the surface as a pyvista.PolyData."""

import math
import sys
import types
from pathlib import Path

import numpy as np
import pytest

import needlesim
from needlesim import NeedleForce, NeedleHistory, PunctureState

ROOT = Path(__file__).resolve().parents[3]
INSERT_EXTRACT = ROOT / "scenes" / "needle_insert_extract.toml"


@pytest.fixture(scope="module")
def inserted():
    """The insert-extract scene with the needle inside (600 steps, one CPU thread)."""
    sim = needlesim.Simulation.from_scene(INSERT_EXTRACT, threads=1)
    sim.step(600)
    return sim


def test_the_puncture_state_is_an_enum_that_still_compares_to_its_name():
    sim = needlesim.Simulation.from_scene(INSERT_EXTRACT, threads=1)
    assert sim.puncture_state is PunctureState.OUTSIDE
    sim.step(600)
    s = sim.puncture_state
    assert isinstance(s, PunctureState) and s is PunctureState.INSIDE
    assert s == "inside" and str(s) == "inside" and f"{s}" == "inside"
    assert PunctureState("touching") is PunctureState.TOUCHING


def test_the_needle_force_is_a_record_and_reads_like_the_dict_it_replaces(inserted):
    f = inserted.needle_force
    assert isinstance(f, NeedleForce)
    assert f.axial == f["axial"] and f.tip == f["tip"] and f.torque == f["torque"]
    assert set(f) == {"axial", "lateral", "total", "tip", "torque"}
    assert f.total.shape == (3,)
    # axial is the total force's component along the needle, against the insertion.
    assert math.isclose(f.axial, -float(np.dot(f.total, inserted.direction)), rel_tol=1e-9, abs_tol=1e-12)
    with pytest.raises(KeyError):
        f["axail"]
    with pytest.raises(AttributeError):
        f.axial = 1.0  # frozen


def test_the_history_is_a_record_of_columns_with_a_dataframe(inserted):
    h = inserted.history()
    assert isinstance(h, NeedleHistory)
    n = len(h.step)
    assert n == inserted.steps == 600
    for name in h:
        assert len(h[name]) == n, name
    assert all(isinstance(s, PunctureState) for s in h.state)
    assert h.state[-1] == "inside" and h.state[0] == "outside"
    assert np.array_equal(h.axial, h["axial"])
    df = h.to_pandas()
    assert list(df.columns) == list(h) and len(df) == n
    assert (df["state"] == "inside").sum() == sum(s is PunctureState.INSIDE for s in h.state)


def test_neighbours_come_from_the_build_or_from_the_running_simulation(inserted):
    index, weight = inserted.neighbours()
    assert index.shape == weight.shape == (inserted.mesh_nodes, index.shape[1])
    # The build's rows again, not rebuilt: the same arrays from a fresh simulation.
    fresh = needlesim.Simulation.from_scene(INSERT_EXTRACT, threads=1)
    i0, w0 = fresh.neighbours()
    assert np.array_equal(index, i0) and np.array_equal(weight, w0)
    # The current rows: every active node, needle nodes included, edited by the needle.
    ci, cw = inserted.neighbours(current=True)
    assert inserted.needle_nodes >= 1
    assert ci.shape == (inserted.active_nodes, index.shape[1])
    assert not np.array_equal(ci[: inserted.mesh_nodes], index), "the needle edited no row"
    fi, fw = fresh.neighbours(current=True)
    assert np.array_equal(fi, i0) and np.array_equal(fw, w0)


def test_several_arrays_come_in_one_read(inserted):
    p, v, f = inserted.read()
    assert np.array_equal(p, inserted.positions)
    assert np.array_equal(v, inserted.velocities)
    assert np.array_equal(f, inserted.forces)
    nodes = [5, 0, inserted.active_nodes - 1, 5]
    (p2, f2) = inserted.read(["positions", "forces"], nodes=nodes)
    assert np.array_equal(p2, inserted.positions[nodes])
    assert np.array_equal(f2, inserted.forces[nodes])
    with pytest.raises(ValueError, match='unknown field "position"'):
        inserted.read(["position"])
    with pytest.raises(ValueError, match="outside the"):
        inserted.read(nodes=[inserted.active_nodes])
    with pytest.raises(ValueError, match="outside the"):
        inserted.read(nodes=[-1])


def test_surface_mesh_builds_a_pyvista_polydata(inserted, monkeypatch):
    """Against a stand-in for pyvista (CI does not install VTK): the points, the faces in
    VTK's (3, a, b, c) layout and the displacement it is handed are the surface's."""

    made = {}

    class PolyData:
        def __init__(self, points, faces):
            made["points"], made["faces"] = points, faces
            self.point_data = {}

    monkeypatch.setitem(sys.modules, "pyvista", types.SimpleNamespace(PolyData=PolyData))
    mesh = inserted.surface_mesh()
    verts, faces = inserted.surface()
    assert np.array_equal(made["points"], verts)
    cells = made["faces"].reshape(-1, 4)
    assert (cells[:, 0] == 3).all() and np.array_equal(cells[:, 1:], faces)
    disp = mesh.point_data["displacement"]
    assert disp.shape == verts.shape
    # Displacement is from rest: some surface node moved, and rest + displacement is the
    # position.
    assert np.abs(disp).max() > 1e-5
    rest = inserted.rest_positions
    tri = inserted.triangles
    first = tri[0, 0]
    assert np.allclose(rest[first] + disp[0], verts[0], atol=1e-12)


def test_surface_mesh_without_pyvista_says_how_to_get_it(inserted, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyvista", None)  # import pyvista raises ImportError
    with pytest.raises(ImportError, match="needlesim\\[pyvista\\]"):
        inserted.surface_mesh()


def test_numpy_values_in_a_scene_dict_are_their_python_values():
    """A scene dict built with numpy (arrays for vectors, numpy scalars for numbers) gives
    the simulation of the plain dict (numpy arrays were refused, numpy integers became
    floats)."""
    plain = {
        "tissue": {"geometry": {"kind": "box", "min": [0.0, 0.0, 0.0], "max": [0.1, 0.1, 0.1], "nodes": 100}},
        "material": {"model": "mass_spring", "stiffness": 1.0},
        "physics": {"dt": 1e-3, "gravity": [0.0, -9.81, 0.0]},
    }
    numpy = {
        "tissue": {"geometry": {"kind": "box", "min": np.zeros(3), "max": np.full(3, 0.1), "nodes": np.int64(100)}},
        "material": {"model": "mass_spring", "stiffness": np.float32(1.0)},
        "physics": {"dt": np.float64(1e-3), "gravity": np.array([0.0, -9.81, 0.0])},
    }
    a = needlesim.Simulation.from_dict(plain, threads=1)
    b = needlesim.Simulation.from_dict(numpy, threads=1)
    a.step(20)
    b.step(20)
    assert a.active_nodes == b.active_nodes
    assert np.array_equal(a.positions, b.positions)
    with pytest.raises(ValueError, match="expected usize in `nodes`"):
        bad = {**numpy, "tissue": {"geometry": {**numpy["tissue"]["geometry"], "nodes": np.array([[1, 2]])}}}
        needlesim.Simulation.from_dict(bad, threads=1)


def test_relaxation_refuses_what_a_scene_refuses():
    t = np.linspace(0.0, 1.0, 5)
    assert np.allclose(needlesim.relaxation(t, [(0.3, 0.5)])[0], 1.0)
    for terms, ramp, what in [
        ([(1.5, 0.5)], 0.0, "g must lie"),
        ([(0.3, -1.0)], 0.0, "tau must be"),
        ([(0.3, float("nan"))], 0.0, "tau must be"),
        ([(0.6, 0.1), (0.5, 1.0)], 0.0, "sum to less than 1"),
        ([(0.3, 0.5)], -1.0, "ramp"),
    ]:
        with pytest.raises(ValueError, match=what):
            needlesim.relaxation(t, terms, ramp)
