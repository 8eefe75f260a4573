"""needlesim: needle insertion into soft tissue with meshfree particle methods.

    >>> import needlesim
    >>> sim = needlesim.Simulation.from_scene("scenes/needle_insert_extract.toml")
    >>> sim.step(1000)          # releases the interpreter lock while it runs
    >>> sim.puncture_state, sim.needle_force["axial"], sim.positions.shape

Arrays are float64 (int64 for indices) copies of the simulation state, shaped
(n, 3); they do not change when the simulation steps on.
"""

from ._needlesim import Simulation, adapter, __version__

__all__ = ["Simulation", "adapter", "__version__"]
