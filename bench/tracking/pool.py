"""Tracking jobs, run in this process or in worker processes.

A :class:`Job` is one clip (named, not loaded) with the trackers to run on it, their frame
limits and efdm's options: small enough to send to a worker, which loads the clip and builds
the trackers itself.  :func:`track_all` runs jobs on ``workers`` processes (``spawn``: fresh
interpreters, which inherit the one-thread pins of the environment and pin OpenCV again), or
here, one after the other, for ``workers <= 1``.  Each worker is single-threaded and tracks a
clip uninterrupted, but the workers share the machine: their timings are indicative only.
"""

from __future__ import annotations

import functools
import json
import multiprocessing
from collections.abc import Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

import cv2

from bench.common.log import set_family
from bench.tracking.config import NODES
from bench.tracking.run import ClipResult, run_clip
from bench.tracking.sets import ClipSpec
from bench.tracking.trackers import Factory, factory

Options = tuple[tuple[str, Any], ...]
"""efdm's ``TrackerOptions`` fields as sorted (name, value) pairs: hashable, picklable."""


def as_options(mapping: Mapping[str, Any]) -> Options:
    """Options as :data:`Options`."""
    return tuple(sorted(mapping.items()))


def describe(options: Options) -> str:
    """``search_radius=12, stiffness=40`` (``defaults`` for none)."""
    return ", ".join(f"{k}={json.dumps(v)}" for k, v in options) or "defaults"


@dataclass(frozen=True, slots=True)
class Job:
    """Trackers to run on one clip.

    Attributes
    ----------
    clip : ClipSpec
        The clip.
    trackers : tuple of str
        Tracker names (:data:`bench.tracking.trackers.TRACKERS`).
    limits : tuple of (str, int)
        Frames some trackers track at most.
    options : Options
        efdm's options (empty: the defaults).
    reverse : bool
        Run the trackers in reverse order (alternated from clip to clip).
    nodes : int
        Nodes of the initial contour (:data:`bench.tracking.config.NODES` unless
        cross-validating over several node counts).
    """

    clip: ClipSpec
    trackers: tuple[str, ...]
    limits: tuple[tuple[str, int], ...] = ()
    options: Options = ()
    reverse: bool = False
    nodes: int = NODES


@functools.cache
def cached_factory(name: str, options: Options) -> Factory:
    """The factory of a tracker with efdm's options, built once per process."""
    return factory(name, dict(options))


def track(job: Job) -> ClipResult:
    """Run one job here."""
    clip = job.clip.load()
    factories = {name: cached_factory(name, job.options) for name in job.trackers}
    label = f"  [{describe(job.options)}]" if job.options else ""
    label += f"  [{job.nodes} nodes]" if job.nodes != NODES else ""
    limits = dict(job.limits)
    return run_clip(clip, factories, limits, reverse=job.reverse, label=label, nodes=job.nodes)


def start_worker() -> None:
    """A worker's start: one OpenCV thread (the environment pins numpy's and numba's), and
    progress lines named as the parent's."""
    cv2.setNumThreads(1)
    set_family("tracking")


def track_all(jobs: Sequence[Job], workers: int) -> list[ClipResult]:
    """Every job's result, in the jobs' order; on ``workers`` processes when more than one."""
    if workers <= 1 or len(jobs) <= 1:
        return [track(job) for job in jobs]
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(workers, mp_context=context, initializer=start_worker) as pool:
        return list(pool.map(track, jobs))
