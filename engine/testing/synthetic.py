"""Seeded synthetic tracking sequences with ground-truth masks.

A smooth deformable blob (a circle whose radius is modulated by 2-4 low
harmonics with slowly varying amplitudes and phases) moves along a smooth
trajectory (translation plus mild rotation) over a background.  Each of
:data:`CONDITIONS` adds one difficulty on top of ``"plain"``:

- ``"noise"``, ``"strong_noise"``: sensor noise of sigma 10 and 25 grey levels (2 otherwise);
- ``"clutter"``: distractor blobs and bars, two of them on the object's path;
- ``"fast_motion"``, ``"motion_blur"``: 17-20 px/frame; 8-12 px/frame and blurred along it;
- ``"low_contrast"``: object and background a few grey levels apart;
- ``"shape_change"``, ``"scale_change"``: strong, fast harmonics; radius x 2 (or / 2);
- ``"occluder"``: a green bar passes over the object;
- ``"textured"``: stripes or checks on the object;
- ``"matched_background"``: the left half of the background has the object's grey;
- ``"no_contrast_stretch"``: an object-coloured band (25-40 px deep, the object's own shading)
  lies against a contiguous arc of 28-33 % of the outline, fixed on the object and moving with
  it: along that arc there is no edge and no colour step (the band is not in the mask);
- ``"hidden"``: a large occluder of background-like colours covers the whole object for 5-8
  consecutive frames in the middle of the sequence (fewer in short ones, see
  :func:`engine.testing._shapes.hidden_span`) while it moves on at 3-6 px/frame: it
  reappears where its motion took it;
- ``"thin_parts"``: 2-4 straight limbs 4-8 px wide stick out 30-60 px from a smaller body
  (radius 40-55 px) and swing by 4-12 degrees;
- ``"articulated"``: a figure instead of the blob, a trunk with two legs and up to two arms
  of two segments each, whose hips and shoulders swing by 60-120 degrees, knees and elbows
  by 20-70, while the trunk tilts by 45-90 (full swing by frame 35);
- ``"fast_40"``: 38-44 px/frame (about 40 on average: a bounce off the frame's edges shortens
  that frame's step), turning smoothly;
- ``"small"``: 20-40 px across in every frame (radius 12.5-17 px), 2-6 px/frame;
- ``"lighting_change"``: the light changes gradually over the sequence: from the first
  frame to the last it dims to 55-70 % of its brightness, with a colour cast that moves each
  channel by up to 15 % more or less (a cloud, a dimmed lamp, a camera's exposure or white
  balance drifting).

Conventions: points are ``[x, y]`` pixels (x = column, y = row, a pixel's
centre has integer coordinates), frames are H x W x 3 BGR ``uint8`` as OpenCV
gives them, masks are H x W ``uint8`` with 0 = background and 255 = object.
The mask is the object's whole silhouette at that frame: it is *amodal*, so
the occluder of ``"occluder"`` does not cut it (a tracker is expected to keep
the shape through the occlusion), and it is not blurred in ``"motion_blur"``.
``SyntheticSequence.visible`` says per frame whether any of the object can be
seen: False only in the frames ``"hidden"`` covers it entirely, whose masks
still show where it is.
Frames are anti-aliased by 4 x 4 supersampled coverage, and a mask holds the
pixels the object covers at least half of, as DAVIS's annotations do (not
every pixel its outline touches, which would be half a pixel more all round).

The object always stays at least 10 pixels inside the frame.  Speeds are in
pixels per frame and do not depend on the frame size; the object's radius
(about 50-70 pixels) and the other sizes above shrink only for frames smaller
than 480 pixels, except ``"small"``'s object and the width of ``"thin_parts"``'
limbs, which never do.
Generation is deterministic for a given ``seed`` and condition.  Motion and
shape change are set per frame, so a shorter sequence is a prefix of a longer
one with the same seed, except where the timing is spread over the whole
sequence: the growth or shrinkage of ``"scale_change"`` (a factor 2 in radius
from first to last frame), the pass of the ``"occluder"`` bar (clear of the
object in the first and last frames), where ``"clutter"`` places the
distractors it puts on the object's path, when ``"hidden"`` hides the
object (its gap is centred), and ``"lighting_change"``'s change of light.  New
conditions are appended to :data:`CONDITIONS`: a condition's random stream is seeded
with its index.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.testing import _painting, _shapes

__all__ = ["CONDITIONS", "SyntheticSequence", "make_sequence"]

CONDITIONS: tuple[str, ...] = (
    "plain",
    "noise",
    "strong_noise",
    "clutter",
    "fast_motion",
    "motion_blur",
    "low_contrast",
    "shape_change",
    "scale_change",
    "occluder",
    "textured",
    "matched_background",
    # appended, never inserted: a condition's random stream is seeded with its index
    "no_contrast_stretch",
    "hidden",
    "thin_parts",
    "articulated",
    "fast_40",
    "small",
    "lighting_change",
)

MIN_SIZE = 96
"""Smallest accepted height and width, in pixels."""

_MARGIN = 12.0  # pixels between the outline's extreme points and the frame edge (mask: >= 10)
_VERTICES = 360
_OCCLUDER_BGR = (40.0, 165.0, 40.0)  # saturated green bar of "occluder"
_ARC_FRACTION = (0.28, 0.33)
"""Share of the outline's length along which ``"no_contrast_stretch"``'s object meets its own
colour: a quarter to a third, kept above 0.25 by the band's tapered ends (5 % of the arc each)."""
_BAND_DEPTH = (25.0, 40.0)
"""Depth of that object-coloured band, px (scaled with the frame): beyond the reach of a
local edge or region cue, so the true outline there can only be inferred from the rest."""
_HIDDEN_FRAMES = (5, 8)
"""Least and most frames ``"hidden"``'s object is out of sight (fewer in short sequences)."""
_HIDER_CLEARANCE = 12.0
"""Pixels between the hidden object's outline and the edge of the occluder over it: more than
the anti-aliasing (1 px), so no trace of the object shows."""
_HIDER_SHADE = 12.0
"""Most difference per channel between the occluder's base colour and the background's:
background-like, with a faint edge."""

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]


@dataclass(frozen=True)
class SyntheticSequence:
    """A generated sequence and its ground truth.

    Attributes
    ----------
    condition : str
        One of :data:`CONDITIONS`.
    frames : tuple of numpy.ndarray
        H x W x 3 BGR ``uint8`` images (read-only).
    masks : tuple of numpy.ndarray
        H x W ``uint8``, 0 background / 255 object, the amodal silhouette (read-only).
    visible : tuple of bool
        Whether any of the object can be seen in each frame: False only while ``"hidden"``
        hides it entirely.  Optional when constructing: left out (or empty), every frame is
        visible, so it is always one flag per frame once constructed.

    Raises
    ------
    ValueError
        If ``visible`` is given with another length than ``frames``.
    """

    condition: str
    frames: tuple[U8, ...]
    masks: tuple[U8, ...]
    visible: tuple[bool, ...] = ()

    def __post_init__(self) -> None:
        if not self.visible:
            object.__setattr__(self, "visible", (True,) * len(self.frames))
        elif len(self.visible) != len(self.frames):
            raise ValueError(f"visible has {len(self.visible)} flags for {len(self.frames)} frames")

    def __len__(self) -> int:
        return len(self.frames)


@dataclass(frozen=True)
class _Knobs:
    speed: tuple[float, float] = (2.0, 5.0)  # px/frame
    noise: float = 2.0  # sensor noise sigma, grey levels
    shape: tuple[float, float] = (0.06, 0.12)  # total harmonic amplitude / radius
    period: tuple[float, float] = (40.0, 90.0)  # frames per cycle of the shape change
    scale: float = 1.0  # radius factor from the first to the last frame (or its inverse)
    radius: tuple[float, float] = (50.0, 70.0)  # blob radius R0, px at 480 px and more
    shrinks: bool = True  # R0 scaled down for frames smaller than 480 px


_KNOBS: dict[str, _Knobs] = {
    "noise": _Knobs(noise=10.0),
    "strong_noise": _Knobs(noise=25.0),
    "fast_motion": _Knobs(speed=(17.0, 20.0)),
    "motion_blur": _Knobs(speed=(8.0, 12.0)),
    "low_contrast": _Knobs(noise=3.0),
    "shape_change": _Knobs(shape=(0.25, 0.32), period=(15.0, 30.0)),
    "scale_change": _Knobs(scale=2.0),
    "hidden": _Knobs(speed=(3.0, 6.0)),  # a clear way from where it vanished
    "thin_parts": _Knobs(radius=(40.0, 55.0)),  # the body; the limbs reach further
    "fast_40": _Knobs(speed=(38.0, 44.0)),  # bounces shorten the steps: about 40 on average
    # 20-40 px across in every frame: R0 (1 +- 3 %)(1 +- shape) stays within 10-20 px
    "small": _Knobs(speed=(2.0, 6.0), shape=(0.04, 0.10), radius=(12.5, 17.0), shrinks=False),
}


def make_sequence(
    condition: str, *, seed: int = 0, length: int = 40, size: tuple[int, int] = (480, 640)
) -> SyntheticSequence:
    """Generate a synthetic tracking sequence.

    Parameters
    ----------
    condition : str
        One of :data:`CONDITIONS`.
    seed : int
        Non-negative seed; equal seeds give identical sequences.
    length : int
        Number of frames (>= 2; ``"hidden"`` keeps at least 3 hidden frames with 2 visible
        before and 5 after from 10 frames on).
    size : tuple of int
        ``(height, width)`` in pixels, each >= :data:`MIN_SIZE`.

    Returns
    -------
    SyntheticSequence
        ``length`` frames, their amodal masks and whether the object can be seen in each
        (``visible``: False only in the gap of ``"hidden"``); the conditions are described
        in :mod:`engine.testing.synthetic`.

    Raises
    ------
    ValueError
        For an unknown condition, a negative seed, ``length < 2`` or a too small size.
    """
    if condition not in CONDITIONS:
        raise ValueError(
            f"unknown condition {condition!r}; expected one of {', '.join(CONDITIONS)}"
        )
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer; got {seed!r}")
    if isinstance(length, bool) or not isinstance(length, int | np.integer) or length < 2:
        raise ValueError(f"length must be an integer >= 2; got {length!r}")
    try:
        H, W = (int(v) for v in size)
    except (TypeError, ValueError):
        raise ValueError(f"size must be (height, width); got {size!r}") from None
    if min(H, W) < MIN_SIZE:
        raise ValueError(f"size must be at least {MIN_SIZE} x {MIN_SIZE} pixels; got {H} x {W}")
    rng = np.random.default_rng([int(seed), CONDITIONS.index(condition)])
    return _render(condition, rng, int(length), H, W)


def _render(cond: str, rng: np.random.Generator, T: int, H: int, W: int) -> SyntheticSequence:
    """Draw the scene's parameters from ``rng``, then render ``T`` frames of ``H`` x ``W``."""
    knobs = _KNOBS.get(cond, _Knobs())
    s = min(1.0, min(H, W) / 480)
    t = np.arange(T, dtype=np.float64)

    # shape: radius R(t) (1 + sum_k a_k(t) cos(k theta + phi_k(t))), rotation rot(t)
    R0 = rng.uniform(*knobs.radius) * (s if knobs.shrinks else 1.0)
    ks = rng.choice([2, 3, 4, 5], size=int(rng.integers(2, 5)), replace=False)
    amax = rng.dirichlet(np.ones(len(ks))) * rng.uniform(*knobs.shape)
    omega = 2 * np.pi / rng.uniform(*knobs.period, size=len(ks))
    amp = amax[:, None] * (
        0.5 + 0.5 * np.sin(omega[:, None] * t + rng.uniform(0, 6.3, (len(ks), 1)))
    )
    phase = rng.uniform(0, 2 * np.pi, (len(ks), 1)) + rng.uniform(-0.03, 0.03, (len(ks), 1)) * t
    rot = rng.uniform(0, 2 * np.pi) + rng.choice([-1, 1]) * np.radians(rng.uniform(0.3, 1.5)) * t
    if knobs.scale != 1.0:
        f = knobs.scale ** rng.choice([-1.0, 1.0])
        radius = R0 * f ** (t / (T - 1) - 0.5)
    else:
        radius = R0 * (1 + 0.03 * np.sin(2 * np.pi * t / rng.uniform(30, 60) + rng.uniform(0, 6.3)))
    theta = np.linspace(0.0, 2 * np.pi, _VERTICES, endpoint=False)
    r = radius[:, None] * (
        1 + np.einsum("kt,ktv->tv", amp, np.cos(ks[:, None, None] * theta + phase[..., None]))
    )
    env = R0 * max(1.03, np.sqrt(knobs.scale)) * (1 + float(amax.sum()))  # >= every r; not T
    extra: _shapes.Parts | None = None  # object-coordinate polygons beyond (or for) the blob
    if cond == "thin_parts":
        extra, env = _shapes.thin_limbs(rng, r, theta, s, env)
    elif cond == "articulated":  # the figure replaces the blob
        extra, env = _shapes.articulated_figure(rng, T, s)
    elif cond == "no_contrast_stretch":
        arc_start = int(rng.integers(_VERTICES))
        arc_fraction = rng.uniform(*_ARC_FRACTION)
        band_depth = rng.uniform(*_BAND_DEPTH) * s
        env += band_depth

    # trajectory: smooth heading and speed, reflected at the walls (keeps the speed)
    blur_pad = 7.0 if cond == "motion_blur" else 0.0
    lo = _MARGIN + blur_pad + env + 1
    hi = np.array([W, H], np.float64) - 1 - lo
    v_lo, v_hi = knobs.speed
    speed = v_lo + (v_hi - v_lo) * (0.5 + 0.5 * np.sin(t / rng.uniform(3, 8) + rng.uniform(0, 6.3)))
    head = rng.uniform(0, 2 * np.pi)
    start = rng.uniform(lo, hi)
    if cond == "matched_background":  # straddle the matched left half, heading into it
        head = np.pi + rng.uniform(-0.5, 0.5)
        start[0] = W / 2 + rng.uniform(-0.2, 0.3) * env
    heading = head + 0.7 * np.sin(t / rng.uniform(4, 10) + rng.uniform(0, 6.3))
    steps = speed[:, None] * np.c_[np.cos(heading), np.sin(heading)]
    raw = start + np.vstack([np.zeros(2), np.cumsum(steps, axis=0)]) - lo
    span = np.maximum(hi - lo, 1e-9)
    q = np.mod(raw, 2 * span)
    path = lo + np.where(q > span, 2 * span - q, q)  # T + 1 points: one past the end for blur
    center = path[:T]
    polys = center[:, None, :] + r[..., None] * np.stack(
        [np.cos(theta + rot[:, None]), np.sin(theta + rot[:, None])], axis=-1
    )
    # per frame: the polygons whose union is the object (its mask), and those painted
    # in the object's colours (the object, and the band of "no_contrast_stretch")
    if extra is None:
        body = [[polys[i]] for i in range(T)]
    else:
        placed = [_shapes.place(extra[i], center[i], rot[i]) for i in range(T)]
        body = placed if cond == "articulated" else [[polys[i], *placed[i]] for i in range(T)]
    painted = body
    if cond == "no_contrast_stretch":
        painted = [
            [*body[i], _shapes.band(polys[i], center[i], arc_start, arc_fraction, band_depth)]
            for i in range(T)
        ]

    # appearance
    obj_bgr = np.array([55.0, 60.0, 150.0]) + rng.uniform(-8, 8, 3)
    shade_amp = 8.0
    bg_base = np.array([175.0, 180.0, 165.0]) + rng.uniform(-10, 10, 3)
    bg = _painting.background(rng, H, W, bg_base, 20.0)
    hidden = range(0)  # the frames the object is out of sight
    if cond == "low_contrast":
        bg_base = np.array([125.0, 130.0, 138.0]) + rng.uniform(-10, 10, 3)
        bg = _painting.background(rng, H, W, bg_base, 3.0)
        obj_bgr = bg_base + rng.choice([-1.0, 1.0]) * rng.uniform(15, 20)
        shade_amp = 1.5
    elif cond == "matched_background":  # same grey as the object: B +8, R -3
        matched = _painting.background(rng, H, W, obj_bgr + np.array([8.0, 0.0, -3.0]), 3.0)
        w = np.clip((W / 2 - np.arange(W, dtype=np.float32)) / 8 + 0.5, 0, 1)[None, :, None]
        bg += w * (matched - bg)
    elif cond == "hidden":  # a large background-like occluder over the object's way
        gap = int(rng.integers(*_HIDDEN_FRAMES, endpoint=True))
        hidden = range(*_shapes.hidden_span(T, gap))
        way = center[hidden.start : hidden.stop]
        mid = way.mean(axis=0)
        reach = float(np.hypot(*(way - mid).T).max()) + env + _HIDER_CLEARANCE
        hider = _painting.blob(rng, mid, reach / 0.7)  # blob's radius varies by at most 30 %
        hider_bg = _painting.background(
            rng, H, W, bg_base + rng.uniform(-1, 1, 3) * _HIDER_SHADE, 20.0
        )
    elif cond == "clutter":
        for i in range(int(rng.integers(6, 10))):
            size = rng.uniform(15, 45) * s
            if i < 2:  # touching the object's path
                k = min(int(rng.random() * T), T - 1)
                u = rng.uniform(0, 2 * np.pi)
                c = center[k] + (r[k].mean() + 0.5 * size) * np.array([np.cos(u), np.sin(u)])
            else:
                c = rng.uniform((0, 0), (W, H))
            colour = obj_bgr + rng.choice([-1, 1], 3) * rng.uniform(15, 35, 3)
            if rng.random() < 0.5:
                colour = rng.uniform(0, 255, 3)
            if rng.random() < 0.5:
                _painting.paint(bg, _painting.blob(rng, c, size), colour)
            else:
                box = ((c[0], c[1]), (2 * size, size * rng.uniform(0.4, 1.2)), rng.uniform(0, 180))
                _painting.paint(bg, cv2.boxPoints(box).astype(np.float64), colour)
    tex_kind = int(rng.integers(2))
    tex_bgr = np.array([150.0, 215.0, 235.0]) + rng.uniform(-15, 15, 3)
    tex_period = rng.uniform(16, 28) * s
    tex_angle = rng.uniform(0, np.pi)
    shade_k = rng.uniform(0.04, 0.09, (3, 2)) * rng.choice([-1, 1], (3, 2)) / max(s, 0.3)
    shade_p = rng.uniform(0, 2 * np.pi, 3)
    occ_angle = rng.uniform(0, np.pi)
    occ_width = rng.uniform(8, 14)
    blur = cond == "motion_blur"
    noise_lut = _painting.gauss_table() * np.float32(knobs.noise)

    light = None
    if cond == "lighting_change":  # per frame and channel, 1 in the first frame
        change = rng.uniform(-0.45, -0.30) + rng.uniform(-0.15, 0.15, 3)
        light = (1.0 + np.outer(t / max(T - 1, 1), change)).astype(np.float32)

    frames: list[U8] = []
    masks: list[U8] = []
    for i in range(T):
        img = bg.copy()
        pad = int(blur_pad) + 2 if blur else 0
        cov = _painting.coverage(painted[i], H, W)
        assert cov is not None  # the object is always inside the frame
        y0, x0, a = cov
        if pad:
            a = np.asarray(
                cv2.copyMakeBorder(a, pad, pad, pad, pad, cv2.BORDER_CONSTANT), np.float32
            )
            y0, x0 = y0 - pad, x0 - pad  # still >= 0: the trajectory's margin includes blur_pad
        h, w_ = a.shape
        # object colour in object coordinates (rotating and scaling with the object)
        ys, xs = np.mgrid[y0 : y0 + h, x0 : x0 + w_].astype(np.float64)
        dx, dy = xs - center[i, 0], ys - center[i, 1]
        c_, s_ = np.cos(rot[i]), np.sin(rot[i])
        zoom = R0 / radius[i]
        ou, ov = (c_ * dx + s_ * dy) * zoom, (-s_ * dx + c_ * dy) * zoom
        shade = sum(np.sin(shade_k[j, 0] * ou + shade_k[j, 1] * ov + shade_p[j]) for j in range(3))
        obj = obj_bgr.astype(np.float32) + (shade_amp / 3 * shade)[..., None].astype(np.float32)
        if cond == "textured":
            su = np.cos(tex_angle) * ou + np.sin(tex_angle) * ov
            pat = np.sin(2 * np.pi * su / tex_period)
            if tex_kind:
                sv = -np.sin(tex_angle) * ou + np.cos(tex_angle) * ov
                pat = pat * np.sin(2 * np.pi * sv / tex_period)
            m = (np.clip(pat * 4, -1, 1) * 0.5 + 0.5)[..., None].astype(np.float32)
            obj += m * (tex_bgr.astype(np.float32) - obj)
        if blur:
            vel = (path[i + 1] - path[max(i - 1, 0)]) / (i + 1 - max(i - 1, 0))
            n = max(float(np.hypot(*vel)), 1.0)
            kc = pad
            line = np.array([kc, kc]) + np.outer([-0.5, 0.5, 0.5, -0.5], vel)
            line += np.outer([-0.5, -0.5, 0.5, 0.5], (-vel[1] / n, vel[0] / n))
            kcov = _painting.coverage(line, 2 * kc + 1, 2 * kc + 1)
            kern = np.zeros((2 * kc + 1, 2 * kc + 1), np.float32)
            if kcov is not None:
                ky, kx, ka = kcov
                kern[ky : ky + ka.shape[0], kx : kx + ka.shape[1]] = ka
            kern /= kern.sum()
            premult = cv2.filter2D(a[..., None] * obj, -1, kern, borderType=cv2.BORDER_CONSTANT)
            a = np.asarray(cv2.filter2D(a, -1, kern, borderType=cv2.BORDER_CONSTANT), np.float32)
        else:
            premult = a[..., None] * obj
        roi = img[y0 : y0 + h, x0 : x0 + w_]
        roi *= 1 - a[..., None]
        roi += premult
        if cond == "occluder":
            nrm = np.array([np.cos(occ_angle), np.sin(occ_angle)])
            along = np.array([-nrm[1], nrm[0]])
            off = (2 * i / (T - 1) - 1) * (env + occ_width + 10)
            mid = center[i] + off * nrm
            half_l, half_w = 2 * env + 30, occ_width / 2
            bar = (
                mid
                + np.outer([-1, 1, 1, -1], along * half_l)
                + np.outer([-1, -1, 1, 1], nrm * half_w)
            )
            _painting.paint(img, bar, _OCCLUDER_BGR)
        if i in hidden:
            _painting.paint_image(img, hider, hider_bg)
        if light is not None:
            img *= light[i]
        img += noise_lut[rng.integers(0, 65536, (H, W, 3), dtype=np.uint16)]
        np.clip(img, 0, 255, out=img)
        frame = np.rint(img).astype(np.uint8)
        mask = _painting.fill(body[i], H, W)
        frame.flags.writeable = False
        mask.flags.writeable = False
        frames.append(frame)
        masks.append(mask)
    visible = tuple(i not in hidden for i in range(T))
    return SyntheticSequence(cond, tuple(frames), tuple(masks), visible)
