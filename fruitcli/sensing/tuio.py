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
4. plain messages: ``/fruit/frame f t_s n``, then ``/fruit/down id x y z i j peak`` for
   each touch that starts, ``/fruit/touch id x y z i j peak`` for every touch,
   ``/fruit/up id`` for each that ended (x y z mm, i j grid, peak counts).

s and id are session ids (a finger keeps its id; ids are never reused), f counts the
frames sent (fseq). X, Y (Z) are velocities (normalized units per s) from the previous
frame's position of the same session, m the motion acceleration (change of speed per s,
as the TUIO reference implementation defines it); both are 0 on a session's first frame.
Ints are int32, values float32, t_s (host time, s) float64.
"""

from __future__ import annotations

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
    """Velocity and motion acceleration per session from successive positions."""

    def __init__(self, dim: int):
        self.ids: dict[int, int] = {}  # session -> row of the arrays below
        self.t = np.zeros(0)
        self.pos = np.zeros((0, dim))
        self.vel = np.zeros((0, dim))
        self.speed = np.zeros(0)

    def update(self, ids: list[int], pos: np.ndarray, t_s: float
               ) -> tuple[np.ndarray, np.ndarray]:
        """(velocity (n, d), acceleration (n,)) for positions (n, d) of sessions `ids`:
        v = (p - p_prev) / dt, m = (|v| - |v_prev|) / dt; 0 for a new session (and v
        kept, m 0, when dt <= 0)."""
        row = np.array([self.ids.get(s, -1) for s in ids], np.int64)
        old = row >= 0
        vel = np.zeros_like(pos)
        acc = np.zeros(len(ids))
        if old.any():
            r = row[old]
            dt = t_s - self.t[r]
            ok = dt > 0
            dtc = np.where(ok, dt, 1.0)
            v = np.where(ok[:, None], (pos[old] - self.pos[r]) / dtc[:, None], self.vel[r])
            vel[old] = v
            acc[old] = np.where(ok, (np.linalg.norm(v, axis=1) - self.speed[r]) / dtc, 0.0)
        self.ids = {s: k for k, s in enumerate(ids)}
        self.t = np.full(len(ids), t_s)
        self.pos, self.vel = pos.copy(), vel
        self.speed = np.linalg.norm(vel, axis=1)
        return vel, acc


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
        self.k2, self.k3 = Kinematics(2), Kinematics(3)
        self._templates()
        self.fseq = 0
        self.sent = 0  # datagrams sent
        self.failed = 0  # datagrams the OS refused (counted, never fatal)

    def _templates(self) -> None:
        p2, p3, pp = self.profiles
        self._source = {p: osc.Template(p, ("source", self.source)).pack() for p in self.profiles}
        self._set = {p2: osc.Template(p2, ("set",), "ifffff"),
                     p3: osc.Template(p3, ("set",), "ifffffff"),
                     pp: osc.Template(pp, ("set",), "if")}
        self._fseq = {p: osc.Template(p, ("fseq",), "i") for p in self.profiles}
        self._alive: dict[tuple[str, int], osc.Template] = {}
        self._frame = osc.Template("/fruit/frame", (), "idi")
        self._down = osc.Template("/fruit/down", (), "iffffff")
        self._touch = osc.Template("/fruit/touch", (), "iffffff")
        self._up = osc.Template("/fruit/up", (), "i")

    def _profile(self, profile: str, ids: list[int], rows: list[list]) -> bytes:
        alive = self._alive.get((profile, len(ids)))
        if alive is None:
            alive = self._alive[(profile, len(ids))] = osc.Template(profile, ("alive",),
                                                                     "i" * len(ids))
        st = self._set[profile]
        msgs = [self._source[profile], alive.pack(*ids)]
        msgs += [st.pack(s, *row) for s, row in zip(ids, rows, strict=True)]
        msgs.append(self._fseq[profile].pack(self.fseq))
        return osc.bundle(msgs)

    def bundles(self, t_s: float, ids: np.ndarray, new: np.ndarray, ended: list[int],
                ij: np.ndarray, xyz_mm: np.ndarray, peak: np.ndarray) -> list[bytes]:
        """The frame's four datagrams (and advance fseq). `ij` (n, 2) grid position,
        `xyz_mm` (n, 3), `peak` (n,) counts, `ids` (n,) sessions, `new` (n,) bool."""
        self.fseq += 1
        sid = [int(s) for s in ids]
        g2 = self.norm.grid(ij[:, 0], ij[:, 1])
        g3 = self.norm.space(xyz_mm)
        v2, m2 = self.k2.update(sid, g2, t_s)
        v3, m3 = self.k3.update(sid, g3, t_s)
        plain = [self._frame.pack(self.fseq, float(t_s), len(sid))]
        rows = np.column_stack([xyz_mm, ij, peak]).tolist()
        plain += [self._down.pack(sid[k], *rows[k]) for k in np.flatnonzero(new).tolist()]
        plain += [self._touch.pack(s, *r) for s, r in zip(sid, rows, strict=True)]
        plain += [self._up.pack(int(s)) for s in ended]
        p2, p3, pp = self.profiles
        return [self._profile(p2, sid, np.column_stack([g2, v2, m2]).tolist()),
                self._profile(p3, sid, np.column_stack([g3, v3, m3]).tolist()),
                self._profile(pp, sid, np.asarray(peak, float)[:, None].tolist()),
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
