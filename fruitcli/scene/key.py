"""One scene key (`Key`): its kind, default, meaning and the values it accepts; the Python
type a record gives each kind (`KIND_TYPES`); and the "did you mean" hint of a misspelt
name (`closest`)."""

from __future__ import annotations

import difflib
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

NUM = (int, float)


@dataclass(frozen=True)
class Key:
    """One scene key: its accepted type, default (None: optional), meaning, and the
    values it accepts beyond its type (`choices`, a range [`min`, `max`], `valid`).

    `expected` is the error's "expected ..." text when the derived one ("one of a, b",
    "> 0", "0 <= value < 1") says too little. A range applies to a number, to each
    number of a vector, and to each value of a table."""

    kind: str  # "str", "path", "num", "int", "bool", "vec2", "vec3", "box", "list", "table",
    # "range" (a number or [lo, hi])
    default: Any = None
    doc: str = ""
    required: bool = False
    choices: tuple[str, ...] | None = None
    min: float | None = None
    max: float | None = None
    min_exclusive: bool = False
    max_exclusive: bool = False
    valid: Callable[[Any], bool] | None = None
    expected: str | None = None
    max_items: int | None = None  # most entries of a list or table
    unbounded: str = ""  # why a number has no declared min or max (where it is checked)

    def in_range(self, value: float) -> bool:
        """True when `value` lies in [min, max] (ends excluded as declared)."""
        if self.min is not None and (value <= self.min if self.min_exclusive else value < self.min):
            return False
        return self.max is None or (value < self.max if self.max_exclusive else value <= self.max)

    def expectation(self, value: Any = None) -> str:
        """What a valid value is, for error messages; given the number refused, the side of
        the range it broke (a number too small: the lower bound only)."""
        hi = "" if self.max is None else f" {'<' if self.max_exclusive else '<='} {self.max:g}"
        above = isinstance(value, NUM) and self.max is not None and not self.in_range(value)
        above = above and (value >= self.max if self.max_exclusive else value > self.max)
        if self.expected is not None and self.max is not None:
            forms = {f"{self.max:g}", f"{self.max:,}"}
            if float(self.max).is_integer():
                forms.add(f"{int(self.max):,}")
            # the text already gives an upper end: the max itself, or "lo < value < hi"
            said = any(form in self.expected for form in forms) or self.expected.count("<") >= 2
            return f"{self.expected} and{hi}" if above and not said else self.expected
        if self.expected is not None:
            return self.expected
        if self.choices is not None:
            return f"one of {', '.join(self.choices)}"
        lo = "" if self.min is None else f"{self.min:g} {'<' if self.min_exclusive else '<='} "
        if isinstance(value, NUM) and not above:
            hi = ""
        if lo and hi:
            return f"{lo}value{hi}"
        if lo:
            return f"{'>' if self.min_exclusive else '>='} {self.min:g}"
        return f"{'<' if self.max_exclusive else '<='} {self.max:g}"


KIND_TYPES = {
    "str": "str",
    "path": "Path",
    "num": "float",
    "int": "int",
    "bool": "bool",
    "vec2": "list[float]",
    "vec3": "list[float]",
    "box": "list[float]",
    "list": "list",
    "table": "dict",
    "range": "float | list[float]",
}
"""The annotation of a record's field for each kind (`| None` added when the default is
None); `records` is written with them and its test checks it."""


def number(v: Any) -> bool:
    """True for a finite int or float (not a bool)."""
    return isinstance(v, NUM) and not isinstance(v, bool) and math.isfinite(v)


def closest(name: str, options: Iterable[str]) -> str:
    """' (did you mean 'x'?)' for the option nearest `name`, '' when there is none."""
    match = difflib.get_close_matches(name, list(options), n=1, cutoff=0.0)
    return f" (did you mean '{match[0]}'?)" if match else ""
