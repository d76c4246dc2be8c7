"""``LocalColour``: colour models of the object against its own surroundings, window by window.

A single colour histogram for the whole object fails where the object's
colours appear in the background elsewhere (a shadow, grass, water): it
calls them object everywhere.  Square windows centred on the contour, as in
Video SnapCut (Bai et al., SIGGRAPH 2009), each learn the object's and the
background's colours *there*; in the next frame they move with the
predicted contour and say, pixel by pixel, how object-like each colour is
locally.  Where a window never saw a colour, the global model's p(object)
fills in.  Learnt from every frame's final contour (pixels a few pixels
away from it on either side, so that the boundary's mixed pixels teach
neither side).  Coordinates are ``[x, y]`` pixels (x = column, y = row).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import bounding_box, contour_to_mask, perimeter
from engine.tracking._state_codec import pack_counts, unpack_counts
from engine.tracking.appearance import bin_count as histogram_bins
from engine.tracking.appearance import kernel_image

__all__ = ["WINDOWS", "LocalColour"]

WINDOWS = 32
"""Windows along the contour: a 128-node contour gets one every four nodes,
dense enough that neighbouring windows overlap by a third."""
MAX_HALF = 512
"""Largest half side (pixels) of a window: the window of a contour far larger than any
frame (a user's outline of 10^6 pixels) is capped at a frame's size, instead of a
Gaussian table of (2 half + 1)^2 weights that does not fit in memory.  A 128-node contour
on 480-line video has windows of half side 12-70."""
MIN_HALF = 12
"""Smallest half side (pixels) of a window: 25 x 25 pixels, a few hundred of
each side's pixels, enough for a 512-bin histogram to say something."""
OVERLAP = 0.75
"""Half side = 0.75 x the contour length per window: windows overlap so that
every pixel near the contour is covered by two or three of them."""
INSET = 2
"""Pixels within 2 of the contour teach neither side: they mix object and background."""
COLOUR_BITS = 3
"""8 levels per BGR channel, 512 bins: a window has only hundreds of pixels per side."""
GREY_BITS = 5
"""32 grey levels for grey frames."""
TRUST = 12.0
"""A window trusts its own p(object) for a colour fully after 12 sightings of it."""
MIN_COUNT = 10.0
"""A window with fewer pixels than this on either side says nothing."""


def bin_count(image: NDArray[np.uint8]) -> int:
    """Number of bins for frames like ``image``."""
    return histogram_bins(image, GREY_BITS, COLOUR_BITS)


def window_half(nodes: NDArray[np.float64]) -> int:
    """Half side (pixels) of the windows for a contour: :data:`OVERLAP` of its length per window
    (within :data:`MIN_HALF` and :data:`MAX_HALF`)."""
    return min(MAX_HALF, max(MIN_HALF, round(OVERLAP * perimeter(nodes) / WINDOWS)))


def window_nodes(count: int) -> NDArray[np.int64]:
    """Indices of the nodes the windows are centred on (evenly spaced)."""
    return (np.arange(WINDOWS) * count) // WINDOWS


@dataclass(frozen=True, slots=True)
class LocalColour:
    """Colour counts of the object and of the background in windows along a contour.

    Attributes
    ----------
    half : int
        Half side of each window, pixels.
    nodes : int
        Node count of the contour the windows ride on (windows sit on nodes
        :func:`window_nodes` of it).
    object_counts, background_counts : numpy.ndarray
        (:data:`WINDOWS`, bins) float32 pixel counts per colour bin.
    """

    half: int
    nodes: int
    object_counts: NDArray[np.float32]
    background_counts: NDArray[np.float32]

    @classmethod
    def learn(cls, image: NDArray[np.uint8], nodes: NDArray[np.float64]) -> LocalColour | None:
        """The windows' models from a frame and the object's contour on it (None off-frame)."""
        from engine.tracking._cut_kernels import learn_windows

        half = window_half(nodes)
        x0, y0, x1, y1 = bounding_box(image.shape, nodes, half + 1, half + 2, keep_inside=False)
        if x1 - x0 < 3 or y1 - y0 < 3:
            return None
        mask = contour_to_mask(nodes - [x0, y0], (y1 - y0, x1 - x0))
        kernel = np.ones((2 * INSET + 1, 2 * INSET + 1), np.uint8)
        inside = (cv2.erode(mask, kernel) > 0).astype(np.uint8)
        outside = (cv2.dilate(mask, kernel) == 0).astype(np.uint8)
        centres = np.round(nodes[window_nodes(len(nodes))] - [x0, y0]).astype(np.int64)
        fg, bg = learn_windows(
            kernel_image(image[y0:y1, x0:x1]),
            GREY_BITS,
            COLOUR_BITS,
            inside,
            outside,
            centres,
            half,
            bin_count(image),
        )
        return cls(half, len(nodes), fg, bg)

    def probability(
        self,
        region: NDArray[np.uint8],
        origin: tuple[int, int],
        nodes: NDArray[np.float64],
        fallback: NDArray[np.float32],
        wanted: NDArray[np.uint8],
        *,
        scale: int = 1,
    ) -> NDArray[np.float32]:
        """p(object) over a region of the frame, the windows riding on ``nodes``.

        Parameters
        ----------
        region : numpy.ndarray
            The region of the frame (BGR or grey), possibly shrunk by ``scale``.
        origin : tuple of int
            ``(x, y)`` of the region's top-left pixel in the frame.
        nodes : numpy.ndarray
            (N, 2) ``[x, y]`` frame pixels: the contour the windows are
            centred on (the predicted one).
        fallback : numpy.ndarray
            The global model's p(object) over the region (its shape), used
            where no window knows better.
        wanted : numpy.ndarray
            uint8, 1 where p is needed (elsewhere ``fallback`` is returned).
        scale : int
            The region is the frame's shrunk by this factor.
        """
        from engine.tracking._cut_kernels import local_probability

        if len(nodes) != self.nodes or bin_count(region) != self.object_counts.shape[1]:
            return fallback
        points = (nodes[window_nodes(len(nodes))] - np.asarray(origin) + 0.5) / scale - 0.5
        result: NDArray[np.float32] = local_probability(
            kernel_image(region),
            GREY_BITS,
            COLOUR_BITS,
            wanted,
            np.round(points).astype(np.int64),
            max(1, round(self.half / scale)),
            self.object_counts,
            self.background_counts,
            TRUST,
            MIN_COUNT,
            np.ascontiguousarray(fallback, dtype=np.float32),
        )
        return result

    def to_state(self) -> dict[str, Any]:
        """``{"half", "nodes", "object", "background"}`` (counts packed exactly)."""
        return {
            "half": self.half,
            "nodes": self.nodes,
            "object": pack_counts(self.object_counts),
            "background": pack_counts(self.background_counts),
        }

    @classmethod
    def from_state(cls, state: Mapping[str, Any]) -> LocalColour:
        """Inverse of :meth:`to_state`; ValueError on anything malformed."""
        half, nodes = int(state["half"]), int(state["nodes"])
        if not 1 <= half <= MAX_HALF or nodes < 3:
            raise ValueError("local colour windows: bad window size or node count")
        sizes = (1 << GREY_BITS, 1 << (3 * COLOUR_BITS))
        fg = unpack_counts(state["object"], WINDOWS, sizes)
        bg = unpack_counts(state["background"], WINDOWS, sizes)
        if fg.shape != bg.shape:
            raise ValueError("local colour windows: object and background counts differ in size")
        return cls(half, nodes, fg, bg)
