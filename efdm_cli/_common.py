"""What every ``efdm`` sub-command shares: exit codes and the error type."""

from __future__ import annotations

__all__ = ["EXIT_INVALID", "EXIT_IO", "EXIT_MISSING", "EXIT_OK", "CliError"]

EXIT_OK, EXIT_IO, EXIT_INVALID = 0, 1, 2
EXIT_MISSING = 3
"""A part of the program is not installed (``efdm serve`` without the ``[service]`` extra)."""


class CliError(Exception):
    """A failure with its exit code and a message for stderr.

    Parameters
    ----------
    message : str
        What went wrong, printed as ``efdm COMMAND: error: MESSAGE``.
    code : int
        :data:`EXIT_IO`, :data:`EXIT_INVALID` or :data:`EXIT_MISSING`.
    """

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code
