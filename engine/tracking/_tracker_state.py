"""The tracker's JSON state: written by ``Tracker.to_state``, read by ``Tracker.from_state``.

A snapshot holds the contour, the options, the frame count and, unless left out, the
previous grey frame with each stage's state, the search's memory and the lighting, so
that tracking resumes bit for bit (or, compact, within a few tens of kB).  Older
versions are read and continue as the tracker that wrote them.
Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

import binascii
import dataclasses
import json
import zlib
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from engine.geometry import as_nodes, circle_nodes
from engine.tracking._state_codec import (
    count,
    pack_compact_frame,
    pack_image,
    unpack_compact_frame,
    unpack_image,
)
from engine.tracking._state_codec import from_version_1 as _from_version_1
from engine.tracking.appearance import LEGACY_COLOUR_BITS
from engine.tracking.flash import FLASH_FRAMES
from engine.tracking.lighting import Lighting
from engine.tracking.looks import Look
from engine.tracking.memory import Memory
from engine.tracking.working import working_scale

if TYPE_CHECKING:
    from engine.tracking.tracker import Tracker

__all__ = ["COMPACT_BYTES", "STATE_VERSION", "restore", "snapshot"]

STATE_VERSION = 3
"""Version 3 adds the segmentation stage; version 2 (each other stage's state
under ``"stages"``) and version 1 (the colour model, probability and corners
at the top level) are still read, the segmentation learning afresh."""
STAGES = ("motion", "appearance", "cues", "segmentation")
STAND_IN_RADIUS = 10.0
"""Radius (pixels) of the circle a tracker is rebuilt on before its state's own contour is
set: any contour the constructor accepts would do."""
COMPACT_BYTES = 52 * 1024
"""JSON size a compact state aims at (the previous frame's detail gets what the rest
leaves): the service's Redis record adds about 9 kB for a 128-node session (its
contour and rest shape), which keeps a committed frame within 64 kB."""


def _stage_state(stage: object, compact: bool) -> dict[str, Any]:
    """A stage's state: its compact one when asked for and offered, else the exact one."""
    method = getattr(stage, "to_compact_state", None) if compact else None
    if method is None:
        method = getattr(stage, "to_state")  # noqa: B009 - every stage has it (protocol)
    state: dict[str, Any] = method()
    return state


def snapshot(tracker: Tracker, *, include_frame: bool, compact: bool) -> dict[str, Any]:
    """``tracker``'s state, as :meth:`engine.tracking.Tracker.to_state` documents it."""
    previous = tracker._previous if include_frame else None
    state: dict[str, Any] = {
        "version": STATE_VERSION,
        # on the working grid with the frame they resume from, else in the frame's pixels
        "nodes": (tracker._nodes if previous is not None else tracker.nodes).tolist(),
        "options": dataclasses.asdict(tracker.options),
        "frame_index": tracker.frame_index,
        "previous": None,
        "stages": None
        if previous is None
        else {name: _stage_state(getattr(tracker, name), compact) for name in STAGES},
        "search": None if previous is None else tracker._memory.to_state(),
        "lighting": None
        if previous is None or not tracker.options.lighting
        else tracker._lighting.to_state(compact=compact),
    }
    if previous is not None:  # the kind of frame the stages learnt from, and the other's look
        state["passed"] = tracker._passed  # frames passed over as a flash since it
        state["reported"] = tracker._reported  # the confidence last reported
        aside = tracker._aside
        state["look"] = {
            "grey": tracker._look_grey,
            "aside": None if aside is None else aside.to_state(compact),
        }
    if previous is not None and compact:
        search = state["search"]  # the shape searched for, to a hundredth of a pixel
        search["shape"] = np.round(tracker._memory.shape, 2).tolist()
        search["hold"] = np.round(tracker._memory.hold, 3).tolist()
        if tracker._memory.outline is not None:
            search["outline"] = np.round(tracker._memory.outline, 2).tolist()
        if tracker._memory.marks is not None:
            search["marks"] = np.round(tracker._memory.marks, 3).tolist()
        room = COMPACT_BYTES - len(json.dumps(state))
        state["previous"] = pack_compact_frame(previous, tracker._nodes, room)
    elif previous is not None:
        state["previous"] = pack_image(previous)
    if previous is not None and tracker._frame_shape is not None:
        state["frame_shape"] = list(tracker._frame_shape)  # the size of the frames given
        state["grid_side"] = tracker._grid_side  # and of the grid they are tracked on
    return state


def restore(make: Callable[..., Tracker], state: Mapping[str, Any]) -> Tracker:
    """A tracker resumed from ``state``, as :meth:`engine.tracking.Tracker.from_state`
    documents it; ValueError when the state is malformed.

    ``make(nodes, **options)`` builds the tracker (the class with the caller's stages
    bound); the state's stages are then loaded into the stages it built.
    """
    if not isinstance(state, Mapping) or state.get("version") not in (1, 2, STATE_VERSION):
        raise ValueError(f"tracker state must be a dict of version 1 to {STATE_VERSION}")
    try:
        if state["version"] == 1:
            state = _from_version_1(state)
        options = dict(state["options"])
        if state["version"] < STATE_VERSION:
            # written before the segmentation stage: continue as the tracker that wrote it
            options.setdefault("cut_band", 0)
            options.setdefault("reacquire_above", 1.0)
            options.setdefault("hold_below", 0.0)
        # written before the motion contrast and the figure-ground split of the motion:
        # continue as the tracker that wrote it
        options.setdefault("motion_contrast", False)
        options.setdefault("figure_ground", False)
        options.setdefault("shape_memory", False)  # and before the shape memory
        options.setdefault("lighting", False)  # and before the lighting
        options.setdefault("far_background", 0.0)  # and before the far background
        options.setdefault("rigid_behind", False)  # and before the rigid prediction behind
        options.setdefault("revealed_background", False)  # and before uncovered background
        options.setdefault("bridge_strips", False)  # and before the strips bridged
        options.setdefault("carve_gaps", False)  # and before the gaps carved
        options.setdefault("full_resolution_edges", False)  # and before the second cut
        options.setdefault("align_prediction", False)  # and before the alignment
        options.setdefault("colour_bits", LEGACY_COLOUR_BITS)  # and before 32 colour levels
        options.setdefault("turn_outline", False)  # and before the outline turned
        options.setdefault("working_side", 0)  # and before the working resolution
        options.setdefault("object_side", 0)  # and before a large object's grid
        options.setdefault("grey_texture", False)  # and before grey frames' texture
        nodes = as_nodes(state["nodes"])
        # built on a stand-in of as many nodes: a tracked contour may have shrunk below what
        # a new one may enclose; it is then set exactly, not resampled again
        tracker = make(circle_nodes((0.0, 0.0), STAND_IN_RADIUS, len(nodes)), **options)
        tracker._nodes = nodes
        tracker._memory = Memory.fresh(nodes)  # as the state's "search" says, if it has one
        tracker.frame_index = int(state["frame_index"])
        stages, previous = state.get("stages"), state.get("previous")
        if stages is not None and previous is not None:
            tracker.motion = tracker.motion.from_state(stages["motion"])
            tracker.appearance = tracker.appearance.from_state(stages["appearance"])
            tracker.cues = tracker.cues.from_state(stages["cues"])
            if "segmentation" in stages:  # not in version 2
                segmented = tracker.segmentation.from_state(stages["segmentation"])
                tracker.segmentation = segmented
            search = state.get("search")
            if search is not None:
                tracker._memory = Memory.from_state(search, len(tracker._nodes))
                if not tracker.options.shape_memory:
                    tracker._memory.outline = None
                if not (tracker.options.shape_memory and tracker.options.turn_outline):
                    tracker._memory.marks = None  # the marks stay on the nodes
            lighting = state.get("lighting")
            if lighting is not None and tracker.options.lighting:
                tracker._lighting = Lighting.from_state(lighting)
            _restore_look(tracker, state.get("look"))
            tracker._passed = count(state.get("passed", 0))  # 0: written before the flashes
            if tracker._passed > FLASH_FRAMES:
                raise ValueError(f"passed counts at most {FLASH_FRAMES} frames")
            reported = state.get("reported", 1.0)  # 1: written before it (none lower)
            if isinstance(reported, bool) or not (
                isinstance(reported, int | float) and 0 <= reported <= 1
            ):
                raise ValueError(f"reported must be a confidence in [0, 1]; got {reported!r}")
            tracker._reported = float(reported)
            tracker._previous = (
                unpack_compact_frame(previous)
                if isinstance(previous, Mapping)
                else unpack_image(previous)
            )
            _regrid(tracker, state.get("frame_shape"), state.get("grid_side"))
    # AttributeError: a part that should be a dict is not; OverflowError: an infinite count
    except (
        KeyError,
        TypeError,
        ValueError,
        AttributeError,
        OverflowError,
        binascii.Error,
        zlib.error,
    ) as exc:
        raise ValueError(f"malformed tracker state: {exc}") from None
    return tracker


def _restore_look(tracker: Tracker, look: object) -> None:
    """The kind of frame the restored stages learnt from and the other kind's look
    (:mod:`engine.tracking.looks`); a state written before the looks has neither, and its
    next frame sets the kind."""
    if look is None:
        return
    if not isinstance(look, Mapping) or not isinstance(look.get("grey"), bool | None):
        raise ValueError("look must be a dict whose 'grey' is true, false or null")
    tracker._look_grey = look["grey"]
    aside = look.get("aside")
    if aside is not None:
        tracker._aside = Look.from_state(
            aside, tracker.appearance, tracker.cues, tracker.segmentation
        )
        if tracker._aside.grey == tracker._look_grey:
            raise ValueError("the look put aside must be of the other kind of frame")


def _regrid(tracker: Tracker, frame_shape: object, grid_side: object) -> None:
    """The restored tracker's frame size and working grid, checked against its previous
    frame (states written before the working resolution: that frame's size; before a
    large object's grid: ``working_side``'s)."""
    previous = tracker._previous
    assert previous is not None
    if frame_shape is None:
        shape = (previous.shape[0], previous.shape[1])
    elif (
        isinstance(frame_shape, list | tuple)
        and len(frame_shape) == 2
        and all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in frame_shape)
    ):
        shape = (int(frame_shape[0]), int(frame_shape[1]))
    else:
        raise ValueError(f"frame_shape must be [height, width]; got {frame_shape!r}")
    side = tracker.options.working_side if grid_side is None else grid_side
    if isinstance(side, bool) or not isinstance(side, int) or side < 0:
        raise ValueError(f"grid_side must be a whole number of pixels; got {grid_side!r}")
    scale = working_scale(shape, side)
    grid = shape if scale is None else (scale.size[1], scale.size[0])
    if previous.shape[:2] != grid:
        raise ValueError(
            f"the previous frame is {previous.shape[1]} x {previous.shape[0]}; frames of "
            f"{shape[1]} x {shape[0]} are tracked at {grid[1]} x {grid[0]}"
        )
    tracker._frame_shape, tracker._scale, tracker._grid_side = shape, scale, side
