#!/usr/bin/env python3
"""Finds import cycles between the Rust source files of each crate of the workspace.

A file depends on the file that defines what it names: `use` paths and inline paths
(`crate::a::b::Item`, `super::x`, `self::x`), with items re-exported by a `pub use`
followed to the module that defines them. `mod x;` declarations and `pub use` re-exports
themselves are not dependencies (a parent module's interface). Comments, strings and
`#[cfg(test)]` modules are ignored. Prints every cycle and exits 1 if there is one.

Usage: scripts/import_cycles.py [ROOT]   (default: the repository root)
"""

import re
import sys
from pathlib import Path

ROOT = Path(sys.argv[1] if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent)


def strip(text: str) -> str:
    """Source without comments, string and char literals and `#[cfg(test)] mod` blocks."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            i = text.find("\n", i)
            i = n if i < 0 else i
        elif text.startswith("/*", i):
            depth, i = 1, i + 2
            while i < n and depth:
                if text.startswith("/*", i):
                    depth, i = depth + 1, i + 2
                elif text.startswith("*/", i):
                    depth, i = depth - 1, i + 2
                else:
                    i += 1
        elif (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")) and re.match(
            r'b?r#*"', text[i : i + 80]
        ):
            m = re.match(r'b?r(#*)"', text[i:])
            end = text.find('"' + m.group(1), i + m.end())
            out.append('""')
            i = n if end < 0 else end + 1 + len(m.group(1))
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            out.append('""')
            i = j + 1
        elif c == "'" and re.match(r"'(?:\\.|\\u\{[0-9a-fA-F]+\}|[^'\\])'", text[i:]):
            i += re.match(r"'(?:\\.|\\u\{[0-9a-fA-F]+\}|[^'\\])'", text[i:]).end()
        else:
            out.append(c)
            i += 1
    text = "".join(out)
    out, i = [], 0
    for m in re.finditer(r"#\[cfg\(test\)\]\s*mod\s+\w+\s*\{", text):
        if m.start() < i:
            continue
        out.append(text[i : m.start()])
        depth, j = 1, m.end()
        while j < len(text) and depth:
            depth += {"{": 1, "}": -1}.get(text[j], 0)
            j += 1
        i = j
    out.append(text[i:])
    return "".join(out)


def crate_modules(src: Path) -> dict:
    """Module path (tuple) -> file, for one crate's src folder."""
    mods = {}
    for f in src.rglob("*.rs"):
        rel = f.relative_to(src).with_suffix("")
        parts = list(rel.parts)
        if parts[0] == "bin":
            continue
        if parts[-1] in ("lib", "main", "mod"):
            parts = parts[:-1]
        mods[tuple(parts)] = f
    return mods


def module_of(f: Path, src: Path) -> tuple:
    parts = list(f.relative_to(src).with_suffix("").parts)
    if parts[-1] in ("lib", "main", "mod"):
        parts = parts[:-1]
    return tuple(parts)


def use_paths(tree: str):
    """Expands a use tree `a::{b, c::{d, e}}` into paths."""
    tree = tree.replace(" ", "").replace("\n", "")
    depth, i = 0, tree.find("{")
    if i < 0:
        yield tree.split(" as ")[0]
        return
    prefix, body = tree[:i], tree[i + 1 : tree.rfind("}")]
    items, cur = [], ""
    for ch in body:
        depth += {"{": 1, "}": -1}.get(ch, 0)
        if ch == "," and depth == 0:
            items.append(cur)
            cur = ""
        else:
            cur += ch
    items.append(cur)
    for it in items:
        if it:
            for p in use_paths(it):
                yield prefix + p if p != "self" else prefix.rstrip(":")


def check_crate(src: Path) -> list:
    mods = crate_modules(src)
    texts = {m: strip(f.read_text()) for m, f in mods.items()}
    # Re-exports: (module, name) -> absolute path of what it names.
    reexports = {}
    for m, t in texts.items():
        for u in re.finditer(r"\bpub(?:\([^)]*\))?\s+use\s+([^;]+);", t):
            for p in use_paths(u.group(1)):
                name = p.split("::")[-1].split(" as ")[-1]
                reexports[(m, name)] = absolute(m, p)

    def resolve(path: list, depth=0):
        """Longest module prefix of `path` with a file, following re-exports."""
        for n in range(len(path), -1, -1):
            if tuple(path[:n]) in mods:
                m = tuple(path[:n])
                rest = path[n:]
                if rest and (m, rest[0]) in reexports and depth < 8:
                    return resolve(reexports[(m, rest[0])], depth + 1)
                return m
        return None

    edges = {m: set() for m in mods}
    for m, t in texts.items():
        body = re.sub(r"\bpub(?:\([^)]*\))?\s+use\s+[^;]+;", "", t)
        body = re.sub(r"\bmod\s+\w+\s*;", "", body)
        paths = []
        for u in re.finditer(r"\buse\s+([^;]+);", body):
            paths += list(use_paths(u.group(1)))
        body = re.sub(r"\buse\s+[^;]+;", "", body)
        paths += re.findall(r"\b(?:crate|super|self)(?:::\w+)+", body)
        for p in paths:
            if not p.split("::")[0] in ("crate", "super", "self"):
                continue
            target = resolve(absolute(m, p))
            if target is not None and target != m:
                edges[m].add(target)
    return [(mods, c) for c in cycles(edges)]


def absolute(m: tuple, p: str) -> list:
    parts = [x for x in p.split("::") if x]
    if parts[0] == "crate":
        return parts[1:]
    base = list(m)
    while parts and parts[0] in ("super", "self"):
        if parts.pop(0) == "super":
            base = base[:-1]
    return base + parts


def cycles(edges: dict) -> list:
    """Strongly connected components with more than one file (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(comp)

    sys.setrecursionlimit(10000)
    for v in edges:
        if v not in index:
            visit(v)
    return out


def main() -> int:
    srcs = [p.parent for p in ROOT.glob("**/Cargo.toml") if (p.parent / "src").is_dir()]
    srcs = [s / "src" for s in srcs if "target" not in s.parts and ".venv" not in s.parts]
    found = 0
    for src in sorted(srcs):
        for mods, comp in check_crate(src):
            found += 1
            files = sorted(str(mods[m].relative_to(ROOT)) for m in comp)
            print("import cycle: " + " <-> ".join(files))
    if found:
        return 1
    print(f"no import cycles in {len(srcs)} crates")
    return 0


if __name__ == "__main__":
    sys.exit(main())
