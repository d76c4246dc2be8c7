"""Objects tracked on worker processes: :class:`ObjectsTracker` with ``processes=True``.

The trackers hold Python's GIL for most of their time, so a second thread
gains nothing; a second process does.  Each worker process holds the
trackers assigned to it (:class:`Remote` is the parent's handle on one) and
steps them when asked.  A frame goes to the workers once, through shared
memory (the image, its grey version and the whole-frame flow of
:class:`~engine.tracking.shared.SharedMotion`), each worker copying it out
before it answers, so the parent may write the next frame as soon as every
worker has answered.  A worker rebuilds the frame's
:class:`~engine.tracking.shared.SharedMotion` around its own copy of the
last grey frame, which is every one of its trackers' previous frame: they
step exactly as they would in the parent, bit for bit.  Errors raised in a
worker are raised again in the parent.  Coordinates are ``[x, y]`` pixels.
"""

from __future__ import annotations

import contextlib
import itertools
import multiprocessing
import weakref
from collections.abc import Hashable, Mapping, Sequence
from multiprocessing.connection import Connection
from multiprocessing.shared_memory import SharedMemory
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.tracking.noise import Smoothing
from engine.tracking.pieces import PiecesTracker
from engine.tracking.shared import Crowd, SharedLight, SharedMotion
from engine.tracking.tracker import Tracker
from engine.tracking.working import WorkingFrames, WorkingScale

__all__ = ["Remote", "Workers", "contours_of", "probability_of", "restore", "started"]

Layout = tuple[tuple[int, ...], tuple[int, ...], tuple[int, ...] | None]
"""Shapes of the image, the grey frame and the flow (None: none) in the block."""


class Workers:
    """Worker processes holding trackers, and the shared memory frames reach them through.

    Parameters
    ----------
    count : int
        Processes (started on first use; ended by :meth:`close`, or with the
        parent, as daemons).
    """

    def __init__(self, count: int) -> None:
        self.count = count
        self._pipes: list[Connection] = []
        self._processes: list[Any] = []
        self._block: SharedMemory | None = None
        self._ids = itertools.count()
        self._load = [0] * count
        self._finalizer: weakref.finalize[Any, Workers] | None = None

    def _start(self) -> None:
        if self._pipes:
            return
        context = multiprocessing.get_context("spawn")  # fork is unsafe with OpenCV's threads
        for _ in range(self.count):
            parent, child = context.Pipe()
            process = context.Process(target=_serve, args=(child,), daemon=True)
            process.start()
            child.close()
            self._pipes.append(parent)
            self._processes.append(process)
        self._finalizer = weakref.finalize(self, _shut, self._pipes, self._processes, [None])

    def place(self, tracker: Tracker | PiecesTracker) -> Remote:
        """Hand ``tracker`` (its state) to the least loaded worker; its :class:`Remote`."""
        self._start()
        index = int(np.argmin(self._load))
        ident = next(self._ids)
        self.call(index, ("put", ident, tracker.to_state()))
        self._load[index] += 1
        return Remote(self, index, ident, tracker)

    def drop(self, remote: Remote) -> None:
        """The worker forgets the tracker."""
        self.call(remote.index, ("drop", remote.ident))
        self._load[remote.index] -= 1

    def call(self, index: int, message: tuple[Any, ...]) -> Any:
        """Send ``message`` to worker ``index`` and wait for its answer."""
        self.send(index, message)
        return self.receive(index)

    def send(self, index: int, message: tuple[Any, ...]) -> None:
        try:
            self._pipes[index].send(message)
        except (BrokenPipeError, EOFError, OSError) as error:
            raise RuntimeError(f"tracking worker process {index} is gone") from error

    def receive(self, index: int) -> Any:
        return self.gather([index])[0]

    def gather(self, indices: Sequence[int]) -> list[Any]:
        """The answers of these workers, each read before any error is raised (so that no
        answer is left to be taken for the next one)."""
        answers: list[Any] = []
        failed: BaseException | None = None
        for index in indices:
            try:
                ok, value = self._pipes[index].recv()
            except (BrokenPipeError, EOFError, OSError) as error:
                gone = RuntimeError(f"tracking worker process {index} is gone")
                gone.__cause__ = error
                ok, value = False, gone
            if not ok and failed is None:
                failed = value
            answers.append(value)
        if failed is not None:
            raise failed
        return answers

    def frame(
        self,
        image: NDArray[np.uint8],
        grey: NDArray[np.uint8],
        shared: SharedMotion | None,
        grid: WorkingScale | None = None,
    ) -> None:
        """Hand this frame (and its shared motion, measured on the working ``grid`` if
        given) to every worker, through shared memory."""
        flow = None if shared is None or shared.flow is None else shared.flow.flow
        parts: list[NDArray[Any]] = [image, grey]
        if shared is not None:  # measured from this previous frame: the workers get it too
            parts.append(shared.previous)
        if flow is not None:
            parts.append(flow)
        size = sum(p.nbytes for p in parts)
        block = self._block
        if block is None or block.size < size:
            if block is not None:
                block.close()
                block.unlink()
            block = self._block = SharedMemory(create=True, size=size)
            assert self._finalizer is not None
            self._finalizer.detach()
            self._finalizer = weakref.finalize(self, _shut, self._pipes, self._processes, [block])
        offset = 0
        for part in parts:
            view = np.ndarray(part.shape, part.dtype, block.buf, offset)
            view[...] = part
            offset += part.nbytes
        layout: Layout = (image.shape, grey.shape, None if flow is None else flow.shape)
        motion = None
        if shared is not None:
            light = shared.light
            lit = None if light is None else (light.sample, light.step)
            on = None if grid is None else (grid.frame_shape, grid.size)
            motion = (shared.background, flow is not None, lit, on)
        for index in range(self.count):
            self.send(index, ("frame", block.name, layout, motion))
        self.gather(range(self.count))

    def step(
        self, work: Sequence[tuple[Tracker | PiecesTracker | Remote, NDArray[np.bool_] | None]]
    ) -> list[Any]:
        """Step these trackers (held here, each with its ``covered`` mask) on the last frame,
        every worker's share at once; their results in that order."""
        groups: dict[int, list[int]] = {}
        for at, (remote, _) in enumerate(work):
            if not isinstance(remote, Remote) or remote.workers is not self:
                raise ValueError("only trackers held by these workers can be stepped here")
            groups.setdefault(remote.index, []).append(at)
        for index, ats in groups.items():  # every worker starts before any is waited for
            share = [(_ident(work[at][0]), work[at][1]) for at in ats]
            self.send(index, ("step", share))
        results: list[Any] = [None] * len(work)
        for ats, answer in zip(groups.values(), self.gather(list(groups)), strict=True):
            for at, result in zip(ats, answer, strict=True):
                _held(work[at][0]).took(result)
                results[at] = result
        return results

    def close(self) -> None:
        """End the processes and free the shared memory."""
        if self._finalizer is not None:
            self._finalizer()
        self._pipes, self._processes, self._block = [], [], None
        self._load = [0] * self.count


class Remote:
    """The parent's handle on a tracker held by a worker process.

    It knows what :class:`ObjectsTracker` asks of every tracker between frames
    (its contours, whether it has started) and asks the worker the rest.
    """

    def __init__(
        self, workers: Workers, index: int, ident: int, tracker: Tracker | PiecesTracker
    ) -> None:
        self.workers, self.index, self.ident = workers, index, ident
        self.contours: list[NDArray[np.float64]] = (
            tracker.contours if isinstance(tracker, PiecesTracker) else [tracker.nodes]
        )
        self.started = started(tracker)

    def took(self, result: Any) -> None:
        """Keep what a step answered: the contours, and that the tracker has started."""
        self.contours = contours_of(result)
        self.started = True

    def probability(self, region: NDArray[np.uint8]) -> NDArray[np.float32]:
        """The object's appearance p(object) over an image region."""
        result: NDArray[np.float32] = self.workers.call(self.index, ("p", self.ident, region))
        return result

    def to_state(self, **kwargs: Any) -> dict[str, Any]:
        """The tracker's state (``kwargs`` as :meth:`Tracker.to_state`'s)."""
        result: dict[str, Any] = self.workers.call(self.index, ("state", self.ident, kwargs))
        return result


def probability_of(
    tracker: Tracker | PiecesTracker | Remote, region: NDArray[np.uint8]
) -> NDArray[np.float32]:
    """The object's appearance p(object) over an image region (its pieces': the largest)."""
    if isinstance(tracker, Remote):
        return tracker.probability(region)
    if isinstance(tracker, PiecesTracker):
        found = [t.appearance.probability(region) for t in tracker.trackers]
        return np.asarray(np.maximum.reduce(found), np.float32)
    return np.asarray(tracker.appearance.probability(region), np.float32)


def _held(tracker: Tracker | PiecesTracker | Remote) -> Remote:
    assert isinstance(tracker, Remote)
    return tracker


def _ident(tracker: Tracker | PiecesTracker | Remote) -> int:
    return _held(tracker).ident


def started(tracker: Tracker | PiecesTracker | Remote) -> bool:
    """Whether the tracker has seen a frame (a new object is only placed on this one)."""
    if isinstance(tracker, PiecesTracker):
        return all(t.started for t in tracker.trackers)
    return tracker.started


def contours_of(result: Any) -> list[NDArray[np.float64]]:
    """A tracker's or a pieces tracker's step result as its list of contours."""
    return list(result.contours) if hasattr(result, "contours") else [result.nodes]


def restore(state: Mapping[str, Any]) -> Tracker | PiecesTracker:
    """A :class:`Tracker` or :class:`PiecesTracker` from its state (ValueError if malformed)."""
    kind = state.get("kind") if isinstance(state, Mapping) else None
    if kind == "pieces":
        return PiecesTracker.from_state(state)
    if kind is not None:  # a tracker's state has no kind
        raise ValueError(f"an object's state is a tracker's or of kind 'pieces'; got {kind!r}")
    return Tracker.from_state(state)


def _serve(pipe: Connection) -> None:  # pragma: no cover - runs in the worker process
    """A worker's loop: answer ``(True, value)`` or ``(False, exception)`` to each message."""
    import cv2

    from engine.tracking._warm import warm_up
    from engine.tracking.flow import FlowField
    from engine.tracking.motion import FramePair

    cv2.setNumThreads(1)  # the parallelism is the processes'
    warm_up()  # the compiled kernels loaded before the first frame, not during it
    trackers: dict[Hashable, Tracker | PiecesTracker] = {}
    blocks: dict[str, SharedMemory] = {}
    image: NDArray[np.uint8] | None = None
    grey: NDArray[np.uint8] | None = None
    shared: SharedMotion | None = None
    working: WorkingFrames | None = None
    smoothing: Smoothing | None = None
    while True:
        try:
            message = pipe.recv()
        except EOFError:
            break
        kind = message[0]
        try:
            if kind == "close":
                break
            if kind == "put":
                trackers[message[1]] = restore(message[2])
                value: Any = None
            elif kind == "drop":
                value = trackers.pop(message[1], None) and None
            elif kind == "frame":
                name, (image_shape, grey_shape, flow_shape), motion = message[1:]
                if name not in blocks:
                    for old in blocks.values():
                        old.close()
                    blocks = {name: _attach(name)}
                buffer = blocks[name].buf
                image = np.ndarray(image_shape, np.uint8, buffer).copy()
                offset = image.nbytes
                grey = np.ndarray(grey_shape, np.uint8, buffer, offset).copy()
                offset += grey.nbytes
                # smoothed, and brought down to the working grid, once for this worker's objects
                smoothing, working = Smoothing(image, grey), WorkingFrames(image, grey)
                shared = None
                if motion is not None:
                    background, has_flow, lit, on = motion
                    current = grey  # measured on the frame, or on the trackers' working grid
                    if on is not None:
                        current = working.at(WorkingScale(*on), image, grey)[1]
                    last = np.ndarray(current.shape, np.uint8, buffer, offset).copy()
                    offset += last.nbytes
                    flow = None
                    if has_flow:
                        vectors = np.ndarray(flow_shape, np.float32, buffer, offset).copy()
                        flow = FlowField(FramePair.whole(last, current), vectors)
                    light = None if lit is None else SharedLight(*lit)
                    shared = SharedMotion(last, current, background, flow, light)
                value = None
            elif kind == "step":
                assert image is not None
                assert grey is not None
                value = []
                for ident, covered in message[1]:
                    tracker = trackers[ident]
                    crowd = Crowd(covered, shared, smoothing, working)
                    value.append(tracker.step_prepared(image, grey, crowd))
            elif kind == "p":
                value = probability_of(trackers[message[1]], message[2])
            elif kind == "state":
                value = trackers[message[1]].to_state(**message[2])
            else:
                raise ValueError(f"unknown message {kind!r}")
            pipe.send((True, value))
        except Exception as error:  # every error goes back to the parent
            try:
                pipe.send((False, error))
            except Exception:  # an error that cannot be pickled: its message
                pipe.send((False, RuntimeError(f"{type(error).__name__}: {error}")))
    for block in blocks.values():
        block.close()


def _attach(name: str) -> SharedMemory:  # pragma: no cover - runs in the worker process
    """The parent's block (the parent frees it; the resource tracker both share knows it)."""
    return SharedMemory(name=name)


def _shut(pipes: list[Connection], processes: list[Any], blocks: list[SharedMemory | None]) -> None:
    """End the workers and free the shared memory (also when the tracker is collected)."""
    for pipe in pipes:
        with contextlib.suppress(BrokenPipeError, OSError):
            pipe.send(("close",))
    for process in processes:
        process.join(timeout=5)
        if process.is_alive():
            process.kill()
    for block in blocks:
        if block is not None:
            block.close()
            block.unlink()
