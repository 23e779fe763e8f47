#!/usr/bin/env python3
"""The declared minimum Rust version (workspace `rust-version`) against what the build needs.

No older toolchain can be installed here, so the check is what can be known without one:
every package in the resolved dependency graph (normal and build dependencies of the
workspace, for the host) must declare a `rust-version` no newer than ours; the standard library
APIs our own code uses are checked against it by clippy's `incompatible_msrv` lint (on by
default in `cargo clippy -D warnings`). Exits non-zero naming each package that needs more.
"""
import json
import subprocess
import sys


def version(v):
    return tuple(int(x) for x in v.split(".")[:3]) + (0,) * (3 - len(v.split(".")[:3]))


run = subprocess.run(
    ["cargo", "metadata", "--format-version", "1", "--locked"],
    capture_output=True,
    text=True,
)
if run.returncode != 0:
    print(f"cargo metadata failed:\n{run.stderr}", file=sys.stderr)
    sys.exit(1)
meta = json.loads(run.stdout)
packages = {p["id"]: p for p in meta["packages"]}
members = set(meta["workspace_members"])
declared = {packages[m]["name"]: packages[m].get("rust_version") for m in members}
missing = [n for n, v in declared.items() if not v]
if missing:
    print(f"workspace crates without rust-version: {', '.join(sorted(missing))}", file=sys.stderr)
    sys.exit(1)
ours = max(version(v) for v in declared.values())

# Walk the graph from the workspace members along normal and build dependencies only
# (dev-dependencies of dependencies are not built).
nodes = {n["id"]: n for n in meta["resolve"]["nodes"]}
seen, todo = set(), list(members)
while todo:
    pid = todo.pop()
    if pid in seen:
        continue
    seen.add(pid)
    for dep in nodes[pid]["deps"]:
        kinds = {k["kind"] for k in dep["dep_kinds"]}
        if pid in members or kinds & {None, "build"}:
            todo.append(dep["pkg"])

too_new = []
for pid in sorted(seen):
    p = packages[pid]
    rv = p.get("rust_version")
    if rv and version(rv) > ours:
        too_new.append(f"{p['name']} {p['version']} needs Rust {rv}")
ours_text = ".".join(str(x) for x in ours)
if too_new:
    print(f"declared minimum Rust version {ours_text}, but:", file=sys.stderr)
    for t in too_new:
        print(f"  {t}", file=sys.stderr)
    sys.exit(1)
print(f"minimum Rust version {ours_text}: {len(seen)} packages in the graph, none needs more")
