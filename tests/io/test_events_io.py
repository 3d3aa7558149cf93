"""RES.events.csv: path beside RES.txt, round trip, and a clear error for each bad input."""

from __future__ import annotations

import numpy as np
import pytest

from jaxtrack.errors import FileFormatError, InputError
from jaxtrack.filters.hier_events import EVENT_NAMES
from jaxtrack.io.events import events_path, read_events, write_events
from jaxtrack.metrics.events import EventRows


def sample() -> EventRows:
    rng = np.random.default_rng(0)
    frames = np.repeat(np.arange(1, 21), 3)
    ids = np.tile([4, 1, 9], 20)
    names = np.array(EVENT_NAMES)[rng.integers(0, len(EVENT_NAMES), 60)]
    return EventRows(frames, ids, names)


def test_events_path():
    assert str(events_path("out/PETS09-S2L1.txt")) == "out/PETS09-S2L1.events.csv"
    with pytest.raises(InputError, match=r"must end in \.txt"):
        events_path("out/res.csv")


def test_round_trip(tmp_path):
    rows = sample()
    path = write_events(tmp_path / "r.events.csv", rows)
    lines = path.read_text().splitlines()
    assert lines[0] == "frame,id,event" and len(lines) == 61
    assert lines[1] == f"1,1,{rows.names[1]}"  # sorted by frame, then id
    back = read_events(path)
    order = np.lexsort((rows.ids, rows.frames))
    np.testing.assert_array_equal(back.frames, rows.frames[order])
    np.testing.assert_array_equal(back.ids, rows.ids[order])
    np.testing.assert_array_equal(back.names, rows.names[order])


def test_write_refuses_bad_rows(tmp_path):
    rows = sample()
    with pytest.raises(InputError, match="unknown event name 'waving'"):
        write_events(
            tmp_path / "a.csv", rows._replace(names=np.where(rows.ids == 4, "waving", rows.names))
        )
    with pytest.raises(InputError, match="identity 1 has two events on frame 1"):
        write_events(tmp_path / "b.csv", rows._replace(ids=np.where(rows.ids == 4, 1, rows.ids)))


@pytest.mark.parametrize(
    ("text", "line", "reason"),
    [
        ("", 1, "header"),
        ("frame,id,state\n1,1,single\n", 1, "header"),
        ("frame,id,event\n1,1,single\n2,1\n", 3, "expected 3 columns"),
        ("frame,id,event\n1,1,single,x\n", 2, "expected 3 columns"),
        ("frame,id,event\n1,1,single\n1.5,1,single\n", 3, "must be integers"),
        ("frame,id,event\n1,a,single\n", 2, "must be integers"),
        ("frame,id,event\n0,1,single\n", 2, "1-based"),
        ("frame,id,event\n1,1,single\n1,2,waving\n", 3, "unknown event 'waving'"),
        ("frame,id,event\n1,1,single\n2,1,single\n1,1,grouped\n", 4, r"frame 1 \(line 2\)"),
    ],
)
def test_read_errors_name_file_and_line(tmp_path, text, line, reason):
    path = tmp_path / "bad.events.csv"
    path.write_text(text)
    with pytest.raises(FileFormatError, match=reason) as caught:
        read_events(path)
    assert caught.value.line == line and caught.value.path == str(path)
    assert f"{path}, line {line}: " in str(caught.value)


def test_read_missing_file(tmp_path):
    with pytest.raises(FileFormatError, match="not found"):
        read_events(tmp_path / "none.events.csv")
