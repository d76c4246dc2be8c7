"""What the tracking benchmark runs: the sets, their sizes, the slow baseline's limits."""

from __future__ import annotations

from dataclasses import dataclass

from bench.common.config import Config as BaseConfig

NODES = 128
"""Contour nodes of every tracker (the DAVIS READMEs' protocol)."""
SETS = ("davis-train", "davis-val", "synthetic")
"""The sets: the thirty DAVIS-2016 training sequences (tuned on, by cross-validation only),
the five validation ones (reported, never tuned on) and the synthetic conditions."""
WORKERS = 2
"""Worker processes for the tracking runs whose timings are not reported (2 cores)."""
FOLDS = 5
"""Cross-validation folds of the training sequences."""
TIMED_PASSES = 2
"""Times the timed set is tracked: the speed figures are the fastest pass's median (as
``timeit`` takes the fastest repeat: a slower one measures the machine's other work, not
the code), and every pass must give the same contours (tracking is deterministic)."""


@dataclass(frozen=True, slots=True)
class Config(BaseConfig):
    """What the tracking benchmark runs.

    Attributes
    ----------
    train_count, val_count, synthetic_count : int or None
        How many training / validation sequences and synthetic conditions (None: all).
    davis_frames : int or None
        Frames per DAVIS sequence (None: all).
    synthetic_length : int
        Frames per synthetic sequence.
    skimage_davis, skimage_synthetic : int or None
        Frames the slow skimage baseline tracks per clip (None: all).
    davis_sheets : int
        DAVIS sequences (training and validation together) that get a contact sheet:
        those where efdm scores lowest.
    synthetic_sheets : int
        Synthetic clips that get a contact sheet (those where efdm scores lowest).
    synthetic_seeds : int
        Seeds each synthetic condition is drawn with (0, 1, ...): one seed's layout can be
        kind or cruel to a tracker, several show the condition.
    davis_resize : float
        Factor the DAVIS frames and masks are resized by before tracking (1: as they are;
        1.5 is a 720-line camera's view of the same scenes).
    davis_grey : bool
        Whether the DAVIS frames are turned grey before tracking (a grey camera's view).
    davis_tint : bool
        Whether the DAVIS frames are given a sepia tone through YUV 4:2:0 before tracking
        (a monochrome camera with a warm cast).
    davis_noise : float
        Deviation (levels) of the Gaussian noise added to every channel of the DAVIS
        frames before tracking (a noisy sensor's; 0: none).
    davis_stride : int
        Every how many frames of a DAVIS sequence are tracked and scored (1: all; 2: a
        camera at half the frame rate, or a service dropping every other frame).
    davis_codec : str
        A lossy video codec the DAVIS frames go through before tracking (a key of
        :data:`bench.tracking.sets.CODECS`; empty: none).
    """

    train_count: int | None
    val_count: int | None
    davis_frames: int | None
    synthetic_count: int | None
    synthetic_length: int
    skimage_davis: int | None
    skimage_synthetic: int | None
    davis_sheets: int = 5
    synthetic_sheets: int = 3
    synthetic_seeds: int = 1
    davis_resize: float = 1.0
    davis_grey: bool = False
    davis_tint: bool = False
    davis_noise: float = 0.0
    davis_stride: int = 1
    davis_codec: str = ""


FULL = Config("full", None, None, None, None, 40, None, 15, synthetic_seeds=3)
QUICK = Config("quick", 3, 2, 15, 3, 12, 5, 5, davis_sheets=2, synthetic_sheets=1)
