"""What the service benchmark runs: clips, rounds, sessions, ``/forces`` loads, time limits."""

from __future__ import annotations

from dataclasses import dataclass

from bench.common.config import Config as BaseConfig


@dataclass(frozen=True, slots=True)
class Config(BaseConfig):
    """What the service benchmark runs.

    Attributes
    ----------
    frames : int or None
        Frames per clip (None: all).
    rounds : int
        Rounds of the single-session rows, interleaved so they see the same machine.
    open_rate_factor : float
        Open-loop sending rate as a multiple of the fastest single-session frames/s.
    sessions : tuple of int
        Concurrent WebSocket sessions to try.
    session_frames : int
        Frames each concurrent session streams.
    forces_clients : tuple of int
        Concurrent ``/forces`` clients to try.
    forces_requests, forces_warmup : int
        Timed requests per ``/forces`` row (split among clients); untimed ones per client.
    forces_nodes : int
        Nodes of the ``/forces`` sessions.
    wrk_seconds : float
        Duration of each ``wrk`` run.
    row_seconds : float
        Time limit of any one measurement.
    synthetic_length : int
        Frames per synthetic clip (used without DAVIS).
    """

    frames: int | None
    rounds: int
    open_rate_factor: float
    sessions: tuple[int, ...]
    session_frames: int
    forces_clients: tuple[int, ...]
    forces_requests: int
    forces_warmup: int
    forces_nodes: int
    wrk_seconds: float
    row_seconds: float
    synthetic_length: int


FULL = Config("full", None, 3, 2.0, (4, 16), 30, (1, 8), 4000, 50, 256, 4.0, 30.0, 40)
QUICK = Config("quick", 6, 1, 2.0, (2,), 4, (1, 2), 60, 5, 256, 1.0, 10.0, 6)
