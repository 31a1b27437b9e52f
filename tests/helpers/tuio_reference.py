"""The TUIO/OSC encoder before it was vectorized (compared with the new one byte for byte
by tests/sensing/detection/test_stream_kernel.py)."""

import math
import socket

import numpy as np

from fruitcli.errors import FrameError
from fruitcli.sensing.outputs import osc
from fruitcli.sensing.outputs.tuio import PROFILES_3D, Normalizer


class Kinematics:
    """Velocity and motion acceleration per session from successive positions, for the
    2D and the 3D profile at once (plain Python: a frame has at most 10 touches, too
    few for numpy to pay)."""

    def __init__(self):
        self.last: dict[int, tuple[float, list[float], list[float], float, float]] = {}

    def update(
        self, ids: list[int], pos: list[list[float]], t_s: float
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


class ReferenceTuioSender:
    """`fruitcli.sensing.outputs.tuio.TuioSender` in its plain-Python form (per touch): its
    datagrams, without a socket."""

    def __init__(
        self, address: tuple, norm: Normalizer, profile_3d: str = "3Dcur", source: str | None = None
    ):
        if profile_3d not in PROFILES_3D:
            raise FrameError(
                f"TUIO 3D profile: expected one of {', '.join(PROFILES_3D)}, got {profile_3d!r}"
            )
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
        self._source = {
            p: osc.Template(p, ("source", self.source)).element() for p in self.profiles
        }
        self._set = {
            p2: osc.Template(p2, ("set",), "ifffff"),
            p3: osc.Template(p3, ("set",), "ifffffff"),
            pp: osc.Template(pp, ("set",), "if"),
        }
        self._fseq = {p: osc.Template(p, ("fseq",), "i") for p in self.profiles}
        self._alive: dict[tuple[str, int], osc.Template] = {}
        self._frame = osc.Template("/fruit/frame", (), "iif")
        self._down = osc.Template("/fruit/down", (), "i" + "f" * 9 + "i")
        self._touch = osc.Template("/fruit/touch", (), "i" + "f" * 9 + "i")
        self._up = osc.Template("/fruit/up", (), "i")

    def _profile(self, profile: str, ids: list[int], rows: list[list]) -> bytes:
        alive = self._alive.get((profile, len(ids)))
        if alive is None:
            alive = self._alive[(profile, len(ids))] = osc.Template(
                profile, ("alive",), "i" * len(ids)
            )
        st = self._set[profile]
        msgs = [self._source[profile], alive.element(*ids)]
        msgs += [st.element(s, *row) for s, row in zip(ids, rows, strict=True)]
        msgs.append(self._fseq[profile].element(self.fseq))
        return osc.bundle(msgs)

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
        `xyz_mm` (n, 3), `peak` (n,) counts, `ids` (n,) sessions, `new` (n,) bool."""
        self.fseq += 1
        sid = [int(s) for s in ids]
        ijl, xyzl, peaks = ij.tolist(), xyz_mm.tolist(), np.asarray(peak, float).tolist()
        nm = self.norm
        g2 = [[(i - nm.i_min) / nm.i_span, 1.0 - (j - nm.j_min) / nm.j_span] for i, j in ijl]
        o, sc = nm.origin_mm.tolist(), nm.scale_mm
        n = len(sid)
        shape = np.full((n, 3), np.nan) if shape is None else np.asarray(shape, float)
        kinds = [0] * n if kind is None else [int(k) for k in kind]
        if self.profiles[1] == "/tuio/25Dcur":  # the 2D cursor, z the height
            g3 = [[a, b, h / sc] for (a, b), h in zip(g2, shape[:, 0].tolist(), strict=True)]
        else:
            g3 = [[(p[0] - o[0]) / sc, (p[1] - o[1]) / sc, (p[2] - o[2]) / sc] for p in xyzl]
        kin = self.kin.update(sid, [a + b for a, b in zip(g2, g3, strict=True)], t_s)
        rows = [
            (s, *p, *q, pk, *sh, k)
            for s, p, q, pk, sh, k in zip(sid, xyzl, ijl, peaks, shape.tolist(), kinds, strict=True)
        ]
        plain = [self._frame.element(self.fseq, len(sid), float(t_s))]
        plain += [
            self._down.element(*r) for r, is_new in zip(rows, new.tolist(), strict=True) if is_new
        ]
        plain += [self._touch.element(*r) for r in rows]
        plain += [self._up.element(int(s)) for s in ended]
        p2, p3, pp = self.profiles
        return [
            self._profile(
                p2, sid, [(*g, *v[:2], m2) for g, (v, m2, _) in zip(g2, kin, strict=True)]
            ),
            self._profile(
                p3, sid, [(*g, *v[2:], m3) for g, (v, _, m3) in zip(g3, kin, strict=True)]
            ),
            self._profile(pp, sid, [(pk,) for pk in peaks]),
            osc.bundle(plain),
        ]
