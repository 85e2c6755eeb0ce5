"""The package's layering, read from the source (ast): no import from a higher layer, no private
name of another package, no import cycle at import time. The layers are documented in
docs/internals.md ("Layers"); a failure names the module, the line and the import."""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
PACKAGE = SRC / "socialnav"

#: Lowest first. A module belongs to the unit with the longest matching prefix; a unit may import
#: only units of a lower layer (units of one layer are independent of each other). Imports inside
#: a unit are free, and so is a package's ``__init__`` re-exporting its own submodules (its API).
LAYERS: list[dict[str, tuple[str, ...]]] = [
    {"io": ("socialnav._io", "socialnav._runtime", "socialnav._progress", "socialnav._core",
            "socialnav.plugins", "socialnav.settings"),
     "data": ("socialnav.checkpoints", "socialnav.configs")},
    {"maps": ("socialnav.maps",)},
    {"scenarios": ("socialnav.scenarios",)},
    {"trajectory": ("socialnav.trajectory", "socialnav.trajectory_io")},
    {"metrics": ("socialnav.metrics",)},
    {"sim": ("socialnav.sim",)},
    {"presets": ("socialnav.presets",)},
    {"envs": ("socialnav.envs",)},
    {"policies": ("socialnav.policies", "socialnav.integrations")},
    {"evaluate": ("socialnav.evaluate",)},
    {"train": ("socialnav.train",), "logs": ("socialnav.logs",)},
    {"sweep": ("socialnav.sweep",), "viz": ("socialnav.viz",)},
    {"cli": ("socialnav.cli", "socialnav.__main__")},
]
#: The package root wires the layers together (env ids, the env's viewer); importing it (for
#: ``__version__``) is allowed from anywhere, and its own imports are not checked.
ROOT = "socialnav"
#: Private by name, shared by every package on purpose: the I/O and runtime layer, the C++ core.
SHARED_PRIVATE = ("socialnav._io", "socialnav._runtime", "socialnav._progress", "socialnav._core")
#: A package whose API keeps the public path of names that live higher up: ``socialnav.sim`` gives the
#: Gymnasium envs' names (``from socialnav.sim import SocialNavEnv``), which live in ``socialnav.envs``.
#: Only the package's ``__init__``, only lazily (its ``_EXPORTS`` strings; the imports for type checkers
#: are not run), so importing the lower package never imports the higher one.
API_REEXPORTS = {"socialnav.sim": ("socialnav.envs",)}


@dataclass(frozen=True)
class Import:
    module: str  # the importing module
    target: str  # the module imported (for ``from M import name``: M, or M.name if that is a module)
    names: tuple[str, ...]  # the names taken from it
    line: int
    at_import_time: bool  # at module level (not in a function, not under TYPE_CHECKING)


def module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def all_modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


MODULES = all_modules()


def resolve(module: str, node: ast.ImportFrom) -> str:
    if node.level == 0:
        return node.module or ""
    base = module.split(".")
    is_package = MODULES.get(module, Path()).name == "__init__.py"
    base = base[: len(base) - node.level + (1 if is_package else 0)]
    return ".".join(base + ([node.module] if node.module else []))


def imports_of(module: str, path: Path) -> list[Import]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out: list[Import] = []

    def visit(node: ast.AST, top: bool) -> None:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            top = False
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            top = False
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith(ROOT):
                    out.append(Import(module, alias.name, (), node.lineno, top))
        elif isinstance(node, ast.ImportFrom):
            target = resolve(module, node)
            if target.startswith(ROOT):
                for alias in node.names:
                    sub = f"{target}.{alias.name}"
                    if sub in MODULES or sub in SHARED_PRIVATE:
                        out.append(Import(module, sub, (), node.lineno, top))
                    else:
                        out.append(Import(module, target, (alias.name,), node.lineno, top))
        for child in ast.iter_child_nodes(node):
            visit(child, top)

    visit(tree, True)
    return out


def unit_of(module: str) -> tuple[str, int] | None:
    best: tuple[int, str, int] | None = None
    for rank, layer in enumerate(LAYERS):
        for unit, prefixes in layer.items():
            for prefix in prefixes:
                if module == prefix or module.startswith(prefix + "."):
                    if best is None or len(prefix) > best[0]:
                        best = (len(prefix), unit, rank)
    return None if best is None else (best[1], best[2])


def top_package(module: str) -> str:
    return ".".join(module.split(".")[:2])


ALL_IMPORTS = [imp for module, path in MODULES.items() for imp in imports_of(module, path)]


def test_every_module_has_a_layer():
    missing = sorted(m for m in MODULES if m != ROOT and unit_of(m) is None)
    assert all(unit_of(m) is not None for m in SHARED_PRIVATE)
    assert not missing, f"modules in no layer (add them to LAYERS and docs/internals.md): {missing}"


def test_no_import_from_a_higher_layer():
    bad = []
    for imp in ALL_IMPORTS:
        if imp.module == ROOT or imp.target == ROOT:
            continue
        if MODULES[imp.module].name == "__init__.py" and imp.target.startswith(imp.module + "."):
            continue  # the package's API
        if not imp.at_import_time and imp.target.startswith(API_REEXPORTS.get(imp.module, ("-",))):
            continue  # a public path kept, loaded lazily
        (unit, rank), (target_unit, target_rank) = unit_of(imp.module), unit_of(imp.target)
        if unit != target_unit and target_rank >= rank:
            bad.append(f"{imp.module}:{imp.line} ({unit}, layer {rank}) imports {imp.target} "
                       f"({target_unit}, layer {target_rank})")
    assert not bad, "imports from the same or a higher layer:\n" + "\n".join(bad)


def test_no_private_name_of_another_package():
    bad = []
    for imp in ALL_IMPORTS:
        if top_package(imp.module) == top_package(imp.target) or imp.target.startswith(SHARED_PRIVATE):
            continue
        private_module = [p for p in imp.target.split(".")[1:] if p.startswith("_") and p != "__init__"]
        private_names = [n for n in imp.names if n.startswith("_") and not n.startswith("__")]
        if private_module or private_names:
            bad.append(f"{imp.module}:{imp.line} imports {imp.target} {', '.join(imp.names)}")
    assert not bad, "private names used across packages:\n" + "\n".join(bad)


def test_no_private_attribute_of_another_package():
    """``from socialnav.evaluate import runner`` then ``runner._scoring_pool``: the same defect."""
    bad = []
    for module, path in MODULES.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        aliases = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                target = resolve(module, node)
                for alias in node.names:
                    sub = f"{target}.{alias.name}"
                    if sub in MODULES and top_package(sub) != top_package(module):
                        aliases[alias.asname or alias.name] = sub
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                    and node.value.id in aliases and node.attr.startswith("_")
                    and not node.attr.startswith("__")
                    and not aliases[node.value.id].startswith(SHARED_PRIVATE)):
                bad.append(f"{module}:{node.lineno} uses {aliases[node.value.id]}.{node.attr}")
    assert not bad, "private attributes used across packages:\n" + "\n".join(bad)


def test_no_import_cycle_at_import_time():
    graph: dict[str, set[str]] = {}
    for imp in ALL_IMPORTS:
        if imp.at_import_time and imp.target in MODULES and imp.target != imp.module:
            graph.setdefault(imp.module, set()).add(imp.target)
    cycles = []
    state: dict[str, int] = {}
    stack: list[str] = []

    def walk(node: str) -> None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                cycles.append(" -> ".join(stack[stack.index(nxt):] + [nxt]))
            elif nxt not in state:
                walk(nxt)
        stack.pop()
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            walk(node)
    assert not cycles, "import cycles at import time:\n" + "\n".join(cycles)


def test_the_layer_test_sees_violations(tmp_path):
    """The checks above would fail on the defects they exist for (they are not vacuous)."""
    fake = Import("socialnav.sim.world", "socialnav.viz.draw", ("FrameRenderer",), 1, True)
    (unit, rank), (target_unit, target_rank) = unit_of(fake.module), unit_of(fake.target)
    assert unit != target_unit and target_rank >= rank
    assert unit_of("socialnav.envs.single") == ("envs", 7) and unit_of("socialnav.sim.world") == ("sim", 5)
    assert Import("socialnav.sweep.x", "socialnav._core", (), 1, True) in [
        imp for imp in imports_of("socialnav.sweep.x", _written(tmp_path, "from socialnav import _core\n"))
    ]
    assert len(ALL_IMPORTS) > 300


def _written(folder: Path, text: str) -> Path:
    path = folder / "x.py"
    path.write_text(text)
    return path
