"""Generated scene dicts (issue 18, item 5): `Simulation.from_dict` on about 300 mutations
of a valid scene either builds or raises a ValueError, RuntimeError, TypeError or
OverflowError; never a PanicException (a BaseException) nor a crash."""

import copy
import math
import random
import tomllib
from pathlib import Path

import needlesim

ROOT = Path(__file__).resolve().parents[3]
INSERT_EXTRACT = ROOT / "scenes" / "needle_insert_extract.toml"

ALLOWED = (ValueError, RuntimeError, TypeError, OverflowError)
CASES = 300
# The most box nodes a generated scene may ask for; more would be slow to build.
MAX_NODES = 5000
# A small memory limit (`run.max_memory_gib`) so that a scene whose size a mutation raised
# fails fast with an error instead of allocating.
MAX_MEMORY_GIB = 0.05


NUMBERS = [0.0, -0.0, -1.0, 1e-300, 1e300, -1e300, 5e-324, 1.7976931348623157e308, math.nan,
           math.inf, -math.inf, 1e-45, 3.5e38, 1e-9, 1e9, 0.5, 2.0]
INTEGERS = [0, -1, 1, 2, 7, 100, 10**6, 2**31, 2**63 - 1, -(2**63)]


def leaf_paths(node, path=()):
    """Every path to a leaf (a value that is not a dict or a list) and to every container."""
    out = [path] if path else []
    if isinstance(node, dict):
        for k, v in node.items():
            out += leaf_paths(v, path + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += leaf_paths(v, path + (i,))
    return out


def parent_of(d, path):
    node = d
    for k in path[:-1]:
        node = node[k]
    return node


def random_value(rng, depth=0):
    """A value from the edges of what a scene may hold."""
    choices = [
        0,
        -0.0,
        -1,
        -(10**6),
        2**31,
        2**63 - 1,
        -(2**63),
        2**64,
        10**400,
        -(10**400),
        1e-300,
        1e300,
        -1e300,
        5e-324,
        1.7976931348623157e308,
        math.nan,
        math.inf,
        -math.inf,
        1e-45,
        3.5e38,
        True,
        False,
        "",
        "x",
        "nan",
        "box",
        "obj",
        "cpu",
        "move",
        "\0",
        "\u00e9\u4e2d",
        "\udcff",
        "a" * 100_000,
        [],
        [1.0],
        [0.0, 0.0, 0.0],
        [1.0, 2.0, 3.0, 4.0],
        [math.nan, math.inf, -math.inf],
        {},
        {"kind": "box"},
        (1.0, 2.0, 3.0),
    ]
    r = rng.random()
    if r < 0.6:
        return copy.deepcopy(rng.choice(choices))
    if r < 0.75:
        return rng.uniform(-2.0, 2.0) * 10 ** rng.randint(-10, 10)
    if r < 0.85:
        return rng.randint(-100, 100)
    if depth < 3 and r < 0.93:
        return [random_value(rng, depth + 1) for _ in range(rng.randint(0, 4))]
    if depth < 3:
        return {rng.choice(["kind", "min", "x", "spacing", "nodes"]): random_value(rng, depth + 1)}
    return rng.random()


def mutate(rng, scene):
    d = copy.deepcopy(scene)
    for _ in range(rng.randint(1, 3)):
        paths = leaf_paths(d)
        if not paths:
            break
        path = rng.choice(paths)
        parent = parent_of(d, path)
        key = path[-1]
        r = rng.random()
        old = parent[key]
        if r < 0.3 and isinstance(old, (int, float)) and not isinstance(old, bool):
            # A number of the same kind at an edge, so that more scenes get past the types.
            parent[key] = rng.choice(NUMBERS) if isinstance(old, float) else rng.choice(INTEGERS)
        elif r < 0.6:
            parent[key] = random_value(rng)
        elif r < 0.8:
            del parent[key]
        elif isinstance(parent, dict):
            parent[rng.choice(["banana", "nodes", "spacing", "kind", "path", "x" * 50])] = random_value(rng)
        else:
            parent.append(random_value(rng))
    return d


def too_big(d):
    """Whether a box geometry asks for more than MAX_NODES nodes (surface files and
    needles are judged by the memory estimate, which comes before any allocation)."""
    try:
        g = d["tissue"]["geometry"]
        if isinstance(g.get("nodes"), (int, float)) and not isinstance(g.get("nodes"), bool):
            if not g["nodes"] <= MAX_NODES:
                return True
        h = g.get("spacing")
        if isinstance(h, (int, float)) and not isinstance(h, bool):
            count = 1.0
            for a, b in zip(g["min"], g["max"]):
                count *= abs(float(b) - float(a)) / float(h) + 1.0
            return not count <= MAX_NODES
    except (KeyError, TypeError, AttributeError, ValueError, ZeroDivisionError, OverflowError):
        pass
    return False


def test_generated_scene_dicts_build_or_raise_a_typed_error():
    with open(INSERT_EXTRACT, "rb") as f:
        reference = tomllib.load(f)
    # The reference scene builds under the small memory limit.
    base = copy.deepcopy(reference)
    base["run"]["max_memory_gib"] = MAX_MEMORY_GIB
    needlesim.Simulation.from_dict(base, backend="cpu", threads=1, base_dir=INSERT_EXTRACT.parent)

    rng = random.Random(1234)
    failures = []
    for case in range(CASES):
        d = mutate(rng, reference)
        if "run" not in d:
            d["run"] = {}
        if isinstance(d["run"], dict):
            d["run"]["max_memory_gib"] = MAX_MEMORY_GIB
        if too_big(d):
            continue
        try:
            needlesim.Simulation.from_dict(d, backend="cpu", threads=1, base_dir=INSERT_EXTRACT.parent)
        except ALLOWED:
            pass
        except BaseException as e:  # noqa: BLE001 - a PanicException is a BaseException
            if isinstance(e, KeyboardInterrupt):
                raise
            failures.append(f"case {case}: {type(e).__module__}.{type(e).__name__}: {e}\n  {d!r:.2000}")
    assert not failures, "\n".join(failures)
