"""Object-versus-background colour model: histograms and a probability map.

The object's colour histogram comes from inside the contour, the
background's from a band just outside it; the posterior
p(object | colour) is looked up per pixel.  Coordinates are ``[x, y]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import contour_to_mask

__all__ = ["AppearanceModel"]

_COLOUR_BITS = 4  # 16 levels per channel: 4096 colour bins
_GREY_BITS = 5  # 32 grey levels


def quantise(image: NDArray[np.uint8]) -> NDArray[np.uint16]:
    """Histogram bin of every pixel (BGR: 16^3 bins; grey: 32 bins), one compiled pass."""
    from engine._image_kernels import colour_bins

    bins: NDArray[np.uint16] = colour_bins(_three_d(image), _GREY_BITS, _COLOUR_BITS)
    return bins


def _three_d(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """A contiguous H x W x C view or copy (grey images get C = 1), for the kernels."""
    arr = np.ascontiguousarray(image, dtype=np.uint8)
    return arr[..., None] if arr.ndim == 2 else arr


def bin_count(image: NDArray[np.uint8]) -> int:
    """Number of histogram bins for frames like ``image``."""
    return 1 << (_GREY_BITS if image.ndim == 2 else 3 * _COLOUR_BITS)


@dataclass(frozen=True, slots=True)
class AppearanceModel:
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
        cls, frame: NDArray[np.uint8], nodes: NDArray[np.float64], band: int
    ) -> AppearanceModel:
        """Histograms from the filled contour and a ``band``-pixel ring around it."""
        obj, bg = _histograms(frame, nodes, band)
        return cls(obj, bg)

    def updated(
        self, frame: NDArray[np.uint8], nodes: NDArray[np.float64], band: int, rate: float
    ) -> AppearanceModel:
        """Blend in the histograms of a new frame with weight ``rate``.

        Only pixels the current model already finds object-like (p > 0.55)
        teach the object histogram, and only pixels it does not find clearly
        object-like (p < 0.9) teach the background's: an occluder crossing
        the contour, or a contour that lags behind the object, does not leak
        into the wrong histogram.
        """
        obj, bg = _histograms(frame, nodes, band, self.table())
        if obj.shape != self.object_hist.shape:
            return AppearanceModel(obj, bg)

        def blend(old: NDArray[np.float64], new: NDArray[np.float64]) -> NDArray[np.float64]:
            return old if new.sum() == 0 else (1 - rate) * old + rate * new  # nothing learnt

        return AppearanceModel(blend(self.object_hist, obj), blend(self.background_hist, bg))

    def table(self) -> NDArray[np.float32]:
        """p(object | bin), with a weak prior of 0.5 for rarely seen colours."""
        prior = 1e-3
        o, b = self.object_hist + prior / len(self.object_hist), self.background_hist
        b = b + prior / len(b)
        return np.asarray(o / (o + b), dtype=np.float32)

    def probability(
        self, image: NDArray[np.uint8], table: NDArray[np.float32] | None = None
    ) -> NDArray[np.float32]:
        """Per-pixel p(object) of an image (or a region of one), float32 in [0, 1]."""
        from engine._image_kernels import colour_lookup

        lut = self.table() if table is None else table
        if bin_count(image) != len(lut):
            return np.full(image.shape[:2], 0.5, dtype=np.float32)
        result: NDArray[np.float32] = colour_lookup(
            _three_d(image), _GREY_BITS, _COLOUR_BITS, np.ascontiguousarray(lut)
        )
        return result

    def separation(self) -> float:
        """How distinct the two histograms are: 1 - Bhattacharyya coefficient."""
        return float(1.0 - np.sqrt(self.object_hist * self.background_hist).sum())


def _histograms(
    frame: NDArray[np.uint8],
    nodes: NDArray[np.float64],
    band: int,
    table: NDArray[np.float32] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Object and background histograms; with a ``table``, only agreeing pixels."""
    h, w = frame.shape[:2]
    x0, y0 = np.floor(nodes.min(axis=0)).astype(int) - band - 2
    x1, y1 = np.ceil(nodes.max(axis=0)).astype(int) + band + 3
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    n_bins = bin_count(frame)
    if x1 <= x0 or y1 <= y0:
        return np.zeros(n_bins), np.zeros(n_bins)
    roi = frame[y0:y1, x0:x1]
    mask = contour_to_mask(nodes - [x0, y0], roi.shape)
    # a square ring: dilation by a rectangle is separable, hence cheap
    kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * band + 1, 2 * band + 1))
    outer = cv2.dilate(mask, kernel) > 0
    inner = cv2.erode(mask, np.ones((5, 5), np.uint8)) > 0
    bins = quantise(roi)
    ring = outer & (mask == 0)
    if table is not None and len(table) == n_bins:
        p = table[bins]
        inner &= p > 0.55
        ring &= p < 0.9
    obj = np.bincount(bins[inner], minlength=n_bins).astype(np.float64)
    bg = np.bincount(bins[ring], minlength=n_bins).astype(np.float64)
    return obj / max(obj.sum(), 1.0), bg / max(bg.sum(), 1.0)
