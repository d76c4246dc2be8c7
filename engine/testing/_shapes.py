"""Shapes of the synthetic conditions that are not one smooth blob.

Private helpers of :mod:`engine.testing.synthetic`: thin limbs sticking out of
the blob (``"thin_parts"``), an articulated figure of capsules
(``"articulated"``), the object-coloured band along an arc of the outline
(``"no_contrast_stretch"``) and the frames the object is hidden
(``"hidden"``).  Points are ``[x, y]`` pixels.  Shapes are made in *object
coordinates*: relative to the object's centre, before its rotation;
:func:`place` puts them in the frame.  Every random number comes from the
generator passed in, in a fixed order, so that a condition's sequence is
deterministic per seed.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]
Parts = list[list[F64]]
"""Per frame, the polygons whose union is the object (or a part of the scene)."""

CAP_VERTICES = 12
"""Vertices of each half-circle end of a capsule: about 1 px apart at the largest radius."""
LIMB_WIDTH = (4.0, 8.0)
"""Width of ``"thin_parts"``' limbs, px; not scaled with the frame, so they stay thin and
visible.  A 4-8 px limb is 2-4 px from its axis: below a usual smoothing scale."""
LIMB_OUT = (30.0, 60.0)
"""Length of a limb beyond the body's outline, px (scaled with the frame)."""
LIMB_SWING = (4.0, 12.0)
"""Amplitude of a limb's swing about its root, degrees: a little motion of its own."""
JOINT_SWING = (60.0, 120.0)
"""Swing of an articulated limb's root joint, degrees: a large change of the silhouette."""
BEND_SWING = (20.0, 70.0)
"""Swing of an articulated limb's middle joint (knee, elbow), degrees."""
TILT_SWING = (45.0, 90.0)
"""Tilt of the articulated figure's trunk over the swing, degrees: upright to lying."""
SWING_PERIOD = (50.0, 70.0)
"""Frames per back-and-forth cycle of the articulated joints: the full swing is reached
at half the period, so by frame 35."""
BAND_TAPER = 0.05
"""Share of the arc at each end of ``"no_contrast_stretch"``'s band over which its depth
grows from 0 (the band meets the outline without a step)."""
VISIBLE_BEFORE = 2
"""Visible frames before ``"hidden"``'s gap: the given first frame and one tracked frame."""
VISIBLE_AFTER = 5
"""Visible frames after the gap (room to find the object again)."""


def rotation(angle: float) -> F64:
    """The 2 x 2 matrix turning ``[x, y]`` row vectors by ``angle`` (x towards y)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, s], [-s, c]], np.float64)


def place(parts: Sequence[F64], center: F64, angle: float) -> list[F64]:
    """Polygons in object coordinates turned by ``angle`` and moved to ``center``."""
    turn = rotation(angle)
    return [np.asarray(p @ turn + center, np.float64) for p in parts]


def capsule(a: F64, b: F64, radius: float) -> F64:
    """The outline of the points within ``radius`` of the segment ``a``-``b``."""
    d = b - a
    heading = float(np.arctan2(d[1], d[0]))
    u = np.linspace(-np.pi / 2, np.pi / 2, CAP_VERTICES)
    end_b = b + radius * np.c_[np.cos(heading + u), np.sin(heading + u)]
    end_a = a + radius * np.c_[np.cos(heading + np.pi + u), np.sin(heading + np.pi + u)]
    return np.asarray(np.vstack([end_b, end_a]), np.float64)


def bar(root: F64, heading: float, length: float, width: float) -> F64:
    """A rectangle of ``width`` from ``root`` along ``heading`` for ``length``."""
    along = np.array([np.cos(heading), np.sin(heading)])
    side = np.array([-along[1], along[0]]) * width / 2
    tip = root + length * along
    return np.asarray(np.stack([root - side, tip - side, tip + side, root + side]), np.float64)


def thin_limbs(
    rng: np.random.Generator, r: F64, theta: F64, scale: float, body: float
) -> tuple[Parts, float]:
    """2-4 straight limbs sticking out of a blob, each swinging a little about its root.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the limbs' parameters.
    r : numpy.ndarray
        T x V radii of the blob's outline at the angles ``theta`` (object coordinates).
    theta : numpy.ndarray
        The V angles, evenly spaced from 0.
    scale : float
        Length factor (< 1 for frames smaller than 480 px); widths are not scaled.
    body : float
        A bound on ``r`` that does not depend on the number of frames.

    Returns
    -------
    parts : Parts
        Per frame, the limbs' rectangles in object coordinates; each starts inside the
        blob, at half its first frame's smallest radius, and ends :data:`LIMB_OUT` beyond
        its outline.
    reach : float
        A bound on the distance of the limbs' points from the origin that does not depend
        on the number of frames (so that a shorter sequence is a prefix of a longer one).
    """
    T, V = r.shape
    n = int(rng.integers(2, 5))
    base = rng.uniform(0, 2 * np.pi) + 2 * np.pi * np.arange(n) / n + rng.uniform(-0.3, 0.3, n)
    tilt = np.radians(rng.uniform(-15, 15, n))
    width = rng.uniform(*LIMB_WIDTH, n)
    out = rng.uniform(*LIMB_OUT, n) * scale
    swing = np.radians(rng.uniform(*LIMB_SWING, n))
    omega = 2 * np.pi / rng.uniform(20, 45, n)
    phase = rng.uniform(0, 2 * np.pi, n)
    root = 0.5 * float(r[0].min())  # inside: r varies by less than a factor 1.7
    index = np.rint(np.mod(base, 2 * np.pi) / (2 * np.pi) * V).astype(int) % V
    t = np.arange(T, dtype=np.float64)
    heading = base + tilt + swing * np.sin(omega * t[:, None] + phase)  # T x n
    parts: Parts = []
    for i in range(T):
        frame_parts = []
        for k in range(n):
            start = root * np.array([np.cos(base[k]), np.sin(base[k])])
            length = r[i, index[k]] - root + out[k]
            frame_parts.append(bar(start, float(heading[i, k]), float(length), float(width[k])))
        parts.append(frame_parts)
    return parts, body + float(np.max(out + width / 2))


def _swing(t: F64, period: F64 | float) -> F64:
    """0 at frame 0, rising smoothly to 1 at half the period and back."""
    return np.asarray(0.5 - 0.5 * np.cos(2 * np.pi * t / period), np.float64)


def articulated_figure(rng: np.random.Generator, T: int, scale: float) -> tuple[Parts, float]:
    """A trunk with two legs and up to two arms, each of two segments, that swing at their
    joints by :data:`JOINT_SWING` while the trunk tilts by :data:`TILT_SWING`.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the figure's parameters.
    T : int
        Frames.
    scale : float
        Size factor (< 1 for frames smaller than 480 px).

    Returns
    -------
    parts : Parts
        Per frame, the capsules of the trunk and the limb segments in object coordinates
        (the trunk's centre at the origin, upright at frame 0: its axis along y).
    reach : float
        The largest distance any pose can reach from the origin.
    """
    half = rng.uniform(25, 35) * scale
    trunk_r = rng.uniform(18, 24) * scale
    arms = int(rng.integers(0, 3))
    # joints: hips (legs) then shoulders (arms); x away from the axis, y along it (down: +y)
    joints = [(-0.5, 1.0), (0.5, 1.0), (-0.6, -1.0), (0.6, -1.0)][: 2 + arms]
    n = len(joints)
    rest = np.array([np.pi / 2 + 0.25, np.pi / 2 - 0.25, np.pi / 2 + 0.8, np.pi / 2 - 0.8])[:n]
    rest += rng.uniform(-0.15, 0.15, n)
    lengths = rng.uniform((40, 35), (55, 50), (n, 2)) * scale
    radii = rng.uniform((7, 6), (10, 9), (n, 2)) * scale
    sign = rng.choice([-1.0, 1.0], n)
    hip = np.radians(rng.uniform(*JOINT_SWING, n)) * sign
    knee = np.radians(rng.uniform(*BEND_SWING, n)) * rng.choice([-1.0, 1.0], n)
    bend = rng.uniform(-0.2, 0.2, n)
    period = rng.uniform(*SWING_PERIOD, (n, 2))
    tilt = np.radians(rng.uniform(*TILT_SWING)) * rng.choice([-1.0, 1.0])
    tilt_period = rng.uniform(*SWING_PERIOD)
    t = np.arange(T, dtype=np.float64)
    upper = rest + hip * _swing(t[:, None], period[:, 0])  # T x n, object coordinates
    lower = upper + bend + knee * _swing(t[:, None], period[:, 1])
    lean = tilt * _swing(t, tilt_period)
    parts: Parts = []
    for i in range(T):
        body = [capsule(np.array([0.0, -half]), np.array([0.0, half]), trunk_r)]
        for k, (jx, jy) in enumerate(joints):
            a = np.array([jx * trunk_r, jy * half])
            b = a + lengths[k, 0] * np.array([np.cos(upper[i, k]), np.sin(upper[i, k])])
            c = b + lengths[k, 1] * np.array([np.cos(lower[i, k]), np.sin(lower[i, k])])
            body += [capsule(a, b, radii[k, 0]), capsule(b, c, radii[k, 1])]
        parts.append(place(body, np.zeros(2), float(lean[i])))
    shoulder = np.hypot(np.array(joints)[:, 0] * trunk_r, half)
    reach = shoulder + lengths.sum(axis=1) + radii.max(axis=1)
    return parts, max(half + trunk_r, float(reach.max()))


def band(poly: F64, center: F64, start: int, fraction: float, depth: float) -> F64:
    """A band outside the arc of ``poly`` that starts at vertex ``start`` and covers
    ``fraction`` of its length, ``depth`` deep (radially from ``center``), tapered to 0 at
    both ends over :data:`BAND_TAPER` of the arc.

    ``poly`` must be star-shaped about ``center`` (the blob is); the band then is a simple
    polygon that shares the arc with ``poly``.
    """
    ring = np.roll(poly, -start, axis=0)
    steps = np.hypot(*np.diff(np.vstack([ring, ring[:1]]), axis=0).T)
    along = np.concatenate([[0.0], np.cumsum(steps)])  # arc length at each vertex (and back)
    stop = fraction * along[-1]
    count = int(np.searchsorted(along, stop, side="right"))
    arc = ring[:count]
    u = along[:count] / stop
    deep = depth * np.clip(np.minimum(u, 1 - u) / BAND_TAPER, 0, 1)
    radial = arc - center
    outer = arc + radial * (deep / np.hypot(*radial.T))[:, None]
    return np.asarray(np.vstack([arc, outer[::-1]]), np.float64)


def hidden_span(T: int, wanted: int) -> tuple[int, int]:
    """Frames ``[first, stop)`` of ``"hidden"``'s gap of ``wanted`` frames in ``T``.

    The gap is centred in the sequence but leaves :data:`VISIBLE_BEFORE` frames before it
    and :data:`VISIBLE_AFTER` after; it shrinks (to 3 frames for ``T = 10``) when the
    sequence is too short for both.  Shorter sequences get a gap of ``max(T - 7, 1)`` frames
    and, below 8 frames, fewer visible frames after it (none for ``T = 2``); frame 0 is
    always visible.
    """
    n = min(wanted, max(T - VISIBLE_BEFORE - VISIBLE_AFTER, 1))
    first = min((T - n) // 2, T - VISIBLE_AFTER - n)
    first = max(first, min(VISIBLE_BEFORE, T - n))
    return first, first + n
