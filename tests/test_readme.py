"""The README's Python examples run as written."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
# Python blocks run as written, except those right after a "<!-- not run ... -->"
# comment (they need a server or data the tests do not have).
BLOCKS = [
    code
    for marker, code in re.findall(
        r"(<!-- not run[^>]*-->\n)?```python\n(.*?)```", README.read_text(), flags=re.DOTALL
    )
    if not marker
]


def test_readme_has_python_examples() -> None:
    assert BLOCKS


@pytest.mark.parametrize("code", BLOCKS, ids=[f"block{i}" for i in range(len(BLOCKS))])
def test_readme_example_runs(code: str) -> None:
    exec(compile(code, str(README), "exec"), {})
