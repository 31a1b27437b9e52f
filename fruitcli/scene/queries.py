"""What a scene implies for the stages: its number of actuation states, whether gravity
loads the body (and why a declared [gravity] may not), whether anything deforms it."""

from __future__ import annotations

from fruitcli.scene.records import Sections


def n_states(scene: Sections) -> int:
    """Number of actuation states (1 when the scene has no [actuation])."""
    act = scene.actuation
    for table in (act.pressure_kpa, act.volume_growth_mm3):
        if table:
            return len(next(iter(table.values())))
    return 1


def has_gravity(scene: Sections) -> bool:
    """True when gravity loads the body: [gravity] declared with a non-zero vector, a
    body with mass, held by a [[fixed]] region or a [[jig]] (a free body under gravity
    would only fall)."""
    return (
        scene.has("gravity")
        and any(scene.gravity.vector_m_s2)
        and scene.material.density_kg_m3 > 0
        and bool(scene.fixed or scene.jig)
    )


def gravity_left_out(scene: Sections) -> str | None:
    """Why a declared [gravity] loads nothing (None when it applies or is not declared):
    a weightless body, or no [[fixed]] region nor [[jig]] holding it."""
    if not scene.has("gravity") or not any(scene.gravity.vector_m_s2):
        return None
    if scene.material.density_kg_m3 == 0:
        return "[gravity] left out: [material].density_kg_m3 = 0 (a weightless body)"
    if not (scene.fixed or scene.jig):
        return (
            "[gravity] left out: no [[fixed]] region or [[jig]] holds the body "
            "(a free body would only fall)"
        )
    return None


def has_deformation(scene: Sections) -> bool:
    """True when something moves the body: non-zero actuation, a jig, a moved clamp or
    gravity on a held body."""
    act = scene.actuation
    for table in (act.pressure_kpa, act.volume_growth_mm3):
        if table and any(v != 0 for vals in table.values() for v in vals):
            return True
    moved = any(f.displacement_mm is not None and any(f.displacement_mm) for f in scene.fixed)
    return bool(scene.jig) or moved or has_gravity(scene)
