#!/usr/bin/env python3
"""Checks penumbra's layering: no import cycle between source files, no import from a lower layer
to a higher one, every top-level module on a floor, and the floors of docs/ARCHITECTURE.md
("Layers") in the order of LAYERS below.

Reads `src/**/*.rs` as text: every `crate::a::b…` path, every `super::…` path and every path that
starts with a child module of the file becomes an edge to the deepest file that exists for it.
A parent module's edges to its own children (`mod x;`, `pub use x::…`: the module's face) are
not counted. Comments and doc comments are skipped.

Usage: python3 tools/check_layers.py [--graph]   (exit 1 on a violation)
"""

import pathlib
import re
import sys

SRC = pathlib.Path(__file__).resolve().parent.parent / "src"

# Top-level library modules from the top floor down; a module may use those listed after it.
# Modules on one line form one floor (they may not use each other in both directions: the cycle
# check catches that).
LAYERS = [
    ["scenario"],
    ["products"],
    ["compute"],
    ["gpu"],
    ["twins"],
    ["render"],
    ["model"],
    ["shadow", "horizon"],
    ["terrain", "illum", "comms"],
    ["output"],
    ["ephem"],
    ["frames"],
    ["lib"],
]
RANK = {m: len(LAYERS) - i for i, floor in enumerate(LAYERS) for m in floor}


def module_of(path: pathlib.Path) -> tuple:
    rel = path.relative_to(SRC).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "mod":
        parts = parts[:-1]
    if parts == ["lib"]:
        return ()
    return tuple(parts)


def file_of(module: tuple, files: dict):
    """The file that defines `module` or its deepest existing ancestor."""
    while module and module not in files:
        module = module[:-1]
    return module


def strip_comments(text: str) -> str:
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    return "\n".join(line.split("//")[0] for line in text.splitlines())


def paths_in_use(text: str):
    """Yields every path of `use` trees and every inline `crate::`/`super::` path."""
    for m in re.finditer(r"\buse\s+([^;]+);", text):
        yield from expand(m.group(1).replace("\n", " "))
    for m in re.finditer(r"\b((?:crate|super|self)(?:::\w+)+)", text):
        yield m.group(1)


def expand(tree: str, prefix: str = ""):
    tree = tree.strip()
    if "{" not in tree:
        for part in tree.split(","):
            part = part.strip().split(" as ")[0].strip()
            if part:
                yield prefix + part
        return
    head, _, rest = tree.partition("{")
    body = rest[: rest.rfind("}")]
    depth, start, items = 0, 0, []
    for i, ch in enumerate(body):
        if ch == "{":
            depth += 1
        elif ch == "}":
            depth -= 1
        elif ch == "," and depth == 0:
            items.append(body[start:i])
            start = i + 1
    items.append(body[start:])
    for item in items:
        if item.strip():
            yield from expand(item, prefix + head.strip())


ARCHITECTURE = SRC.parent / "docs" / "ARCHITECTURE.md"
# Names of the layer block that are not library modules (the binding, the binary).
OUTSIDE = {"python", "main", "cli"}


def documented_floors() -> list:
    """The floors of the ```text block under "## Layers" in docs/ARCHITECTURE.md: per line, the
    leading names written `name/` or `name.rs`."""
    text = ARCHITECTURE.read_text()
    section = text.split("## Layers", 1)[1]
    block = section.split("```text", 1)[1].split("```", 1)[0]
    floors = []
    for line in block.splitlines():
        names = []
        for word in line.split():
            m = re.fullmatch(r"([a-z_]+)(/|\.rs)", word)
            if not m:
                break
            names.append(m.group(1))
        names = [n for n in names if n not in OUTSIDE]
        if names:
            floors.append(names)
    return floors


def main() -> int:
    files = {}
    for p in SRC.rglob("*.rs"):
        if p.name == "main.rs" or "cli" in p.relative_to(SRC).parts:
            continue  # the binary
        files[module_of(p)] = p
    children = {m: {c[-1] for c in files if c[:-1] == m and c} for m in files}
    edges = {m: set() for m in files}
    for mod, path in files.items():
        text = strip_comments(path.read_text())
        is_dir_module = path.name in ("mod.rs", "lib.rs")
        here = mod if is_dir_module else mod  # the module's own path
        for raw in paths_in_use(text):
            parts = [x for x in raw.split("::") if x]
            if not parts:
                continue
            if parts[0] == "crate":
                target = tuple(parts[1:])
            elif parts[0] == "super":
                base = list(here)
                while parts and parts[0] == "super":
                    base = base[:-1]
                    parts = parts[1:]
                target = tuple(base + parts)
            elif parts[0] == "self":
                target = tuple(list(here) + parts[1:])
            elif parts[0] in children.get(mod, ()):
                target = tuple(list(here) + parts)
            else:
                continue
            dest = file_of(target, files)
            if dest == mod or dest is None:
                continue
            if dest[:-1] == mod:
                continue  # a parent's face: `mod x;` / `pub use x::…`
            if mod[: len(dest)] == dest and dest != ():
                pass  # a child using its parent's items: a real edge
            edges[mod].add(dest)
    bad = []
    # Every top-level module on a floor, every floor a module, the documented floors in order.
    tops = {m[0] for m in files if m}
    listed = {m for floor in LAYERS for m in floor if m != "lib"}
    for m in sorted(tops - listed):
        bad.append(f"src/{m}: a top-level module that LAYERS does not place")
    for m in sorted(listed - tops):
        bad.append(f"LAYERS names '{m}', which is not a module of src/")
    expected = [sorted(floor) for floor in LAYERS if floor != ["lib"]]
    written = [sorted(floor) for floor in documented_floors()]
    if written != expected:
        bad.append(
            f"docs/ARCHITECTURE.md's layer list {written} differs from LAYERS {expected}"
        )
    # Upward imports between top-level modules.
    for a, outs in edges.items():
        top_a = a[0] if a else "lib"
        for b in outs:
            top_b = b[0] if b else "lib"
            if top_a == top_b:
                continue
            if top_a not in RANK or top_b not in RANK:
                bad.append(f"{files[a]}: module '{top_a}' or '{top_b}' is missing from LAYERS")
            elif RANK[top_b] > RANK[top_a]:
                bad.append(f"upward import: {files[a].relative_to(SRC.parent)} -> {files[b].relative_to(SRC.parent)}")
    # Cycles between files (Tarjan).
    index, low, stack, on, sccs, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges[v]:
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
                sccs.append(comp)

    sys.setrecursionlimit(10000)
    for v in files:
        if v not in index:
            visit(v)
    for comp in sccs:
        names = ", ".join(str(files[m].relative_to(SRC.parent)) for m in comp)
        bad.append(f"import cycle: {names}")
    if "--graph" in sys.argv:
        for a in sorted(edges):
            print(files[a].relative_to(SRC.parent), "->",
                  ", ".join(sorted(str(files[b].relative_to(SRC.parent)) for b in edges[a])))
    n_edges = sum(len(v) for v in edges.values())
    if bad:
        print("\n".join(bad))
        print(f"check_layers: {len(bad)} violation(s) in {len(files)} files, {n_edges} imports")
        return 1
    print(f"check_layers: {len(files)} files, {n_edges} imports, no cycle, nothing imports upward")
    return 0


if __name__ == "__main__":
    sys.exit(main())
