"""``/docs`` and ``/redoc`` served from the package: they work on an air-gapped machine.

FastAPI's own pages load Swagger UI and ReDoc (and ReDoc's fonts) from a CDN,
so without internet ``/docs`` is blank.  The assets come instead from
`fastapi-offline <https://pypi.org/project/fastapi-offline/>`_, which bundles
them, served under :data:`ASSETS`; the pages reference no other host, and
ReDoc's "API docs by Redocly" logo, which its bundle loads from Redocly's CDN,
is the local favicon.
"""

from __future__ import annotations

from pathlib import Path

from fastapi import FastAPI, Request
from fastapi.openapi.docs import (
    get_redoc_html,
    get_swagger_ui_html,
    get_swagger_ui_oauth2_redirect_html,
)
from fastapi.responses import HTMLResponse, Response
from fastapi.staticfiles import StaticFiles

ASSETS = "/docs-assets"
"""Where the bundled Swagger UI, ReDoc and favicon files are served."""
REDOC_LOGO = "https://cdn.redoc.ly/redoc/logo-mini.svg"
"""The one remote file ReDoc's bundle loads by itself (its footer's logo)."""


def _bundled() -> Path:
    import fastapi_offline

    return Path(fastapi_offline.__file__).parent / "static"


def install(app: FastAPI) -> None:
    """Serve ``/docs`` (Swagger UI), its OAuth2 redirect, and ``/redoc`` from local assets.

    The app must be made with ``docs_url=None, redoc_url=None``.
    """
    redoc_js = (_bundled() / "redoc.standalone.js").read_bytes()
    redoc_js = redoc_js.replace(REDOC_LOGO.encode(), f"{ASSETS}/favicon.png".encode())

    @app.get(f"{ASSETS}/redoc.local.js", include_in_schema=False)
    async def redoc_bundle() -> Response:  # before the mount below, which would take the path
        return Response(redoc_js, media_type="text/javascript")

    app.mount(ASSETS, StaticFiles(directory=_bundled()), name="docs-assets")
    openapi = app.openapi_url or "/openapi.json"
    redirect = app.swagger_ui_oauth2_redirect_url or "/docs/oauth2-redirect"

    @app.get("/docs", include_in_schema=False)
    async def swagger(request: Request) -> HTMLResponse:
        root = request.scope.get("root_path", "")
        return get_swagger_ui_html(
            openapi_url=f"{root}{openapi}",
            title=f"{app.title} - Swagger UI",
            oauth2_redirect_url=f"{root}{redirect}",
            swagger_js_url=f"{root}{ASSETS}/swagger-ui-bundle.js",
            swagger_css_url=f"{root}{ASSETS}/swagger-ui.css",
            swagger_favicon_url=f"{root}{ASSETS}/favicon.png",
            swagger_ui_parameters=app.swagger_ui_parameters,
        )

    @app.get(redirect, include_in_schema=False)
    async def swagger_redirect() -> HTMLResponse:
        return get_swagger_ui_oauth2_redirect_html()

    @app.get("/redoc", include_in_schema=False)
    async def redoc(request: Request) -> HTMLResponse:
        root = request.scope.get("root_path", "")
        return get_redoc_html(
            openapi_url=f"{root}{openapi}",
            title=f"{app.title} - ReDoc",
            redoc_js_url=f"{root}{ASSETS}/redoc.local.js",
            redoc_favicon_url=f"{root}{ASSETS}/favicon.png",
            with_google_fonts=False,
        )
