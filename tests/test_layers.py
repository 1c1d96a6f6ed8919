"""The layer rule, read from the source: every module's imports (ast), module-level and local.

Layers, lowest first: core ``pbrcheck`` (0) <- renderers ``reference``, ``realtime``, ``clients`` (1) <- the
comparator ``compare`` (2) <- ``compare.research`` (3) <- ``compare.report`` (4) <- the CLI
(package ``pbrcheck_cli``, the top, outside the core: the one package allowed to import upward, and
no other imports it). A module may import its own layer and
the layers below it; the two renderers never import each other. Any import cycle between modules
is an error too. Each failure names the importing module, the imported one and the line.
"""

from __future__ import annotations

import ast
import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("pbrcheck", "reference", "realtime", "clients", "compare", "pbrcheck_cli")
#: The only package that may import every layer.
ENTRY = "pbrcheck_cli"


def layer(module: str) -> tuple[int, str]:
    """(rank, group) of a project module; renderers share a rank but not a group."""
    if module == ENTRY or module.startswith(ENTRY + "."):
        return 5, "cli"
    if module.startswith("compare.report"):
        return 4, "report"
    if module.startswith("compare.research"):
        return 3, "research"
    if module.startswith("compare"):
        return 2, "compare"
    if module.startswith("reference"):
        return 1, "reference"
    if module.startswith("realtime"):
        return 1, "realtime"
    if module.startswith("clients"):
        return 1, "clients"
    return 0, "core"


#: Folders never walked: a client's own environment (clients/cycles/.venv: Blender's scripts, some
#: 10^4 files) and the engines' npm trees: walking them, then filtering, took ~20 s a test.
SKIPPED_DIRS = ("node_modules", "__pycache__")


def _python_files(top: Path) -> list[Path]:
    found = []
    for d, dirs, files in os.walk(top):
        dirs[:] = [x for x in dirs if not x.startswith(".") and x not in SKIPPED_DIRS]
        found.extend(Path(d) / f for f in files if f.endswith(".py"))
    return sorted(found)


def modules() -> dict[str, Path]:
    out = {}
    for pkg in PACKAGES:
        for p in _python_files(ROOT / pkg):
            rel = p.relative_to(ROOT).with_suffix("")
            parts = list(rel.parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = p
    return out


def imports_of(name: str, path: Path) -> list[tuple[str, int]]:
    """Project modules ``name`` imports (absolute, resolved), with the line."""
    tree = ast.parse(path.read_text(), str(path))
    is_pkg = path.name == "__init__.py"
    base = name.split(".") if is_pkg else name.split(".")[:-1]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(a.name, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                pkg = base[:len(base) - (node.level - 1)]
                mod = ".".join(pkg + ([node.module] if node.module else []))
            else:
                mod = node.module
            out.append((mod, node.lineno))
            out += [(f"{mod}.{a.name}", node.lineno) for a in node.names]  # `from pkg import module`
    known = modules()
    return [(m, line) for m, line in out if m in known and m != name]


def violations(mods: dict[str, Path]) -> list[str]:
    bad = []
    for name, path in mods.items():
        rank, group = layer(name)
        if group == "cli":
            continue
        for dep, line in imports_of(name, path):
            if layer(dep)[1] == "cli":
                bad.append(f"{name} imports the CLI {dep} (line {line})")
                continue
            drank, dgroup = layer(dep)
            if drank > rank:
                bad.append(f"{name} ({group}) imports {dep} ({dgroup}), a higher layer (line {line})")
            elif drank == rank == 1 and dgroup != group:
                bad.append(f"{name} ({group}) imports {dep} ({dgroup}): renderers never import each other "
                           f"(line {line})")
    return bad


def cycles(mods: dict[str, Path]) -> list[list[str]]:
    """Import cycles between modules (a package's ``__init__`` importing its own submodules is not one)."""
    graph = {n: sorted({d for d, _ in imports_of(n, p) if not n.startswith(d + ".") and not d.startswith(n + ".")})
             for n, p in mods.items()}
    found, state, stack = [], {}, []

    def visit(n):
        state[n] = 1
        stack.append(n)
        for d in graph.get(n, ()):
            if state.get(d) == 1:
                found.append(stack[stack.index(d):] + [d])
            elif d not in state:
                visit(d)
        stack.pop()
        state[n] = 2

    for n in graph:
        if n not in state:
            visit(n)
    return found


def test_no_upward_or_sideways_import():
    bad = violations(modules())
    assert not bad, "layer rule broken:\n" + "\n".join(bad)


def test_no_import_cycle():
    found = cycles(modules())
    assert not found, "import cycles:\n" + "\n".join(" -> ".join(c) for c in found)


@pytest.mark.parametrize("source,expect", [
    ("from compare.metrics import compare_images\n", "pbrcheck.scene (core) imports compare.metrics (compare)"),
    ("import realtime.render\n", "pbrcheck.scene (core) imports realtime.render (realtime)"),
    ("from pbrcheck_cli import main\n", "pbrcheck.scene imports the CLI pbrcheck_cli"),
])
def test_the_check_catches_an_upward_import(tmp_path, monkeypatch, source, expect):
    """A core module that imports upward is named with the module it imports."""
    fake = tmp_path / "scene.py"
    fake.write_text((ROOT / "pbrcheck" / "scene.py").read_text() + "\n" + source)
    mods = dict(modules())
    mods["pbrcheck.scene"] = fake
    assert any(v.startswith(expect) for v in violations(mods)), violations(mods)


def test_the_check_catches_a_renderer_importing_the_other_and_a_cycle(tmp_path):
    a = tmp_path / "a.py"
    a.write_text("from reference.render import render_reference\n")
    mods = dict(modules())
    mods["realtime.fake"] = a
    assert any("renderers never import each other" in v for v in violations(mods))
    b = tmp_path / "b.py"
    b.write_text((ROOT / "pbrcheck" / "environment.py").read_text() + "\nimport pbrcheck.cache\n")
    c = tmp_path / "c.py"
    c.write_text((ROOT / "pbrcheck" / "cache.py").read_text() + "\nimport pbrcheck.environment\n")
    mods = dict(modules())
    mods["pbrcheck.environment"], mods["pbrcheck.cache"] = b, c
    assert any("pbrcheck.environment" in cyc and "pbrcheck.cache" in cyc for cyc in cycles(mods)), cycles(mods)


#: The gate package's modules, lowest first: each imports only the ones before it (the budget knows
#: nothing of verdicts, the verdicts nothing of evaluation, the writers nothing of accepting).
GATE_ORDER = ("compare.gate.budget", "compare.gate.verdict", "compare.gate.evaluate", "compare.gate.text",
              "compare.gate.writers", "compare.gate.accept", "compare.gate.run")


def gate_order_violations(mods: dict[str, Path]) -> list[str]:
    bad = []
    for i, name in enumerate(GATE_ORDER):
        for dep, line in imports_of(name, mods[name]):
            d = next((m for m in GATE_ORDER if dep == m or dep.startswith(m + ".")), None)
            if d is not None and GATE_ORDER.index(d) >= i and d != name:
                bad.append(f"{name} imports {d}, a later module of the gate (line {line})")
    return bad


def test_gate_package_modules_import_downward_only(tmp_path):
    mods = modules()
    assert set(GATE_ORDER) == {m for m in mods if m.startswith("compare.gate.")}, "a gate module not in GATE_ORDER"
    bad = gate_order_violations(mods)
    assert not bad, "\n".join(bad)
    fake = tmp_path / "budget.py"  # the check catches a budget that imports the verdicts
    fake.write_text((ROOT / "compare" / "gate" / "budget.py").read_text() + "\nfrom .verdict import Verdict\n")
    mods = {**mods, "compare.gate.budget": fake}
    assert gate_order_violations(mods) == [f"compare.gate.budget imports compare.gate.verdict, a later module of "
                                           f"the gate (line {len(fake.read_text().splitlines())})"]


def test_the_core_holds_no_cli():
    """The command line is its own top-level package: no module of the core parses a command line
    into subcommands or maps errors to exit codes (issue 33: the core held the CLI, the only upward
    arrows of the import graph)."""
    assert not (ROOT / "pbrcheck" / "cli.py").exists() and (ROOT / ENTRY / "__init__.py").is_file()
    for name, path in modules().items():
        if layer(name)[1] != "cli":
            assert "add_subparsers(" not in path.read_text(), name
