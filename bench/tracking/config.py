"""What the tracking benchmark runs: the clips, their lengths, the slow baseline's limits."""

from __future__ import annotations

from dataclasses import dataclass

from bench.common.config import Config as BaseConfig

NODES = 128
"""Contour nodes of every tracker (the DAVIS README's protocol)."""


@dataclass(frozen=True, slots=True)
class Config(BaseConfig):
    """What the tracking benchmark runs.

    Attributes
    ----------
    davis_count, synthetic_count : int or None
        How many DAVIS sequences / synthetic conditions (None: all).
    davis_frames : int or None
        Frames per DAVIS sequence (None: all).
    synthetic_length : int
        Frames per synthetic sequence.
    skimage_davis, skimage_synthetic : int or None
        Frames the slow skimage baseline tracks per clip (None: all).
    synthetic_sheets : int
        Synthetic conditions that get a contact sheet (those where efdm scores lowest).
    """

    davis_count: int | None
    davis_frames: int | None
    synthetic_count: int | None
    synthetic_length: int
    skimage_davis: int | None
    skimage_synthetic: int | None
    synthetic_sheets: int = 3


FULL = Config("full", None, None, None, 40, None, 15)
QUICK = Config("quick", 2, 15, 3, 12, 5, 5)
