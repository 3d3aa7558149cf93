"""Typed, frozen, validated tracker configurations (base layer).

Every tracker has one configuration type: a frozen dataclass whose fields are declared with
:func:`setting`, so that each carries its documentation and its rule (type, range, choices,
length). Instances are hashable (compiled functions are cached on them), round-trip through
JSON (:meth:`TrackerConfig.to_dict` / :meth:`TrackerConfig.from_dict` /
:func:`load_config_file`) and are validated once, when built: a bad value is an
:class:`~jaxtrack.errors.InputError` naming the key (and the file, when read from one).

Rules, one per kind of value:

* ``int``: an integer (not a bool) within the field's ``[lower, upper]``;
* ``float``: a finite number (an int is accepted) within the field's bounds (each bound
  inclusive or exclusive, as the field says);
* ``str``: one of the field's choices;
* ``tuple``: a list of exactly ``length`` floats, each following the float rule.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any, ClassVar, Self

from jaxtrack.errors import FileFormatError, InputError


@dataclasses.dataclass(frozen=True)
class Rule:
    """The rule of one configuration field (see the module docstring).

    Attributes:
        doc: what the value means, in words (shown by ``--help`` and in errors).
        kind: ``int``, ``float``, ``str`` or ``tuple``.
        lower: smallest allowed value (None: unbounded).
        upper: largest allowed value (None: unbounded).
        lower_open: the lower bound itself is excluded.
        upper_open: the upper bound itself is excluded.
        choices: the allowed strings (``str`` fields).
        length: the number of items (``tuple`` fields).
    """

    doc: str
    kind: type
    lower: float | None = None
    upper: float | None = None
    lower_open: bool = False
    upper_open: bool = False
    choices: tuple[str, ...] = ()
    length: int = 0

    def check(self, key: str, value: Any) -> Any:
        """``value`` converted to the field's type.

        Raises:
            InputError: naming ``key``, when the value breaks the rule.
        """
        if self.kind is str:
            if value not in self.choices:
                raise InputError(f"{key} must be one of {', '.join(self.choices)}, got {value!r}")
            return value
        if self.kind is tuple:
            if not isinstance(value, list | tuple) or len(value) != self.length:
                raise InputError(f"{key} must be a list of {self.length} numbers, got {value!r}")
            return tuple(self._number(f"{key}[{i}]", item) for i, item in enumerate(value))
        return self._number(key, value)

    def _number(self, key: str, value: Any) -> int | float:
        integer = self.kind is int
        if isinstance(value, bool) or not isinstance(value, int if integer else int | float):
            kind = "an integer" if integer else "a number"
            raise InputError(f"{key} must be {kind}, got {value!r}")
        if not math.isfinite(value):
            raise InputError(f"{key} must be finite, got {value!r}")
        low_bad = self.lower is not None and (
            value <= self.lower if self.lower_open else value < self.lower
        )
        high_bad = self.upper is not None and (
            value >= self.upper if self.upper_open else value > self.upper
        )
        if low_bad or high_bad:
            raise InputError(f"{key} must lie in {self.interval()}, got {value!r}")
        return int(value) if integer else float(value)

    def interval(self) -> str:
        """The allowed range in interval notation, e.g. ``(0, 1]``."""
        low = "-inf" if self.lower is None else f"{self.lower:g}"
        high = "inf" if self.upper is None else f"{self.upper:g}"
        left = "(" if self.lower_open or self.lower is None else "["
        right = ")" if self.upper_open or self.upper is None else "]"
        return f"{left}{low}, {high}{right}"


#: The output rule every tracker configuration shares (``output``).
OUTPUT = Rule(
    "'offline': confirmed tracks over their whole life, gaps of up to max_gap frames "
    "interpolated; 'online': the tracker's frame-by-frame output",
    str,
    choices=("offline", "online"),
)
#: The gap-filling rule every tracker configuration shares (``max_gap``).
MAX_GAP = Rule("longest gap (frames) filled by the offline output", int, 0, 1000)


def setting(default: Any, rule: Rule) -> Any:
    """A configuration field: its default and its :class:`Rule`."""
    return dataclasses.field(default=default, metadata={"rule": rule})


@dataclasses.dataclass(frozen=True)
class TrackerConfig:
    """Base of the tracker configurations: validation, JSON round trip, replacement.

    Subclasses are frozen dataclasses of :func:`setting` fields and set :attr:`tracker`
    (the registry name, ``jaxtrack track --tracker NAME``).
    """

    tracker: ClassVar[str] = ""

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            value = field.metadata["rule"].check(field.name, getattr(self, field.name))
            object.__setattr__(self, field.name, value)

    @classmethod
    def rules(cls) -> dict[str, Rule]:
        """The rule of every field, by key."""
        return {field.name: field.metadata["rule"] for field in dataclasses.fields(cls)}

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> Self:
        """A configuration from a JSON object: the defaults with ``values`` applied.

        Raises:
            InputError: an unknown key, or a value breaking its rule (the key is named).
        """
        if not isinstance(values, dict):
            raise InputError(f"a {cls.tracker} configuration must be a JSON object")
        known = cls.rules()
        unknown = sorted(set(values) - set(known))
        if unknown:
            raise InputError(
                f"unknown {cls.tracker} configuration key(s) {', '.join(map(repr, unknown))}; "
                f"known: {', '.join(known)}"
            )
        return cls(**values)

    def to_dict(self) -> dict[str, Any]:
        """Every key with its value, JSON-ready (tuples as lists)."""
        return {
            key: list(value) if isinstance(value, tuple) else value
            for key, value in dataclasses.asdict(self).items()
        }

    def overrides(self) -> dict[str, Any]:
        """The keys whose values differ from the defaults (JSON-ready)."""
        default = type(self)().to_dict()
        return {key: value for key, value in self.to_dict().items() if value != default[key]}

    def replace(self, **changes: Any) -> Self:
        """A copy with some keys changed (validated)."""
        return self.from_dict({**self.to_dict(), **changes})


def load_config_file(path: str | Path, config_type: type[TrackerConfig]) -> TrackerConfig:
    """Reads a configuration JSON file (keys not in the file keep their defaults).

    Raises:
        FileFormatError: a missing or unreadable file, invalid JSON (with its line), or a bad
            key or value (named).
    """
    file = Path(path)
    if not file.is_file():
        raise FileFormatError(file, None, "file not found")
    try:
        values = json.loads(file.read_text(encoding="utf-8"), parse_constant=_no_constant)
    except UnicodeDecodeError:
        raise FileFormatError(file, None, "not a UTF-8 text file") from None
    except json.JSONDecodeError as err:
        raise FileFormatError(file, err.lineno, f"not valid JSON ({err.msg})") from None
    except ValueError as err:
        raise FileFormatError(file, None, str(err)) from None
    try:
        return config_type.from_dict(values)
    except InputError as err:
        raise FileFormatError(file, None, str(err)) from None


def _no_constant(name: str) -> None:
    raise ValueError(f"{name} is not a number a configuration accepts")
