"""Touches out over OSC/UDP: TUIO 1.1 cursors and plain ``/fruit/...`` messages.

Units: the TUIO profiles are normalized (see `Normalizer`), velocities per second,
accelerations per second squared; the plain messages are in mm, grid units and counts.

Per frame (the baseline frames excepted) four OSC bundles leave, in this order:

1. ``/tuio/2Dcur``: ``source fruit@<host>``, ``alive s...``, one ``set s x y X Y m`` per
   touch, ``fseq f``: the touch's grid position (i, j) normalized to 0-1.
2. ``/tuio/3Dcur``: ``source``, ``alive``, one ``set s x y z X Y Z m`` per touch,
   ``fseq``: the 3D point on the (deformed) body; or ``/tuio/25Dcur``: the same
   messages with x, y the 2D cursor's and z the height above the surface (mm / L, the
   3D scale), 0 at contact.
3. ``/tuio/_sp`` (a TUIO 1.1 custom profile): ``source``, ``alive``, one ``set s p`` per
   touch with p the touch's peak activation (counts), ``fseq``.
4. plain messages: ``/fruit/frame f n t_s``, then ``/fruit/down id x y z i j peak h s w
   kind`` for each touch that starts, ``/fruit/touch id x y z i j peak h s w kind`` for
   every touch, ``/fruit/up id`` for each that ended (x y z mm, i j grid, peak counts,
   h height above the surface mm, s strength (1: contact), w footprint size mm, kind 0
   touch or 1 hover).

Hovers are sent as touches are (a session that starts hovering keeps its id when it
comes down); the plain messages' kind tells them apart.

s and id are session ids (a finger keeps its id; ids are never reused), f counts the
frames sent (fseq). X, Y (Z) are velocities (normalized units per s) from the previous
frame's position of the same session, m the motion acceleration (change of speed per s,
as the TUIO reference implementation defines it); both are 0 on a session's first frame.
Ints are int32, values float32 (so t_s, the host time of the run in s, has a resolution of
1 ms up to 2.3 h and 8 ms after a day); only the standard types i, f, s are used.
"""

from __future__ import annotations

import math
import socket
from dataclasses import dataclass

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.sensing.outputs import osc

PROFILES_3D = ("3Dcur", "25Dcur")


def parse_host_port(text: str, option: str, default_host: str | None = None) -> tuple[str, int]:
    """``HOST:PORT`` (or ``PORT`` when `default_host` is given) -> (host, port)."""
    given, sep, port = text.rpartition(":")
    if not sep:
        given, port = default_host or "", text
    host = given.strip("[]")  # [::1]:9000
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        form = "[HOST:]PORT" if default_host else "HOST:PORT"
        raise FrameError(f"{option} {text}: expected {form} with a port in 1-65535")
    return host, int(port)


def resolve(host: str, port: int, option: str) -> tuple:
    """The UDP socket address of host:port; FrameError when the name does not resolve."""
    try:
        info = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)
    except (socket.gaierror, UnicodeError) as exc:
        why = getattr(exc, "strerror", None) or str(exc)
        raise FrameError(
            f"{option} {host}:{port}: host {host!r} does not resolve ({why})"
        ) from None
    return info[0][4]


@dataclass(frozen=True)
class Normalizer:
    """TUIO scaling, from the taxels at rest.

    2D: x = (i - i_min) / (i_max - i_min), y = 1 - (j - j_min) / (j_max - j_min): the grid
    seen from above (+z towards the viewer) with TUIO's origin at the top left.
    3D: (x, y, z) = (p - p_min) / L with p_min the corner of the rest taxels' bounding box
    and L its largest side (mm), so one scale for all axes: multiply by L to get mm.
    Deformed points can leave 0-1 by the deformation.
    """

    i_min: float
    i_span: float
    j_min: float
    j_span: float
    origin_mm: np.ndarray  # (3,)
    scale_mm: float

    @classmethod
    def from_taxels(cls, i: np.ndarray, j: np.ndarray, xyz_mm: np.ndarray) -> Normalizer:
        lo, hi = xyz_mm.min(axis=0), xyz_mm.max(axis=0)
        return cls(
            float(i.min()),
            float(max(i.max() - i.min(), 1)),
            float(j.min()),
            float(max(j.max() - j.min(), 1)),
            lo,
            float(max((hi - lo).max(), 1e-9)),
        )

    def grid(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """(n, 2) normalized grid positions."""
        return np.stack(
            [(i - self.i_min) / self.i_span, 1.0 - (j - self.j_min) / self.j_span], axis=1
        )

    def space(self, xyz_mm: np.ndarray) -> np.ndarray:
        """(n, 3) normalized 3D positions."""
        return (xyz_mm - self.origin_mm) / self.scale_mm


class Kinematics:
    """Velocity and motion acceleration per session from successive positions, for the
    2D and the 3D profile at once: positions and velocities compiled
    (`tuio_kernel.motion`), the speeds by `math.hypot` per touch (CPython's, as before:
    the kernel's libm hypot may round otherwise)."""

    def __init__(self):
        from fruitcli.sensing.outputs.tuio_kernel import motion

        self._motion = motion
        self.t_s: float | None = None  # time of the previous update (s)
        self.ids = np.zeros(0, np.int64)  # the previous update's sessions
        self.g, self.vel = np.zeros((0, 5)), np.zeros((0, 5))
        self.speed: list[tuple[float, float]] = []  # |v| of the 2D and of the 3D part

    def update(
        self,
        ids: np.ndarray,
        ij: np.ndarray,
        xyz_mm: np.ndarray,
        norm: np.ndarray,
        t_s: float,
        height_mm: np.ndarray | None = None,
        plane: bool = False,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sessions `ids` (n,) at grid positions ij (n, 2) and points xyz_mm (n, 3) ->
        (positions g (n, 5) = (x2, y2, x3, y3, z3) normalized by `norm` (see `motion`),
        velocity (n, 5), acceleration (n, 2) = (m2, m3)): v = (p - p_prev) / dt,
        m = (|v| - |v_prev|) / dt over the 2D and the 3D part; 0 for a new session (and
        v kept, m 0, when dt <= 0)."""
        n = ids.shape[0]
        dt = 0.0 if self.t_s is None else t_s - self.t_s
        g, vel, rows = np.empty((n, 5)), np.empty((n, 5)), np.empty(n, np.int64)
        h = np.zeros(n) if height_mm is None else np.ascontiguousarray(height_mm, dtype=float)
        self._motion(ids, ij, xyz_mm, norm, self.ids, self.g, self.vel, dt, g, vel, rows, h, plane)
        hypot, prev = math.hypot, self.speed
        speed, acc = [], []
        for r, (a, b, c, d, e) in zip(rows.tolist(), vel.tolist(), strict=True):
            if r < 0:
                speed.append((0.0, 0.0))
                acc.append((0.0, 0.0))
            elif dt > 0:
                s2, s3 = hypot(a, b), hypot(c, d, e)
                speed.append((s2, s3))
                acc.append(((s2 - prev[r][0]) / dt, (s3 - prev[r][1]) / dt))
            else:
                speed.append(prev[r])
                acc.append((0.0, 0.0))
        self.t_s, self.ids, self.g, self.vel, self.speed = t_s, ids, g, vel, speed
        return g, vel, np.array(acc, dtype=float).reshape(n, 2)


class TuioSender:
    """Send each frame's touches to one OSC/UDP address (see the module docstring)."""

    def __init__(
        self, address: tuple, norm: Normalizer, profile_3d: str = "3Dcur", source: str | None = None
    ):
        if profile_3d not in PROFILES_3D:
            raise FrameError(
                f"TUIO 3D profile: expected one of {', '.join(PROFILES_3D)}, got {profile_3d!r}"
            )
        self.address = address
        self.sock = socket.socket(
            socket.AF_INET6 if len(address) == 4 else socket.AF_INET, socket.SOCK_DGRAM
        )
        self.sock.setblocking(False)
        self.norm = norm
        self.profiles = ("/tuio/2Dcur", f"/tuio/{profile_3d}", "/tuio/_sp")
        self.source = source or f"fruit@{socket.gethostname()}"
        self.kin = Kinematics()
        self.fseq = 0
        self._norm = np.array(
            [
                norm.i_min,
                norm.i_span,
                norm.j_min,
                norm.j_span,
                *np.asarray(norm.origin_mm, dtype=float),
                norm.scale_mm,
            ]
        )
        self._templates()
        self.bundles(
            0.0,
            np.zeros(0, np.int64),
            np.zeros(0, bool),
            [],
            np.zeros((0, 2)),
            np.zeros((0, 3)),
            np.zeros(0),
        )  # the kernels loaded now, not on a frame
        self.kin = Kinematics()
        self.fseq = 0
        self.sent = 0  # datagrams sent
        self.failed = 0  # datagrams the OS refused (counted, never fatal)

    def _templates(self) -> None:
        p2, p3, pp = self.profiles
        self._source = {
            p: osc.Template(p, ("source", self.source)).element() for p in self.profiles
        }
        self._set = {
            p2: osc.Template(p2, ("set",), "ifffff"),
            p3: osc.Template(p3, ("set",), "ifffffff"),
            pp: osc.Template(pp, ("set",), "if"),
        }
        self._fseq = {p: osc.Template(p, ("fseq",), "i") for p in self.profiles}
        self._frame = osc.Template("/fruit/frame", (), "iif")
        self._down = osc.Template("/fruit/down", (), "i" + "f" * 9 + "i")
        self._touch = osc.Template("/fruit/touch", (), "i" + "f" * 9 + "i")
        self._up = osc.Template("/fruit/up", (), "i")
        self._consts: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        from fruitcli.sensing.outputs.tuio_kernel import pack_frame

        self._pack = pack_frame
        self._out = np.empty(1 << 16, np.uint8)
        self._ends = np.empty(4, np.int64)

    def _pieces(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """The constant bytes of a frame of n touches and their (start, length) rows, in
        `tuio_kernel`'s order (made once per n)."""
        got = self._consts.get(n)
        if got is None:
            pieces = [
                osc.BUNDLE_HEAD + self._source[p] + osc.Template(p, ("alive",), "i" * n).head
                for p in self.profiles
            ]
            pieces += [self._set[p].head for p in self.profiles]
            pieces += [self._fseq[p].head for p in self.profiles]
            pieces += [
                osc.BUNDLE_HEAD + self._frame.head,
                self._down.head,
                self._touch.head,
                self._up.head,
            ]
            length = np.array([len(x) for x in pieces], np.int64)
            seg = np.column_stack([np.cumsum(length) - length, length])
            got = self._consts[n] = (np.frombuffer(b"".join(pieces), np.uint8), seg)
        return got

    def bundles(
        self,
        t_s: float,
        ids: np.ndarray,
        new: np.ndarray,
        ended: list[int],
        ij: np.ndarray,
        xyz_mm: np.ndarray,
        peak: np.ndarray,
        shape: np.ndarray | None = None,
        kind: np.ndarray | None = None,
    ) -> list[bytes]:
        """The frame's four datagrams (and advance fseq). `ij` (n, 2) grid position,
        `xyz_mm` (n, 3), `peak` (n,) counts, `ids` (n,) sessions, `new` (n,) bool,
        `shape` (n, 3) height mm, strength, size mm (None: NaN), `kind` (n,) 0 touch,
        1 hover (None: touches).
        Positions and kinematics in float64 (`Kinematics`), the datagrams packed by the
        compiled `tuio_kernel.pack_frame`: the bytes of the per-touch Python encoder this
        replaced (tests/test_sensing_live_kernel.py)."""
        self.fseq += 1
        sid = np.array(ids, dtype=np.int64)
        n = sid.shape[0]
        ij = np.ascontiguousarray(ij, dtype=float).reshape(n, 2)
        xyz = np.ascontiguousarray(xyz_mm, dtype=float).reshape(n, 3)
        shape = (
            np.full((n, 3), np.nan)
            if shape is None
            else np.ascontiguousarray(shape, dtype=float).reshape(n, 3)
        )
        kind = np.zeros(n, np.int64) if kind is None else np.asarray(kind, np.int64)
        g, vel, acc = self.kin.update(
            sid, ij, xyz, self._norm, t_s, shape[:, 0], self.profiles[1] == "/tuio/25Dcur"
        )
        consts, seg = self._pieces(n)
        need = (consts.size + 200) * (n + 2) + 8 * len(ended)
        if self._out.size < need:
            self._out = np.empty(need, np.uint8)
        self._pack(
            self._out,
            consts,
            seg,
            sid,
            np.asarray(new, dtype=bool).reshape(n),
            np.asarray(ended, np.int64),
            g,
            vel,
            acc,
            xyz,
            ij,
            np.asarray(peak, dtype=float).reshape(n),
            shape,
            kind,
            self.fseq,
            float(t_s),
            self._ends,
        )
        data = self._out[: self._ends[3]].tobytes()
        e = self._ends.tolist()
        return [data[: e[0]], data[e[0] : e[1]], data[e[1] : e[2]], data[e[2] : e[3]]]

    def send(
        self,
        t_s: float,
        ids: np.ndarray,
        new: np.ndarray,
        ended: list[int],
        ij: np.ndarray,
        xyz_mm: np.ndarray,
        peak: np.ndarray,
        shape: np.ndarray | None = None,
        kind: np.ndarray | None = None,
    ) -> None:
        """Send the frame's bundles; an OS error (no route, full buffer) is counted."""
        for dgram in self.bundles(t_s, ids, new, ended, ij, xyz_mm, peak, shape, kind):
            try:
                self.sock.sendto(dgram, self.address)
                self.sent += 1
            except OSError:
                self.failed += 1

    def close(self) -> None:
        self.sock.close()
