"""A synthetic scene with known entry/exit zones (tests of zone learning and learn-zones)."""

from __future__ import annotations

from jaxtrack.datasets.scene_config import EntryZone, SceneConfig

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
