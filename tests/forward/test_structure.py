"""Facts of the physics package anyone can check: its modules import one another without
a cycle, no private name crosses a module, and it never imports lidarinv."""

import ast
import graphlib
from pathlib import Path

FORWARD = Path(__file__).resolve().parents[2] / "forward"


def _modules():
    """Dotted name → parsed source of every module of the package."""
    out = {}
    for path in FORWARD.rglob("*.py"):
        parts = path.relative_to(FORWARD.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = (ast.parse(path.read_text()), path.name == "__init__.py")
    return out


def _imports(name, tree, is_package):
    """(module imported, names taken from it) of every import of package modules."""
    here = name.split(".") if is_package else name.split(".")[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            base = here[: len(here) - node.level + 1] if node.level else []
            target = ".".join(base + ([node.module] if node.module else []))
            yield target, [alias.name for alias in node.names]
        elif isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, []


def test_forward_imports_form_no_cycle_and_never_reach_lidarinv():
    modules = _modules()
    graph = {}
    for name, (tree, is_package) in modules.items():
        graph[name] = set()
        for target, names in _imports(name, tree, is_package):
            assert not target.startswith("lidarinv"), f"{name} imports {target}"
            for taken in names:  # a submodule taken from a package is an arrow to it
                if f"{target}.{taken}" in modules:
                    graph[name].add(f"{target}.{taken}")
                elif target in modules:
                    graph[name].add(target)
    # a package importing its own submodules is its layout, not a cycle
    arrows = {a: {b for b in bs if not a.startswith(b + ".")} for a, bs in graph.items()}
    graphlib.TopologicalSorter(arrows).prepare()  # raises CycleError on a cycle


def test_no_private_name_crosses_a_module_of_forward():
    crossing = [
        f"{name} imports {target}.{taken}"
        for name, (tree, is_package) in _modules().items()
        for target, names in _imports(name, tree, is_package)
        if target.startswith("forward")
        for taken in names
        if taken.startswith("_")
    ]
    assert crossing == []
