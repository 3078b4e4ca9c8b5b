"""The rooms of the house import one way (ARCHITECTURE.md): every ``import circuitsim.X`` and
``from circuitsim.X import`` in the package, at module level or inside a function, is read
from the source and checked against what its room may import."""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "circuitsim"

# room -> rooms it must never import (directly or inside a function)
FORBIDDEN = {
    "mechanics": {"netlist", "solver", "synthesis", "compare", "interop", "studies", "bench",
                  "cli"},  # fmt: skip
    "netlist": {"solver", "synthesis", "compare", "interop", "studies", "bench", "cli"},
    "solver": {"synthesis", "compare", "interop", "studies", "bench", "cli"},
    "synthesis": {"compare", "studies", "bench", "cli"},
    "interop": {"compare", "studies", "bench", "cli"},
    "compare": {"studies", "bench", "cli"},
    "studies": {"bench", "cli"},
    "bench": {"cli"},
}


def _imported_rooms(path: Path) -> set[tuple[str, int]]:
    """Rooms of circuitsim a module imports, with the line of each import."""
    tree = ast.parse(path.read_text(), filename=str(path))
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        else:
            continue
        for name in names:
            parts = name.split(".")
            if parts[0] == "circuitsim" and len(parts) > 1:
                found.add((parts[1], node.lineno))
    return found


@pytest.mark.parametrize("room", sorted(FORBIDDEN))
def test_room_imports_only_downstream(room):
    offences = [
        f"{path.relative_to(PACKAGE.parent)}:{line} imports circuitsim.{target}"
        for path in sorted((PACKAGE / room).rglob("*.py"))
        for target, line in sorted(_imported_rooms(path))
        if target in FORBIDDEN[room]
    ]
    assert not offences, "\n".join(offences)


def test_the_checker_sees_a_function_level_import(tmp_path):
    """A lazy import inside a function counts as much as one at the top."""
    module = tmp_path / "m.py"
    module.write_text("def f():\n    from circuitsim.studies.hunting import run\n")
    assert _imported_rooms(module) == {("studies", 2)}
