"""``ColourHistogram``: the default :class:`~engine.tracking.stages.AppearanceModel`.

The object's colour histogram comes from inside the contour, the
background's from a band just outside it; the posterior
p(object | colour) is looked up per pixel.  Coordinates are ``[x, y]``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Self

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import bounding_box, contour_to_mask
from engine.tracking._state_codec import pack_histogram, unpack_histogram
from engine.tracking.stages import check_kind

__all__ = ["ColourHistogram", "Histograms", "bin_count", "kernel_image", "quantise"]

KIND = "colour-histogram"

_COLOUR_BITS = 4
"""16 levels per BGR channel, 4096 bins: coarse enough that a few thousand object
pixels fill the histogram, fine enough to tell most objects from their surroundings."""
_GREY_BITS = 5
"""32 grey levels: one channel needs fewer pixels per bin than three."""
UNKNOWN = 0.5
"""p(object) where nothing is known: neither object nor background."""
PRIOR = 1e-3
"""Weight of the uniform prior added to both histograms: a colour seen in
neither gets p(object) = 0.5 instead of 0/0."""
TEACH_OBJECT_ABOVE = 0.55
"""Only pixels the model already finds object-like (p > 0.55) teach the object
histogram: an occluder or the background inside a lagging contour does not."""
TEACH_BACKGROUND_BELOW = 0.9
"""Only pixels the model does not find clearly object-like (p < 0.9) teach the
background's: the object's own parts outside a lagging contour do not."""
FAR_RINGS = 2
"""The far background starts two rings (``2 * band`` pixels) from the contour: past where
the object may move within a few frames, so its own colours there are not taken in."""
OBJECT_INSET = 2
"""Object pixels are taken this far inside the contour (a 5 x 5 erosion):
the contour's own pixels mix object and background."""


def quantise(
    image: NDArray[np.uint8], grey_bits: int = _GREY_BITS, colour_bits: int = _COLOUR_BITS
) -> NDArray[np.uint16]:
    """Histogram bin of every pixel (by default BGR: 16^3 bins; grey: 32), one compiled pass."""
    from engine.tracking._image_kernels import colour_bins

    bins: NDArray[np.uint16] = colour_bins(kernel_image(image), grey_bits, colour_bits)
    return bins


def kernel_image(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """A contiguous H x W x C view or copy (grey images get C = 1), as the colour kernels take."""
    arr = np.ascontiguousarray(image, dtype=np.uint8)
    return arr[..., None] if arr.ndim == 2 else arr


def bin_count(
    image: NDArray[np.uint8], grey_bits: int = _GREY_BITS, colour_bits: int = _COLOUR_BITS
) -> int:
    """Number of histogram bins for frames like ``image`` (at those bits per channel)."""
    return 1 << (grey_bits if image.ndim == 2 else 3 * colour_bits)


@dataclass(frozen=True, slots=True)
class Histograms:
    """Normalised colour histograms of the object and of its surroundings.

    Attributes
    ----------
    object_hist, background_hist : numpy.ndarray
        float64, each summing to 1 (or all zero when nothing was seen).
    """

    object_hist: NDArray[np.float64]
    background_hist: NDArray[np.float64]

    @classmethod
    def fit(
        cls, frame: NDArray[np.uint8], nodes: NDArray[np.float64], band: int, far: float = 0.0
    ) -> Histograms:
        """Histograms from the filled contour and a ``band``-pixel ring around it.

        With ``far`` in (0, 1], that share of the background histogram comes from
        the whole frame beyond ``2 * band`` pixels of the contour (:func:`_far_histogram`)
        and the rest from the ring.
        """
        obj, bg = _histograms(frame, nodes, band)
        if far > 0:
            seen = _far_histogram(frame, nodes, FAR_RINGS * band)
            if seen is not None:
                bg = (1.0 - far) * bg + far * seen
        return cls(obj, bg)

    def updated(
        self, frame: NDArray[np.uint8], nodes: NDArray[np.float64], band: int, rate: float
    ) -> Histograms:
        """Blend in the histograms of a new frame with weight ``rate``.

        Only pixels the current model already finds object-like
        (:data:`TEACH_OBJECT_ABOVE`) teach the object histogram, and only
        pixels it does not find clearly object-like
        (:data:`TEACH_BACKGROUND_BELOW`) teach the background's: an occluder
        crossing the contour, or a contour that lags behind the object, does
        not leak into the wrong histogram.
        """
        obj, bg = _histograms(frame, nodes, band, self.table())
        if obj.shape != self.object_hist.shape:
            return Histograms(obj, bg)

        def blend(old: NDArray[np.float64], new: NDArray[np.float64]) -> NDArray[np.float64]:
            return old if new.sum() == 0 else (1 - rate) * old + rate * new  # nothing learnt

        return Histograms(blend(self.object_hist, obj), blend(self.background_hist, bg))

    def table(self) -> NDArray[np.float32]:
        """p(object | bin), with a weak prior of 0.5 for rarely seen colours."""
        o, b = self.object_hist + PRIOR / len(self.object_hist), self.background_hist
        b = b + PRIOR / len(b)
        return np.asarray(o / (o + b), dtype=np.float32)

    def probability(
        self, image: NDArray[np.uint8], table: NDArray[np.float32] | None = None
    ) -> NDArray[np.float32]:
        """Per-pixel p(object) of an image (or a region of one), float32 in [0, 1]."""
        from engine.tracking._image_kernels import colour_lookup

        lut = self.table() if table is None else table
        if bin_count(image) != len(lut):
            return np.full(image.shape[:2], UNKNOWN, dtype=np.float32)
        result: NDArray[np.float32] = colour_lookup(
            kernel_image(image), _GREY_BITS, _COLOUR_BITS, np.ascontiguousarray(lut)
        )
        return result

    def separation(self) -> float:
        """How distinct the two histograms are: 1 - Bhattacharyya coefficient."""
        return float(1.0 - np.sqrt(self.object_hist * self.background_hist).sum())


class ColourHistogram:
    """Object and background colour histograms, learnt online.

    Parameters
    ----------
    band : int
        :attr:`TrackerOptions.band`: width (pixels) of the background ring.
    learning_rate : float
        :attr:`TrackerOptions.learning_rate`: share of each confident frame
        blended into the histograms (0: learn from the first frame only).

    Attributes
    ----------
    histograms : Histograms or None
        What was learnt (None before the first frame).
    """

    def __init__(self, band: int, learning_rate: float, far_background: float = 0.0) -> None:
        self.band = band
        self.learning_rate = learning_rate
        self.far_background = far_background
        self.histograms: Histograms | None = None

    def fit(self, image: NDArray[np.uint8], nodes: NDArray[np.float64]) -> None:
        """Learn anew from the filled contour, the ring around it and (with
        ``far_background``) the rest of the frame."""
        self.histograms = Histograms.fit(image, nodes, self.band, self.far_background)

    def update(self, image: NDArray[np.uint8], nodes: NDArray[np.float64]) -> None:
        """Blend in a confident frame (see :meth:`Histograms.updated`)."""
        if self.histograms is None:
            self.fit(image, nodes)
        elif self.learning_rate > 0:
            self.histograms = self.histograms.updated(image, nodes, self.band, self.learning_rate)

    def probability(self, image: NDArray[np.uint8]) -> NDArray[np.float32]:
        """Per-pixel p(object), float32 in [0, 1] (0.5 everywhere before the first frame)."""
        if self.histograms is None:
            return np.full(image.shape[:2], UNKNOWN, dtype=np.float32)
        return self.histograms.probability(image)

    def to_state(self) -> dict[str, Any]:
        """``{"kind", "object", "background"}``: compressed histograms (None before fitting)."""
        h = self.histograms
        return {
            "kind": KIND,
            "object": None if h is None else pack_histogram(h.object_hist),
            "background": None if h is None else pack_histogram(h.background_hist),
        }

    def from_state(self, state: Mapping[str, Any]) -> Self:
        """This model's parameters holding ``state`` (of :meth:`to_state`)."""
        check_kind(state, KIND, "appearance")
        restored = type(self)(self.band, self.learning_rate, self.far_background)
        if state.get("object") is not None or state.get("background") is not None:
            obj = unpack_histogram(state["object"])
            bg = unpack_histogram(state["background"])
            if obj.shape != bg.shape:
                raise ValueError("object and background histograms differ in size")
            restored.histograms = Histograms(obj, bg)
        return restored


def _far_histogram(
    frame: NDArray[np.uint8], nodes: NDArray[np.float64], reach: int
) -> NDArray[np.float64] | None:
    """Normalised colour histogram of the frame beyond ``reach`` pixels of the contour
    (a square reach, as the ring's), or None when nothing is that far."""
    inside = contour_to_mask(nodes, frame.shape[:2])
    kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * reach + 1, 2 * reach + 1))
    far = np.asarray(cv2.dilate(inside, kernel), np.uint8) == 0
    bins = quantise(frame)[far]
    if len(bins) == 0:
        return None
    counts = np.bincount(bins, minlength=bin_count(frame)).astype(np.float64)
    result: NDArray[np.float64] = counts / len(bins)
    return result


def _histograms(
    frame: NDArray[np.uint8],
    nodes: NDArray[np.float64],
    band: int,
    table: NDArray[np.float32] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Object and background histograms; with a ``table``, only agreeing pixels."""
    from engine.tracking._image_kernels import taught_counts

    # the ring, two pixels of slack, and one more past the box's exclusive end
    x0, y0, x1, y1 = bounding_box(frame.shape, nodes, band + 2, band + 3, keep_inside=False)
    n_bins = bin_count(frame)
    if x1 <= x0 or y1 <= y0:
        return np.zeros(n_bins), np.zeros(n_bins)
    roi = frame[y0:y1, x0:x1]
    mask = contour_to_mask(nodes - [x0, y0], roi.shape)
    # a square ring: dilation by a rectangle is separable, hence cheap
    kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * band + 1, 2 * band + 1))
    outer = np.asarray(cv2.dilate(mask, kernel), np.uint8)
    inset = np.ones((2 * OBJECT_INSET + 1, 2 * OBJECT_INSET + 1), np.uint8)
    inner = np.asarray(cv2.erode(mask, inset), np.uint8)
    check = table is not None and len(table) == n_bins
    counts = taught_counts(
        kernel_image(roi),
        _GREY_BITS,
        _COLOUR_BITS,
        mask,
        inner,
        outer,
        np.ascontiguousarray(table if check else np.empty(0), np.float32),
        np.float32(TEACH_OBJECT_ABOVE),
        np.float32(TEACH_BACKGROUND_BELOW),
        n_bins,
    )
    obj, bg = (c.astype(np.float64) for c in counts)
    return obj / max(obj.sum(), 1.0), bg / max(bg.sum(), 1.0)
