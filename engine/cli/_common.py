"""What every ``efdm`` sub-command shares: exit codes and the error type."""

from __future__ import annotations

__all__ = ["EXIT_INVALID", "EXIT_IO", "EXIT_OK", "CliError"]

EXIT_OK, EXIT_IO, EXIT_INVALID = 0, 1, 2


class CliError(Exception):
    """A failure with its exit code and a message for stderr.

    Parameters
    ----------
    message : str
        What went wrong, printed as ``efdm COMMAND: error: MESSAGE``.
    code : int
        :data:`EXIT_IO` or :data:`EXIT_INVALID`.
    """

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code
