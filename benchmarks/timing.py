"""Wall-clock timing shared by the benchmark scripts (imported as ``timing``: a script's
own folder is first on ``sys.path``)."""

from __future__ import annotations

import time


def best_time(function, repeats: int) -> float:
    """The smallest wall-clock time of ``repeats`` calls, seconds."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def timed(function) -> tuple[float, object]:
    """One call's wall-clock time (seconds) and its value."""
    start = time.perf_counter()
    value = function()
    return time.perf_counter() - start, value
