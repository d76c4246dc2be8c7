"""The whole suite: one closing line that names what was skipped and why.

``-ra`` (pyproject) already lists each skipped test; a person reading the end
of ``make test`` wants the groups: which files skipped how many tests, and the
reason, e.g. ``skipped 6 in tests/service/test_demo_page.py: /usr/bin/chromium
is missing (apt-get install chromium)``.
"""

from __future__ import annotations

from collections import Counter

import pytest


def skip_groups(reports: list[pytest.TestReport]) -> list[str]:
    """``"N in FILE: REASON"`` per (file, reason), most skipped first."""
    groups: Counter[tuple[str, str]] = Counter()
    for report in reports:
        if not report.skipped or not isinstance(report.longrepr, tuple):
            continue
        where = report.nodeid.split("::", 1)[0]
        reason = str(report.longrepr[2]).removeprefix("Skipped: ")
        groups[where, reason] += 1
    return [f"{n} in {where}: {reason}" for (where, reason), n in groups.most_common()]


def pytest_unconfigure(config: pytest.Config) -> None:
    """End the run, after pytest's own summary, with one line of the skipped groups."""
    reporter = config.pluginmanager.get_plugin("terminalreporter")
    if reporter is None:
        return
    groups = skip_groups(reporter.stats.get("skipped", []))
    if groups:
        reporter.write_line("skipped " + "; ".join(groups), yellow=True, bold=True)
