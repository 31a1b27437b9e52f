"""The scene schema's sections of the body and its taxels: [scene], [geometry] (with
[[geometry.chamber]] and its ellipsoid), [tracks], [grid], [mold], [mesh]. Units in the key
names (mm, s)."""

from __future__ import annotations

from fruitcli.geometry.mesh.units import MAX_EXTENT_MM, UNIT_TO_MM
from fruitcli.scene.key import Key
from fruitcli.scene.limits import (
    COORDINATE,
    LENGTH,
    MAX_FACES,
    MAX_GRID_LINES,
    MAX_ITEMS,
    MAX_SECONDS,
    OPEN_FRACTION,
    POSITIVE,
    POSITIVE_LENGTH,
    plain_folder_name,
    two_positive_ints,
)

SECTIONS: dict[str, dict[str, Key]] = {
    "scene": {
        "name": Key(
            "str",
            None,
            "scene name (default: file stem)",
            valid=plain_folder_name,
            expected="a plain folder name (it names out/<name>)",
        ),
        "description": Key("str", "", "free text"),
        "configuration": Key("str", "Rest", "configuration label in tables (Rest, Deformed, ...)"),
    },
    "geometry": {
        "artist": Key("path", None, "artist's high-resolution closed mesh (STL/OBJ/PLY)"),
        "generate_artist": Key("bool", False, "write the default fruit to `artist` if missing"),
        "unit": Key(
            "str",
            "mm",
            "unit of the mesh files (artist, solid, surface): mm, cm, m",
            choices=tuple(UNIT_TO_MM),
        ),
        "fit_mm": Key(
            "num",
            None,
            "scale the artist mesh (after unit) so that its largest "
            "extent is this (mm); chambers stay as given (mm)",
            **POSITIVE_LENGTH,
        ),
        "solid": Key("path", None, "closed surface used as the FEM body as is ([geometry].unit)"),
        "pad_size_mm": Key(
            "vec3",
            None,
            "flat pad [x, y, thickness] in mm, centred at x=y=0",
            **POSITIVE_LENGTH,
            expected=f"[x, y, thickness] each > 0 and <= {MAX_EXTENT_MM:g} mm",
        ),
        "chamber": Key(
            "list", [], "pneumatic chambers ([[geometry.chamber]])", max_items=MAX_ITEMS
        ),
    },
    "tracks": {
        "cover_mm": Key(
            "num",
            2.0,
            "inward offset for the cover layer (mm)",
            **LENGTH,
            expected="a thickness >= 0 mm",
        ),
        "faces": Key(
            "int",
            5000,
            "target triangle count of the reduced surface",
            min=4,
            max=MAX_FACES,
            expected=f"a triangle count 4 <= faces <= {MAX_FACES:,}",
        ),
        "track_radius_mm": Key(
            "num",
            0.6,
            "radius of the yarn tubes (mm)",
            **POSITIVE_LENGTH,
            expected="a radius > 0 mm",
        ),
        "split_z_mm": Key(
            "num", None, "casting split plane height (mm; default: automatic)", **COORDINATE
        ),
        "yarn_max_stretch": Key(
            "num",
            0.25,
            "warn when a track stretches more than this "
            "fraction (yarn limit 0.3 minus a 0.05 margin)",
            **OPEN_FRACTION,
            expected="a fraction 0 < value < 1 (0.25 = 25 %)",
        ),
        "zigzag_pitch_mm": Key(
            "num",
            4.0,
            "zig-zag pitch of the sewn yarn (mm): the warnings' "
            "amplitude and the length of the local stretch",
            **POSITIVE_LENGTH,
            expected="> 0 (mm)",
        ),
        "file": Key(
            "path",
            None,
            "track centre lines given directly (track,axis,index,point,"
            "x_mm,y_mm,z_mm; default: make-tracks' tracks.csv)",
        ),
    },
    "grid": {
        "spacing_x_mm": Key(
            "num", 16.0, "distance between x = const planes (mm)", **POSITIVE_LENGTH
        ),
        "spacing_y_mm": Key(
            "num", 12.0, "distance between y = const planes (mm)", **POSITIVE_LENGTH
        ),
        "origin_mm": Key(
            "vec2", None, "[x0, y0] of plane (0, 0) (mm; default: centred)", **COORDINATE
        ),
        "count": Key(
            "list",
            None,
            "[nx, ny] taxels on a flat pad",
            valid=two_positive_ints,
            expected=f"two positive integers [nx, ny], each at most {MAX_GRID_LINES:,}",
            max_items=2,
        ),
        "taxels": Key("path", None, "taxel CSV given directly (id,i,j,x_mm,y_mm,z_mm)"),
    },
    "mold": {
        "wall_mm": Key(
            "num",
            4.0,
            "mold wall thickness (mm, at least 1)",
            max=MAX_EXTENT_MM,
            unbounded="its lower bound is the mold's (fabrication.mold.MoldOptions.check)",
        ),
        "clearance_mm": Key(
            "num",
            0.3,
            "gap between keys and sockets, pins and holes (mm)",
            max=MAX_EXTENT_MM,
            unbounded="its lower bound is the mold's (fabrication.mold.MoldOptions.check)",
        ),
        "key_radius_mm": Key(
            "num",
            3.0,
            "radius of the registration keys (mm)",
            max=MAX_EXTENT_MM,
            unbounded="its lower bound is the mold's (fabrication.mold.MoldOptions.check)",
        ),
        "pour_diameter_mm": Key(
            "num",
            8.0,
            "pour hole diameter (mm)",
            max=MAX_EXTENT_MM,
            unbounded="its lower bound is the mold's (fabrication.mold.MoldOptions.check)",
        ),
        "vent_diameter_mm": Key(
            "num",
            2.0,
            "vent diameter (mm)",
            max=MAX_EXTENT_MM,
            unbounded="its lower bound is the mold's (fabrication.mold.MoldOptions.check)",
        ),
        "pin_diameter_mm": Key(
            "num",
            3.0,
            "diameter of the pins holding chamber cores (mm)",
            max=MAX_EXTENT_MM,
            unbounded="its lower bound is the mold's (fabrication.mold.MoldOptions.check)",
        ),
        "vents": Key(
            "int",
            4,
            "vents at the cavity's highest points besides the pour hole",
            max=16,
            unbounded="its lower bound is the mold's (fabrication.mold.MoldOptions.check)",
        ),
    },
    "mesh": {
        "size_mm": Key("num", 3.0, "target tetrahedron edge length (mm)", **POSITIVE_LENGTH),
        "min_size_mm": Key(
            "num", None, "smallest edge near chambers and taxels (mm)", **POSITIVE_LENGTH
        ),
        "time_limit_s": Key(
            "num",
            120.0,
            "gmsh is killed after this many seconds",
            **POSITIVE,
            max=MAX_SECONDS,
            expected="a time limit > 0 s",
        ),
        "min_quality": Key(
            "num",
            0.05,
            "refuse meshes whose worst SICN is below this",
            min=-1.0,
            max=1.0,
            expected="a SICN -1 <= value <= 1",
        ),
    },
}
"""The sections, in the order the schema lists them."""

ITEMS: dict[str, dict[str, Key]] = {
    "geometry.chamber": {
        "name": Key("str", None, "chamber name, used in [actuation]", required=True),
        "ellipsoid": Key("table", None, "{center_mm = [x,y,z], radii_mm = [a,b,c]}"),
        "surface": Key("path", None, "closed surface of the cavity ([geometry].unit)"),
    },
}
"""The keys of one table of each array of tables."""

SUBTABLES: dict[str, dict[str, Key]] = {
    "ellipsoid": {
        "center_mm": Key("vec3", required=True, **COORDINATE),
        "radii_mm": Key(
            "vec3",
            required=True,
            **POSITIVE_LENGTH,
            expected="positive radii",
        ),
    }
}
"""Tables inside an array's item ([[geometry.chamber]].ellipsoid)."""
