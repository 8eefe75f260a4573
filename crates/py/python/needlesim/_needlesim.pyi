"""Type stubs of the native module (see needlesim.Simulation)."""

from os import PathLike
from typing import Any, Dict, List, Literal, Optional, Sequence, Tuple, Union, final

import numpy as np
import numpy.typing as npt

from ._types import NeedleForce, NeedleHistory, PunctureState

__all__ = [
    "Simulation",
    "HapticLoop",
    "SineDevice",
    "adapter",
    "models",
    "flexible_needle",
    "__version__",
]

__version__: str

_BackendName = Literal["cpu", "cpu-parallel", "gpu", "auto"]

@final
class Simulation:
    """A needle insertion simulation (or a plain tissue simulation when the scene has no
    [needle] table) on the CPU or the GPU."""

    @staticmethod
    def from_scene(
        path: Union[str, PathLike[str]],
        backend: Optional[_BackendName] = None,
        threads: Optional[int] = None,
    ) -> "Simulation":
        """Builds the scene in a TOML file. Raises ValueError naming the bad key."""
    @staticmethod
    def from_dict(
        scene: Dict[str, Any],
        backend: Optional[_BackendName] = None,
        threads: Optional[int] = None,
        base_dir: Optional[Union[str, PathLike[str]]] = None,
    ) -> "Simulation":
        """Builds a scene given as a dict with the TOML format's keys."""
    def save(self, path: Union[str, PathLike[str]]) -> None:
        """Writes the whole state and the scene to one versioned file (atomically)."""
    @staticmethod
    def load(
        path: Union[str, PathLike[str]],
        backend: Optional[_BackendName] = None,
        threads: Optional[int] = None,
    ) -> "Simulation":
        """The simulation save() wrote; continues bitwise on the CPU backends. ValueError
        for a truncated or altered file or another format version."""
    @property
    def history_limit(self) -> Optional[int]:
        """Most steps history() keeps (None, the default: all, 160 bytes a step)."""
    @history_limit.setter
    def history_limit(self, limit: Optional[int]) -> None: ...
    def step(self, n: int = 1) -> None:
        """Runs n steps with the interpreter lock released; RuntimeError on divergence."""
    @property
    def positions(self) -> npt.NDArray[np.float64]:
        """(active_nodes, 3) positions in m (copy): the f32 position plus the
        integrator's remainder, resolving displacements far below f32's spacing."""
    @property
    def velocities(self) -> npt.NDArray[np.float64]:
        """(active_nodes, 3) velocities in m/s (copy)."""
    @property
    def forces(self) -> npt.NDArray[np.float64]:
        """(active_nodes, 3) forces of the last step in N (copy)."""
    @property
    def rest_positions(self) -> npt.NDArray[np.float64]:
        """(active_nodes, 3) rest positions in m (copy)."""
    @property
    def triangles(self) -> npt.NDArray[np.int64]:
        """(triangles, 3) surface triangles as indices into positions."""
    def surface(self) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
        """The surface as (vertices (m, 3), faces (t, 3) into vertices)."""
    def surface_mesh(self) -> Any:
        """The surface as a pyvista.PolyData with point data "displacement" (m); ImportError
        without PyVista (pip install needlesim[pyvista])."""
    def read(
        self,
        fields: List[Literal["positions", "velocities", "forces"]] = ...,
        nodes: Optional[List[int]] = None,
    ) -> Tuple[npt.NDArray[np.float64], ...]:
        """Several (n, 3) arrays in one read (one device round trip on the GPU), for the
        active nodes or the listed ones; default all three fields."""
    def screenshot(self, path: Union[str, PathLike[str]], width: int = 800, height: int = 600) -> None:
        """Renders the simulation now to a PNG (offscreen; RuntimeError without a Vulkan driver)."""
    def set_pose(self, base: Tuple[float, float, float], direction: Tuple[float, float, float], roll: Optional[float] = None) -> None:
        """Puts the needle at a pose (and optionally its roll about its axis, rad) for the next step; keyframes stop playing."""
    @property
    def roll(self) -> Optional[float]:
        """Needle roll about its own axis in rad, None without a needle."""
    @property
    def tip(self) -> Optional[npt.NDArray[np.float64]]:
        """Needle tip (3,), None without a needle."""
    @property
    def base(self) -> Optional[npt.NDArray[np.float64]]:
        """Needle base point (3,), None without a needle."""
    @property
    def direction(self) -> Optional[npt.NDArray[np.float64]]:
        """Unit needle direction base -> tip (3,), None without a needle."""
    @property
    def puncture_state(self) -> PunctureState:
        """OUTSIDE, TOUCHING or INSIDE (a str enum, equal to "outside", ...)."""
    @property
    def tip_region(self) -> Optional[str]:
        """The tissue region the tip is in (a [[region]] name, or "tissue" for the nodes in
        none), or None while the tip is not inside."""
    @property
    def regions(self) -> List[str]:
        """Names of the tissue regions, "tissue" (the nodes in no [[region]]) first."""
    @property
    def masses(self) -> npt.NDArray[np.float64]:
        """(mesh_nodes,) node masses in kg (density times cell volume by default)."""
    def neighbours(self, current: bool = False) -> Tuple[npt.NDArray[np.int64], npt.NDArray[np.float32]]:
        """(index, weight), both (nodes, K), weight 0 marking an empty or broken slot: the
        mesh's rows as the scene built them (kept, not rebuilt), or with current=True the
        rows in use now for every active node (needle edits and added nodes included)."""
    def reactions(self) -> Dict[str, npt.NDArray[np.float64]]:
        """{set name: (3,) force in N} that each [[fixed]] / [[prescribed]] set exerts on
        the body, from the last step's forces."""
    @property
    def needle_force(self) -> NeedleForce:
        """axial, lateral, tip (N), torque (N m), total ((3,) N) of the last step; also a
        read-only mapping of those keys."""
    def history(self, clear: bool = False) -> NeedleHistory:
        """Per-step arrays: step, time, depth, axial, lateral, tip, torque, active_nodes,
        needle_nodes, tissue_depth (m, NaN while the tip is not in contact); state (a list of
        PunctureState) and region (the region the tip is in, "" when not inside, a list of
        str). A read-only mapping of those columns too; to_pandas() gives a DataFrame.
        clear=True also empties the record (streaming)."""
    @property
    def active_nodes(self) -> int: ...
    @property
    def capacity(self) -> int: ...
    @property
    def mesh_nodes(self) -> int: ...
    @property
    def needle_nodes(self) -> int: ...
    @property
    def time(self) -> float: ...
    @property
    def steps(self) -> int: ...
    @property
    def dt(self) -> float: ...
    @property
    def run_steps(self) -> int:
        """Steps the scene's [run] asks for: run.steps, or ceil(run.duration / dt)."""
    @property
    def backend(self) -> str:
        """The backend in use, e.g. "cpu (1 thread)" or "gpu (<adapter>)"."""
    @property
    def warnings(self) -> List[str]: ...

@final
class SineDevice:
    """A simulated device: a sinusoidal insertion from `start` along `direction`,
    `amplitude` m deep, `frequency` strokes per second."""

    def __new__(
        cls,
        start: Tuple[float, float, float],
        direction: Tuple[float, float, float],
        amplitude: float,
        frequency: float,
        clock: Literal["scheduled", "wall"] = "scheduled",
    ) -> "SineDevice": ...
    def position_at(self, t: float) -> npt.NDArray[np.float64]:
        """The base position at time t (s)."""

@final
class HapticLoop:
    """Steps a Simulation on its own thread at `rate` Hz with the needle tied to a device
    by a virtual coupling; sends the device the coupling force."""

    def __new__(
        cls,
        sim: Simulation,
        rate: float = 1000.0,
        stiffness: Optional[float] = None,
        damping: Optional[float] = None,
        proxy_mass: Optional[float] = None,
        proxy_damping: Optional[float] = None,
        lowpass: Optional[float] = None,
        max_force: float = 10.0,
        max_ticks: Optional[int] = None,
        device: Optional[SineDevice] = None,
    ) -> "HapticLoop": ...
    def set_device(self, position: Tuple[float, float, float], direction: Tuple[float, float, float]) -> None:
        """Sets the device pose (needle base, direction) for the next tick."""
    @property
    def force(self) -> npt.NDArray[np.float64]:
        """Force sent to the device in the last tick, N, (3,)."""
    def latest(self) -> Optional[Dict[str, Any]]:
        """The last tick's record."""
    @property
    def running(self) -> bool: ...
    def stats(self) -> Dict[str, float]:
        """ticks, overruns, saturated, target and p50/p99/max of period, work, latency (s)."""
    def records(self) -> Dict[str, Any]:
        """The tick records kept, as numpy arrays."""
    def stop(self) -> Dict[str, float]:
        """Stops the loop (zero force last) and returns its stats; RuntimeError if it had
        stopped on an error."""
    def join(self) -> Dict[str, float]:
        """Waits for the loop to stop after max_ticks, then returns like stop."""

def adapter() -> Optional[str]:
    """The GPU adapter wgpu finds, or None."""

def models() -> List[Dict[str, Any]]:
    """The tissue models, from needlesim's registry: one dict per model with its TOML
    tag (``model = "<tag>"`` in ``[material]``), ``short_name``, ``label`` and
    ``structural_keys`` (the keys every ``[[region]]`` must share)."""

def flexible_needle(
    length: float,
    outer_diameter: float,
    inner_diameter: float = 0.0,
    *,
    young_modulus: float = 193e9,
    poisson_ratio: float = 0.29,
    segments: int = 20,
    forces: Sequence[Tuple[float, float, float, float]] = ...,
    moments: Sequence[Tuple[float, float, float, float]] = ...,
    per_length: Tuple[float, float, float] = ...,
) -> npt.NDArray[np.float64]:
    """The centre line of a flexible needle clamped at the origin along +z, in
    equilibrium under point forces and moments and a load per length: an (N + 2, 3)
    array of the base, the N hinges and the tip (m). ``forces`` and ``moments`` are
    sequences of ``(s, x, y, z)``: arc length from the base (m) and the vector (N, N m).
    A chain of ``segments`` rigid elements (``needlesim::needle::rod``); 20 elements are
    within 0.13% of the Euler-Bernoulli cantilever. ValueError names a bad parameter, a
    load off the shaft, or a load the solve finds no equilibrium for."""
