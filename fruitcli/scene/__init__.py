"""Scene files: one TOML per experiment, validated strictly against the schema.

Every user-facing key carries its unit in its name (`young_modulus_kpa`,
`spacing_x_mm`). Relative paths are resolved against the scene file's folder, then
against the project root (`paths`).

Modules, by what they do: `key` (one key: kind, default, choices, range), `limits` (the
ranges and conditions keys share), `sections_body`, `sections_mechanics` and
`sections_sensing` (the keys of each section), `schema` (`SCHEMA`, `ARRAY_SCHEMA`: the one
definition of the keys), `records` (one frozen dataclass per section, written out from
the schema so that a type checker sees every key), `kinds` and `validation` (a table's
keys checked, defaults filled in), `cross_checks` (the checks across keys), `scene`
(`Scene`), `loading` (`load_scene`, `parse_scene`, `default_scene`) and `queries`
(`n_states`, `has_gravity`, ...).

A scene reads as typed records (`scene.fem.element`, `scene.chambers[0].name`); a key the
schema lacks is an AttributeError naming the closest one. `Scene.values` gives a section
as plain data (stage hashes), `Scene.with_values` a checked copy with values changed
(studies).

May import: `fruitcli.errors`, `fruitcli.fsutil`, the tables of choices (listed in the
top package's docstring), `fruitcli.fem.materials.build` (the [material] check across
keys in `cross_checks`, which imports of `fruitcli` only `fruitcli.errors` and a table) and
`fruitcli.bundled_files` (the bundled scenes' names, for a missing scene's hint); never
`fruitcli.workflow`, `fruitcli.cli` or any other module of a stage's package. The
schema, its keys and its records (`key`, `limits`, `sections_*`, `schema`, `records`)
import nothing of `fruitcli` but the tables.
"""

from fruitcli.scene.key import Key
from fruitcli.scene.limits import MAX_FACES, MAX_ITEMS
from fruitcli.scene.loading import default_scene, load_scene, load_skin_table, parse_scene
from fruitcli.scene.paths import resolve_path
from fruitcli.scene.queries import gravity_left_out, has_deformation, has_gravity, n_states
from fruitcli.scene.records import (
    ITEM_TYPES,
    SECTION_TYPES,
    SUBTABLE_TYPES,
    ActuationSection,
    BenchSection,
    BoardSection,
    ChamberTable,
    DetectionSection,
    EllipsoidTable,
    EvaluateTable,
    FemSection,
    FixedTable,
    FramesSection,
    GeometrySection,
    GravitySection,
    GridSection,
    JigTable,
    MaterialSection,
    MeshSection,
    MoldSection,
    PrinterSection,
    Record,
    ReducedSection,
    ReportSection,
    SceneSection,
    Sections,
    SensitivitySection,
    SkinSection,
    SolverSection,
    TracksSection,
)
from fruitcli.scene.scene import Scene
from fruitcli.scene.schema import ARRAY_SCHEMA, ARRAY_SECTIONS, ITEM_LABELS, SCHEMA, SUBTABLES
from fruitcli.scene.validation import check_value

_check_value = check_value  # the name tests/workflow/test_stage_hashes.py imports

__all__ = [
    "ARRAY_SCHEMA",
    "ARRAY_SECTIONS",
    "ITEM_LABELS",
    "ITEM_TYPES",
    "MAX_FACES",
    "MAX_ITEMS",
    "SCHEMA",
    "SECTION_TYPES",
    "SUBTABLES",
    "SUBTABLE_TYPES",
    "ActuationSection",
    "BenchSection",
    "BoardSection",
    "ChamberTable",
    "DetectionSection",
    "EllipsoidTable",
    "EvaluateTable",
    "FemSection",
    "FixedTable",
    "FramesSection",
    "GeometrySection",
    "GravitySection",
    "GridSection",
    "JigTable",
    "Key",
    "MaterialSection",
    "MeshSection",
    "MoldSection",
    "PrinterSection",
    "Record",
    "ReducedSection",
    "ReportSection",
    "Scene",
    "SceneSection",
    "Sections",
    "SensitivitySection",
    "SkinSection",
    "SolverSection",
    "TracksSection",
    "check_value",
    "default_scene",
    "gravity_left_out",
    "has_deformation",
    "has_gravity",
    "load_scene",
    "load_skin_table",
    "n_states",
    "parse_scene",
    "resolve_path",
]
