"""Exceptions and warnings for bad user input.

Every error caused by a user's file or argument derives from :class:`InputError`; the CLI
prints its message (which names the file and, where there is one, the line) without a
traceback and exits with status 2. A legal but suspicious value gives an
:class:`InputWarning` (see :mod:`jaxtrack.limits` for every rule).
"""

from __future__ import annotations

from os import PathLike


class InputError(ValueError):
    """A user-supplied file or argument is invalid."""


class FileFormatError(InputError):
    """A data file is missing or malformed.

    Args:
        path: the offending file.
        line: 1-based line number, or None when the problem is not on one line.
        reason: what is wrong, in words.
    """

    def __init__(self, path: str | PathLike, line: int | None, reason: str):
        self.path = str(path)
        self.line = line
        self.reason = reason
        where = f"{self.path}, line {line}" if line is not None else self.path
        super().__init__(f"{where}: {reason}")


class InputWarning(UserWarning):
    """A user-supplied value is legal but suspicious (e.g. every box lies outside the image).

    Raised with :func:`warnings.warn`; the run goes on. The CLI prints it as one line,
    ``jaxtrack <command>: warning: <message>``, on stderr.
    """
