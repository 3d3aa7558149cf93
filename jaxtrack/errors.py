"""Exceptions for bad user input.

Every error caused by a user's file or argument derives from :class:`InputError`; the CLI
prints its message (which names the file and, where there is one, the line) without a
traceback and exits with status 2.
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
