"""GrabCut for the snap (:mod:`engine.tracking.snap`): OpenCV's iterated cut, the likelihood
of its colour models, and one more cut of the same energy with evidence besides colour.

OpenCV's ``cv2.grabCut`` (Rother et al., "GrabCut", SIGGRAPH 2004) learns a Gaussian
mixture of colours for each side and labels the pixels by a minimum cut of

    E(L) = sum_p -log p(z_p | L_p) + GAMMA sum_{p~q} [L_p != L_q] exp(-beta |z_p - z_q|^2) / |p - q|

over the 8-neighbour grid, ``beta = 1 / (2 <|z_p - z_q|^2>)``.  It takes no evidence but
colour; :func:`cut_with_odds` solves the same energy once more with the learnt models and
added per-pixel log-odds (the snap's motion cue), through PyMaxflow.  Images are indexed
``[y, x]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.special import logsumexp

__all__ = ["MODEL_COMPONENTS", "GrabCut", "cut_with_odds", "grabcut", "log_likelihood"]

SEED = 12345
"""OpenCV's random seed before each GrabCut (k-means starts its colour models):
without it a snap depends on whatever drew random numbers before."""
MODEL_COMPONENTS = 5
"""Gaussians in each of GrabCut's colour models (OpenCV's ``GMM::componentsCount``)."""
GAMMA = 50.0
"""Weight of the smoothness term: OpenCV's (``grabcut.cpp``) and Rother et al.'s value, so
that :func:`cut_with_odds` solves the energy ``cv2.grabCut`` does."""
ODDS_LIMIT = 50.0
"""Colour log-odds are clipped to +-50: a colour one model cannot produce at all (no
component of weight > 0 in reach) would otherwise give an infinite capacity; 50 is far
beyond the odds of any colour the models do produce."""
FIXED = 1e9
"""Capacity that ties a pixel to its side (the outline's outside, the pins)."""


@dataclass(frozen=True)
class GrabCut:
    """GrabCut's labels (``cv2.GC_*``) and its two colour models (OpenCV's 1 x 65 layout)."""

    labels: NDArray[np.uint8]
    background: NDArray[np.float64]
    foreground: NDArray[np.float64]

    @property
    def found(self) -> NDArray[np.uint8]:
        """1 where the labels say object."""
        labels = self.labels
        return np.asarray((labels == cv2.GC_FGD) | (labels == cv2.GC_PR_FGD), np.uint8)

    def odds(self, image: NDArray[np.uint8]) -> NDArray[np.float64]:
        """log p(colour | object) - log p(colour | background) of each pixel, clipped."""
        pixels = image.reshape(-1, 3).astype(np.float64)
        odds = log_likelihood(self.foreground, pixels) - log_likelihood(self.background, pixels)
        clipped = np.clip(np.nan_to_num(odds, nan=0.0), -ODDS_LIMIT, ODDS_LIMIT)
        return clipped.reshape(image.shape[:2])


def grabcut(
    image: NDArray[np.uint8],
    labels: NDArray[np.uint8],
    iterations: int,
    *,
    resume: GrabCut | None = None,
) -> GrabCut | None:
    """``iterations`` of GrabCut from ``labels`` (its models learnt from them, or ``resume``'s
    taken on); None when OpenCV refuses (one label only)."""
    mask = labels.copy()
    if resume is None:
        background, foreground = np.zeros((1, 65)), np.zeros((1, 65))
        mode = cv2.GC_INIT_WITH_MASK
    else:
        background, foreground = resume.background.copy(), resume.foreground.copy()
        mode = cv2.GC_EVAL
    cv2.setRNGSeed(SEED)  # its colour models start from k-means: the same answer every time
    try:
        rect = (0, 0, 1, 1)  # unused: the labels give the start
        cv2.grabCut(image, mask, rect, background, foreground, iterations, mode)
    except cv2.error:
        return None
    return GrabCut(mask, background, foreground)


def log_likelihood(model: NDArray[np.float64], pixels: NDArray[np.float64]) -> NDArray[np.float64]:
    """log p(colour) of (M, 3) ``pixels`` under a GrabCut colour model.

    OpenCV's layout (``grabcut.cpp``, ``GMM``): 5 weights, 5 means of 3, 5
    covariances of 3 x 3; a component of weight 0 is unused.
    """
    k = MODEL_COMPONENTS
    flat = model.reshape(-1)
    weights, means = flat[:k], flat[k : 4 * k].reshape(k, 3)
    covariances = flat[4 * k : 13 * k].reshape(k, 3, 3)
    terms = np.full((len(pixels), k), -np.inf)
    for c in range(k):
        sign, log_det = np.linalg.slogdet(covariances[c])
        if weights[c] <= 0 or sign <= 0:
            continue
        d = pixels - means[c]
        mahalanobis = np.einsum("mi,mi->m", d @ np.linalg.inv(covariances[c]), d)
        terms[:, c] = np.log(weights[c]) - 0.5 * (mahalanobis + log_det + 3 * np.log(2 * np.pi))
    out: NDArray[np.float64] = logsumexp(terms, axis=1)  # -inf where no component is used
    return out


def cut_with_odds(
    image: NDArray[np.uint8], cut: GrabCut, extra: NDArray[np.float64]
) -> NDArray[np.uint8]:
    """GrabCut's energy with ``cut``'s colour models and ``extra`` log-odds added, solved once.

    Parameters
    ----------
    image : numpy.ndarray
        H x W x 3 uint8, the image ``cut`` was made on.
    cut : GrabCut
        Its models give the colour log-odds; its definite labels stay (``GC_BGD``
        background, ``GC_FGD`` object).
    extra : numpy.ndarray
        H x W log-odds of object against background from other evidence.

    Returns
    -------
    numpy.ndarray
        H x W uint8, 1 on the object.
    """
    import maxflow

    z = image.astype(np.float64)
    h, w = z.shape[:2]
    # the four neighbours OpenCV's GrabCut weighs (the other four by symmetry)
    steps = {
        (0, 1): (z[:, 1:] - z[:, :-1], (slice(None), slice(None, -1))),
        (1, 0): (z[1:, :] - z[:-1, :], (slice(None, -1), slice(None))),
        (1, 1): (z[1:, 1:] - z[:-1, :-1], (slice(None, -1), slice(None, -1))),
        (1, -1): (z[1:, :-1] - z[:-1, 1:], (slice(None, -1), slice(1, None))),
    }
    squared = {k: np.sum(d * d, axis=2) for k, (d, _) in steps.items()}
    pairs = sum(s.size for s in squared.values())
    mean = sum(float(s.sum()) for s in squared.values()) / max(pairs, 1)
    beta = 1.0 / (2.0 * mean) if mean > 0 else 0.0
    graph = maxflow.Graph[float]()
    ids = graph.add_grid_nodes((h, w))
    for (dy, dx), square in squared.items():
        weights = np.zeros((h, w))
        weights[steps[(dy, dx)][1]] = GAMMA / np.hypot(dy, dx) * np.exp(-beta * square)
        structure = np.zeros((3, 3))
        structure[1 + dy, 1 + dx] = 1.0
        graph.add_grid_edges(ids, weights=weights, structure=structure, symmetric=True)
    odds = cut.odds(image) + extra
    source, sink = np.maximum(odds, 0.0), np.maximum(-odds, 0.0)
    background, pinned = cut.labels == cv2.GC_BGD, cut.labels == cv2.GC_FGD
    source = np.where(pinned, FIXED, np.where(background, 0.0, source))
    sink = np.where(background, FIXED, np.where(pinned, 0.0, sink))
    graph.add_grid_tedges(ids, source, sink)
    graph.maxflow()
    return np.asarray(~graph.get_grid_segments(ids), np.uint8)
