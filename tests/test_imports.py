"""The package's import structure: Drake stays out of the pure layers, and no module imports
itself back through others (not even inside a function)."""

import ast
import subprocess
import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "mog_drake"


# The layers below the systems, whole, and the modules elsewhere that say they are Drake-free.
PURE = ("geometry", "scenes", "perception", "planning")
PURE_MODULES = ("mog_drake.sim.realism", "mog_drake.experiments.stats", "mog_drake.files", "mog_drake.errors")


def test_the_pure_layers_never_load_pydrake():
    """Every module of geometry, scenes, perception and planning (globbed: a new one is
    checked too), and the Drake-free modules elsewhere, import without pydrake."""
    modules = [_module_name(p) for layer in PURE for p in sorted((PACKAGE / layer).glob("*.py"))]
    modules += list(PURE_MODULES)
    code = (
        "import importlib, sys\n"
        f"for m in {modules!r}: importlib.import_module(m)\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] == 'pydrake'))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]" and len(modules) > 30


def test_no_private_name_is_imported_from_another_module():
    """A name another module needs is public: no ``from mog_drake.x import _name``."""
    found = []
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("mog_drake"):
                found += [f"{_module_name(path)}: {a.name}" for a in node.names if a.name.startswith("_")]
    assert not found, found


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports(path: Path, modules: set[str]) -> set[str]:
    """Every project module ``path`` imports, at the top or inside a function."""
    me = _module_name(path)
    package = me if path.name == "__init__.py" else me.rsplit(".", 1)[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(
                    package.split(".")[: len(package.split(".")) - node.level + 1] + ([base] if base else [])
                )
            # "from pkg import sub" imports the submodule pkg.sub when there is one.
            names = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
        else:
            continue
        out.update(n for n in names if n in modules and n != me)
    return out


def test_no_import_cycle_anywhere_in_the_package():
    files = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph = {m: _imports(p, set(files)) for m, p in files.items()}
    cycles, state = [], {}

    def visit(m, stack):
        state[m] = "open"
        for n in sorted(graph[m]):
            if state.get(n) == "open":
                cycles.append(stack[stack.index(n) :] + [n])
            elif n not in state:
                visit(n, [*stack, n])
        state[m] = "done"

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])
    assert not cycles, "\n".join(" -> ".join(c) for c in cycles)


def test_the_scenario_imports_nothing_from_the_systems():
    """Configuration is data: `mog_drake.scenario` and `mog_drake.config` lie below the
    systems they configure, never above."""
    files = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    for name in ("mog_drake.scenario", "mog_drake.config"):
        upward = sorted(m for m in _imports(files[name], set(files)) if m.startswith("mog_drake.systems"))
        assert upward == [], (name, upward)


def test_no_function_takes_more_than_six_positional_parameters():
    """Past six, a call reads as a row of values: the rest are keyword-only."""
    found = []
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef):
                names = [
                    a.arg for a in node.args.posonlyargs + node.args.args if a.arg not in ("self", "cls")
                ]
                if len(names) > 6:
                    found.append(f"{_module_name(path)}.{node.name}: {len(names)}")
    assert not found, found
