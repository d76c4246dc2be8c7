"""What every ``efdm`` sub-command shares: exit codes, the error type, a quiet stdout."""

from __future__ import annotations

import io
import os
from typing import TextIO

__all__ = ["EXIT_INVALID", "EXIT_IO", "EXIT_MISSING", "EXIT_OK", "CliError", "silence"]

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


def silence(stream: TextIO) -> None:
    """Point ``stream``'s file descriptor at /dev/null, so that flushing it at exit is quiet
    (its reader, e.g. ``head``, has closed the pipe)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, stream.fileno())
        os.close(devnull)
    except (OSError, ValueError, io.UnsupportedOperation):
        pass
