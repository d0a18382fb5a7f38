"""The house's rules (issue 35), read from the code: imports point down only (no circle, function-local
imports included), the decoder never imports the encoder's search, no module above 600 lines and no
function above 120."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "bandelets"
#: What a decoder must never load: the encoder's search and the encoder's own modules.
ENCODER_SIDE = (
    "bandelets.search",
    "bandelets.codec.encoder",
    "bandelets.codec.piece",
    "bandelets.codec.plan",
    "bandelets.codec.alternatives",
    "bandelets.codec.at_threshold",
    "bandelets.codec.restoring",
    "bandelets.codec.tile_encoder",
)


def _module_of(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path) -> set[str]:
    """The package's modules ``path`` imports, wherever the import stands (function-local ones too)."""
    module = _module_of(path)
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            names = [target + "." + alias.name for alias in node.names]
        elif isinstance(node, ast.Import):
            target, names = "", [alias.name for alias in node.names]
        else:
            continue
        for name in [*names, target]:
            if name.startswith("bandelets") and _file_of(name) is not None:
                found.add(name)
                break
    return found - {module}


def _file_of(module: str) -> Path | None:
    base = PACKAGE.parent.joinpath(*module.split("."))
    for candidate in (base.with_suffix(".py"), base / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


def _graph() -> dict[str, set[str]]:
    return {_module_of(path): _imports(path) for path in PACKAGE.rglob("*.py")}


def test_the_imports_make_no_circle():
    graph = _graph()
    state: dict[str, int] = {}

    def visit(module: str, trail: list[str]) -> None:
        state[module] = 1
        for other in sorted(graph.get(module, ())):
            if state.get(other) == 1:
                pytest.fail("import circle: " + " -> ".join([*trail[trail.index(other) :], other]))
            if other not in state:
                visit(other, [*trail, other])
        state[module] = 2

    for module in sorted(graph):
        if module not in state:
            visit(module, [module])


def test_the_decoder_never_imports_the_encoders_search():
    graph, closure, todo = _graph(), set(), ["bandelets.codec.decoder"]
    while todo:
        module = todo.pop()
        if module not in closure:
            closure.add(module)
            todo.extend(graph.get(module, ()))
    assert "bandelets.format.header" in closure  # the walk went somewhere
    assert not [m for m in closure if m.startswith(ENCODER_SIDE)]


@pytest.mark.parametrize("path", sorted(PACKAGE.rglob("*.py")), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_rooms_and_functions_are_short(path: Path):
    source = path.read_text()
    assert source.count("\n") <= 600, f"{path.name} has {source.count(chr(10))} lines"
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            length = node.end_lineno - node.lineno + 1
            assert length <= 120, f"{path.name}: {node.name} is {length} lines"
