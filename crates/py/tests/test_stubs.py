"""The type stubs (`_needlesim.pyi`) against the compiled module: every public name of
every class the module exports is declared in the stubs, and the stubs declare nothing
the module lacks (they once lacked `tip_region`, `regions` and the history's keys)."""
import ast
import pathlib

import needlesim
from needlesim import _needlesim

STUBS = pathlib.Path(__file__).parents[1] / "python" / "needlesim" / "_needlesim.pyi"


def stub_classes():
    tree = ast.parse(STUBS.read_text())
    out = {}
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            out[node.name] = {
                n.name
                for n in node.body
                if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)) and not n.name.startswith("_")
            }
    return out


def test_every_class_member_is_in_the_stubs_and_back():
    stubs = stub_classes()
    compiled = {n for n in dir(_needlesim) if isinstance(getattr(_needlesim, n), type)}
    assert "Simulation" in compiled
    for name in sorted(compiled):
        cls = getattr(_needlesim, name)
        if issubclass(cls, BaseException):
            continue
        public = {m for m in dir(cls) if not m.startswith("_")}
        # Enum-like classes list their members as class attributes, not methods.
        members = {m for m in public if not isinstance(getattr(cls, m), cls)}
        assert name in stubs, f"class {name} is not in the stubs"
        assert members - stubs[name] == set(), f"{name}: missing from the stubs: {sorted(members - stubs[name])}"
        assert stubs[name] - public == set(), f"{name}: in the stubs only: {sorted(stubs[name] - public)}"


def test_the_history_docstring_names_every_key():
    sim = needlesim.Simulation.from_scene(
        str(pathlib.Path(__file__).parents[3] / "scenes" / "needle_insert_extract.toml"), backend="cpu"
    )
    sim.step(2)
    keys = set(sim.history())
    tree = ast.parse(STUBS.read_text())
    doc = next(
        ast.get_docstring(f)
        for c in tree.body
        if isinstance(c, ast.ClassDef) and c.name == "Simulation"
        for f in c.body
        if isinstance(f, ast.FunctionDef) and f.name == "history"
    )
    missing = sorted(k for k in keys if k not in doc)
    assert missing == [], f"history() keys the stub's docstring does not name: {missing}"
