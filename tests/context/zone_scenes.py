"""A synthetic scene with known entry/exit zones (tests of zone learning and learn-zones)."""

from __future__ import annotations

import numpy as np

from jaxtrack.datasets.scene_config import EntryZone, SceneConfig
from jaxtrack.datasets.synthetic import nominal_size

#: Four entry/exit zones on the image borders, centred where a box of the scene's perspective
#: size just fits in the image; people walk to the opposite zone and leave the image there,
#: so every zone sees entries and exits.
CROSSING_ZONES = (
    EntryZone("west", (18.0, 330.0), (3.0, 12.0), (4.0, -0.33), (0.2, 0.05)),
    EntryZone("east", (750.0, 270.0), (3.0, 12.0), (-4.0, 0.33), (0.2, 0.05)),
    EntryZone("north", (300.0, 20.0), (12.0, 3.0), (0.38, 2.5), (0.05, 0.2)),
    EntryZone("south", (380.0, 518.0), (12.0, 3.0), (-0.38, -2.5), (0.05, 0.2)),
)
#: Frames of the scene: about 15 entries per zone.
CROSSING_FRAMES = 1000
#: The scene (768x576, the default perspective).
CROSSING_SCENE = SceneConfig(num_frames=CROSSING_FRAMES, zones=CROSSING_ZONES)


def zone_feet(zones, config: SceneConfig) -> np.ndarray:
    """``[num_zones, 2]`` foot points of the zones' centres: a box of the perspective law's
    nominal height ``h`` centred on a zone's centre ``(c1, c2)`` has its feet at
    ``(c1, c2 + h / 2)``."""
    centres = np.array([zone.centre for zone in zones])
    heights = nominal_size(centres[:, 1], config)[:, 1]
    return centres + np.c_[np.zeros(len(zones)), heights / 2]
