"""needlesim: needle insertion into soft tissue with meshfree particle methods.

    >>> import needlesim
    >>> sim = needlesim.Simulation.from_scene("scenes/needle_insert_extract.toml")
    >>> sim.step(1000)          # releases the interpreter lock while it runs
    >>> sim.puncture_state, sim.needle_force["axial"], sim.positions.shape

A haptic loop steps a simulation at 1 kHz on its own thread (see HapticLoop):

    >>> loop = needlesim.HapticLoop(sim)          # the device pose comes from set_device
    >>> loop.set_device(base, direction); loop.force
    >>> loop.stop()["period_p99"]

Arrays are float64 (int64 for indices) copies of the simulation state, shaped
(n, 3); they do not change when the simulation steps on.
"""

from ._needlesim import HapticLoop, SineDevice, Simulation, adapter, __version__

__all__ = ["HapticLoop", "SineDevice", "Simulation", "adapter", "__version__"]
