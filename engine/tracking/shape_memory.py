"""Shape memory: a node the image says nothing about rests on the object's remembered outline.

Holding (:mod:`engine.tracking.holding`) keeps a node without a colour step
across the contour on the *predicted* shape, but the prediction is the last
contour moved on.  Whatever a frame's cues push such a node by (the cut
taking in a few pixels of the object's colour, an edge of same-coloured
background coming within reach) is kept, and frame after frame the contour
creeps into background that looks like the object, never to come back.

So the tracker remembers the outline it was given on the first frame (the
one contour known to be right), carries it with the object's similarity
motion and re-aligns it every frame, robustly (least median of squares), to
the nodes that do have boundary evidence.  A node that was held on the first
frame, still shows no colour step, and lies outside the remembered outline
rests on it (the rest shape X0 of the refinement, paper eq. 13-16) instead of
on the prediction.  A node with evidence is never moved: a genuine change of
shape where the image shows it (a vault, a dancer's arms) is followed, and
held nodes between free ones follow them through the chain.
Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from engine.geometry import fit_similarity, nearest, outward_normals, resample
from engine.physics import deform

__all__ = ["DENSITY", "FREE_BELOW", "MIN_FREE", "SPREAD", "follow", "marks_at", "rest_on"]

FREE_BELOW = 0.5
"""A node held less than this (:func:`engine.tracking.holding.hold_factors`) had a
colour step on the first frame: its place is evidence, and it aligns the outline."""
MIN_FREE = 8
"""Fewer free nodes than this cannot fix a similarity robustly: the outline then
only moves with the object's motion."""
DENSITY = 4
"""Points per node of the outline a node is put back on: the nearest of them is
within an eighth of a node spacing of the nearest point of the outline."""
SPREAD = 5.0
"""``a`` of the chain that spreads the pull back onto the outline over the
neighbouring nodes (1/e over about two nodes): a node put back while its
neighbour is not (it sees a colour step) would leave a spike in the rest shape,
which the chain then keeps and which grows into the background.  Compared on
seven seeds of the synthetic ``no_contrast_stretch``: mean IoU 0.939 without
spreading (seeds 3-6 spiked), 0.944, 0.956, 0.948 and 0.932 with ``a`` = 2, 5,
10 and 20; on the thirty training sequences J 0.689 against 0.687 without."""


def follow(
    outline: NDArray[np.float64],
    motion: NDArray[np.float64],
    nodes: NDArray[np.float64],
    hold: NDArray[np.float64],
) -> NDArray[np.float64]:
    """The remembered outline moved by the object's motion, then aligned to the free nodes.

    Parameters
    ----------
    outline : numpy.ndarray
        (M, 2) ``[x, y]`` remembered outline in the previous frame.
    motion : numpy.ndarray
        2 x 3 similarity of the object from the previous frame to this one
        (:attr:`engine.tracking.stages.Prediction.matrix`).
    nodes : numpy.ndarray
        (N, 2) ``[x, y]`` predicted contour in this frame.
    hold : numpy.ndarray
        (N,) per node of ``nodes``, in [0, 1]: how far it is held; the nodes
        held less than :data:`FREE_BELOW` align the outline.

    Returns
    -------
    numpy.ndarray
        (M, 2) the outline in this frame: moved by ``motion``, then by the
        similarity (least median of squares) that best lays it onto the free
        nodes, each paired with its nearest outline point.
    """
    moved = outline @ motion[:, :2].T + motion[:, 2]
    free = hold < FREE_BELOW
    if len(hold) != len(nodes) or np.count_nonzero(free) < MIN_FREE:
        return moved
    dense = resample(moved, DENSITY * len(moved))
    targets = nodes[free]
    fit, _ = fit_similarity(dense[nearest(targets, dense)], targets, method="lmeds")
    if fit is None:
        return moved
    aligned: NDArray[np.float64] = moved @ fit[:, :2].T + fit[:, 2]
    return aligned


def marks_at(
    nodes: NDArray[np.float64], outline: NDArray[np.float64], marks: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Per node of ``nodes`` (``[x, y]``), the mark of the nearest point of ``outline``.

    ``marks`` (one per point of ``outline``, in [0, 1]) say how far each was held on the
    first frame; riding on the outline, they turn with the object
    (:mod:`engine.tracking.turn`), where marks carried from node to node stay where the
    contour's nodes are.
    """
    if len(marks) != len(outline):
        raise ValueError(f"expected {len(outline)} marks, one per outline point; got {len(marks)}")
    found: NDArray[np.float64] = np.asarray(marks, np.float64)[nearest(nodes, outline)]
    return found


def rest_on(
    nodes: NDArray[np.float64], outline: NDArray[np.float64], weight: NDArray[np.float64]
) -> NDArray[np.float64]:
    """``nodes`` outside the outline moved towards their nearest point of it by ``weight``,
    the moves spread along the chain (:data:`SPREAD`).

    Parameters
    ----------
    nodes : numpy.ndarray
        (N, 2) ``[x, y]`` predicted contour.
    outline : numpy.ndarray
        (M, 2) ``[x, y]`` remembered outline in this frame (:func:`follow`).
    weight : numpy.ndarray
        (N,) in [0, 1]: 1 moves a node onto the outline, 0 does not move it
        itself.  Nodes inside the outline do not move themselves whatever their
        weight: the memory stops a creep outwards, it does not stretch a
        contour that fell short.  Each node then moves by the chain's
        equilibrium under these moves as forces, ``deform(moves, SPREAD)``
        (paper eq. 13-16): a stretch of nodes put back moves nearly as a
        whole, a lone node carries its neighbours part of the way.

    Returns
    -------
    numpy.ndarray
        (N, 2) the contour, ``nodes`` itself when no node moves.
    """
    if len(weight) != len(nodes) or not np.any(weight > 0):
        return nodes
    dense = resample(outline, DENSITY * len(outline))
    closest = nearest(nodes, dense)
    target = dense[closest]
    outside = np.einsum("ij,ij->i", nodes - target, outward_normals(dense)[closest]) > 0
    share = np.where(outside, np.clip(weight, 0.0, 1.0), 0.0)
    if not share.any():
        return nodes
    # spread along the chain: a node put back while its neighbour is not leaves no spike
    pull = deform(share[:, None] * (target - nodes), SPREAD)
    result: NDArray[np.float64] = nodes + pull
    return result
