"""Service settings, in one place: environment variables prefixed ``EFDM_``."""

from __future__ import annotations

from functools import cached_property
from typing import Annotated

from pydantic import Field, field_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

from engine.tracking.tracker import MAX_NODES


class Settings(BaseSettings):
    """Configuration of ``efdm serve`` (e.g. ``EFDM_PORT=9000``, ``EFDM_API_KEYS=a,b``)."""

    model_config = SettingsConfigDict(env_prefix="EFDM_", frozen=True)

    host: str = "127.0.0.1"
    port: int = Field(8000, ge=0, le=65535)
    session_ttl_seconds: float = Field(900.0, gt=0, description="idle sessions expire")
    max_sessions: int = Field(1000, ge=1)
    max_nodes: int = Field(MAX_NODES, ge=3, le=MAX_NODES, description="nodes of a contour")
    max_frame_bytes: int = Field(8 * 1024 * 1024, ge=1024, description="encoded image size")
    max_frame_pixels: int = Field(4096 * 2160, ge=64, description="decoded width x height")
    max_json_bytes: int = Field(2 * 1024 * 1024, ge=1024, description="JSON request bodies")
    api_keys: Annotated[tuple[str, ...], NoDecode] = Field(
        (), description="comma-separated; when set, every /v1 call needs a Bearer key"
    )
    workers: int = Field(0, ge=0, description="CPU threads for tracking; 0 = number of cores")
    redis_url: str | None = Field(
        None, description="redis://host:port/db: share sessions between replicas"
    )
    redis_exact_cache: int = Field(
        64,
        ge=0,
        description="sessions each replica keeps exactly after writing them to Redis "
        "(which holds a compact, lossy tracker state); 0 = none",
    )
    stream_commit_every: int = Field(
        1, ge=1, description="a WebSocket stream writes its session through every k frames"
    )
    log_level: str = Field("warning", pattern="^(critical|error|warning|info|debug)$")
    header_timeout_seconds: float = Field(
        10.0, gt=0, description="a request's headers must arrive within this (slowloris)"
    )
    body_timeout_seconds: float = Field(
        30.0, gt=0, description="longest wait for the next piece of a request's body"
    )
    ws_send_timeout_seconds: float = Field(
        10.0, gt=0, description="a stream whose client reads nothing for this long is closed"
    )
    max_connections: int = Field(
        4096, ge=1, description="concurrent connections and requests; beyond, 503"
    )
    metrics_key: str | None = Field(
        None, description="when set, /metrics needs 'Authorization: Bearer <this key>'"
    )

    @field_validator("api_keys", mode="before")
    @classmethod
    def _split_keys(cls, value: object) -> object:
        if isinstance(value, str):
            return tuple(k.strip() for k in value.split(",") if k.strip())
        return value

    @cached_property
    def auth_enabled(self) -> bool:
        """Whether API keys are required."""
        return bool(self.api_keys)
