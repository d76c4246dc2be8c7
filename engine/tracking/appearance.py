"""``ColourHistogram``: the default :class:`~engine.tracking.stages.AppearanceModel`.

The object's colour histogram comes from inside the contour, the
background's from a band just outside it; the posterior
p(object | colour) is looked up per pixel.  Coordinates are ``[x, y]``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Self

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import bounding_box, contour_to_mask
from engine.tracking._state_codec import pack_histogram, unpack_histogram
from engine.tracking.stages import check_kind

__all__ = [
    "COLOUR_BITS",
    "LEGACY_COLOUR_BITS",
    "MAX_COLOUR_BITS",
    "ColourHistogram",
    "Histograms",
    "bin_count",
    "kernel_image",
    "quantise",
]

KIND = "colour-histogram"

COLOUR_BITS = 5
"""32 levels per BGR channel, 32768 bins.  At 16 levels (4 bits) a colour 8 levels off the
object's fell into the object's own bins half the time: the synthetic ``matched_background``
(the object's colour, 8 levels bluer) missed its goal on 11 of 24 seeds (mean IoU 0.887),
none at 32 levels (0.987).  The thirty DAVIS training sequences, over five node counts,
0.7457 at 16 levels, 0.7490 at 32 (see docs/tracking-log.md).  A few thousand object pixels
leave most bins empty; :data:`PRIOR` makes an unseen colour neutral."""
COMPACT_DTYPE = "float16"
"""A compact state's histograms: three significant digits, enough to read p(object) by."""
MAX_COLOUR_BITS = 5
"""Bins are ``uint16``: 3 x 5 bits is the most that fits."""
LEGACY_COLOUR_BITS = 4
"""The resolution of histograms saved before :data:`COLOUR_BITS` became 5 (4096 bins): a
tracker state written then resumes at it, so its tracks do not change."""
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
    image: NDArray[np.uint8], grey_bits: int = _GREY_BITS, colour_bits: int = COLOUR_BITS
) -> NDArray[np.uint16]:
    """Histogram bin of every pixel (by default BGR: 32^3 bins; grey: 32), one compiled pass."""
    from engine.tracking._image_kernels import colour_bins

    bins: NDArray[np.uint16] = colour_bins(kernel_image(image), grey_bits, colour_bits)
    return bins


def kernel_image(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """A contiguous H x W x C view or copy (grey images get C = 1), as the colour kernels take."""
    arr = np.ascontiguousarray(image, dtype=np.uint8)
    return arr[..., None] if arr.ndim == 2 else arr


def bin_count(
    image: NDArray[np.uint8], grey_bits: int = _GREY_BITS, colour_bits: int = COLOUR_BITS
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
    colour_bits : int, default :data:`COLOUR_BITS`
        Levels per BGR channel, as a power of two, of colour frames' bins
        (grey frames always have 32 bins).
    """

    object_hist: NDArray[np.float64]
    background_hist: NDArray[np.float64]
    colour_bits: int = COLOUR_BITS
    _table: list[NDArray[np.float32]] = field(
        default_factory=list, init=False, repr=False, compare=False
    )
    """The table of :meth:`table`, once made (the histograms never change)."""

    @classmethod
    def fit(
        cls,
        frame: NDArray[np.uint8],
        nodes: NDArray[np.float64],
        band: int,
        far: float = 0.0,
        colour_bits: int = COLOUR_BITS,
    ) -> Histograms:
        """Histograms from the filled contour and a ``band``-pixel ring around it.

        With ``far`` in (0, 1], that share of the background histogram comes from
        the whole frame beyond ``2 * band`` pixels of the contour (:func:`_far_histogram`)
        and the rest from the ring.  ``nodes`` are ``[x, y]`` pixels.
        """
        obj, bg = _histograms(frame, nodes, band, colour_bits)
        if far > 0:
            seen = _far_histogram(frame, nodes, FAR_RINGS * band, colour_bits)
            if seen is not None:
                bg = (1.0 - far) * bg + far * seen
        return cls(obj, bg, colour_bits)

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
        obj, bg = _histograms(frame, nodes, band, self.colour_bits, self.table())
        if obj.shape != self.object_hist.shape:
            return Histograms(obj, bg, self.colour_bits)

        from engine.tracking._histogram_kernels import blended

        return Histograms(
            blended(self.object_hist, obj, rate),
            blended(self.background_hist, bg, rate),
            self.colour_bits,
        )

    def table(self) -> NDArray[np.float32]:
        """p(object | bin), with a weak prior of 0.5 for rarely seen colours (made once
        per histograms: the frame's attempts and the update that follows share it, so
        it is not to be written to)."""
        from engine.tracking._histogram_kernels import odds_table

        if not self._table:
            self._table.append(odds_table(self.object_hist, self.background_hist, PRIOR))
        return self._table[0]

    def probability(
        self, image: NDArray[np.uint8], table: NDArray[np.float32] | None = None
    ) -> NDArray[np.float32]:
        """Per-pixel p(object) of an image (or a region of one), float32 in [0, 1]."""
        from engine.tracking._image_kernels import colour_lookup

        lut = self.table() if table is None else table
        if bin_count(image, colour_bits=self.colour_bits) != len(lut):
            return np.full(image.shape[:2], UNKNOWN, dtype=np.float32)
        result: NDArray[np.float32] = colour_lookup(
            kernel_image(image), _GREY_BITS, self.colour_bits, np.ascontiguousarray(lut)
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
    far_background : float, default 0
        :attr:`TrackerOptions.far_background`: share of the first frame's background
        histogram drawn from the whole frame (:meth:`Histograms.fit`).
    colour_bits : int, default :data:`COLOUR_BITS`
        Levels per BGR channel, as a power of two (1 to :data:`MAX_COLOUR_BITS`), of the
        histograms it learns (:attr:`TrackerOptions.colour_bits`).

    Attributes
    ----------
    histograms : Histograms or None
        What was learnt (None before the first frame).

    Raises
    ------
    ValueError
        If ``colour_bits`` is not an integer from 1 to :data:`MAX_COLOUR_BITS`.
    """

    def __init__(
        self,
        band: int,
        learning_rate: float,
        far_background: float = 0.0,
        colour_bits: int = COLOUR_BITS,
    ) -> None:
        if (
            isinstance(colour_bits, bool)
            or not isinstance(colour_bits, int | np.integer)
            or not 1 <= colour_bits <= MAX_COLOUR_BITS
        ):
            raise ValueError(
                f"colour_bits must be an integer from 1 to {MAX_COLOUR_BITS}, got {colour_bits!r}"
            )
        self.band = band
        self.learning_rate = learning_rate
        self.far_background = far_background
        self.colour_bits = int(colour_bits)
        self.histograms: Histograms | None = None

    def fit(self, image: NDArray[np.uint8], nodes: NDArray[np.float64]) -> None:
        """Learn anew from the filled contour (``[x, y]`` pixels), the ring around it and
        (with ``far_background``) the rest of the frame."""
        self.histograms = Histograms.fit(
            image, nodes, self.band, self.far_background, self.colour_bits
        )

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

    def to_compact_state(self) -> dict[str, Any]:
        """:meth:`to_state` with the histograms to three digits (float16): at 32 levels
        a quarter of the exact state's size, so a compact tracker state stays small."""
        h = self.histograms
        return {
            "kind": KIND,
            "object": None if h is None else pack_histogram(h.object_hist, COMPACT_DTYPE),
            "background": None if h is None else pack_histogram(h.background_hist, COMPACT_DTYPE),
            "dtype": COMPACT_DTYPE,
        }

    def from_state(self, state: Mapping[str, Any]) -> Self:
        """This model's parameters holding ``state`` (of :meth:`to_state` or
        :meth:`to_compact_state`).

        Raises
        ------
        ValueError
            If the state holds one histogram without the other, or colour histograms
            of another resolution than ``colour_bits``.
        """
        check_kind(state, KIND, "appearance")
        texts = state.get("object"), state.get("background")
        if texts == (None, None):
            return type(self)(self.band, self.learning_rate, self.far_background, self.colour_bits)
        obj_text, bg_text = texts
        if not isinstance(obj_text, str) or not isinstance(bg_text, str):
            raise ValueError("appearance state must hold both histograms (base64 text) or neither")
        dtype = state.get("dtype", "float64")
        if not isinstance(dtype, str):
            raise ValueError(f"appearance state's dtype must be text, got {dtype!r}")
        obj, bg = unpack_histogram(obj_text, dtype), unpack_histogram(bg_text, dtype)
        if obj.shape != bg.shape:
            raise ValueError("object and background histograms differ in size")
        if len(obj) not in (1 << _GREY_BITS, 1 << (3 * self.colour_bits)):
            raise ValueError(
                f"colour histograms of {len(obj)} bins are not of colour_bits={self.colour_bits}"
            )
        restored = type(self)(self.band, self.learning_rate, self.far_background, self.colour_bits)
        restored.histograms = Histograms(obj, bg, self.colour_bits)
        return restored


def _far_histogram(
    frame: NDArray[np.uint8], nodes: NDArray[np.float64], reach: int, colour_bits: int
) -> NDArray[np.float64] | None:
    """Normalised colour histogram of the frame beyond ``reach`` pixels of the contour
    (a square reach, as the ring's), or None when nothing is that far."""
    inside = contour_to_mask(nodes, frame.shape[:2])
    kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * reach + 1, 2 * reach + 1))
    far = np.asarray(cv2.dilate(inside, kernel), np.uint8) == 0
    bins = quantise(frame, colour_bits=colour_bits)[far]
    if len(bins) == 0:
        return None
    counts = np.bincount(bins, minlength=bin_count(frame, colour_bits=colour_bits))
    counts = counts.astype(np.float64)
    result: NDArray[np.float64] = counts / len(bins)
    return result


def _histograms(
    frame: NDArray[np.uint8],
    nodes: NDArray[np.float64],
    band: int,
    colour_bits: int,
    table: NDArray[np.float32] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Object and background histograms; with a ``table``, only agreeing pixels."""
    from engine.tracking._histogram_kernels import shares
    from engine.tracking._image_kernels import taught_counts

    # the ring, two pixels of slack, and one more past the box's exclusive end
    x0, y0, x1, y1 = bounding_box(frame.shape, nodes, band + 2, band + 3, keep_inside=False)
    n_bins = bin_count(frame, colour_bits=colour_bits)
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
        colour_bits,
        mask,
        inner,
        outer,
        np.ascontiguousarray(table if check else np.empty(0), np.float32),
        np.float32(TEACH_OBJECT_ABOVE),
        np.float32(TEACH_BACKGROUND_BELOW),
        n_bins,
    )
    return shares(counts[0]), shares(counts[1])
