"""Layering: sessions, stores and frame decoding know nothing of HTTP.

They raise domain errors (:mod:`service.domain_errors`); only the web layer
(:mod:`service.errors`, the routes) knows statuses.  The client imports no web
framework either.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

SERVICE = Path(__file__).resolve().parents[2] / "service"
DOMAIN_MODULES = [
    "sessions.py",
    "store.py",
    "redis_store.py",
    "images.py",
    "image_types.py",
    "domain_errors.py",
]
WEB = ("fastapi", "starlette", "service.errors", "service.deps", "service.routes")


def imported_modules(tree: ast.AST) -> set[str]:
    """Every module an ``import`` or ``from ... import`` of ``tree`` names."""
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module is not None:
            names.add(node.module)
    return names


def is_web(module: str) -> bool:
    return any(module == w or module.startswith(w + ".") for w in WEB)


@pytest.mark.parametrize("name", DOMAIN_MODULES)
def test_domain_modules_import_no_web_code(name: str) -> None:
    tree = ast.parse((SERVICE / name).read_text(), filename=name)
    assert sorted(m for m in imported_modules(tree) if is_web(m)) == []


@pytest.mark.parametrize("name", DOMAIN_MODULES)
def test_domain_modules_name_no_http_error(name: str) -> None:
    tree = ast.parse((SERVICE / name).read_text(), filename=name)
    used = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
    used |= {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)}
    assert not used & {"ApiError", "HTTPException", "as_api_error"}


def test_the_parser_sees_web_imports() -> None:
    """The checks above would catch a web import (they are not vacuous)."""
    tree = ast.parse("import fastapi\nfrom service.errors import ApiError\n")
    assert sorted(m for m in imported_modules(tree) if is_web(m)) == [
        "fastapi",
        "service.errors",
    ]


def test_domain_and_client_import_without_the_web_framework() -> None:
    """Transitively too: with FastAPI and Starlette unimportable, these still import."""
    code = (
        "import sys\n"
        "sys.modules.update(fastapi=None, starlette=None)\n"
        "import service.sessions, service.store, service.redis_store, service.images\n"
        "import service.client\n"
        "from service.client._common import media_type\n"
        "assert media_type(b'\\x89PNG\\r\\n\\x1a\\n') == 'image/png'\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code],
        cwd=SERVICE.parent,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr
