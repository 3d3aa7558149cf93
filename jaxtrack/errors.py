"""Exceptions and warnings for bad user input.

Every error caused by a user's file or argument derives from :class:`InputError`; the CLI
prints its message (which names the file and, where there is one, the line) without a
traceback and exits with status 2. A legal but suspicious value gives an
:class:`InputWarning` (see :mod:`jaxtrack.limits` for every rule).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
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


def check_keys(
    data: Mapping, required: Collection[str], optional: Collection[str] = (), where: str = ""
) -> None:
    """Checks the keys of a parsed JSON object: each of ``required`` present, no key outside
    ``required`` and ``optional``.

    Raises:
        InputError: naming the first missing key (in ``required`` order), else the first
            unknown one (sorted), prefixed with ``where: `` when given.
    """
    prefix = f"{where}: " if where else ""
    missing = [key for key in required if key not in data]
    if missing:
        raise InputError(f"{prefix}missing key {missing[0]!r}")
    unknown = sorted(set(data) - set(required) - set(optional))
    if unknown:
        raise InputError(f"{prefix}unknown key {unknown[0]!r}")
