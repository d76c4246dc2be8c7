"""What can go wrong with sessions, frames and stores, in the service's own terms.

Sessions, stores and frame decoding raise these; they know nothing of HTTP.
The web layer (:mod:`service.errors`) maps each kind to a status, an error
code and headers, in one table.
"""

from __future__ import annotations

__all__ = [
    "BadImageError",
    "ImageTooLargeError",
    "InvalidInputError",
    "ObjectNotFoundError",
    "PreconditionFailedError",
    "ServiceError",
    "SessionNotFoundError",
    "StoreUnavailableError",
    "TooManySessionsError",
    "UnsupportedImageTypeError",
    "VersionConflictError",
]


class ServiceError(Exception):
    """A request the service cannot carry out (the client's doing, or retryable).

    Parameters
    ----------
    message : str
        Human-readable explanation, passed on to the client.

    Attributes
    ----------
    retry_after : int or None
        Seconds after which the same request may succeed; None when waiting
        does not help.
    """

    retry_after: int | None = None

    def __init__(self, message: str) -> None:
        super().__init__(message)
        self.message = message


class InvalidInputError(ServiceError):
    """The request's contour, options, forces or message cannot be used."""


class BadImageError(ServiceError):
    """A frame that is empty, not a JPEG / PNG / WebP, or does not decode."""


class ImageTooLargeError(ServiceError):
    """A frame beyond the byte or pixel limit."""


class UnsupportedImageTypeError(ServiceError):
    """A frame declared as a type the service does not decode."""


class SessionNotFoundError(ServiceError):
    """An unknown, expired or someone else's session (indistinguishable on purpose)."""

    def __init__(self, message: str = "no such session (unknown, expired or deleted)") -> None:
        super().__init__(message)


class ObjectNotFoundError(ServiceError):
    """An object id the session does not hold."""


class PreconditionFailedError(ServiceError):
    """The client expected another session version than the current one."""


class VersionConflictError(ServiceError):
    """The session changed concurrently (elsewhere) while this change was made."""

    def __init__(self, message: str = "the session changed concurrently; retry") -> None:
        super().__init__(message)


class StreamReplacedError(ServiceError):
    """A newer WebSocket stream took this stream's session over (one stream per session)."""

    def __init__(
        self, message: str = "another stream took the session over (one stream per session)"
    ) -> None:
        super().__init__(message)


class TooManySessionsError(ServiceError):
    """The store holds as many sessions as it may.

    Parameters
    ----------
    limit : int
        The session cap.
    retry_after : int
        Seconds after which idle sessions may have expired.
    """

    retry_after: int

    def __init__(self, limit: int, retry_after: int = 10) -> None:
        super().__init__(f"session limit of {limit} reached")
        self.limit = limit
        self.retry_after = retry_after


class StoreUnavailableError(ServiceError):
    """The session store cannot be reached; it recovers by itself.

    Parameters
    ----------
    retry_after : int
        Seconds to wait before retrying.
    """

    retry_after: int

    def __init__(self, retry_after: int = 1) -> None:
        super().__init__("session store unreachable; retry")
        self.retry_after = retry_after
