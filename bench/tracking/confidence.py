"""Lost detection on sequences the confidence model was not fitted on.

``python -m bench.tracking.confidence [--quick] [--out DIR]`` tracks the thirty DAVIS-2016
training sequences and the five validation ones with the default tracker, from every node
count of the cross-validation (:data:`NODE_COUNTS`), keeps each scored frame's evidence
(:attr:`engine.tracking.Tracker.evidence`) and IoU (frames 1..T-2, as the tracking
benchmark), and writes ``confidence.md`` and ``confidence.json``:

- **as shipped**: how the shipped model (:data:`engine.tracking.confidence.COEFFICIENTS`) and
  threshold (:data:`~engine.tracking.confidence.TRACKING_FROM`) report the frames: in-sample
  on the thirty, which they were fitted on; held out on the five;
- **cross-validated**: on folds of the thirty, dealt as the tracking benchmark's
  cross-validation deals them, the model is fitted anew on the other folds (cross-entropy to
  the IoU, as the shipped one was), the threshold chosen there, and the fold's frames scored
  with both.  The threshold keeps a share of the fitting folds' frames with IoU >= 0.6
  ``tracking``; which share (:data:`KEEP_CHOICES`) is itself chosen by a cross-validation
  within the fitting folds (:func:`choose_keep`), so the held-out fold judges the whole rule;
- **the rule on all thirty**: the share that inner cross-validation chooses on the thirty,
  and the threshold it gives the shipped model (what
  :data:`~engine.tracking.confidence.TRACKING_FROM` is set to).

``--grey`` does all of it with the frames turned grey (as a grey camera gives them; the
tracker reads their texture, :mod:`engine.tracking.texture`), for the grey frames' model
(:data:`~engine.tracking.confidence.GREY_COEFFICIENTS`), and writes
``confidence_grey.md`` and ``.json``.  That model is shipped with its bias moved so that
the rule's threshold falls on :data:`~engine.tracking.confidence.TRACKING_FROM`: the report
gives the bias it would need.

The contours do not depend on the confidence model, so one tracking run serves every fold.
"""

from __future__ import annotations

import functools
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize
from scipy.special import logit

from bench.common.data import davis_names
from bench.common.study import on_two_processes, study_main
from bench.tracking.cv import make_folds
from engine.tracking.confidence import EMPTY_BELOW, SEPARATION_BELOW

NODE_COUNTS = (112, 120, 128, 136, 144)
"""The cross-validation's node counts: every frame of each counts once."""
QUICK_SEQUENCES = 2
"""Sequences per set with ``--quick`` (and 128 nodes only)."""
FOLDS = 5
"""Folds of the thirty, as the cross-validation's."""
KEEP_CHOICES = (0.975, 0.98, 0.985, 0.99)
"""Shares of the fitting frames with IoU >= 0.6 (of those the threshold decides: not the
capped or unseen ones) a threshold may keep ``tracking``: from the goal's 95 % with room
for sequences never seen (97.5 %, the rule until 2026-11-27) to nearly all."""
INNER_FOLDS = 4
"""Folds of the fitting sequences the share is chosen on (:func:`choose_keep`)."""
GOOD_FROM, BAD_BELOW = 0.6, 0.2
"""The issue's overlaps: frames that should be ``tracking``, and frames that should not."""
GOOD_GOAL, BAD_GOAL = 95.0, 80.0
"""The issue's goals (%): good frames reported ``tracking``, bad ones not."""
FEATURES = 9
"""Inputs of the model, in :data:`engine.tracking.confidence.COEFFICIENTS` order (after
its bias): a row is these, then the frame's kind, reported confidence and IoU."""
UNSEEN, CAPPED, PLAIN = 0, 1, 2
"""How a frame's reported confidence relates to its evidence: 0 (the contour outside the
frame), capped just below ``tracking`` (probation after a re-acquisition), or the model's."""


def _sequence(job: tuple[str, str, str, int, bool]) -> dict[str, Any]:
    """Track one sequence (in grey if asked); each scored frame's features, kind,
    confidence and IoU."""
    label, name, root, nodes, grey = job
    import cv2

    cv2.setNumThreads(1)
    from bench.common.data import load_davis
    from bench.tracking.sets import grey_frame
    from engine.geometry import contour_to_mask, mask_iou, mask_to_contour
    from engine.tracking import Tracker

    clip = load_davis(name, root=Path(root))
    tracker = Tracker(mask_to_contour(clip.masks[0], nodes))
    rows: list[list[float]] = []
    last = len(clip.frames) - 1
    for i, (frame, mask) in enumerate(zip(clip.frames, clip.masks, strict=True)):
        result = tracker.step(grey_frame(frame) if grey else frame)
        e = tracker.evidence
        if i in (0, last):
            continue
        iou = mask_iou(contour_to_mask(result.nodes, mask.shape), mask)
        if e is None:
            rows.append([0.0] * FEATURES + [UNSEEN, result.confidence, iou])
            continue
        kind = UNSEEN if result.confidence == 0.0 else PLAIN
        if kind == PLAIN and tracker.unconfirmed:
            kind = CAPPED  # on probation (calibrated has its own cap, applied in reported)
        features = [e.inside, e.outside, e.settled, e.motion_inside, e.motion_outside]
        features += [e.motion_seen, e.judged_shape, *e.change]
        rows.append([*map(float, features), kind, result.confidence, iou])
    return {"set": label, "name": name, "nodes": nodes, "rows": rows}


def fit_model(features: NDArray[np.float64], iou: NDArray[np.float64]) -> NDArray[np.float64]:
    """Bias and weights of the logistic model of ``iou`` (cross-entropy to it, as
    :data:`engine.tracking.confidence.COEFFICIENTS` was fitted)."""
    x = np.column_stack([np.ones(len(features)), features])

    def loss(w: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
        p = np.clip(1.0 / (1.0 + np.exp(-(x @ w))), 1e-9, 1 - 1e-9)
        value = -np.mean(iou * np.log(p) + (1 - iou) * np.log(1 - p))
        return float(value), x.T @ (p - iou) / len(iou)

    found = minimize(loss, np.zeros(x.shape[1]), jac=True, method="L-BFGS-B")
    return np.asarray(found.x, np.float64)


def reported(
    w: NDArray[np.float64], features: NDArray[np.float64], kind: NDArray[np.int64], thr: float
) -> NDArray[np.float64]:
    """The confidences the model ``w`` with threshold ``thr`` reports, as the tracker does
    (capped just below ``thr`` on probation, with nothing object-like inside and with
    nothing telling the inside from the ring)."""
    c = 1.0 / (1.0 + np.exp(-(w[0] + features @ w[1:])))
    inside, outside = features[:, 0], features[:, 1]
    capped = (kind == CAPPED) | (inside < EMPTY_BELOW) | (inside - outside < SEPARATION_BELOW)
    c = np.where(capped, np.minimum(c, thr - 1e-3), c)
    return np.where(kind == UNSEEN, 0.0, c)


def choose_threshold(
    conf: NDArray[np.float64], kind: NDArray[np.int64], iou: NDArray[np.float64], keep: float
) -> float:
    """The confidence from which a share ``keep`` of the good frames the threshold decides
    report ``tracking`` (capped and unseen frames are decided otherwise; 0.5 without any)."""
    free = conf[(iou >= GOOD_FROM) & (kind == PLAIN)]
    if not len(free):
        return 0.5
    return float(np.quantile(free, 1.0 - keep))


def fit_rule(rows: list[list[float]], keep: float) -> tuple[NDArray[np.float64], float]:
    """The model fitted to ``rows`` and the threshold keeping ``keep`` of their good frames."""
    features, kind, _, iou = _arrays(rows)
    w = fit_model(features[kind != UNSEEN], iou[kind != UNSEEN])
    return w, choose_threshold(reported(w, features, kind, 1.0), kind, iou, keep)


def margin(found: dict[str, Any]) -> float:
    """How far lost detection clears the nearer of its two goals (percentage points; a
    missing share, no frames of that kind, clears it by any amount)."""
    bad = math.inf if found["bad_reported"] is None else found["bad_reported"] - BAD_GOAL
    good = math.inf if found["good_tracking"] is None else found["good_tracking"] - GOOD_GOAL
    return float(min(bad, good))


def _fixed(keep: float, fitting: dict[str, list[list[float]]]) -> float:
    """``keep``, whatever the fitting sequences."""
    return keep


def choose_keep(rows: dict[str, list[list[float]]]) -> float:
    """The share of :data:`KEEP_CHOICES` whose rule, cross-validated over
    :data:`INNER_FOLDS` folds of these sequences, clears both goals by the most (ties: the
    first; the first when there are fewer than two sequences to fold)."""
    best, best_margin = KEEP_CHOICES[0], -math.inf
    if len(rows) < 2:
        return best
    for keep in KEEP_CHOICES:
        cleared = margin(_held_out(rows, INNER_FOLDS, functools.partial(_fixed, keep))[0])
        if cleared > best_margin:
            best, best_margin = keep, cleared
    return best


def detection(
    conf: NDArray[np.float64], iou: NDArray[np.float64], thr: float | NDArray[np.float64]
) -> dict[str, Any]:
    """Lost detection at ``thr`` (one threshold, or each frame's): shares (%) and counts of
    bad and good frames, mean error."""
    thr = np.broadcast_to(thr, conf.shape)
    bad, good = iou < BAD_BELOW, iou >= GOOD_FROM
    nb, ng = int(np.count_nonzero(bad)), int(np.count_nonzero(good))
    return {
        "bad_frames": nb,
        "bad_reported": 100.0 * np.count_nonzero(conf[bad] < thr[bad]) / nb if nb else None,
        "good_frames": ng,
        "good_tracking": 100.0 * np.count_nonzero(conf[good] >= thr[good]) / ng if ng else None,
        "mean_error": float(np.mean(np.abs(conf - iou))) if len(iou) else None,
    }


def _arrays(
    rows: list[list[float]],
) -> tuple[NDArray[Any], NDArray[Any], NDArray[Any], NDArray[Any]]:
    a = np.asarray(rows, np.float64).reshape(-1, FEATURES + 3)
    return a[:, :FEATURES], a[:, FEATURES].astype(np.int64), a[:, -2], a[:, -1]


def _held_out(
    rows: dict[str, list[list[float]]],
    folds: int,
    keep_for: Callable[[dict[str, list[list[float]]]], float],
) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """Fit the rule on all folds but one (its share from ``keep_for`` of the fitting
    sequences), score that one; the pooled figures and each fold's."""
    held: list[tuple[NDArray[np.float64], NDArray[np.float64], float]] = []
    per_fold = []
    for fold in make_folds(list(rows), folds):
        fitting = {name: r for name, r in rows.items() if name not in fold}
        keep = keep_for(fitting)
        w, thr = fit_rule([row for seq in fitting.values() for row in seq], keep)
        tf, tk, _, ti = _arrays([r for name in fold for r in rows[name]])
        conf = reported(w, tf, tk, thr)
        held.append((conf, ti, thr))
        per_fold.append(
            {"sequences": list(fold), "keep": keep, "threshold": thr, **detection(conf, ti, thr)}
        )
    conf = np.concatenate([c for c, _, _ in held])
    iou = np.concatenate([i for _, i, _ in held])
    thresholds = np.concatenate([np.full(len(c), t) for c, _, t in held])
    return detection(conf, iou, thresholds), per_fold


def cross_validate(rows: dict[str, list[list[float]]], folds: int) -> dict[str, Any]:
    """Fit the rule on all folds but one, its share chosen within them (:func:`choose_keep`),
    and score that one; the pooled held-out figures and each fold's."""
    pooled, per_fold = _held_out(rows, folds, choose_keep)
    return {"pooled": pooled, "folds": per_fold}


def run(sets: dict[str, Path], quick: bool, grey: bool = False) -> dict[str, Any]:
    """Track every sequence at every node count on two processes (its frames turned grey
    with ``grey``); score and cross-validate."""
    from engine.tracking.confidence import COEFFICIENTS, GREY_COEFFICIENTS, TRACKING_FROM

    model = GREY_COEFFICIENTS if grey else COEFFICIENTS
    counts = (128,) if quick else NODE_COUNTS
    jobs = [
        (label, name, str(root), n, grey)
        for label, root in sets.items()
        for name in davis_names(root)[: QUICK_SEQUENCES if quick else None]
        for n in counts
    ]
    done = on_two_processes(_sequence, jobs)
    out: dict[str, Any] = {"node_counts": list(counts), "grey": grey}
    for label in sets:
        by_name: dict[str, list[list[float]]] = {}
        for d in done:
            if d["set"] == label:
                by_name.setdefault(d["name"], []).extend(d["rows"])
        _, _, conf, iou = _arrays([r for rows in by_name.values() for r in rows])
        figures: dict[str, Any] = {
            "sequences": len(by_name),
            "frames": len(iou),
            "shipped": detection(conf, iou, TRACKING_FROM),
        }
        if label == "davis-train":
            figures["cross_validated"] = cross_validate(by_name, FOLDS)
            keep = choose_keep(by_name)
            features, kind, _, iou = _arrays([r for rows in by_name.values() for r in rows])
            shipped = reported(np.asarray(model), features, kind, 1.0)
            fitted, threshold = fit_rule([r for rows in by_name.values() for r in rows], keep)
            figures["rule"] = {
                "keep": keep,
                "shipped_threshold": choose_threshold(shipped, kind, iou, keep),
                "fitted": [round(float(w), 4) for w in fitted],
                "fitted_threshold": threshold,
                "bias_at_tracking_from": round(
                    float(fitted[0] + logit(TRACKING_FROM) - logit(threshold)), 4
                ),
            }
        out[label] = figures
    out["shipped_model"] = {"coefficients": list(model), "tracking_from": TRACKING_FROM}
    return out


def _cells(d: dict[str, Any]) -> str:
    def pct(v: float | None) -> str:
        return "n/a" if v is None else f"{v:.1f} %"

    error = "n/a" if d["mean_error"] is None else f"{d['mean_error']:.3f}"
    return (
        f"{pct(d['bad_reported'])} of {d['bad_frames']} | "
        f"{pct(d['good_tracking'])} of {d['good_frames']} | {error}"
    )


def render(results: dict[str, Any], seconds: float) -> str:
    """The markdown report."""
    counts = ", ".join(str(n) for n in results["node_counts"])
    grey = bool(results.get("grey"))
    name = "GREY_COEFFICIENTS" if grey else "COEFFICIENTS"
    lines = [
        "# Lost detection: the confidence model on sequences it was not fitted on"
        + (" (grey frames)" if grey else ""),
        "",
        f"- date: {time.strftime('%Y-%m-%dT%H:%M:%S%z')}; {seconds:.0f} s wall time;"
        f" `python -m bench.tracking.confidence{' --grey' if grey else ''}`",
        *(["- the DAVIS frames turned grey (the tracker reads their texture)"] if grey else []),
        f"- default tracker, nodes {counts} (every frame of each counts once); frames 1..T-2;"
        f" cross-validated: {FOLDS} folds of the thirty, the model refitted and the threshold"
        " chosen on the other folds: the share of their good frames it keeps tracking, of"
        f" {', '.join(f'{k:.1%}' for k in KEEP_CHOICES)}, chosen by {INNER_FOLDS}-fold"
        " cross-validation within them (the one that clears both goals by the most)",
        "",
        "| set, model | IoU < 0.2 → uncertain/lost (goal ≥ 80 %) "
        "| IoU ≥ 0.6 → tracking (goal ≥ 95 %) | mean \\|conf. - IoU\\| |",
        "|---|---|---|---|",
    ]
    for label, r in results.items():
        if not isinstance(r, dict) or "shipped" not in r:
            continue
        where = "in-sample" if label == "davis-train" else "held out"
        lines.append(
            f"| {label} ({r['sequences']}), as shipped ({where}) | {_cells(r['shipped'])} |"
        )
        if "cross_validated" in r:
            cv = r["cross_validated"]
            lines.append(f"| {label}, cross-validated (held-out folds) | {_cells(cv['pooled'])} |")
    train = results.get("davis-train", {}).get("cross_validated")
    if train:
        lines += ["", "Folds (share and threshold chosen on the others; its frames scored):", ""]
        for k, f in enumerate(train["folds"]):
            lines.append(
                f"- fold {k} (keeps {f['keep']:.1%}, threshold {f['threshold']:.3f}): "
                + _cells(f).replace(" | ", "; ")
            )
    rule = results.get("davis-train", {}).get("rule")
    if rule:
        shipped = results.get("shipped_model", {}).get("tracking_from")
        lines += [
            "",
            f"The rule on all thirty: keep {rule['keep']:.1%} of the good frames tracking; the"
            f" shipped model's threshold under it {rule['shipped_threshold']:.3f}"
            f" (shipped: {shipped}).  The model fitted to all thirty:"
            f" {tuple(rule['fitted'])}, threshold {rule['fitted_threshold']:.3f}"
            f" (shipped: the coefficients of `engine.tracking.confidence.{name}`); its bias"
            f" for that threshold to fall on {shipped}: {rule['bias_at_tracking_from']}.",
        ]
    lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    quick = f"{QUICK_SEQUENCES} sequences a set, 128 nodes"
    flags = {"grey": "turn the frames grey: the grey frames' model (confidence_grey.md)"}
    return study_main(argv, __doc__, "confidence", run, render, quick, flags)


if __name__ == "__main__":
    sys.exit(main())
