"""jaxtrack.limits: the Rule of one value, float32 representability, the rules table."""

from __future__ import annotations

import math

import numpy as np
import pytest

from jaxtrack.errors import InputError
from jaxtrack.limits import (
    FLOAT32_TINY,
    FRAME_RATE,
    IMAGE_SIZE,
    RULES,
    SEED,
    Rule,
    float32_trouble,
    rules_markdown,
)


def test_float32_trouble():
    values = np.array([0.0, 1.0, -3e38, 3.5e38, -1e39, 1e-37, FLOAT32_TINY, 1e-39, np.nan, np.inf])
    np.testing.assert_array_equal(float32_trouble(values), [0, 0, 0, 1, 1, 0, 0, 1, 1, 1])


@pytest.mark.parametrize(
    ("rule", "value", "message"),
    [
        (FRAME_RATE, 1e300, r"x must lie in \[1, 1000\], got 1e\+300"),
        (FRAME_RATE, 10**400, r"x must be finite, got 10000000000+\.\.\.\(401 characters\)"),
        (FRAME_RATE, -(10**400), "x must be finite"),
        (FRAME_RATE, math.nan, "x must be finite, got nan"),
        (FRAME_RATE, "25", "x must be a number"),
        (FRAME_RATE, True, "x must be a number"),
        (IMAGE_SIZE, 10**400, r"x must lie in \[16, 65536\], got 10000000000000000000000000000"),
        (IMAGE_SIZE, 640.0, "x must be an integer"),
        (SEED, -1, r"x must lie in \[0, 4294967295\]"),
        (Rule("rate", float, 0.0, 1.0, lower_open=True), 1e-300, "not representable in float32"),
        (Rule("any", float), 1e39, "not representable in float32"),
        (Rule("pair", tuple, 0.0, 1.0, length=2), [0.5, 2], r"x\[1\] must lie in \[0, 1\]"),
        (Rule("pair", tuple, length=2), [0.5], "x must be a list of 2 numbers"),
        (Rule("mode", str, choices=("a", "b")), "c", "x must be one of a, b"),
    ],
)
def test_rule_errors_name_the_key(rule, value, message):
    with pytest.raises(InputError, match=message):
        rule.check("x", value)


def test_rule_converts_and_keeps_legal_values():
    assert FRAME_RATE.check("x", 25) == 25.0 and isinstance(FRAME_RATE.check("x", 25), float)
    assert IMAGE_SIZE.check("x", 65536) == 65536
    assert Rule("any", float).check("x", 0.0) == 0.0  # zero is representable
    assert Rule("pair", tuple, length=2).check("x", [1, 2.5]) == (1.0, 2.5)
    assert Rule("r", float, 0, 1, lower_open=True, upper_open=True).interval() == "(0, 1)"


def test_rules_table_lists_every_rule():
    table = rules_markdown().splitlines()
    assert table[0] == "| Quantity | From | Rule | Outcome |"
    assert len(table) == 2 + len(RULES)
    quantities = {limit.quantity for limit in RULES}
    for needed in ("frame number", "image width, height", "frame rate", "box w, h", "identity"):
        assert needed in quantities
    assert {limit.outcome for limit in RULES} == {"error", "warning"}
