"""Request and response bodies of the v1 API.

Coordinates are ``[x, y]`` pixels everywhere (x = column, y = row), as in
OpenCV; nodes and forces are lists of such pairs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from engine.physics import METHODS

LIMIT = 1e9
"""Largest coordinate or force magnitude accepted (pixels): far beyond any image,
far below where float64 arithmetic on a contour could overflow."""
Finite = Annotated[float, Field(strict=True, allow_inf_nan=False, ge=-LIMIT, le=LIMIT)]
"""A coordinate or force: a JSON number (strict: not ``"12"`` or ``true``)."""
Flag = Annotated[bool, Field(strict=True)]
"""A JSON ``true`` or ``false`` (strict: not ``"yes"`` or ``1``)."""
Point = Annotated[tuple[Finite, Finite], Field(description="[x, y] pixels")]
if TYPE_CHECKING:
    Method = str
else:  # the engine's one list of solvers, as an enum in the schema
    Method = Literal[METHODS]


class Circle(BaseModel):
    """A circular initial contour."""

    model_config = ConfigDict(extra="forbid")

    center: Point
    radius: Annotated[float, Field(strict=True, gt=0, le=1e6, allow_inf_nan=False)]
    count: Annotated[int, Field(strict=True, ge=3, description="number of nodes")] = 64

    @model_validator(mode="after")
    def _inside_limits(self) -> Circle:
        if max(abs(c) for c in self.center) + self.radius > LIMIT:
            raise ValueError(f"the circle must lie within +-{LIMIT:g} pixels")
        return self


BOX_NODES = 64
"""Nodes of a contour started from a box (as a circle's default ``count``)."""


MAX_OBJECTS = 32
"""Objects one session tracks at most (each costs about one tracker's time per frame)."""
ObjectId = Annotated[str, Field(pattern=r"^[A-Za-z0-9_.-]{1,64}$", description="object id")]


class ObjectSpec(BaseModel):
    """One object of a session: exactly one of ``nodes``, ``circle``, ``box`` or ``mask``."""

    model_config = ConfigDict(extra="forbid")

    id: ObjectId | None = Field(None, description="default: the next free number, as text")
    nodes: list[Point] | None = Field(None, description="contour, [[x, y], ...]")
    circle: Circle | None = None
    box: tuple[Finite, Finite, Finite, Finite] | None = Field(
        None,
        description="[x0, y0, x1, y1], pixel edges, the object's bounding box (the object "
        "reaches every side); snapped unless 'snap' is false",
    )
    mask: str | None = Field(
        None,
        max_length=4 * 1024 * 1024,
        description="PNG (base64) of the frames' size, non-zero on the object; every separate "
        "piece of at least 100 pixels becomes one of the object's contours",
    )
    snap: Flag | None = Field(None, description="snap the outline on the next frame")

    @model_validator(mode="after")
    def _one_shape(self) -> ObjectSpec:
        given = [k for k in ("nodes", "circle", "box", "mask") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError("give exactly one of 'nodes', 'circle', 'box' or 'mask'")
        if self.box is not None and not (self.box[2] > self.box[0] and self.box[3] > self.box[1]):
            raise ValueError(
                f"box must be [x0, y0, x1, y1] with x1 > x0 and y1 > y0; got {list(self.box)}"
            )
        if self.mask is not None and self.snap:
            raise ValueError("a mask is the object's outline already: it does not snap")
        return self

    @property
    def snaps(self) -> bool:
        """Whether the outline is snapped onto the object on the next frame."""
        return self.box is not None if self.snap is None else self.snap


class SessionCreate(BaseModel):
    """``POST /v1/sessions``: the initial contour and the model."""

    model_config = ConfigDict(extra="forbid")

    nodes: list[Point] | None = Field(None, description="initial contour, [[x, y], ...]")
    circle: Circle | None = None
    box: tuple[Finite, Finite, Finite, Finite] | None = Field(
        None,
        description="[x0, y0, x1, y1] around the object, pixel edges (the box of a mask whose "
        f"pixels span columns x0..x1-1, rows y0..y1-1: the object reaches every side); a "
        f"contour of {BOX_NODES} nodes, snapped onto the object on the first frame unless "
        "'snap' is false",
    )
    snap: Flag | None = Field(
        None,
        description="snap the outline onto the object inside it on the first frame (GrabCut; "
        "under a second at 854x480): default true for 'box', false for 'nodes' and 'circle'",
    )
    objects: list[ObjectSpec] | None = Field(
        None,
        max_length=MAX_OBJECTS,
        description=f"several objects (at most {MAX_OBJECTS}) instead of one contour; frame "
        "results then carry 'objects'",
    )
    closed: Flag = True
    stiffness: Annotated[float, Field(strict=True, gt=0, le=1e6, allow_inf_nan=False)] = 10.0
    method: Method = "exact"
    tracking: dict[str, Any] = Field(
        default_factory=dict, description="engine.TrackerOptions fields, e.g. {'stiffness': 40}"
    )
    ttl_seconds: Annotated[float, Field(strict=True, gt=0, le=1e9, allow_inf_nan=False)] | None = (
        Field(
            None,
            description="idle seconds before the session expires; at most, and by default, the "
            "server's EFDM_SESSION_TTL_SECONDS (the demo page asks for 120)",
        )
    )

    @model_validator(mode="after")
    def _one_contour(self) -> SessionCreate:
        given = [k for k in ("nodes", "circle", "box", "objects") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError("give exactly one of 'nodes', 'circle', 'box' or 'objects'")
        if self.objects is not None:
            ids = [o.id for o in self.objects if o.id is not None]
            if len(ids) != len(set(ids)):
                raise ValueError("object ids must differ")
            if not self.objects or not self.closed or self.snap is not None:
                raise ValueError(
                    "'objects' needs at least one object, closed contours, and 'snap' per object"
                )
        if self.box is not None:
            x0, y0, x1, y1 = self.box
            if not (x1 > x0 and y1 > y0):
                raise ValueError(
                    f"box must be [x0, y0, x1, y1] with x1 > x0 and y1 > y0; got {list(self.box)}"
                )
        if self.snaps and not self.closed:
            raise ValueError("'snap' needs a closed contour (an object's outline)")
        return self

    @property
    def snaps(self) -> bool:
        """Whether the outline is snapped onto the object on the first frame."""
        return self.box is not None if self.snap is None else self.snap


class SessionOut(BaseModel):
    """A session as the API shows it."""

    id: str
    nodes: list[Point]
    closed: bool
    stiffness: float
    method: Method
    tracking: dict[str, Any]
    frame_index: int = Field(description="index of the last tracked frame; -1 before any")
    version: int = Field(description="incremented by every change; use with If-Match")
    expires_at: str = Field(description="ISO 8601 UTC; idle sessions expire")
    objects: list[ObjectOut] | None = Field(None, description="a session of several objects")


class SessionListed(BaseModel):
    """A session as a listing shows it."""

    id: str
    frame_index: int = Field(description="index of the last tracked frame; -1 before any")
    version: int
    expires_at: str = Field(description="ISO 8601 UTC; idle sessions expire")


class SessionList(BaseModel):
    """``GET /v1/sessions``: a page of the caller's sessions, in id order."""

    sessions: list[SessionListed]
    next: str | None = Field(
        description="the 'after' of the next page (its URL is in the Link header); null: the last"
    )


class ForcesIn(BaseModel):
    """``POST /v1/sessions/{id}/forces``: one force per node."""

    model_config = ConfigDict(extra="forbid")

    forces: list[Point] = Field(description="[[fx, fy], ...], one per node, pixels")


class ForcesOut(BaseModel):
    """Equilibrium under the forces: nodes = rest + displacements (paper eq. 15)."""

    nodes: list[Point]
    displacements: list[Point]
    version: int


class ObjectOut(BaseModel):
    """One object's contour(s) and, in a frame result, its status."""

    id: str
    nodes: list[Point] | None = Field(None, description="its contour (one piece)")
    contours: list[list[Point]] | None = Field(None, description="its pieces' contours")
    confidence: float | None = Field(None, ge=0, le=1)
    status: Literal["tracking", "uncertain", "lost"] | None = None
    behind: list[str] | None = Field(
        None,
        description="in a frame result: the ids of the objects in front of it where they "
        "overlap (their pixels are left to them; it keeps its whole outline under them)",
    )


class FrameOut(BaseModel):
    """Result of tracking one frame."""

    frame_index: int
    nodes: list[Point]
    iterations: int
    converged: bool
    confidence: float = Field(
        ge=0, le=1, description="the predicted overlap (IoU) of the contour with the object"
    )
    status: Literal["tracking", "uncertain", "lost"] = Field(
        description="tracking: on the object; uncertain: may be off; lost: most likely not on it"
    )
    reset: str | None = Field(
        None,
        description="set when this frame restarted tracking, saying why (e.g. the frame size "
        "changed); the contour is then the previous one, as on a first frame",
    )
    version: int
    elapsed_ms: float
    objects: list[ObjectOut] | None = Field(
        None, description="a session of several objects: each one's contour(s) and status"
    )


class StreamFrameOut(FrameOut):
    """A frame result on the WebSocket, with frames skipped since the last one."""

    dropped: int = Field(description="frames skipped because a newer one arrived first")


class ErrorDetail(BaseModel):
    """What went wrong."""

    status: int
    code: str
    message: str


class ErrorOut(BaseModel):
    """Every error response."""

    error: ErrorDetail
