"""Touches out over OSC/UDP: TUIO 1.1 cursors and plain ``/fruit/...`` messages.

Units: the TUIO profiles are normalized (see `Normalizer`), velocities per second,
accelerations per second squared; the plain messages are in mm, grid units and counts.

Per frame (the baseline frames excepted) four OSC bundles leave, in this order:

1. ``/tuio/2Dcur``: ``source fruit@<host>``, ``alive s...``, one ``set s x y X Y m`` per
   touch, ``fseq f``: the touch's grid position (i, j) normalized to 0-1.
2. ``/tuio/3Dcur`` (or ``/tuio/25Dcur``): ``source``, ``alive``, one
   ``set s x y z X Y Z m`` per touch, ``fseq``: the 3D point on the (deformed) body.
3. ``/tuio/_sp`` (a TUIO 1.1 custom profile): ``source``, ``alive``, one ``set s p`` per
   touch with p the touch's peak activation (counts), ``fseq``.
4. plain messages: ``/fruit/frame f n t_s``, then ``/fruit/down id x y z i j peak`` for
   each touch that starts, ``/fruit/touch id x y z i j peak`` for every touch,
   ``/fruit/up id`` for each that ended (x y z mm, i j grid, peak counts).

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
from fruitcli.sensing import osc

PROFILES_3D = ("3Dcur", "25Dcur")


def parse_host_port(text: str, option: str, default_host: str | None = None
                    ) -> tuple[str, int]:
    """``HOST:PORT`` (or ``PORT`` when `default_host` is given) -> (host, port)."""
    host, sep, port = text.rpartition(":")
    if not sep:
        host, port = default_host, text
    host = (host or "").strip("[]")  # [::1]:9000
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
        raise FrameError(f"{option} {host}:{port}: host {host!r} does not resolve ({why})"
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
        return cls(float(i.min()), float(max(i.max() - i.min(), 1)), float(j.min()),
                   float(max(j.max() - j.min(), 1)), lo, float(max((hi - lo).max(), 1e-9)))

    def grid(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """(n, 2) normalized grid positions."""
        return np.stack([(i - self.i_min) / self.i_span,
                         1.0 - (j - self.j_min) / self.j_span], axis=1)

    def space(self, xyz_mm: np.ndarray) -> np.ndarray:
        """(n, 3) normalized 3D positions."""
        return (xyz_mm - self.origin_mm) / self.scale_mm


class Kinematics:
    """Velocity and motion acceleration per session from successive positions, for the
    2D and the 3D profile at once (plain Python: a frame has at most 10 touches, too
    few for numpy to pay)."""

    def __init__(self):
        self.last: dict[int, tuple[float, list[float], list[float], float, float]] = {}

    def update(self, ids: list[int], pos: list[list[float]], t_s: float
               ) -> list[tuple[list[float], float, float]]:
        """Positions (x2, y2, x3, y3, z3) of sessions `ids` -> [(velocity (5 values), m2,
        m3)]: v = (p - p_prev) / dt, m = (|v| - |v_prev|) / dt over the 2D and the 3D
        part; 0 for a new session (and v kept, m 0, when dt <= 0)."""
        out, now = [], {}
        hypot = math.hypot
        for s, p in zip(ids, pos, strict=True):
            prev = self.last.get(s)
            if prev is None:
                v, m2, m3 = [0.0] * 5, 0.0, 0.0
                s2 = s3 = 0.0
            else:
                t0, p0, v0, s20, s30 = prev
                dt = t_s - t0
                if dt > 0:
                    v = [(a - b) / dt for a, b in zip(p, p0, strict=True)]
                    s2, s3 = hypot(v[0], v[1]), hypot(v[2], v[3], v[4])
                    m2, m3 = (s2 - s20) / dt, (s3 - s30) / dt
                else:
                    v, m2, m3, s2, s3 = v0, 0.0, 0.0, s20, s30
            now[s] = (t_s, p, v, s2, s3)
            out.append((v, m2, m3))
        self.last = now
        return out


class TuioSender:
    """Send each frame's touches to one OSC/UDP address (see the module docstring)."""

    def __init__(self, address: tuple, norm: Normalizer, profile_3d: str = "3Dcur",
                 source: str | None = None):
        if profile_3d not in PROFILES_3D:
            raise FrameError(f"TUIO 3D profile: expected one of {', '.join(PROFILES_3D)}, "
                             f"got {profile_3d!r}")
        self.address = address
        self.sock = socket.socket(socket.AF_INET6 if len(address) == 4 else socket.AF_INET,
                                  socket.SOCK_DGRAM)
        self.sock.setblocking(False)
        self.norm = norm
        self.profiles = ("/tuio/2Dcur", f"/tuio/{profile_3d}", "/tuio/_sp")
        self.source = source or f"fruit@{socket.gethostname()}"
        self.kin = Kinematics()
        self._templates()
        self.fseq = 0
        self.sent = 0  # datagrams sent
        self.failed = 0  # datagrams the OS refused (counted, never fatal)

    def _templates(self) -> None:
        p2, p3, pp = self.profiles
        self._source = {p: osc.Template(p, ("source", self.source)).element()
                        for p in self.profiles}
        self._set = {p2: osc.Template(p2, ("set",), "ifffff"),
                     p3: osc.Template(p3, ("set",), "ifffffff"),
                     pp: osc.Template(pp, ("set",), "if")}
        self._fseq = {p: osc.Template(p, ("fseq",), "i") for p in self.profiles}
        self._alive: dict[tuple[str, int], osc.Template] = {}
        self._frame = osc.Template("/fruit/frame", (), "iif")
        self._down = osc.Template("/fruit/down", (), "iffffff")
        self._touch = osc.Template("/fruit/touch", (), "iffffff")
        self._up = osc.Template("/fruit/up", (), "i")

    def _profile(self, profile: str, ids: list[int], rows: list[list]) -> bytes:
        alive = self._alive.get((profile, len(ids)))
        if alive is None:
            alive = self._alive[(profile, len(ids))] = osc.Template(profile, ("alive",),
                                                                     "i" * len(ids))
        st = self._set[profile]
        msgs = [self._source[profile], alive.element(*ids)]
        msgs += [st.element(s, *row) for s, row in zip(ids, rows, strict=True)]
        msgs.append(self._fseq[profile].element(self.fseq))
        return osc.bundle(msgs)

    def bundles(self, t_s: float, ids: np.ndarray, new: np.ndarray, ended: list[int],
                ij: np.ndarray, xyz_mm: np.ndarray, peak: np.ndarray) -> list[bytes]:
        """The frame's four datagrams (and advance fseq). `ij` (n, 2) grid position,
        `xyz_mm` (n, 3), `peak` (n,) counts, `ids` (n,) sessions, `new` (n,) bool."""
        self.fseq += 1
        sid = [int(s) for s in ids]
        ijl, xyzl, peaks = ij.tolist(), xyz_mm.tolist(), np.asarray(peak, float).tolist()
        nm = self.norm
        g2 = [[(i - nm.i_min) / nm.i_span, 1.0 - (j - nm.j_min) / nm.j_span] for i, j in ijl]
        o, sc = nm.origin_mm.tolist(), nm.scale_mm
        g3 = [[(p[0] - o[0]) / sc, (p[1] - o[1]) / sc, (p[2] - o[2]) / sc] for p in xyzl]
        kin = self.kin.update(sid, [a + b for a, b in zip(g2, g3, strict=True)], t_s)
        rows = [(s, *p, *q, pk) for s, p, q, pk in zip(sid, xyzl, ijl, peaks, strict=True)]
        plain = [self._frame.element(self.fseq, len(sid), float(t_s))]
        plain += [self._down.element(*r) for r, is_new in zip(rows, new.tolist(), strict=True)
                  if is_new]
        plain += [self._touch.element(*r) for r in rows]
        plain += [self._up.element(int(s)) for s in ended]
        p2, p3, pp = self.profiles
        return [self._profile(p2, sid, [(*g, *v[:2], m2) for g, (v, m2, _) in
                                        zip(g2, kin, strict=True)]),
                self._profile(p3, sid, [(*g, *v[2:], m3) for g, (v, _, m3) in
                                        zip(g3, kin, strict=True)]),
                self._profile(pp, sid, [(pk,) for pk in peaks]),
                osc.bundle(plain)]

    def send(self, t_s: float, ids: np.ndarray, new: np.ndarray, ended: list[int],
             ij: np.ndarray, xyz_mm: np.ndarray, peak: np.ndarray) -> None:
        """Send the frame's bundles; an OS error (no route, full buffer) is counted."""
        for dgram in self.bundles(t_s, ids, new, ended, ij, xyz_mm, peak):
            try:
                self.sock.sendto(dgram, self.address)
                self.sent += 1
            except OSError:
                self.failed += 1

    def close(self) -> None:
        self.sock.close()
