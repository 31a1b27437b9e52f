"""The scene's typed records: one frozen dataclass per section (`FemSection`), per table of
an array of tables (`FixedTable`) and per table inside one (`EllipsoidTable`), each with
the schema's keys in its order, typed by their kind (`key.KIND_TYPES`; `| None` when the
default is None) and defaulting as the schema says (a required key has no default).
`Sections` types the sections a `Scene` holds. Written out from the schema so that a
type checker sees every key; tests/test_scene_records.py checks that they match it (a
key added to the schema gets its field here)."""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING

from fruitcli.scene.key import closest


class Record:
    """Base of the typed scene tables: reading a key the schema lacks fails loudly,
    naming the closest key (at run time; a type checker reports it before)."""

    if not TYPE_CHECKING:  # hidden from the type checker, which then sees misspelt keys

        def __getattr__(self, name: str):
            if name.startswith("__"):
                raise AttributeError(name)
            keys = [f.name for f in fields(self)]
            raise AttributeError(f"{type(self).__name__} has no key '{name}'{closest(name, keys)}")


@dataclass(frozen=True)
class EllipsoidTable(Record):
    """One ellipsoid table ([[geometry.chamber]].ellipsoid)."""

    center_mm: list[float]
    radii_mm: list[float]


@dataclass(frozen=True)
class ChamberTable(Record):
    """One [[geometry.chamber]] table."""

    name: str
    ellipsoid: EllipsoidTable | None = None
    surface: Path | None = None


@dataclass(frozen=True)
class FixedTable(Record):
    """One [[fixed]] table."""

    box_mm: list[float]
    displacement_mm: list[float] | None = None


@dataclass(frozen=True)
class JigTable(Record):
    """One [[jig]] table."""

    region_box_mm: list[float]
    rotate_deg: float = 0.0
    axis: list[float] = field(default_factory=lambda: [0.0, 0.0, 1.0])
    pivot_mm: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    translate_mm: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    stiffness_n_per_mm: float = 10.0


@dataclass(frozen=True)
class EvaluateTable(Record):
    """One [[evaluate]] table."""

    label: str
    truth: Path
    measured: Path
    reference_length_mm: float | None = None
    register: str = "none"


@dataclass(frozen=True)
class SceneSection(Record):
    """The [scene] section."""

    name: str | None = None
    description: str = ""
    configuration: str = "Rest"


@dataclass(frozen=True)
class GeometrySection(Record):
    """The [geometry] section."""

    artist: Path | None = None
    generate_artist: bool = False
    unit: str = "mm"
    fit_mm: float | None = None
    solid: Path | None = None
    pad_size_mm: list[float] | None = None
    chamber: tuple[ChamberTable, ...] = ()


@dataclass(frozen=True)
class TracksSection(Record):
    """The [tracks] section."""

    cover_mm: float = 2.0
    faces: int = 5000
    track_radius_mm: float = 0.6
    split_z_mm: float | None = None
    yarn_max_stretch: float = 0.25
    zigzag_pitch_mm: float = 4.0
    file: Path | None = None


@dataclass(frozen=True)
class GridSection(Record):
    """The [grid] section."""

    spacing_x_mm: float = 16.0
    spacing_y_mm: float = 12.0
    origin_mm: list[float] | None = None
    count: list | None = None
    taxels: Path | None = None


@dataclass(frozen=True)
class MoldSection(Record):
    """The [mold] section."""

    wall_mm: float = 4.0
    clearance_mm: float = 0.3
    key_radius_mm: float = 3.0
    pour_diameter_mm: float = 8.0
    vent_diameter_mm: float = 2.0
    pin_diameter_mm: float = 3.0
    vents: int = 4


@dataclass(frozen=True)
class MeshSection(Record):
    """The [mesh] section."""

    size_mm: float = 3.0
    min_size_mm: float | None = None
    time_limit_s: float = 120.0
    min_quality: float = 0.05


@dataclass(frozen=True)
class FemSection(Record):
    """The [fem] section."""

    element: str = "p2"


@dataclass(frozen=True)
class MaterialSection(Record):
    """The [material] section."""

    model: str = "neo-hookean"
    c10_kpa: float | None = None
    c20_kpa: float = 0.0
    c30_kpa: float = 0.0
    bulk_modulus_kpa: float | None = None
    young_modulus_kpa: float = 100.0
    poisson_ratio: float = 0.45
    density_kg_m3: float = 1070.0


@dataclass(frozen=True)
class GravitySection(Record):
    """The [gravity] section."""

    vector_m_s2: list[float] = field(default_factory=lambda: [0.0, 0.0, -9.81])


@dataclass(frozen=True)
class ActuationSection(Record):
    """The [actuation] section."""

    pressure_kpa: dict | None = None
    volume_growth_mm3: dict | None = None
    period_s: float | None = None


@dataclass(frozen=True)
class SolverSection(Record):
    """The [solver] section."""

    tolerance: float = 1e-06
    displacement_tolerance_mm: float = 0.0001
    max_iterations: int = 25
    max_subdivisions: int = 6
    linear_solver: str = "pcg"
    jig_steps: int = 1
    first_steps: int = 4
    max_seconds: float = 300.0


@dataclass(frozen=True)
class ReducedSection(Record):
    """The [reduced] section."""

    pressure_range_kpa: list[float] | None = None
    margin: float = 0.1
    points_per_axis: int = 5
    max_degree: int = 4
    validation: int = 50
    seed: int = 0


@dataclass(frozen=True)
class BoardSection(Record):
    """The [board] section."""

    rows: int = 21
    cols: int = 12
    offset_i: int = 0
    offset_j: int = 0
    flip_i: bool = False
    flip_j: bool = False
    transpose: bool = False
    format: str = "auto"


@dataclass(frozen=True)
class FramesSection(Record):
    """The [frames] section."""

    recording: Path | None = None
    model: str = "reduced"


@dataclass(frozen=True)
class DetectionSection(Record):
    """The [detection] section."""

    threshold_counts: float = 20.0
    baseline_frames: int = 10
    method: str = "n9"
    model_frames: int = 1
    noise_floor_counts: float = 0.0
    hysteresis_counts: float = 0.0
    debounce_frames: int = 0
    drift_rate: float = 0.0
    track_gate_mm: float = 0.0
    project: str = "none"
    divide_by_gain: bool = False
    hovers: bool = False
    hover_threshold_counts: float | None = None
    hover_hysteresis_counts: float | None = None
    footprint: str | None = None


@dataclass(frozen=True)
class BenchSection(Record):
    """The [bench] section."""

    indenters: list = field(default_factory=lambda: ["small", "medium"])
    samples: str = "quarter"
    state: int = 0
    step_mm: float = 0.1
    seed: int = 0
    baseline_frames: int = 10
    reference_length_mm: float | None = None
    register: str = "none"


@dataclass(frozen=True)
class SkinSection(Record):
    """The [skin] section."""

    footprint_sigma_mm: dict | None = None
    contact_counts: float = 60.0
    gap_decay_mm: float = 2.0
    height_as_distance: float = 1.0
    height_as_gap: float = 0.0
    widening_per_mm: float = 0.0
    gain_spread: float = 0.0
    noise_std_counts: float | list[float] = field(default_factory=lambda: [0.5, 1.85])
    taxel_gain: Path | None = None
    model: str = "gaussian"
    permittivity: float = 2.8
    yarn_radius_mm: float | None = None
    insulation_mm: float = 0.1
    counts_per_ff: float | None = None
    gaps_mm: list = field(
        default_factory=lambda: [0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0]
    )


@dataclass(frozen=True)
class PrinterSection(Record):
    """The [printer] section."""

    model_origin_mm: list[float] | None = None
    rotate_z_deg: float = 0.0
    safe_height_mm: float = 20.0
    step_mm: float = 0.1
    feed_mm_min: float = 600.0
    max_press_mm: float = 1.5
    bed_mm: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0, 220.0, 220.0, 250.0])
    baud: int = 115200
    home: bool = False
    timeout_s: float = 30.0


@dataclass(frozen=True)
class SensitivitySection(Record):
    """The [sensitivity] section."""

    noise_frames: int = 300
    animation_frames: int = 60


@dataclass(frozen=True)
class ReportSection(Record):
    """The [report] section."""

    paper_rows: list = field(default_factory=list)


class Sections:
    """A scene's sections as their records (what `Scene` reads through): a table section
    is its record, an array of tables a tuple of them; `declared` the sections the file
    declares."""

    scene: SceneSection
    geometry: GeometrySection
    tracks: TracksSection
    grid: GridSection
    mold: MoldSection
    mesh: MeshSection
    fem: FemSection
    material: MaterialSection
    gravity: GravitySection
    fixed: tuple[FixedTable, ...]
    jig: tuple[JigTable, ...]
    actuation: ActuationSection
    solver: SolverSection
    reduced: ReducedSection
    board: BoardSection
    frames: FramesSection
    detection: DetectionSection
    bench: BenchSection
    skin: SkinSection
    printer: PrinterSection
    sensitivity: SensitivitySection
    report: ReportSection
    evaluate: tuple[EvaluateTable, ...]
    declared: frozenset[str]

    def has(self, section: str) -> bool:
        """True when the file declares `section` (or a non-empty array of it)."""
        return section in self.declared

    @property
    def chambers(self) -> tuple[ChamberTable, ...]:
        """The [[geometry.chamber]] records."""
        return self.geometry.chamber


SECTION_TYPES: dict[str, type[Record]] = {
    "scene": SceneSection,
    "geometry": GeometrySection,
    "tracks": TracksSection,
    "grid": GridSection,
    "mold": MoldSection,
    "mesh": MeshSection,
    "fem": FemSection,
    "material": MaterialSection,
    "gravity": GravitySection,
    "actuation": ActuationSection,
    "solver": SolverSection,
    "reduced": ReducedSection,
    "board": BoardSection,
    "frames": FramesSection,
    "detection": DetectionSection,
    "bench": BenchSection,
    "skin": SkinSection,
    "printer": PrinterSection,
    "sensitivity": SensitivitySection,
    "report": ReportSection,
}
ITEM_TYPES: dict[str, type[Record]] = {
    "geometry.chamber": ChamberTable,
    "fixed": FixedTable,
    "jig": JigTable,
    "evaluate": EvaluateTable,
}
SUBTABLE_TYPES: dict[str, type[Record]] = {
    "ellipsoid": EllipsoidTable,
}
