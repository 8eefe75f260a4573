#!/usr/bin/env python3
"""Checks that the workspace's stated minimum Rust version is honest.

    python3 scripts/msrv.py

CI cannot install a second toolchain, so the check reads the dependencies' own
`rust-version` fields from `cargo metadata`: every package a workspace crate needs to
build (normal and build dependencies, not dev-dependencies, all features on) must
state a `rust-version` at or below ours. Exits 1 naming the packages that need a newer
compiler.
"""
import json
import subprocess
import sys


def version_key(v):
    return tuple(int(x) for x in (v.split(".") + ["0", "0"])[:3])


def main():
    meta = json.loads(
        subprocess.check_output(
            ["cargo", "metadata", "--format-version", "1", "--all-features", "--locked"]
        )
    )
    packages = {p["id"]: p for p in meta["packages"]}
    members = set(meta["workspace_members"])
    ours = {packages[m].get("rust_version") for m in members}
    if len(ours) != 1 or None in ours:
        sys.exit(f"the workspace crates state different or no rust-version: {sorted(map(str, ours))}")
    ours = ours.pop()
    nodes = {n["id"]: n for n in meta["resolve"]["nodes"]}
    # Everything reachable from the workspace crates through normal and build edges.
    seen, stack = set(), list(members)
    while stack:
        pid = stack.pop()
        if pid in seen:
            continue
        seen.add(pid)
        for dep in nodes[pid]["deps"]:
            kinds = {k["kind"] for k in dep["dep_kinds"]}
            if kinds - {"dev"}:
                stack.append(dep["pkg"])
    needs = sorted(
        (
            (packages[p].get("rust_version") or "0", packages[p]["name"], packages[p]["version"])
            for p in seen - members
        ),
        key=lambda x: version_key(x[0]),
    )
    newest = needs[-1] if needs else ("0", "-", "-")
    too_new = [n for n in needs if version_key(n[0]) > version_key(ours)]
    print(f"rust-version {ours}; the newest a dependency needs: {newest[0]} ({newest[1]} {newest[2]})")
    if too_new:
        for v, name, ver in too_new:
            print(f"  {name} {ver} needs Rust {v}", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
