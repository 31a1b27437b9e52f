"""The scene schema: every section's keys (`SCHEMA`), the keys of one table of each array
of tables (`ARRAY_SCHEMA`), the tables inside an item (`SUBTABLES`), in file order. The
keys themselves are written in `sections_body`, `sections_mechanics` and
`sections_sensing`."""

from __future__ import annotations

from fruitcli.scene import sections_body, sections_mechanics, sections_sensing
from fruitcli.scene.key import Key

SCHEMA: dict[str, dict[str, Key]] = {
    **sections_body.SECTIONS,
    **sections_mechanics.SECTIONS,
    **sections_sensing.SECTIONS,
}
"""Section name -> its keys; an array of tables ([[fixed]]) has an empty entry here and
its keys in `ARRAY_SCHEMA`."""
ARRAY_SCHEMA: dict[str, dict[str, Key]] = {
    **sections_body.ITEMS,
    **sections_mechanics.ITEMS,
    **sections_sensing.ITEMS,
}
ARRAY_SECTIONS = {"fixed", "jig", "evaluate"}
"""The sections that are arrays of tables ([[geometry.chamber]] is a key of [geometry])."""
SUBTABLES = sections_body.SUBTABLES
ITEM_LABELS = {"geometry.chamber": "name", "evaluate": "label"}
"""Arrays whose items' value errors name them by this key ('c1') rather than by number."""
