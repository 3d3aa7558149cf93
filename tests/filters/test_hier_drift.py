"""The drift check (``HierarchicalConfig.drift_check``): a tracker single again after a
collision checks its track's box against its appearance and lets a wrong track go."""

from __future__ import annotations

import pytest

from jaxtrack.filters.hierarchical_tracker import HierarchicalConfig
from tests.filters.test_hier_exchanges import assert_sides, bounce_scene
from tests.filters.test_hierarchical import tracked


@pytest.mark.parametrize(("drift_check", "kept"), [(1, True), (0, False)])
def test_a_drift_at_a_meeting_is_undone_without_the_exchange_check(drift_check, kept):
    """The low level exchanges the two targets' tracks where they meet (bounce scene). With
    the exchange check off, the drift check alone lets both wrong tracks go once the
    trackers are apart; re-associated by appearance, each identity ends with its own target.
    Without either check the identities end on the wrong sides."""
    _, rows = tracked("full", bounce_scene(), exchange_margin=-1.0, drift_check=drift_check)
    assert_sides(rows, kept)


def test_the_drift_check_is_off_by_default():
    """Off: on the MOT15 videos it lost IDF1 (README, "The drift check")."""
    assert HierarchicalConfig().drift_check == 0
