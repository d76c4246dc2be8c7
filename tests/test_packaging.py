"""Packaging follows the layers: the engine alone by default, the web stack as an extra."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
ENGINE = {"numpy", "scipy", "numba", "opencv-python-headless", "pymaxflow", "av"}
WEB = {"fastapi", "uvicorn", "starlette", "pydantic", "pydantic-settings", "redis", "httpx"}


def names(requirements: list[str]) -> set[str]:
    """Distribution names of requirement strings (no versions, extras or markers)."""
    return {re.split(r"[\s\[<>=!~;]", r, maxsplit=1)[0].lower() for r in requirements}


def test_pip_install_dot_is_the_engine_alone() -> None:
    assert names(PROJECT["dependencies"]) == ENGINE


def test_the_service_extra_adds_the_web_stack_and_the_client() -> None:
    service = names(PROJECT["optional-dependencies"]["service"])
    assert {"fastapi", "uvicorn", "pydantic", "redis", "httpx", "websockets"} <= service
    assert not (service & ENGINE)
    for extra, requirements in PROJECT["optional-dependencies"].items():
        if extra != "service":
            assert not (names(requirements) & WEB), f"[{extra}] carries web packages"


def test_the_command_line_is_its_own_package() -> None:
    assert PROJECT["scripts"] == {"efdm": "efdm_cli:main"}
    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert {"engine*", "service*", "efdm_cli*"} <= set(setuptools["packages"]["find"]["include"])


def test_make_installs_everything() -> None:
    assert ".[service,dev,bench]" in (ROOT / "Makefile").read_text()
