"""Fuzzing targets: for every reader and parser a Hypothesis strategy of hostile inputs and
a check that the outcome is either a correct result or the project's own error type with a
one-line message naming the input. Used by test_robust_fuzz.py (a short run) and
fuzz_run.py (a long one, `make fuzz`)."""

from __future__ import annotations

import atexit
import io
import math
import shutil
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import strategies as st

from fruitcli.errors import FruitError

ROWS, COLS = 21, 12
WORK = Path(tempfile.mkdtemp(prefix="fruit-fuzz-"))
atexit.register(shutil.rmtree, WORK, ignore_errors=True)  # the inputs written, at exit


class Misbehaved(AssertionError):
    """A reader answered with something other than a result or one clean error line."""


def clean_error(exc: BaseException, name: str) -> None:
    """`exc` must be a FruitError of one line naming `name`."""
    text = str(exc)
    if not isinstance(exc, FruitError):
        raise Misbehaved(f"{type(exc).__name__}: {text[:300]}") from exc
    if "\n" in text.strip() or name not in text:
        raise Misbehaved(f"message not one line naming {name}: {text[:300]!r}") from exc


def put(name: str, data: bytes | str) -> Path:
    path = WORK / name
    path.write_bytes(data.encode("utf-8", "surrogatepass") if isinstance(data, str) else data)
    return path


def outcome(call, name: str):
    """call() -> its result, or None after checking the error it raised."""
    try:
        return call()
    except Exception as exc:
        clean_error(exc, name)
        return None


# ------------------------------------------------------------------------ values and text
NUMBERS = st.one_of(st.integers(-(10**20), 10**20), st.floats(allow_nan=True, allow_infinity=True))
FIELD = st.one_of(
    NUMBERS.map(str),
    st.sampled_from(["", " ", "nan", "inf", "-0", "1e400", "x", '"1"', "1,2", "\ufeff"]),
    st.text(max_size=6),
)


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return (
            ("nan" if math.isnan(value) else ("inf" if value > 0 else "-inf"))
            if not math.isfinite(value)
            else repr(value)
        )
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return '"' + value.encode("unicode_escape").decode("ascii").replace('"', '\\"') + '"'
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return '""'


def _scene_strategy():
    from fruitcli.scene import SCHEMA

    value = st.one_of(
        NUMBERS,
        st.booleans(),
        st.text(max_size=8),
        st.lists(NUMBERS, max_size=7),
        st.sampled_from(["p1", "p2", "none"]),
    )
    sections = st.sampled_from(sorted(SCHEMA))

    def keys(section):
        names = sorted(SCHEMA[section]) + ["no_such_key"]
        return st.dictionaries(st.sampled_from(names), value, max_size=4)

    tables = st.lists(sections.flatmap(lambda s: keys(s).map(lambda k: (s, k))), max_size=5)

    def to_text(items) -> str:
        out = []
        for section, table in items:
            out.append(f"[{section}]")
            out += [f"{k} = {_toml_value(v)}" for k, v in table.items()]
        return "\n".join(out) + "\n"

    return st.one_of(tables.map(to_text), st.text(max_size=200))


def check_scene(text: str) -> None:
    from fruitcli.scene import Scene, parse_scene

    path = WORK / "fuzz.toml"
    got = outcome(lambda: parse_scene(text, path, must_exist=False), path.name)
    assert got is None or isinstance(got, Scene)


def _csv_strategy(columns: list[str]):
    header = st.lists(st.sampled_from(columns + ["extra", ""]), min_size=1, max_size=8)
    comments = st.lists(st.sampled_from(["# unit mm", "", "   "]), max_size=2)
    number = st.floats(-1e3, 1e3).map(repr)

    def with_rows(head):  # rows of the header's width, mostly numbers, or of any width
        width = st.lists(st.one_of(number, FIELD), min_size=len(head), max_size=len(head))
        return st.tuples(
            st.just(head),
            st.lists(st.one_of(width, width, st.lists(FIELD, max_size=9)), max_size=6),
            comments,
        )

    def to_text(parts) -> str:
        head, body, notes = parts
        return "\n".join(notes + [",".join(head)] + [",".join(r) for r in body]) + "\n"

    good = st.lists(st.tuples(*[st.floats(-1e3, 1e3)] * len(columns)), min_size=1, max_size=5).map(
        lambda r: (
            ",".join(columns) + "\n" + "\n".join(",".join(repr(v) for v in row) for row in r) + "\n"
        )
    )
    return st.one_of(
        header.flatmap(with_rows).map(to_text),
        good,
        st.binary(max_size=100).map(lambda b: b.decode("latin-1")),
    )


def check_table(text: str) -> None:
    from fruitcli.tables import read_table

    path = put("points.csv", text)
    got = outcome(lambda: read_table(path, ["sample", "x_mm", "y_mm"]), str(path))
    if got is not None:
        n = {len(v) for v in got.values()}
        assert len(n) == 1 and all(np.isfinite(got[c]).all() for c in ("x_mm", "y_mm"))


def check_taxels(text: str) -> None:
    from fruitcli.tables import read_taxels

    path = put("taxels.csv", text)
    got = outcome(lambda: read_taxels(path), str(path))
    if got is not None:
        assert len(np.unique(got.ids)) == len(got) and got.xyz_mm.shape == (len(got), 3)


def check_pressures(text: str) -> None:
    from fruitcli.fem.pressure_table import read_pressures

    path = put("pressures.csv", text)
    got = outcome(lambda: read_pressures(path, ["c1", "c2"]), str(path))
    if got is not None:
        kpa, rows = got
        assert kpa.shape == (len(rows), 2) and np.isfinite(kpa).all()


# ------------------------------------------------------------------------ frames
def _ascii_strategy():
    from fruitcli.sensing.frames.muca_line import format_line

    counts = st.lists(st.integers(0, 65535), min_size=ROWS * COLS, max_size=ROWS * COLS)
    line = st.one_of(
        counts.map(
            lambda c: (
                format_line(np.array(c)).decode("ascii")
                if isinstance(format_line(np.array(c)), bytes)
                else format_line(np.array(c))
            )
        ),
        st.lists(FIELD, max_size=ROWS * COLS + 2).map(",".join),
    )
    return (
        st.lists(line, max_size=5)
        .map(lambda ls: "\n".join(ls))
        .flatmap(
            lambda text: st.tuples(
                st.just(text), st.integers(0, max(len(text), 1)), st.binary(max_size=8)
            )
        )
        .map(
            lambda t: (t[0][: t[1]] + t[2].decode("latin-1") + t[0][t[1] :]).encode(
                "latin-1", "replace"
            )
        )
    )


def _binary_strategy():
    from fruitcli.sensing.frames.muca import encode_packet

    frame = st.lists(st.integers(0, 65535), min_size=ROWS * COLS, max_size=ROWS * COLS).map(
        lambda c: encode_packet(np.array(c))
    )
    return st.lists(st.one_of(frame, st.binary(max_size=300)), max_size=4).map(b"".join)


def _check_frames(frames) -> None:
    assert frames.ndim == 3 and frames.shape[1:] == (ROWS, COLS)


def check_ascii_stream(data: bytes) -> None:
    from fruitcli.sensing.frames.muca import decode_bytes

    got = outcome(lambda: decode_bytes(data, "ascii", ROWS, COLS), "")
    if got is not None:
        _check_frames(got[0])


def check_binary_stream(data: bytes) -> None:
    from fruitcli.sensing.frames.muca import decode_bytes

    got = outcome(lambda: decode_bytes(data, "binary", ROWS, COLS), "")
    if got is not None:
        _check_frames(got[0])


def check_log(data: bytes) -> None:
    from fruitcli.sensing.frames.recording import read_recording

    path = put("frames.log", data)
    got = outcome(lambda: read_recording(path), str(path))
    if got is not None:
        _check_frames(got.frames)


def _npz_bytes() -> bytes:
    buf = io.BytesIO()
    np.savez(buf, frames=np.full((3, ROWS, COLS), 1000, np.uint16), t_s=np.arange(3) / 10)
    return buf.getvalue()


NPZ = _npz_bytes()


def _npz_strategy():
    edits = st.lists(st.tuples(st.integers(0, len(NPZ) - 1), st.integers(0, 255)), max_size=4)

    def mutate(args) -> bytes:
        changes, cut = args
        data = bytearray(NPZ)
        for at, byte in changes:
            data[at] = byte
        return bytes(data[:cut])

    return st.tuples(edits, st.integers(0, len(NPZ))).map(mutate)


def _read_in_chunks(path: Path) -> np.ndarray:
    from fruitcli.sensing.frames.recording_chunks import open_recording

    with open_recording(path) as rec:
        return np.concatenate([chunk for _, chunk in rec.chunks(2)])


def check_npz(data: bytes) -> None:
    from fruitcli.sensing.frames.recording import read_recording

    path = put("frames.npz", data)
    for read in (lambda: read_recording(path).frames, lambda: _read_in_chunks(path)):
        got = outcome(read, str(path))
        if got is not None:  # a changed byte that reads back left the frames whole
            _check_frames(got)
            if got.shape[0] != 3 or not (got == 1000).all():
                raise Misbehaved(f"{path}: read back as other frames")


# ------------------------------------------------------------------------ meshes
def _mesh_strategy():
    coord = st.one_of(st.floats(-100, 100), st.sampled_from([float("nan"), 0.0, 1e9]))
    verts = st.lists(st.tuples(coord, coord, coord), min_size=0, max_size=12)

    def with_faces(vs):
        n = max(len(vs), 1)
        return st.tuples(st.just(vs), st.lists(st.tuples(*[st.integers(0, n)] * 3), max_size=16))

    return verts.flatmap(with_faces)


def check_mesh(soup) -> None:
    from fruitcli.geometry.mesh.load import load_mesh

    verts, faces = soup
    text = "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in verts)
    text += "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces)
    path = put("soup.obj", text)
    got = outcome(lambda: load_mesh(path), str(path))
    if got is not None:
        assert np.isfinite(got.vertices).all() and len(got.faces) > 0


# ------------------------------------------------------------------------ G-code replies
class _FakePort:
    """A serial port answering with fixed bytes, then nothing."""

    def __init__(self, reply: bytes):
        self.reply, self.written = bytearray(reply), []

    @property
    def in_waiting(self) -> int:
        return len(self.reply)

    def read(self, n: int) -> bytes:
        out, self.reply[:n] = bytes(self.reply[:n]), b""
        return out

    def write(self, data: bytes) -> int:
        self.written.append(data)
        return len(data)

    def flush(self) -> None:
        pass


def _reply_strategy():
    line = st.one_of(
        st.sampled_from(
            [
                "ok",
                "ok T:20",
                "echo:busy: processing",
                "Resend: 1",
                "Resend: 7",
                "rs N1",
                "Error:checksum mismatch",
                "Error:Printer halted",
                "!! kill",
                "X:1.0 Y:2.0 Z:3.0 E:0",
                "X:nan Y:2 Z:3",
                "start",
                "",
            ]
        ),
        st.text(max_size=20),
    )
    return st.lists(line, max_size=6).map(
        lambda ls: ("\n".join(ls) + "\n").encode("utf-8", "replace")
    )


def check_reply(reply: bytes) -> None:
    from fruitcli.printer.marlin import Marlin

    printer = Marlin(_FakePort(reply), name="fuzz-printer", timeout_s=0.01)
    got = outcome(printer.position, "fuzz-printer")
    if got is not None:
        assert len(got) == 3


# ------------------------------------------------------------------------ sizes and ranges
SIZES = st.one_of(
    st.integers(-(2**63), 2**63 - 1),
    st.integers(-3, 300).map(lambda k: 10.0**k),
    st.integers(-3, 300).map(lambda k: -(10.0**k)),
    st.sampled_from([0, 1, -1, 0.0, 5e-324, 1.7e308, 2**53 + 1]),
)


def _key_strategy():
    """One key of the schema with an extreme value: a number, a vector of them, or a list
    or table far longer than most (sizes and lengths)."""
    from fruitcli.scene import ARRAY_SCHEMA, SCHEMA

    keys = [(s, k, spec) for s, d in SCHEMA.items() for k, spec in d.items()]
    keys += [(s, k, spec) for s, d in ARRAY_SCHEMA.items() for k, spec in d.items()]
    keys = [(s, k, spec) for s, k, spec in keys if spec.kind not in ("str", "path", "bool")]

    def value(spec):
        if spec.kind in ("vec2", "vec3", "box"):
            n = {"vec2": 2, "vec3": 3, "box": 6}[spec.kind]
            return st.lists(SIZES, min_size=n, max_size=n)
        if spec.kind == "list":
            return st.one_of(
                st.lists(SIZES, max_size=4),
                st.integers(0, 3000).map(lambda n: ["small"] * n),
                st.integers(0, 3000).map(lambda n: [float(i) for i in range(n)]),
            )
        if spec.kind == "table":
            return st.dictionaries(st.sampled_from(["small", "c1"]), SIZES, max_size=2)
        return SIZES

    return st.sampled_from(keys).flatmap(
        lambda key: value(key[2]).map(lambda v: (key[0], key[1], v))
    )


def check_key_range(item) -> None:
    """A value is refused in one line naming its key, or accepted within its declared
    range and length."""
    from fruitcli.scene import ARRAY_SCHEMA, SCHEMA, parse_scene

    section, key, value = item
    if section in ARRAY_SCHEMA:
        spec = ARRAY_SCHEMA[section][key]
        required = {"box": [0, 0, 0, 1, 1, 1], "str": "x", "path": "t.csv"}
        table = {k: required[s.kind] for k, s in ARRAY_SCHEMA[section].items() if s.required}
        table[key] = value
        text = f"[[{section}]]\n" + "".join(f"{k} = {_toml_value(v)}\n" for k, v in table.items())
    else:
        spec = SCHEMA[section][key]
        text = f"[{section}]\n{key} = {_toml_value(value)}\n"
    path = WORK / "sizes.toml"
    got = outcome(lambda: parse_scene(text, path, must_exist=False), path.name)
    if got is None:
        return
    held = getattr(
        got.sections[section][0] if section in ARRAY_SCHEMA else got.sections[section], key
    )
    if isinstance(held, (list, tuple, dict)) and spec.max_items is not None:
        assert len(held) <= spec.max_items, (section, key, len(held))
    numbers = held.values() if isinstance(held, dict) else held
    numbers = numbers if isinstance(numbers, (list, tuple)) else [numbers]
    for v in numbers:
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            assert spec.in_range(v), (section, key, v)


def _estimate_strategy():
    pad = st.tuples(SIZES, SIZES, SIZES)
    size = st.one_of(SIZES, st.floats(min_value=0.0, exclude_min=True, max_value=1e-100))
    return st.tuples(pad, st.tuples(SIZES, SIZES), size)


def check_estimates(item) -> None:
    """A flat pad's size, grid and mesh size from the fuzzer: each estimate is a number
    (no overflow, no warning) and what `memory` accepts fits the memory available."""
    import warnings

    from fruitcli import memory
    from fruitcli.fem.meshing.estimate import BYTES_PER_TET, expected_tets
    from fruitcli.geometry.padgrid import ROW_BYTES, check_pad_size, pad_rows
    from fruitcli.sensing.skin.virtual_bench import bench_bytes

    pad, count, size = item
    if size > 0:  # a mesh size or a bench step: the estimates are numbers, inf at worst
        bench = bench_bytes(size, 1000, 1000, 252)
        assert bench > 0 and not math.isnan(bench)
        tets = expected_tets(1200.0, size)
        assert tets >= 0 and not math.isnan(tets)
        outcome(lambda: memory.require(tets * BYTES_PER_TET, "fuzz.toml"), "fuzz.toml")
    if min(pad) <= 0 or min(count) < 1 or max(pad) > 5000 or max(count) > 10_000:
        return  # the schema refuses these first
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        taxels, points = pad_rows(pad, count)
        accepted = outcome(lambda: check_pad_size(pad, count, "fuzz.toml") or True, "fuzz.toml")
        if accepted:
            assert (taxels + points) * ROW_BYTES <= memory.SHARE * memory.available_bytes()


TARGETS = {
    "scene TOML": (_scene_strategy, check_scene),
    "scene sizes and ranges": (_key_strategy, check_key_range),
    "size estimates": (_estimate_strategy, check_estimates),
    "points CSV": (lambda: _csv_strategy(["sample", "x_mm", "y_mm"]), check_table),
    "taxel CSV": (lambda: _csv_strategy(["id", "i", "j", "x_mm", "y_mm", "z_mm"]), check_taxels),
    "pressure table": (lambda: _csv_strategy(["c1_kpa", "c2_kpa"]), check_pressures),
    "MuCa ASCII stream": (_ascii_strategy, check_ascii_stream),
    "MuCa binary stream": (_binary_strategy, check_binary_stream),
    "MuCa log file": (_ascii_strategy, check_log),
    "npz recording": (_npz_strategy, check_npz),
    "mesh soup (OBJ)": (_mesh_strategy, check_mesh),
    "G-code replies": (_reply_strategy, check_reply),
}
