"""``python -m bench.tracking.objects``: its report (the run itself is a minute of tracking)."""

from __future__ import annotations

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
    row = "| seed 0 | 0.99 0.75 | 0.75 | 0 | 4.0 | 32.0 (8.0x) | 20.0 (5.0x) | 18.0 (4.5x) |"
    assert row in report
