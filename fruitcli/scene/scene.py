"""The validated scene (`Scene`): its sections as typed records, read as attributes
(`scene.fem.element`), as plain data (`values`, for stage hashes) or changed into a
checked copy (`with_values`, for studies)."""

from __future__ import annotations

from dataclasses import dataclass, fields, is_dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fruitcli.errors import SceneError, echo
from fruitcli.scene.cross_checks import cross_checks
from fruitcli.scene.key import closest
from fruitcli.scene.records import SECTION_TYPES, Sections
from fruitcli.scene.schema import SCHEMA
from fruitcli.scene.validation import check_value


def plain(value: Any) -> Any:
    """Typed records back to the plain dicts and lists the TOML gave (for hashing)."""
    if is_dataclass(value):
        return {f.name: plain(getattr(value, f.name)) for f in fields(value)}
    if isinstance(value, tuple):
        return [plain(v) for v in value]
    return value


@dataclass(frozen=True)
class Scene(Sections):
    """A validated scene: each section a typed record with defaults filled in
    (`scene.fem.element`), each array of tables a tuple of records (`scene.fixed`,
    `scene.chambers`); a section the schema lacks is an AttributeError naming the
    closest one."""

    path: Path
    sections: dict[str, Any]
    declared: frozenset[str] = frozenset()  # sections present in the file

    if not TYPE_CHECKING:  # the type checker reads the sections' types from `Sections`

        def __getattr__(self, name: str):
            sections = self.__dict__.get("sections")
            if sections is not None and name in sections:
                return sections[name]
            if name.startswith("__") or sections is None:
                raise AttributeError(name)
            raise AttributeError(f"a scene has no section [{name}]{closest(name, sections)}")

    @property
    def name(self) -> str:
        """The [scene].name, else the file's stem."""
        return self.scene.name or self.path.stem

    def values(self, section: str) -> Any:
        """A section's values as plain data, as the TOML gave them with defaults filled
        in: a dict for a table, a list of dicts for an array of tables (stage hashes)."""
        if section not in self.sections:
            raise SceneError(
                f"{self.path.name}: unknown section [{section}]{closest(section, self.sections)}"
            )
        return plain(self.sections[section])

    def with_values(self, changes: dict[str, Any]) -> Scene:
        """A copy with `{"section.key": value}` changed (the value as the typed table
        holds it) or `{"section": record}` replaced; each value is checked against the
        schema's choices and ranges, then the checks across keys run again."""
        where = self.path.name
        sections = dict(self.sections)
        for dotted, value in changes.items():
            section, _, key = dotted.partition(".")
            if section not in SECTION_TYPES:
                raise SceneError(
                    f"{where}: cannot set [{section}]{closest(section, SECTION_TYPES)}"
                )
            if not key:
                if not isinstance(value, SECTION_TYPES[section]):
                    raise SceneError(
                        f"{where}: [{section}]: expected a "
                        f"{SECTION_TYPES[section].__name__}, got {echo(value)}"
                    )
                sections[section] = value
                continue
            spec = SCHEMA[section]
            if key not in spec or key == "chamber":
                raise SceneError(f"{where}: [{section}]: unknown key '{key}'{closest(key, spec)}")
            check_value(f"{where}: [{section}]", key, spec[key], value)
            sections[section] = replace(sections[section], **{key: value})
        scene = replace(self, sections=sections)
        cross_checks(scene, where, must_exist=False)
        return scene
