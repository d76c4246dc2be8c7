"""Liveness, readiness and metrics."""

from __future__ import annotations

import hmac

from fastapi import APIRouter, Response
from fastapi.responses import JSONResponse
from prometheus_client import CONTENT_TYPE_LATEST, generate_latest

from service import metrics
from service.deps import ApiKeyDep, SettingsDep, StoreDep
from service.errors import ApiError

router = APIRouter(tags=["operations"])


@router.get("/healthz")
async def healthz() -> dict[str, str]:
    """Liveness: the process answers."""
    return {"status": "ok"}


@router.get("/readyz", responses={503: {"description": "the session store is unreachable"}})
async def readyz(store: StoreDep) -> JSONResponse:
    """Readiness: the session store is reachable."""
    if await store.ping():
        return JSONResponse({"status": "ready"})
    return JSONResponse({"status": "store unreachable"}, status_code=503)


@router.get("/metrics", response_class=Response, responses={401: {"description": "wrong key"}})
async def prometheus(store: StoreDep, settings: SettingsDep, key: ApiKeyDep) -> Response:
    """Prometheus text format: sessions, frames processed and dropped, latency, errors.

    With ``EFDM_METRICS_KEY`` set, only for ``Authorization: Bearer <that key>``
    (the API keys do not open it: a scraper needs no session rights, a client no metrics).
    """
    wanted = settings.metrics_key
    if wanted and not (key and hmac.compare_digest(key, wanted)):
        raise ApiError(
            401, "unauthorized", "/metrics needs the metrics key", **{"WWW-Authenticate": "Bearer"}
        )
    metrics.SESSIONS.set(await store.count())
    return Response(generate_latest(metrics.REGISTRY), media_type=CONTENT_TYPE_LATEST)
