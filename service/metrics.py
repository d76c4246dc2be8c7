"""Prometheus metrics of the service (exposed at ``GET /metrics``)."""

from __future__ import annotations

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram

REGISTRY = CollectorRegistry(auto_describe=True)

SESSIONS = Gauge("efdm_sessions_active", "Sessions held by this process", registry=REGISTRY)
FRAMES = Counter("efdm_frames_processed_total", "Frames tracked", ["transport"], registry=REGISTRY)
DROPPED = Counter(
    "efdm_frames_dropped_total",
    "Frames skipped because a newer one arrived first (WebSocket)",
    registry=REGISTRY,
)
FRAME_SECONDS = Histogram(
    "efdm_frame_seconds",
    "Time to decode and track one frame",
    ["transport"],
    buckets=(0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0),
    registry=REGISTRY,
)
FORCES = Counter("efdm_forces_total", "Force requests solved", registry=REGISTRY)
ERRORS = Counter("efdm_errors_total", "Errors by kind", ["kind"], registry=REGISTRY)
WEBSOCKETS = Gauge("efdm_websockets_open", "Open WebSocket streams", registry=REGISTRY)
