"""``BandCut``: the default :class:`~engine.tracking.stages.Segmentation`, a joint solve in a band.

The chain's refinement decides each node on its own normal.  Here, as the
leading classic video segmenters do (ObjectFlow, BVS: the propagated mask
as a prior, then one joint segmentation of the region), every pixel within
:attr:`TrackerOptions.cut_band` pixels of the refined contour is labelled
object or background *jointly* by a minimum cut (Boykov-Kolmogorov, through
PyMaxflow), minimising

    E(L) = sum_p U_p(L_p) + sum_{p~q} V_pq [L_p != L_q]

with U the log-odds of the local colour models (:mod:`engine.tracking.local_colour`,
falling back to the global one) plus a shape prior (the signed distance to
the refined contour), and V a contrast-sensitive smoothness.  Pixels beyond
the band keep the side the chain gave them, so the cut can move the
boundary by at most the band per frame: it pulls in thin parts (legs,
wings) and lets go of leaks the chain would carry on, and cannot run away
with the background.  Beyond the band, only what is plain in the cut's p(object)
changes (:mod:`engine.tracking.beyond_band`): a part the contour lost is taken back,
background seen through a gap that opened inside the object is left out, and the
object's part beyond a thin strip that looks like background (a pole, a bar in front
of it) is joined while it lies inside the object's remembered outline.  The
largest piece of the cut becomes the contour again; when the cut splits the
object into comparable pieces (an occluder across it), the chain's contour is
kept, since one contour cannot follow both.  Coordinates are ``[x, y]`` pixels.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, Self

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import contour_to_mask, mask_to_contour, perimeter
from engine.tracking.beyond_band import bridge, carve, regrow
from engine.tracking.local_colour import MAX_HALF, MIN_HALF, LocalColour
from engine.tracking.maps import Maps
from engine.tracking.motion_contrast import with_motion
from engine.tracking.stages import Frame, Move, check_kind

__all__ = ["BandCut"]

KIND = "band-cut"

COLOUR_WEIGHT = 1.0
"""Weight of the colour log-odds in the unary term (the unit of the energy)."""
SHAPE_WEIGHT = 3.0
"""Weight of the shape prior: 3 log-odds per :data:`SHAPE_SCALE` pixels from
the chain's contour, so only colour at least that sure moves the boundary
that far (on the thirty training sequences 1 let leaks grow, 3 and 6 scored
within 0.005 of each other)."""
SHAPE_SCALE = 4.0
"""Pixels over which the shape prior gains :data:`SHAPE_WEIGHT` log-odds."""
SMOOTHNESS = 2.0
"""Cost of cutting a link between two pixels of equal colour (GrabCut's
order of magnitude relative to the colour term)."""
SPLIT_SHARE = 0.1
"""A second piece of the cut covering more than 10 % of the first piece's
share of the prior means the object was split: keep the chain's contour."""
MIN_PIXELS = 20
"""A cut piece smaller than this is noise, not the object."""
MAX_BAND_PIXELS = 12_000
"""A band with more pixels than this (a large object's) is cut at half
resolution: a pixel there is still under 1 % of the object's width, and the
cut stays within the frame's time budget."""
FINE_INSIDE = 2
"""Pixels inside a half-resolution cut's boundary that the second, full-resolution cut
may relabel (:attr:`TrackerOptions.full_resolution_edges`): the half-resolution
boundary is placed to 2 px, and this much freedom places it to the pixel."""
FINE_OUTSIDE = 1
"""Pixels outside it that the second cut may relabel.  On the thirty training sequences
over five node counts, inside / outside 1 / 1, 1 / 2, 2 / 1, 2 / 2 and 3 / 3 gave J 0.7384,
0.7402, 0.7420, 0.7426 and 0.7374 (``docs/tracking-log.md``): the layer outside costs a
quarter of the cut's time for 0.0006."""
FINE_MARGIN = 3
"""Half-resolution pixels kept round the box of the piece that the full-resolution cut
refines: its relabelled pixels and their links reach FINE_OUTSIDE + 1 full-resolution
pixels beyond the piece, and three half-resolution pixels (six full) keep even the
bilinear scaling's border out of their reach, so the cut of the crop is the cut of the
whole region pixel for pixel, on a fraction of its pixels."""
MIN_OVERLAP = 0.3
"""The kept piece must cover 30 % of the chain's silhouette: a cut that lost
most of the object is not trusted over the chain."""


class BandCut:
    """Joint object/background labelling of a band around the contour, local colour models.

    Parameters
    ----------
    band : int
        :attr:`TrackerOptions.cut_band`: pixels on each side of the refined
        contour that the cut may relabel (0 disables the stage).
    bridge : bool, default False
        :attr:`TrackerOptions.bridge_strips`: take back the object's part beyond a
        thin background-looking strip, inside the remembered outline
        (:func:`engine.tracking.beyond_band.bridge`).
    carve : bool, default False
        :attr:`TrackerOptions.carve_gaps`: leave out the background seen through a gap
        that opened inside the object (:func:`engine.tracking.beyond_band.carve`).
    fine : bool, default False
        :attr:`TrackerOptions.full_resolution_edges`: a large object's cut, made at half
        resolution, is followed by a second cut at full resolution within
        :data:`FINE_INSIDE` / :data:`FINE_OUTSIDE` pixels of its boundary.
    """

    def __init__(
        self, band: int, bridge: bool = False, carve: bool = False, fine: bool = False
    ) -> None:
        self.band = band
        self.bridge = bridge
        self.carve = carve
        self.fine = fine
        self._windows: LocalColour | None = None

    def start(self, image: Frame, nodes: NDArray[np.float64]) -> None:
        """Learn the local colour models from the first frame's contour."""
        self._windows = LocalColour.learn(image, nodes) if self.band else None

    def learn(self, image: Frame, nodes: NDArray[np.float64]) -> None:
        """Relearn the local colour models from this frame's final contour."""
        self.start(image, nodes)

    def rescale(self, move: Move, factor: float) -> None:
        """The local colour models' windows on another grid
        (:func:`engine.tracking.regrid.follow_size`): ``factor`` as large in its pixels (their
        counts are colours, not places; ``move`` is not needed)."""
        if self._windows is not None:
            half = min(MAX_HALF, max(MIN_HALF, round(self._windows.half * factor)))
            self._windows = dataclasses.replace(self._windows, half=half)

    def segment(
        self,
        image: Frame,
        maps: Maps,
        predicted: NDArray[np.float64],
        refined: NDArray[np.float64],
        *,
        outline: NDArray[np.float64] | None = None,
    ) -> NDArray[np.float64] | None:
        """The contour of the cut, or None to keep the chain's ``refined`` contour.

        Parameters
        ----------
        image : numpy.ndarray
            The frame (BGR or grey).
        maps : Maps
            The frame's cue maps (their ``probability`` is the global model's
            p(object), occluders made neutral).
        predicted : numpy.ndarray
            (N, 2) ``[x, y]`` predicted contour: where the local windows sit.
        refined : numpy.ndarray
            (N, 2) ``[x, y]`` contour refined by the chain: the shape prior.
        outline : numpy.ndarray, optional
            (M, 2) ``[x, y]`` remembered outline of the object, moved with it
            (:mod:`engine.tracking.shape_memory`): where a part beyond a strip may be
            taken back, with ``bridge``.
        """
        if not self.band:
            return None
        x0, y0 = maps.origin
        h, w = maps.probability.shape
        if h < 3 or w < 3:
            return None
        scale = _scale(refined, self.band)
        region = full = image[y0 : y0 + h, x0 : x0 + w]
        probability, observed, motion = maps.probability, maps.observed, maps.motion
        if scale > 1:  # a large object: the whole cut at half resolution
            # an exact halving (even sides) takes OpenCV's fast area-averaging path
            small = (w // scale, h // scale)
            region = _shrink(region, small, scale)
            probability = _shrink(probability, small, scale)
            observed = None if observed is None else _shrink(observed, small, scale)
            motion = None if motion is None else _shrink(motion, small, scale)
        points = (refined - [x0, y0] + 0.5) / scale - 0.5
        inside = (contour_to_mask(points, region.shape) > 0).astype(np.uint8)
        if not inside.any():
            return None
        distance = _signed_distance(inside)
        band = self.band / scale
        if self._windows is not None:
            wanted = (np.abs(distance) <= band).astype(np.uint8)
            local = self._windows.probability(
                region, (x0, y0), predicted, probability, wanted, scale=scale
            )
            if motion is not None:
                local = with_motion(np.asarray(local, np.float32), motion)
            local = np.asarray(local, np.float32)
            # occluded pixels stay neutral, as the cue stage made them: written in place
            # into ``local``, new here unless it is ``probability`` itself (no window knew
            # better), which has them already
            if observed is not None and local is not probability:
                np.copyto(local, probability, where=probability != observed)
            probability = local
        seg = regrow(_cut(distance, band, region, probability, scale), distance, band, probability)
        if self.carve:
            seg = carve(seg, distance, band, probability)
        if self.bridge and outline is not None:
            remembered = contour_to_mask((outline - [x0, y0] + 0.5) / scale - 0.5, region.shape)
            # the outline's own edge pixels are left out: it is only roughly aligned
            seg = bridge(seg, probability, np.asarray(cv2.erode(remembered, _CROSS)) > 0)
        piece = _main_piece(seg, inside)
        if piece is None:
            return None
        if scale > 1 and self.fine:
            found = _full_resolution(piece, full, probability, len(refined))
        else:
            found = (mask_to_contour(piece, len(refined)) + 0.5) * scale - 0.5
        return found + np.asarray([x0, y0], dtype=np.float64)

    def to_state(self) -> dict[str, Any]:
        """``{"kind", "windows": local colour state or None}``."""
        windows = None if self._windows is None else self._windows.to_state()
        return {"kind": KIND, "windows": windows}

    def from_state(self, state: Mapping[str, Any]) -> Self:
        """This stage holding ``state`` (of :meth:`to_state`)."""
        check_kind(state, KIND, "segmentation")
        restored = type(self)(self.band, self.bridge, self.carve, self.fine)
        windows = state.get("windows")
        if windows is not None:
            restored._windows = LocalColour.from_state(windows)
        return restored


def _shrink(image: NDArray[Any], size: tuple[int, int], scale: int) -> NDArray[Any]:
    """``image`` (cropped to ``scale`` x ``size``) shrunk to ``size`` (width, height) by area."""
    w, h = size
    whole = image[: h * scale, : w * scale]
    return np.asarray(cv2.resize(whole, size, interpolation=cv2.INTER_AREA), dtype=image.dtype)


def _signed_distance(inside: NDArray[np.uint8]) -> NDArray[np.float32]:
    """Distance (pixels) to the silhouette's edge, > 0 inside."""
    return np.asarray(
        cv2.distanceTransform(inside, cv2.DIST_L2, 3)
        - cv2.distanceTransform(1 - inside, cv2.DIST_L2, 3),
        dtype=np.float32,
    )


def _scale(nodes: NDArray[np.float64], band: int) -> int:
    """1, or 2 when the band has more than :data:`MAX_BAND_PIXELS` pixels (a large object)."""
    return 2 if 2 * band * perimeter(nodes) > MAX_BAND_PIXELS else 1


def _cut(
    distance: NDArray[np.float32],
    band: float,
    region: NDArray[np.uint8],
    probability: NDArray[np.float32],
    scale: int,
) -> NDArray[np.bool_]:
    """Object mask of the region: the fixed sides beyond the band, the minimum cut within."""
    import maxflow

    from engine.tracking._cut_kernels import band_graph, settle

    image = np.ascontiguousarray(region)
    image = image[..., None] if image.ndim == 2 else image
    weights = np.array([COLOUR_WEIGHT, SHAPE_WEIGHT, SMOOTHNESS, SHAPE_SCALE / scale])
    pixels, source, sink, neighbours, capacities = band_graph(
        distance, band, image, np.ascontiguousarray(probability, dtype=np.float32), weights
    )
    seg = (distance > band).ravel()
    if len(pixels):
        side, free, source, sink, i, j, cost = settle(source, sink, neighbours, capacities)
        seg[pixels] = side > 0
        if len(free):
            graph = maxflow.Graph[float](len(free), len(i))
            nodes = graph.add_nodes(len(free))
            graph.add_edges(i, j, cost, cost)
            graph.add_grid_tedges(nodes, source, sink)
            graph.maxflow()
            seg[pixels[free]] = ~graph.get_grid_segments(nodes)
    return seg.reshape(distance.shape)


_CROSS = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
"""A pixel and its four neighbours."""


def _main_piece(seg: NDArray[np.bool_], prior: NDArray[np.uint8]) -> NDArray[np.bool_] | None:
    """The cut's piece that covers most of the prior (None: keep the chain's contour)."""
    from engine.tracking._label_kernels import label_shares

    pieces, labels = cv2.connectedComponents(seg.astype(np.uint8), connectivity=8)
    if pieces < 2:
        return None
    counts, covered = label_shares(np.asarray(labels, np.int32), prior, pieces)
    share = counts[1:]
    best = int(np.argmax(share))
    piece: NDArray[np.bool_] = labels == best + 1
    size = int(np.count_nonzero(piece))
    second = np.sort(share)[-2] if len(share) > 1 else 0
    if (
        size <= MIN_PIXELS
        or share[best] <= MIN_OVERLAP * covered
        or second > SPLIT_SHARE * share[best]
    ):
        return None
    return piece


def _full_resolution(
    piece: NDArray[np.bool_],
    region: NDArray[np.uint8],
    probability: NDArray[np.float32],
    count: int,
) -> NDArray[np.float64]:
    """``[x, y]`` contour (full-resolution region pixels) of a half-resolution piece, recut.

    The piece (of a cut at half resolution, whose p(object) is ``probability``) is
    scaled up, and every pixel within :data:`FINE_INSIDE` inside its boundary or
    :data:`FINE_OUTSIDE` outside is labelled again by :func:`_cut` on the
    full-resolution ``region``: the colour term read
    from ``probability`` scaled up, the smoothness from the full-resolution edges.
    "Within" is counted in 4-connected layers, not as the Euclidean distance: a
    few erosions and dilations cost a fraction of a distance transform of a large
    region, and the layers differ from it only along diagonals, by under a pixel.
    """
    # only the piece's box and its surroundings are read: every relabelled pixel, its
    # links and their far ends lie within FINE_OUTSIDE + 1 of the piece
    x, y, box_w, box_h = cv2.boundingRect(piece.astype(np.uint8))
    x0, y0 = max(x - FINE_MARGIN, 0), max(y - FINE_MARGIN, 0)
    x1 = min(x + box_w + FINE_MARGIN, piece.shape[1])
    y1 = min(y + box_h + FINE_MARGIN, piece.shape[0])
    piece, probability = piece[y0:y1, x0:x1], probability[y0:y1, x0:x1]
    region = region[2 * y0 : 2 * y1, 2 * x0 : 2 * x1]
    h, w = piece.shape
    size = (2 * w, 2 * h)
    # linear, not nearest: the half-resolution staircase does not become the prior
    scaled = cv2.resize(piece.astype(np.float32), size, interpolation=cv2.INTER_LINEAR)
    inside = (scaled > 0.5).astype(np.uint8)
    # a pixel's layer: how many erosions it survives (inside) or dilations reach it
    layers = inside.copy()
    eroded, dilated = inside, inside
    for _ in range(FINE_INSIDE):
        eroded = np.asarray(cv2.erode(eroded, _CROSS))
        layers += eroded
    for _ in range(FINE_OUTSIDE):
        dilated = np.asarray(cv2.dilate(dilated, _CROSS))
        layers += dilated
    # layers 0 .. FINE_OUTSIDE + 1 + FINE_INSIDE from far outside to deep inside; as
    # distances: +-0.5 at the edge, the ones beyond the free layers fixed
    band = max(FINE_INSIDE, FINE_OUTSIDE)
    table = np.arange(256, dtype=np.float32) - np.float32(FINE_OUTSIDE + 0.5)
    table[0], table[FINE_OUTSIDE + FINE_INSIDE + 1] = -band - 0.5, band + 0.5
    distance = np.asarray(cv2.LUT(layers, table), np.float32)
    upscaled = np.asarray(cv2.resize(probability, size, interpolation=cv2.INTER_LINEAR), np.float32)
    seg = _cut(distance, band, region, upscaled, 1)
    return mask_to_contour(seg if seg.any() else inside, count, offset=(2 * x0, 2 * y0))
