"""``python -m bench.tracking.objects``: its report (the run itself is a minute of tracking)."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from bench.tracking import objects


def test_the_report_gives_ratios_and_the_worst_object() -> None:
    results = {
        "seed 0": {
            "iou": [0.99, 0.75],
            "swaps": 0,
            "alone_ms": 4.0,
            "together_ms": 32.0,
            "two_threads_ms": 20.0,
            "two_processes_ms": 18.0,
        }
    }
    report = objects.render(results, 12.0)
    row = "| seed 0 | 0.99 0.75 | 0.75 | 0 | 4.0 | 32.0 (8.00x) | 20.0 (5.00x) | 18.0 (4.50x) |"
    assert row in report


def test_a_ratio_just_over_the_goal_is_not_shown_as_the_goal() -> None:
    ms = {"alone_ms": 3.4866, "together_ms": 21.075, "two_threads_ms": 20.8}
    results = {"seed 0": {"iou": [0.99], "swaps": 0, **ms, "two_processes_ms": 16.7}}
    assert "21.1 (6.04x)" in objects.render(results, 1.0)


def test_every_way_is_timed_once_a_pass_in_turn_and_the_fastest_pass_counts(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    calls: list[str] = []
    timings = {"alone": iter([5.0, 4.0]), "together": iter([30.0, 33.0])}

    def fake_pass(make: Callable[[], str], frames: tuple[object, ...]) -> float:
        name = make()
        calls.append(name)
        return next(timings[name])

    monkeypatch.setattr(objects, "_pass_ms", fake_pass)
    makers: dict[str, Callable[[], object]] = {
        "alone": lambda: "alone",
        "together": lambda: "together",
    }
    best = objects._fastest_ms(makers, ())
    assert calls == ["alone", "together", "together", "alone"][: 2 * objects.PASSES]
    assert best == {"alone": 4.0, "together": 30.0}
