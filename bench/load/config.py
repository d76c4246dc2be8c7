"""What the load benchmark runs: sessions per row, frame budgets, time limits, rounds."""

from __future__ import annotations

from dataclasses import dataclass

from bench.common.config import Config as BaseConfig
from bench.load.sessions import Load


@dataclass(frozen=True, slots=True)
class Config(BaseConfig):
    """What the load benchmark runs.

    Attributes
    ----------
    sessions : tuple of int
        Concurrent WebSocket sessions per row.
    frames_per_row : int
        Frame budget of a row per round, shared by its sessions ...
    min_frames_per_session : int
        ... but at least this many per session.
    row_seconds : float
        Time limit of a row's timed part (per round).
    rounds : int
        Times every row runs (pooled), the deployments taking turns.
    clip_length : int
        Frames of the synthetic clip (played forward, then back).
    nodes : int
        Contour nodes of every session.
    """

    sessions: tuple[int, ...]
    frames_per_row: int
    min_frames_per_session: int
    row_seconds: float
    rounds: int
    clip_length: int
    nodes: int

    def load(self, sessions: int) -> Load:
        """The load of the row with ``sessions`` sessions."""
        each = max(self.min_frames_per_session, self.frames_per_row // sessions)
        return Load(sessions, each, self.row_seconds)


FULL = Config("full", (1, 10, 100), 1000, 10, 12.0, 2, 40, 64)
QUICK = Config("quick", (1, 4), 40, 5, 4.0, 1, 8, 64)
