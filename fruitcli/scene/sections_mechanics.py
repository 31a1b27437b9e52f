"""The scene schema's sections of the mechanics: [fem], [material], [gravity], [[fixed]],
[[jig]], [actuation], [solver], [reduced]. Units in the key names (mm, kPa, degrees, s)."""

from __future__ import annotations

from fruitcli.fem.elements.families import ELEMENT_FAMILIES
from fruitcli.fem.materials.models import MATERIAL_MODELS
from fruitcli.fem.solver.solvers import LINEAR_SOLVERS
from fruitcli.geometry.mesh.units import MAX_EXTENT_MM
from fruitcli.scene.key import Key
from fruitcli.scene.limits import (
    ANGLE,
    COORDINATE,
    FAR_MM,
    LENGTH,
    MAX_ITEMS,
    MAX_SECONDS,
    MODULUS_KPA,
    OPEN_FRACTION,
    POSITIVE,
    PRESSURE_KPA,
    SEED,
    increasing_pair,
    nonzero_vector,
)

SECTIONS: dict[str, dict[str, Key]] = {
    "fem": {
        "element": Key(
            "str",
            "p2",
            "p2 (quadratic tets, P2/P0 mean dilatation: no locking), "
            "p2-pure (quadratic, displacement only) or p1 (linear tets, the "
            "paper's SOFA element)",
            choices=tuple(ELEMENT_FAMILIES),
        ),
    },
    "material": {
        "model": Key(
            "str",
            "neo-hookean",
            "neo-hookean (from E and nu), yeoh (c10_kpa, "
            "c20_kpa, c30_kpa) or corotational (the paper's SOFA Hooke, p1 only)",
            choices=tuple(MATERIAL_MODELS),
        ),
        "c10_kpa": Key(
            "num",
            None,
            "yeoh: C10 (kPa; the shear modulus is 2 C10)",
            max=MODULUS_KPA,
            unbounded="its lower bound is the material's (materials.build.from_scene)",
        ),
        "c20_kpa": Key("num", 0.0, "yeoh: C20 (kPa)", min=-MODULUS_KPA, max=MODULUS_KPA),
        "c30_kpa": Key("num", 0.0, "yeoh: C30 (kPa)", min=-MODULUS_KPA, max=MODULUS_KPA),
        "bulk_modulus_kpa": Key(
            "num",
            None,
            "bulk modulus kappa (kPa; default from E, nu)",
            max=MODULUS_KPA,
            unbounded="its lower bound is the material's (materials.build.from_scene)",
        ),
        "young_modulus_kpa": Key(
            "num", 100.0, "Young's modulus E (kPa)", **POSITIVE, max=MODULUS_KPA
        ),
        "poisson_ratio": Key(
            "num",
            0.45,
            "Poisson's ratio nu (-1 < nu < 0.5)",
            min=-1.0,
            max=0.5,
            min_exclusive=True,
            max_exclusive=True,
            expected="-1 < nu < 0.5",
        ),
        "density_kg_m3": Key("num", 1070.0, "density (kg/m^3)", min=0.0, max=1e5),
    },
    "gravity": {
        "vector_m_s2": Key(
            "vec3",
            [0.0, 0.0, -9.81],
            "gravity acceleration (m/s^2); an empty [gravity] means this default",
            min=-1e4,
            max=1e4,
        ),
    },
    "fixed": {},  # arrays of tables: their keys are in ITEMS
    "jig": {},
    "actuation": {
        "pressure_kpa": Key(
            "table",
            None,
            "per chamber: one pressure per state (kPa)",
            min=-PRESSURE_KPA,
            max=PRESSURE_KPA,
            expected=f"pressures -{PRESSURE_KPA:g} <= p <= {PRESSURE_KPA:g} kPa, one per state",
            max_items=MAX_ITEMS,
        ),
        "volume_growth_mm3": Key(
            "table",
            None,
            "per chamber: one volume growth per state (mm^3)",
            min=-(MAX_EXTENT_MM**3),
            max=MAX_EXTENT_MM**3,
            expected=f"volume growths of at most {MAX_EXTENT_MM**3:g} mm^3 either way, one per "
            "state",
            max_items=MAX_ITEMS,
        ),
        "period_s": Key(
            "num",
            None,
            "duration of one cycle of the states (s), for animations",
            **POSITIVE,
            max=MAX_SECONDS,
        ),
    },
    "solver": {
        "tolerance": Key(
            "num",
            1e-6,
            "Newton stops when |residual| <= tolerance * |load|",
            **OPEN_FRACTION,
            expected="0 < tolerance < 1 (a residual relative to the load)",
        ),
        "displacement_tolerance_mm": Key(
            "num",
            1e-4,
            "... or when the kept factor estimates "
            "the correction left within half this (mm; 0 = "
            "off)",
            **LENGTH,
        ),
        "max_iterations": Key("int", 25, "Newton iterations per load step", min=1, max=1000),
        "max_subdivisions": Key("int", 6, "times a failing load step may be halved", min=0, max=30),
        "linear_solver": Key(
            "str",
            "pcg",
            "pcg (CG on a kept Cholesky), direct or jacobi",
            choices=tuple(LINEAR_SOLVERS),
        ),
        "jig_steps": Key("int", 1, "load steps to apply the jig rotation", min=1, max=10_000),
        "first_steps": Key(
            "int",
            4,
            "load steps of the state solved from rest (hyperelastic models)",
            min=1,
            max=10_000,
        ),
        "max_seconds": Key(
            "num",
            300.0,
            "time budget of one state (s); past it the state fails, saying how far its load got",
            **POSITIVE,
            max=MAX_SECONDS,
            expected="a time budget > 0 s",
        ),
    },
    "reduced": {  # the reduced model of the live loop (fruitcli.fem.reduced.build)
        "pressure_range_kpa": Key(
            "vec2",
            None,
            "[lo, hi] kPa for every chamber (default: "
            "each chamber's [actuation] pressures plus the margin)",
            valid=increasing_pair,
            min=-PRESSURE_KPA,
            max=PRESSURE_KPA,
            expected=f"[lo, hi] with -{PRESSURE_KPA:g} <= lo < hi <= {PRESSURE_KPA:g}",
        ),
        "margin": Key(
            "num",
            0.1,
            "fraction of each chamber's [actuation] span added on either side",
            min=0.0,
            max=10.0,
        ),
        "points_per_axis": Key(
            "int", 5, "Chebyshev-Lobatto full solves per chamber", min=2, max=64
        ),
        "max_degree": Key(
            "int", 4, "highest total degree tried (chosen by leave-one-out)", min=1, max=32
        ),
        "validation": Key(
            "int", 50, "held-out random pressure vectors solved in full", min=1, max=100_000
        ),
        "seed": Key("int", 0, "seed of the held-out pressure vectors", **SEED),
    },
}
"""The sections, in the order the schema lists them."""

ITEMS: dict[str, dict[str, Key]] = {
    "fixed": {
        "box_mm": Key(
            "box",
            None,
            "[xmin, ymin, zmin, xmax, ymax, zmax] (mm)",
            required=True,
            **COORDINATE,
        ),
        "displacement_mm": Key(
            "vec3",
            None,
            "the clamp moved by [dx, dy, dz] (mm), ramped "
            "with the load steps (default: held at rest)",
            min=-MAX_EXTENT_MM,
            max=MAX_EXTENT_MM,
        ),
    },
    "jig": {
        "region_box_mm": Key(
            "box", None, "nodes pulled by the springs (mm)", required=True, **COORDINATE
        ),
        "rotate_deg": Key("num", 0.0, "rotation of the target about `axis` (degrees)", **ANGLE),
        "axis": Key(
            "vec3",
            [0.0, 0.0, 1.0],
            "rotation axis",
            valid=nonzero_vector,
            **COORDINATE,
            expected=f"a non-zero vector, each component within +-{FAR_MM:g}",
        ),
        "pivot_mm": Key("vec3", [0.0, 0.0, 0.0], "point on the rotation axis (mm)", **COORDINATE),
        "translate_mm": Key(
            "vec3", [0.0, 0.0, 0.0], "translation after the rotation (mm)", **COORDINATE
        ),
        "stiffness_n_per_mm": Key(
            "num", 10.0, "spring stiffness per node (N/mm)", **POSITIVE, max=1e9
        ),
    },
}
"""The keys of one table of each array of tables."""
