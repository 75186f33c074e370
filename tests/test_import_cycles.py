"""No import circle among the modules of crowd/, sim/, lod/ and render/ (issue 33), and the layering of
shared/ARCHITECTURE.md and docs/architecture.md: crowd -> sim, lod, render; lod -> sim; render -> lod (not sim: the
renderer hands over pixels, files are crowd's); sim imports none of them, nothing imports crowd.

The imports are read from the source (ast), every ``import`` and ``from ... import`` anywhere in a module, inside
functions too: a lazy import hides a circle, it does not remove it. Package ``__init__`` files are left out of the
graph (they list and re-export their modules); a name imported from a package resolves to its module when there is
one (``from lod.points import config`` -> ``lod.points.config``)."""
import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("crowd", "sim", "lod", "render")
#: which packages each package may import (the layers of docs/architecture.md)
MAY_IMPORT = {"crowd": {"crowd", "sim", "lod", "render"}, "sim": {"sim"}, "lod": {"lod", "sim"},
              "render": {"render", "lod"}}


def modules(root: Path, packages) -> dict:
    """module name -> (path, is a package __init__)."""
    out = {}
    for pkg in packages:
        for p in sorted((root / pkg).rglob("*.py")):
            parts = list(p.relative_to(root).with_suffix("").parts)
            init = parts[-1] == "__init__"
            if init:
                parts = parts[:-1]
            out[".".join(parts)] = (p, init)
    return out


def import_graph(root: Path, packages) -> dict:
    """module -> set of project modules it imports (``__init__`` files neither sources nor targets)."""
    mods = modules(root, packages)
    graph = {m: set() for m, (_, init) in mods.items() if not init}
    for m in graph:
        path = mods[m][0]
        pkg = m.rsplit(".", 1)[0]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:  # relative: from the module's package up
                    up = pkg.split(".")[: len(pkg.split(".")) - node.level + 1]
                    base = ".".join(up + ([base] if base else []))
                names = [base] + [f"{base}.{a.name}" for a in node.names]
            for n in names:
                if n in graph and n != m:
                    graph[m].add(n)
    return graph


def cycles(graph: dict) -> list:
    """The strongly connected components of more than one module (Tarjan's algorithm, iterative), sorted."""
    index, low, on, stack, out = {}, {}, set(), [], []
    counter = 0
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on.add(start)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        out.append(sorted(comp))
    return sorted(out)


def test_no_import_circle_in_the_project():
    graph = import_graph(ROOT, PACKAGES)
    assert len(graph) > 150  # the walk found the project's modules
    found = cycles(graph)
    assert not found, "import circles: " + "; ".join(" <-> ".join(c) for c in found)


def test_no_import_from_a_layer_above():
    graph = import_graph(ROOT, PACKAGES)
    bad = sorted(f"{m} imports {t}" for m, ts in graph.items() for t in ts
                 if t.split(".")[0] not in MAY_IMPORT[m.split(".")[0]])
    assert not bad, "; ".join(bad)


def test_a_circle_is_found(tmp_path):
    """The walk fails on a circle: a lazy import inside a function, a relative import and a three-module ring."""
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("from pkg import a\n")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from pkg.sub import b\n")
    (pkg / "sub" / "b.py").write_text("def f():\n    from ..c import g\n    return g\n")
    (pkg / "c.py").write_text("import pkg.a\n\ndef g():\n    return 1\n")
    (pkg / "d.py").write_text("from pkg import c\n")
    graph = import_graph(tmp_path, ("pkg",))
    assert cycles(graph) == [["pkg.a", "pkg.c", "pkg.sub.b"]]
    (pkg / "c.py").write_text("def g():\n    return 1\n")
    assert cycles(import_graph(tmp_path, ("pkg",))) == []
