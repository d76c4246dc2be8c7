"""Liveness, readiness and metrics."""

from __future__ import annotations

from fastapi import APIRouter, Response
from fastapi.responses import JSONResponse
from prometheus_client import CONTENT_TYPE_LATEST, generate_latest

from service import metrics
from service.deps import StoreDep

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


@router.get("/metrics", response_class=Response)
async def prometheus(store: StoreDep) -> Response:
    """Prometheus text format: sessions, frames processed and dropped, latency, errors."""
    metrics.SESSIONS.set(await store.count())
    return Response(generate_latest(metrics.REGISTRY), media_type=CONTENT_TYPE_LATEST)
