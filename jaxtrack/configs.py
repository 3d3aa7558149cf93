"""Typed, frozen, validated tracker configurations (base layer).

Every tracker has one configuration type: a frozen dataclass whose fields are declared with
:func:`setting`, so that each carries its documentation and its rule (type, range, choices,
length). Instances are hashable (compiled functions are cached on them), round-trip through
JSON (:meth:`TrackerConfig.to_dict` / :meth:`TrackerConfig.from_dict` /
:func:`load_config_file`) and are validated once, when built: a bad value is an
:class:`~jaxtrack.errors.InputError` naming the key (and the file, when read from one).

Each field's :class:`~jaxtrack.limits.Rule` says its type and range; floats must also be
finite and representable in float32 (no overflow, no flush to zero), ints are compared exactly
(a 400-digit integer is an error naming the key, not an OverflowError). NaN and Infinity in a
file, deeply nested JSON and non-UTF-8 text are errors naming the file.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any, ClassVar, Self

from jaxtrack.errors import FileFormatError, InputError
from jaxtrack.limits import Rule

#: The output rule every tracker configuration shares (``output``).
OUTPUT = Rule(
    "'offline': confirmed tracks over their whole life, gaps of up to max_gap frames "
    "interpolated; 'online': the tracker's frame-by-frame output",
    str,
    choices=("offline", "online"),
)
#: The gap-filling rule every tracker configuration shares (``max_gap``).
MAX_GAP = Rule("longest gap (frames) filled by the offline output", int, 0, 1000)
#: The offline output's smoothings (``smoothing``): none, or the Rauch-Tung-Striebel smoother
#: of :mod:`jaxtrack.association.smoothing`.
SMOOTHINGS = ("none", "rts")
#: The smoothing rule every tracker configuration shares (``smoothing``).
SMOOTHING = Rule(
    "offline output: 'rts' re-estimates every track's boxes by the Rauch-Tung-Striebel "
    "smoother under the PHD tracker's model (constant-velocity centre, random-walk size, "
    "noise relative to the box size: motion_noise_std and measurement_noise_std, the "
    "configuration's for the PHD tracker, their defaults for the others); 'none': the "
    "tracker's own estimates",
    str,
    choices=SMOOTHINGS,
)
#: Largest ``retrodiction`` (frames).
MAX_RETRODICTION = 1000
#: The retrodiction rule of the trackers that offer it (``retrodiction``: the PHD and Fusion
#: trackers; :mod:`jaxtrack.association.retrodiction`).
RETRODICTION = Rule(
    "offline output: the most frames each confirmed track is extended backwards onto "
    "the detections before its first box (each taken detection overlaps the track's "
    "constant-velocity box, by IoU >= 0.5 for the PHD tracker and >= 0.3, its support "
    "gate, for the Fusion tracker, and no output box; the walk stops at the first frame "
    "without one); 0: off",
    int,
    0,
    MAX_RETRODICTION,
)


def check_retrodiction(config: Any) -> None:
    """Refuses a ``retrodiction`` with the online output (it would be ignored).

    Raises:
        InputError: ``config.retrodiction > 0`` and ``config.output != "offline"``.
    """
    if config.retrodiction and config.output != "offline":
        raise InputError(
            f"retrodiction {config.retrodiction} extends the offline output; with output "
            f"{config.output!r} it would be ignored (set it to 0 or use the offline output)"
        )


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
    #: Whether the offline output drops each identity's leading and trailing rows of score
    #: 0 (a tracker whose rows of score 0 are predictions without evidence).
    trims_tails: ClassVar[bool] = False

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            value = field.metadata["rule"].check(field.name, getattr(self, field.name))
            object.__setattr__(self, field.name, value)
        smoothing = getattr(self, "smoothing", "none")
        if smoothing != "none" and getattr(self, "output", "offline") != "offline":
            raise InputError(
                f"smoothing {smoothing!r} re-estimates the offline output; with output "
                f"{self.output!r} it would be ignored (set it to 'none' or use the offline "
                "output)"
            )

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
        FileFormatError: a missing or unreadable file, invalid JSON (with its line), NaN or
            Infinity, JSON nested too deeply, or a bad key or value (named).
    """
    file = Path(path)
    if not file.is_file():
        raise FileFormatError(file, None, "file not found")
    values = read_json_file(file, "a configuration")
    try:
        return config_type.from_dict(values)
    except InputError as err:
        raise FileFormatError(file, None, str(err)) from None


def read_json_file(path: str | Path, what: str) -> Any:
    """The JSON value in a UTF-8 file, for files whose numbers enter the toolkit.

    Args:
        path: the file.
        what: what the file holds, for the messages (``"a configuration"``).

    Raises:
        FileFormatError: naming the file (and the line of a JSON error), for an unreadable
            file, text that is not UTF-8, invalid JSON, ``NaN`` / ``Infinity`` (``"NaN is not
            a number {what} accepts"``) or JSON nested too deeply.
    """
    path = Path(path)

    def no_constant(name: str) -> None:
        raise ValueError(f"{name} is not a number {what} accepts")

    try:
        return json.loads(path.read_text(encoding="utf-8"), parse_constant=no_constant)
    except OSError as err:
        raise FileFormatError(path, None, f"cannot read ({err.strerror})") from None
    except UnicodeDecodeError:
        raise FileFormatError(path, None, "not a UTF-8 text file") from None
    except RecursionError:
        raise FileFormatError(path, None, "JSON nested too deeply") from None
    except json.JSONDecodeError as err:
        raise FileFormatError(path, err.lineno, f"not valid JSON ({err.msg})") from None
    except ValueError as err:
        raise FileFormatError(path, None, str(err)) from None
