"""The engine's layers: the web service and the command line sit above it, never inside.

Checked on the source (every ``import`` statement of every module under
``engine/``) and at run time (importing every engine module loads no web
module).
"""

from __future__ import annotations

import ast
import json
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest

import engine

ENGINE = Path(engine.__file__).parent
ABOVE = ("service", "efdm_cli", "fastapi", "starlette", "uvicorn", "pydantic", "redis", "bench")
"""Packages the engine must not import: the layers above it and the web stack."""
LAYERS = {"physics": 0, "geometry": 1, "tracking": 2}
"""The engine's own order: a sub-package imports only those before it (testing sits above all)."""


def imported(path: Path) -> set[str]:
    """Every module name an ``import`` or ``from ... import`` of the file names."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return names


SOURCES = sorted(ENGINE.rglob("*.py"))


def test_the_engine_has_its_three_layers() -> None:
    assert {p.name for p in ENGINE.iterdir() if (p / "__init__.py").exists()} >= set(LAYERS)


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(ENGINE)))
def test_no_engine_module_imports_a_layer_above(path: Path) -> None:
    above = {n for n in imported(path) if n.split(".")[0] in ABOVE}
    assert not above, f"{path.relative_to(ENGINE)} imports {sorted(above)}"


@pytest.mark.parametrize(
    "path",
    [p for p in SOURCES if p.relative_to(ENGINE).parts[0] in LAYERS],
    ids=lambda p: str(p.relative_to(ENGINE)),
)
def test_sub_packages_import_only_the_layers_below(path: Path) -> None:
    own = LAYERS[path.relative_to(ENGINE).parts[0]]
    for name in imported(path):
        parts = name.split(".")
        if parts[0] == "engine" and len(parts) > 1 and parts[1] in LAYERS:
            assert LAYERS[parts[1]] <= own, f"{path.relative_to(ENGINE)} imports {name}"
        assert parts[:2] != ["engine", "testing"], f"{path.relative_to(ENGINE)} imports {name}"


def test_importing_every_engine_module_loads_no_web_module() -> None:
    names = [m.name for m in pkgutil.walk_packages([str(ENGINE)], "engine.")]
    code = (
        "import importlib, json, sys\n"
        f"for name in {names!r}:\n"
        "    importlib.import_module(name)\n"
        f"print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in {ABOVE!r})))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert json.loads(out) == []
