"""``efdm eval PRED GT``: score predicted masks against ground truth, as DAVIS does.

PRED and GT are two folders of one sequence's masks, or two folders holding one
sub-folder per sequence.  Masks are matched by file name (without extension);
every ground-truth frame needs a prediction.  Per sequence: region similarity J
and boundary measure F (:mod:`engine.evaluation`), with the first and last frame
left out, each as mean, recall and decay; then the mean over sequences of the
per-sequence means, and J&F, their average.  A table on stdout, or with
``--json`` the same figures as JSON.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import asdict
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from efdm_cli._common import EXIT_INVALID, EXIT_IO, CliError
from efdm_cli._io import IMAGE_SUFFIXES, read_image


def masks_in(folder: Path) -> dict[str, Path]:
    """The image files directly in ``folder``, by name without extension."""
    return {p.stem: p for p in sorted(folder.iterdir()) if p.suffix.lower() in IMAGE_SUFFIXES}


def sequences(pred: Path, truth: Path) -> dict[str, tuple[Path, Path]]:
    """``{name: (predicted folder, true folder)}``: one sequence, or one per sub-folder.

    Raises
    ------
    CliError
        A folder missing or empty, or a sequence of GT without predictions.
    """
    for folder in (pred, truth):
        if not folder.is_dir():
            raise CliError(f"{folder} is not a folder", EXIT_IO)
    if masks_in(truth):  # a DAVIS-style "<sequence>/masks" folder is named after its sequence
        name = truth.resolve().parent.name if truth.name.lower() == "masks" else truth.name
        return {name or truth.name: (pred, truth)}
    subs = sorted(p for p in truth.iterdir() if p.is_dir() and masks_in(p))
    if not subs:
        raise CliError(f"{truth} holds no masks, nor sub-folders of masks", EXIT_INVALID)
    missing = [p.name for p in subs if not (pred / p.name).is_dir()]
    if missing:
        raise CliError(f"{pred} has no folder for {', '.join(missing)}", EXIT_INVALID)
    return {p.name: (pred / p.name, p) for p in subs}


def _mask(path: Path) -> np.ndarray[Any, Any]:
    import cv2

    image = read_image(str(path), cv2.IMREAD_UNCHANGED)
    return image if image.ndim == 2 else np.asarray(image[..., :3].any(axis=2))


def score(pred: Path, truth: Path) -> Any:
    """The :class:`engine.evaluation.SequenceScore` of one sequence's folders."""
    from engine.evaluation import score_sequence

    wanted, given = masks_in(truth), masks_in(pred)
    absent = [name for name in wanted if name not in given]
    if absent:
        shown = ", ".join(absent[:5]) + (" ..." if len(absent) > 5 else "")
        raise CliError(f"{pred} has no mask for {len(absent)} frame(s): {shown}", EXIT_INVALID)
    truths = [_mask(wanted[name]) for name in wanted]
    predictions = [_mask(given[name]) for name in wanted]
    try:
        return score_sequence(predictions, truths)
    except ValueError as exc:
        raise CliError(f"{truth.name}: {exc}", EXIT_INVALID) from None


def run(args: argparse.Namespace, out: TextIO) -> None:
    """Score every sequence; print the table or the JSON."""
    from efdm_cli._progress import Progress

    found = sequences(Path(args.pred), Path(args.gt))
    progress = Progress(len(found), sys.stderr, enabled=not args.quiet, label="efdm eval")
    scores = {}
    for done, (name, (pred, truth)) in enumerate(found.items(), start=1):
        scores[name] = score(pred, truth)
        progress.update(done)
    progress.close()
    j = float(np.mean([s.j.mean for s in scores.values()]))
    f = float(np.mean([s.f.mean for s in scores.values()]))
    means = {
        "J": j,
        "F": f,
        "J&F": (j + f) / 2,
        "J decay": float(np.mean([s.j.decay for s in scores.values()])),
        "F decay": float(np.mean([s.f.decay for s in scores.values()])),
    }
    if args.json:
        body = {
            "sequences": {
                name: {"frames": s.frames, "J": asdict(s.j), "F": asdict(s.f)}
                for name, s in scores.items()
            },
            "mean": means,
        }
        print(json.dumps(body, indent=2), file=out)
        return
    width = max(8, *(len(n) for n in scores))
    head = f"{'sequence':<{width}}  frames  J mean  J recall  J decay  F mean  F recall  F decay"
    print(head, file=out)
    for name, s in scores.items():
        print(
            f"{name:<{width}}  {s.frames:>6}  {s.j.mean:6.3f}  {s.j.recall:8.3f}  "
            f"{s.j.decay:+7.3f}  {s.f.mean:6.3f}  {s.f.recall:8.3f}  {s.f.decay:+7.3f}",
            file=out,
        )
    print(
        f"{'mean':<{width}}  {sum(s.frames for s in scores.values()):>6}  {j:6.3f}  "
        f"{'':8}  {means['J decay']:+7.3f}  {f:6.3f}  {'':8}  {means['F decay']:+7.3f}",
        file=out,
    )
    print(f"J&F {means['J&F']:.3f} over {len(scores)} sequence(s)", file=out)


def add_parser(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register ``eval`` on the sub-command set of ``efdm``."""
    e = commands.add_parser(
        "eval",
        help="score predicted masks against ground truth (DAVIS J and F)",
        description=(
            "Score the masks in PRED against those in GT with the DAVIS measures: region "
            "similarity J and boundary measure F, first and last frame of each sequence left "
            "out, mean, recall and decay per sequence, then the mean over sequences. PRED and "
            "GT are two folders of one sequence's masks (PNG, non-zero = object), or two "
            "folders of one sub-folder per sequence; masks are matched by file name."
        ),
        epilog="exit codes: 0 success, 1 a folder or mask could not be read, 2 invalid data",
    )
    e.add_argument("pred", help="predicted masks (e.g. efdm track --masks-out DIR)")
    e.add_argument("gt", help="ground-truth masks")
    e.add_argument("--json", action="store_true", help="the figures as JSON on stdout")
    e.add_argument("--quiet", "-q", action="store_true", help="no progress on stderr")
    e.set_defaults(handler=run)
