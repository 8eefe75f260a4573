"""needlesim.sweep and needlesim.fit on a Dask LocalCluster with two workers."""

import copy
import sys
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest

import needlesim

ROOT = Path(__file__).resolve().parents[3]
INSERT_EXTRACT = ROOT / "scenes" / "needle_insert_extract.toml"
PHANTOM = ROOT / "scenes" / "phantom_insertion.toml"
SPHERE_OBJ = ROOT / "scenes" / "meshes" / "sphere.obj"


def scene(path):
    with open(path, "rb") as f:
        return tomllib.load(f)


@pytest.fixture(scope="module")
def client():
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, distributed.Client(cluster) as c:
        yield c


# 600 steps: the needle touches the surface at step ~400 and is inside by step 600, so
# the force histories depend on every varied value.
STEPS = 600
GRID = {
    "material.stiffness": [10.0, 20.0],
    "needle.friction.coefficient": [0.2, 0.4],
    "needle.cutting": [0.05, 0.1],
}


def alone(stiffness, friction, cutting):
    """The variant built by hand (not through apply_overrides) and run in this process."""
    s = scene(INSERT_EXTRACT)
    s["material"]["stiffness"] = stiffness
    s["needle"]["friction"]["coefficient"] = friction
    s["needle"]["cutting"] = cutting
    sim = needlesim.Simulation.from_dict(s, backend="cpu", base_dir=INSERT_EXTRACT.parent)
    track = [sim.positions[[0, 300]]]
    for _ in range(STEPS // 200):
        sim.step(200)
        track.append(sim.positions[[0, 300]])
    return sim.history(), np.array(track)


def test_eight_variants_on_two_workers_are_bitwise_the_runs_alone(client):
    res = needlesim.sweep(INSERT_EXTRACT, GRID, client, steps=STEPS, nodes=[0, 300], every=200)
    assert len(res.summary) == 8 and res.summary["ok"].all()
    # Both workers took part (the tasks are spread, not run in the client).
    assert res.summary["worker"].nunique() == 2
    assert set(res.summary["state"]) == {"inside"}
    for i, v in enumerate(needlesim.grid(GRID)):
        h, track = alone(*v.values())
        got = res.variant(i)
        for col, key in [("axial_force_n", "axial"), ("lateral_force_n", "lateral"),
                         ("depth_m", "depth"), ("time_s", "time"), ("step", "step")]:
            assert np.array_equal(got[col].to_numpy(), np.asarray(h[key])), (i, col)
        assert list(got["state"]) == list(h["state"])
        assert (got["material.stiffness"] == v["material.stiffness"]).all()
        nodes = res.nodes[res.nodes["variant"] == i]
        assert list(nodes["step"].unique()) == [0, 200, 400, 600]
        xyz = nodes[["x", "y", "z"]].to_numpy().reshape(4, 2, 3)
        assert np.array_equal(xyz, track)
    # The variants differ from each other (the sweep did vary something).
    hs = [res.variant(i)["axial_force_n"].to_numpy() for i in range(8)]
    assert not any(np.array_equal(hs[i], hs[j]) for i in range(8) for j in range(i + 1, 8))


def test_a_failing_variant_is_reported_and_the_others_complete(client):
    variants = [
        {"material.young_modulus": 2e4},
        {"material.young_modulus": -5.0},  # rejected by the scene parser
        {"physics.dt": 0.01},  # 17x the stable step: diverges
        {"material.no_such.key": 1.0},  # not a place in the scene
        {"material.young_modulus": 3e4},
    ]
    res = needlesim.sweep(PHANTOM, variants, client, steps=300)
    s = res.summary.set_index("variant")
    assert list(s["ok"]) == [True, False, False, False, True]
    assert s.loc[1, "error_type"] == "ValueError" and "young_modulus" in s.loc[1, "error"]
    assert s.loc[2, "error_type"] == "RuntimeError" and "diverged" in s.loc[2, "error"]
    assert s.loc[3, "error_type"] == "OverrideError" and "no_such" in s.loc[3, "error"]
    assert list(res.failed.index) == [1, 2, 3]
    assert sorted(res.force["variant"].unique()) == [0, 4]
    assert (res.force.groupby("variant").size() == 300).all()


def test_surface_files_travel_inline_with_the_tasks(client, tmp_path):
    # A scene whose OBJ lives next to it, moved somewhere the workers do not look: inline
    # files (the default) must arrive; the result equals the run alone.
    (tmp_path / "mesh.obj").write_bytes(SPHERE_OBJ.read_bytes())
    s = scene(ROOT / "scenes" / "sphere_drop_msm.toml")  # its OBJ moved to tmp_path
    s["tissue"]["geometry"]["path"] = "mesh.obj"
    s["run"]["steps"] = 50
    res = needlesim.sweep(s, [{}, {"material.stiffness": 50.0}], client, base_dir=tmp_path,
                          nodes=[0], every=50)
    assert res.summary["ok"].all(), res.summary["error"].tolist()
    sim = needlesim.Simulation.from_dict(s, backend="cpu", base_dir=tmp_path)
    sim.step(50)
    last = res.nodes[(res.nodes["variant"] == 0) & (res.nodes["step"] == 50)]
    assert np.array_equal(last[["x", "y", "z"]].to_numpy()[0], sim.positions[0])
    # A worker that cannot see the scene's folder still runs it from the shipped bytes.
    from needlesim import _sweep

    shipped_scene, shipped = _sweep._ship_files(copy.deepcopy(s), tmp_path, "inline", {})
    assert list(shipped) == ["files/0_mesh.obj"]
    (tmp_path / "mesh.obj").unlink()
    task = {"scene": shipped_scene, "files": shipped, "base_dir": str(tmp_path / "gone"),
            "steps": 50, "duration": None, "nodes": [0], "every": 50, "backend": "cpu",
            "threads": 1}
    out = client.submit(_sweep.run_variant, task, pure=False).result()
    assert out["ok"], out["error"]
    assert np.array_equal(out["node_positions"][-1, 0], sim.positions[0])


def test_without_dask_the_sweep_runs_serially_and_says_so(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed fails
    with pytest.warns(needlesim.SerialSweepWarning, match="one after another"):
        res = needlesim.sweep(INSERT_EXTRACT, [{"needle.cutting": 0.1}], steps=100)
    assert res.summary["ok"].all() and res.summary["worker"].nunique() == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # "serial" asked for: no warning
        needlesim.sweep(INSERT_EXTRACT, [{}], "serial", steps=10)


def test_overrides_and_grids_name_the_bad_key():
    s = scene(INSERT_EXTRACT)
    out = needlesim.apply_overrides(s, {"needle.keyframe.1.duration": 1.5, "run.new": 3})
    assert out["needle"]["keyframe"][1]["duration"] == 1.5 and out["run"]["new"] == 3
    assert s["needle"]["keyframe"][1]["duration"] == 0.5  # the input is not changed
    for key, msg in [("needle.keyframe.7.speed", "index 7 past the 3"),
                     ("needle.keyframe.x.speed", "not an index"),
                     ("material.model.x", "plain value"), ("nope.x", "no `nope`"),
                     ("a..b", "empty part")]:
        with pytest.raises(needlesim.OverrideError, match=msg):
            needlesim.apply_overrides(s, {key: 1})
    assert needlesim.grid({"a": [1, 2], "b": [3]}) == [{"a": 1, "b": 3}, {"a": 2, "b": 3}]
    with pytest.raises(ValueError, match="`b`"):
        needlesim.grid({"a": [1], "b": []})
    with pytest.raises(ValueError, match="steps or duration"):
        needlesim.sweep(s, [{}], "serial", steps=10, duration=1.0, base_dir=ROOT / "scenes")


def test_a_scene_duration_sets_each_variants_steps():
    """`run.duration` in the scene: each variant runs ceil(duration / its dt) steps, so
    two moduli of the `dt = "auto"` phantom run the same simulated time."""
    s = scene(PHANTOM)
    s["run"].pop("steps", None)
    s["run"]["duration"] = 0.05
    res = needlesim.sweep(s, needlesim.grid({"material.young_modulus": [1e4, 4e4]}),
                          "serial", base_dir=ROOT / "scenes")
    assert res.summary["ok"].all(), res.summary["error"].tolist()
    steps = res.summary["steps"].to_numpy()
    assert steps[1] > steps[0]  # the stiffer variant has the smaller dt
    assert np.allclose(res.summary["time_s"], 0.05, rtol=0, atol=0.05 / steps.min())


def synthetic_curve(truth, seed):
    """The phantom's force against depth at `truth`, every 0.1 mm to 35 mm, with 0.02 N
    of Gaussian noise (a load cell's noise on a bench-top insertion)."""
    r = needlesim.sweep(PHANTOM, [truth], "serial", duration=2.0).variant(0)
    d, f = r["depth_m"].to_numpy(), r["axial_force_n"].to_numpy()
    keep = slice(0, int(np.argmax(d)) + 1)
    depth = np.arange(0.0, 0.035, 1e-4)
    rng = np.random.default_rng(seed)
    return depth, np.interp(depth, d[keep], f[keep]) + rng.normal(0.0, 0.02, depth.size)


def test_fit_recovers_modulus_friction_and_puncture_from_a_noisy_curve(client):
    truth = {"material.young_modulus": 2e4, "needle.friction.coefficient": 0.3,
             "needle.puncture_force": 1.0}
    depth, force = synthetic_curve(truth, seed=1)
    # Started 50 %, 33 % and 50 % away from the truth, within wide bounds.
    res = needlesim.fit(PHANTOM, depth, force, list(truth),
                        [(5e3, 8e4), (0.05, 1.0), (0.3, 3.0)], client,
                        x0=[3e4, 0.2, 1.5], duration=2.0)
    p, e = res.parameters, res.stderr
    # The tolerances: E within 5 %, friction within 10 %; the puncture force
    # (not asked) within 10 %.
    assert abs(p["material.young_modulus"] / 2e4 - 1) < 0.05, res
    assert abs(p["needle.friction.coefficient"] / 0.3 - 1) < 0.10, res
    assert abs(p["needle.puncture_force"] / 1.0 - 1) < 0.10, res
    assert all(0 < v < 0.1 * abs(p[k]) for k, v in e.items()), e
    assert res.rms < 0.02  # smoothed residual, below the points' 0.02 N noise
    assert res.simulations == 4 * len(res.evaluations.drop_duplicates(list(truth)))
    assert res.fitted.shape == res.measured.shape == res.depth.shape


def test_fit_rejects_bad_input_and_curves_beyond_the_simulation():
    depth = np.linspace(0.0, 0.03, 50)
    force = np.linspace(0.0, 1.0, 50)
    args = (PHANTOM, depth, force, ["material.young_modulus"])
    with pytest.raises(ValueError, match="low < high"):
        needlesim.fit(*args, [(2e4, 1e4)], "serial")
    with pytest.raises(ValueError, match="outside its bounds"):
        needlesim.fit(*args, [(1e4, 3e4)], "serial", x0=[5e4])
    with pytest.raises(ValueError, match="finite"):
        needlesim.fit(PHANTOM, depth, force * np.nan, ["material.young_modulus"],
                      [(1e4, 3e4)], "serial")
    # 200 steps move the needle 2 mm: the 30 mm curve is out of reach.
    with pytest.raises(needlesim.FitError, match="give more steps"):
        needlesim.fit(*args, [(1e4, 3e4)], "serial", steps=200)
