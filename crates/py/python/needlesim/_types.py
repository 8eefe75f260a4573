"""Typed results of ``Simulation``: the puncture state as an enum, the needle force and its
history as records with attributes (read-only mappings too, so code written against the
earlier plain dicts keeps working), and the surface as a ``pyvista.PolyData``.

The native module builds these from its arrays (``needlesim._needlesim``); they hold the
arrays it hands out, so building one copies nothing."""

import enum
from dataclasses import dataclass, fields
from typing import Any, Dict, Iterator, List, Mapping

import numpy as np
import numpy.typing as npt


class PunctureState(str, enum.Enum):
    """Where the needle tip is: ``OUTSIDE`` the tissue, ``TOUCHING`` its surface (denting
    it, also an inner membrane), ``INSIDE`` it. A ``str`` subclass, so it compares equal to
    its value: ``sim.puncture_state == "inside"``."""

    OUTSIDE = "outside"
    TOUCHING = "touching"
    INSIDE = "inside"

    def __str__(self) -> str:
        return self.value


_STATES: Dict[str, PunctureState] = {s.value: s for s in PunctureState}


class _Record(Mapping[str, Any]):
    """Read-only mapping over a dataclass's fields (``record["axial"]``, ``dict(record)``,
    ``pandas.DataFrame(dict(record))``)."""

    def __getitem__(self, key: str) -> Any:
        if key not in self._names():
            raise KeyError(key)
        return getattr(self, key)

    def __iter__(self) -> Iterator[str]:
        return iter(self._names())

    def __len__(self) -> int:
        return len(self._names())

    def _names(self) -> List[str]:
        return [f.name for f in fields(self)]  # type: ignore[arg-type]


@dataclass(frozen=True, eq=False)
class NeedleForce(_Record):
    """Force of the tissue on the needle in the last step."""

    axial: float
    """N along the needle, positive when the tissue resists insertion."""
    lateral: float
    """N across the needle."""
    total: npt.NDArray[np.float64]
    """The force vector, N, shape (3,)."""
    tip: float
    """The part of the axial force the tip's elements carry (contact, cutting, tearing);
    the rest is the shaft's friction, N."""
    torque: float
    """The friction's torque about the needle's axis, N m."""


@dataclass(frozen=True, eq=False)
class NeedleHistory(_Record):
    """Every recorded step of the needle, one array entry per step (the columns of
    ``needle_force.csv``)."""

    step: npt.NDArray[np.int64]
    time: npt.NDArray[np.float64]
    """s."""
    depth: npt.NDArray[np.float64]
    """m past the first contact point along the needle (negative before it)."""
    axial: npt.NDArray[np.float64]
    """N, positive when the tissue resists insertion."""
    lateral: npt.NDArray[np.float64]
    """N."""
    tip: npt.NDArray[np.float64]
    """N, the tip elements' part of the axial force."""
    torque: npt.NDArray[np.float64]
    """N m about the needle's axis."""
    active_nodes: npt.NDArray[np.int64]
    needle_nodes: npt.NDArray[np.int64]
    state: List[PunctureState]
    region: List[str]
    """The region the tip is in, "" while it is not inside."""
    tissue_depth: npt.NDArray[np.float64]
    """m, the tip's depth in the undeformed tissue; NaN while not in contact."""

    def to_pandas(self) -> Any:
        """The history as a ``pandas.DataFrame``, one row per step (pandas required)."""
        import pandas as pd

        return pd.DataFrame({name: self[name] for name in self})


def _puncture_state(name: str) -> PunctureState:
    return _STATES[name]


def _needle_force(d: Dict[str, Any]) -> NeedleForce:
    return NeedleForce(**d)


def _needle_history(d: Dict[str, Any]) -> NeedleHistory:
    d["state"] = [_STATES[s] for s in d["state"]]
    return NeedleHistory(**d)


def _surface_mesh(
    vertices: npt.NDArray[np.float64],
    faces: npt.NDArray[np.int64],
    displacement: npt.NDArray[np.float64],
) -> Any:
    try:
        import pyvista as pv
    except ImportError as e:  # pragma: no cover - message checked in the tests
        raise ImportError(
            "Simulation.surface_mesh() needs PyVista: pip install needlesim[pyvista] "
            "(Simulation.surface() gives the same mesh as numpy arrays)"
        ) from e
    cells = np.hstack([np.full((len(faces), 1), 3, dtype=np.int64), faces]).ravel()
    mesh = pv.PolyData(vertices, cells)
    mesh.point_data["displacement"] = displacement
    return mesh
