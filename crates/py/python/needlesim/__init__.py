"""needlesim: needle insertion into soft tissue with meshfree particle methods.

    >>> import needlesim
    >>> sim = needlesim.Simulation.from_scene("scenes/needle_insert_extract.toml")
    >>> sim.step(1000)          # releases the interpreter lock while it runs
    >>> sim.puncture_state, sim.needle_force["axial"], sim.positions.shape

A haptic loop steps a simulation at 1 kHz on its own thread (see HapticLoop):

    >>> loop = needlesim.HapticLoop(sim)          # the device pose comes from set_device
    >>> loop.set_device(base, direction); loop.force
    >>> loop.stop()["period_p99"]

Many runs (needlesim.sweep, needlesim.fit) go through Dask when it is installed
(pip install needlesim[dask]) and one after another when it is not:

    >>> res = needlesim.sweep("scene.toml", {"material.young_modulus": [1e4, 2e4]})
    >>> res.force, res.nodes, res.summary          # pandas tables, one row per step
    >>> fit = needlesim.fit("scene.toml", depth, force, ["material.young_modulus"],
    ...                     [(5e3, 5e4)])

Arrays are float64 (int64 for indices) copies of the simulation state, shaped
(n, 3); they do not change when the simulation steps on. Each property is one read
(on the GPU one device round trip): ``sim.read(["positions", "forces"])`` reads several
at once. Results are typed: ``sim.puncture_state`` is a ``PunctureState`` (a str enum),
``sim.needle_force`` a ``NeedleForce`` and ``sim.history()`` a ``NeedleHistory``
(records with attributes that read like the dicts they replace: ``h["axial"]``,
``h.to_pandas()``); ``sim.surface_mesh()`` is a ``pyvista.PolyData`` with PyVista
installed (``pip install needlesim[pyvista]``).
"""

from ._needlesim import (
    HapticLoop,
    SineDevice,
    Simulation,
    adapter,
    flexible_needle,
    models,
    __version__,
)
from ._fit import FitError, FitResult, fit
from ._prony import PronyFit, fit_prony, relaxation
from ._types import NeedleForce, NeedleHistory, PunctureState
from ._sweep import (
    OverrideError,
    SerialSweepWarning,
    SweepResult,
    apply_overrides,
    grid,
    load_scene,
    sweep,
)

__all__ = [
    "FitError",
    "FitResult",
    "HapticLoop",
    "NeedleForce",
    "NeedleHistory",
    "OverrideError",
    "PronyFit",
    "PunctureState",
    "SerialSweepWarning",
    "SineDevice",
    "Simulation",
    "SweepResult",
    "adapter",
    "apply_overrides",
    "flexible_needle",
    "fit",
    "fit_prony",
    "grid",
    "load_scene",
    "models",
    "relaxation",
    "sweep",
    "__version__",
]
