"""tests/conftest.py: the run ends with one line of what was skipped, grouped, and why."""

from __future__ import annotations

from typing import Literal

import pytest

from tests.conftest import skip_groups


def report(
    nodeid: str, outcome: Literal["passed", "failed", "skipped"], reason: str = ""
) -> pytest.TestReport:
    longrepr = (nodeid.split("::")[0], 1, f"Skipped: {reason}") if outcome == "skipped" else None
    return pytest.TestReport(nodeid, (nodeid, 1, "t"), {}, outcome, longrepr, "setup")


def test_skips_are_grouped_by_file_and_reason_most_first() -> None:
    browser = "/usr/bin/chromium is missing (apt-get install chromium)"
    reports = [
        report("tests/a.py::t1", "passed"),
        report("tests/service/test_demo_page.py::t1", "skipped", browser),
        report("tests/service/test_demo_page.py::t2", "skipped", browser),
        report("tests/test_readme.py::t[0]", "skipped", "installs into the environment"),
    ]
    assert skip_groups(reports) == [
        f"2 in tests/service/test_demo_page.py: {browser}",
        "1 in tests/test_readme.py: installs into the environment",
    ]
    assert skip_groups(reports[:1]) == []
