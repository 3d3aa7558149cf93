"""Property test: on arbitrary text the parser loads or raises the documented error type."""

from __future__ import annotations

import string

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from jaxtrack.errors import FileFormatError
from jaxtrack.io import read_mot_file, read_seqinfo

field = st.one_of(
    st.integers(-5, 50).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.text(string.printable, max_size=4),
)
row = st.lists(field, min_size=0, max_size=12).map(",".join)
mot_text = st.one_of(
    st.lists(row, max_size=8).map("\n".join),
    st.text(max_size=200),
)


@settings(
    max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(text=mot_text, kind=st.sampled_from(["det", "gt", "res"]))
def test_parser_loads_or_raises_file_format_error(tmp_path, text, kind):
    path = tmp_path / "file.txt"
    path.write_bytes(text.encode("utf-8", errors="replace"))
    try:
        table = read_mot_file(path, kind, seq_length=40)
    except FileFormatError as err:
        assert err.path == str(path)
        assert err.line is None or err.line >= 1
        return
    # loaded: every documented invariant holds
    assert np.all(np.isfinite(table.boxes)) and np.all(table.boxes[:, 2:] > 0)
    assert np.all((table.frames >= 1) & (table.frames <= 40))
    if kind != "det" and len(table):
        keys = set(zip(table.frames.tolist(), table.ids.tolist(), strict=True))
        assert len(keys) == len(table)


@settings(
    max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(text=st.text(max_size=200))
def test_seqinfo_loads_or_raises_file_format_error(tmp_path, text):
    path = tmp_path / "seqinfo.ini"
    path.write_bytes(text.encode("utf-8", errors="replace"))
    try:
        info = read_seqinfo(path)
    except FileFormatError as err:
        assert err.path == str(path)
        return
    assert info.seq_length > 0 and info.im_width > 0 and info.im_height > 0
