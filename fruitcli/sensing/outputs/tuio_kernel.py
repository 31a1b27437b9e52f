"""Compiled packing (numba) of a frame's four TUIO/OSC datagrams (`tuio.TuioSender`).

Units: those of `tuio` (normalized positions, per second, counts, mm). The constant
bytes (bundle heads, addresses, type tags, leading strings, each message's size) are
encoded once in Python (`osc.Template`) and copied here; the numbers are written
big-endian, ints as int32 and values as float32 (float64 rounded to nearest, as
``struct.pack("f")`` does), so the bytes are those of packing every message with
`osc.Template.element` (tests/test_sensing_live_kernel.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

# pieces of `consts`, as (start, length) rows of `seg`
(
    LEAD_2D,
    LEAD_3D,
    LEAD_SP,
    SET_2D,
    SET_3D,
    SET_SP,
    FSEQ_2D,
    FSEQ_3D,
    FSEQ_SP,
    LEAD_PLAIN,
    DOWN,
    TOUCH,
    UP,
) = range(13)


@njit(cache=True, nogil=True)
def _copy(out, at, consts, seg, piece):
    a = seg[piece, 0]
    n = seg[piece, 1]
    out[at : at + n] = consts[a : a + n]
    return at + n


@njit(cache=True, nogil=True)
def _int(out, at, x):
    u = np.int64(x) & 0xFFFFFFFF
    out[at] = (u >> 24) & 255
    out[at + 1] = (u >> 16) & 255
    out[at + 2] = (u >> 8) & 255
    out[at + 3] = u & 255
    return at + 4


@njit(cache=True, nogil=True)
def _float(out, at, x, f32, u32):
    f32[0] = x  # float64 -> float32, round to nearest
    return _int(out, at, u32[0])


@njit(cache=True, nogil=True)
def pack_frame(
    out, consts, seg, ids, new, ended, g, vel, acc, xyz, ij, peak, shape, kind, fseq, t_s, ends
) -> int:
    """Write the 2D, 3D, peak and plain datagrams one after the other into `out` (uint8);
    ends[0..3] = the offset after each. ids (n,), new (n,) bool, ended (m,), g (n, 5)
    positions (x2, y2, x3, y3, z3), vel (n, 5), acc (n, 2) (m2, m3), xyz (n, 3) mm,
    ij (n, 2), peak (n,), shape (n, 3) (height mm, strength, size mm), kind (n,)."""
    f32 = np.empty(1, np.float32)
    u32 = f32.view(np.uint32)
    n = ids.shape[0]
    at = 0
    for p in range(3):  # the TUIO profiles
        at = _copy(out, at, consts, seg, LEAD_2D + p)  # bundle head, source, alive head
        for k in range(n):
            at = _int(out, at, ids[k])
        for k in range(n):
            at = _copy(out, at, consts, seg, SET_2D + p)
            at = _int(out, at, ids[k])
            if p == 0:
                at = _float(out, at, g[k, 0], f32, u32)
                at = _float(out, at, g[k, 1], f32, u32)
                at = _float(out, at, vel[k, 0], f32, u32)
                at = _float(out, at, vel[k, 1], f32, u32)
                at = _float(out, at, acc[k, 0], f32, u32)
            elif p == 1:
                for q in range(2, 5):
                    at = _float(out, at, g[k, q], f32, u32)
                for q in range(2, 5):
                    at = _float(out, at, vel[k, q], f32, u32)
                at = _float(out, at, acc[k, 1], f32, u32)
            else:
                at = _float(out, at, peak[k], f32, u32)
        at = _copy(out, at, consts, seg, FSEQ_2D + p)
        at = _int(out, at, fseq)
        ends[p] = at
    at = _copy(out, at, consts, seg, LEAD_PLAIN)  # bundle head, /fruit/frame head
    at = _int(out, at, fseq)
    at = _int(out, at, n)
    at = _float(out, at, t_s, f32, u32)
    for piece in (DOWN, TOUCH):
        for k in range(n):
            if piece == TOUCH or new[k]:
                at = _copy(out, at, consts, seg, piece)
                at = _int(out, at, ids[k])
                for q in range(3):
                    at = _float(out, at, xyz[k, q], f32, u32)
                at = _float(out, at, ij[k, 0], f32, u32)
                at = _float(out, at, ij[k, 1], f32, u32)
                at = _float(out, at, peak[k], f32, u32)
                for q in range(3):
                    at = _float(out, at, shape[k, q], f32, u32)
                at = _int(out, at, kind[k])
    for k in range(ended.shape[0]):
        at = _copy(out, at, consts, seg, UP)
        at = _int(out, at, ended[k])
    ends[3] = at
    return at


@njit(cache=True, nogil=True)
def motion(ids, ij, xyz, norm, prev_ids, prev_g, prev_vel, dt, g, vel, rows, height, plane) -> None:
    """Normalized positions and velocities of a frame's sessions (float64, elementwise
    as the per-touch code computed them). norm = (i_min, i_span, j_min, j_span, ox, oy,
    oz, scale); g (n, 5) = (x2, y2, x3, y3, z3), or with `plane` (TUIO 2.5D) (x2, y2, x2,
    y2, height / scale) for heights (n,) mm; rows[k] = the row of session ids[k] in
    the previous frame's `prev_ids` (-1: new), vel[k] = (g - prev_g) / dt (dt > 0),
    prev_vel (dt <= 0) or 0 (new)."""
    for k in range(ids.shape[0]):
        g[k, 0] = (ij[k, 0] - norm[0]) / norm[1]
        g[k, 1] = 1.0 - (ij[k, 1] - norm[2]) / norm[3]
        if plane:
            g[k, 2] = g[k, 0]
            g[k, 3] = g[k, 1]
            g[k, 4] = height[k] / norm[7]
        else:
            for q in range(3):
                g[k, 2 + q] = (xyz[k, q] - norm[4 + q]) / norm[7]
        r = -1
        for m in range(prev_ids.shape[0]):
            if prev_ids[m] == ids[k]:
                r = m
                break
        rows[k] = r
        for q in range(5):
            if r < 0:
                vel[k, q] = 0.0
            elif dt > 0:
                vel[k, q] = (g[k, q] - prev_g[r, q]) / dt
            else:
                vel[k, q] = prev_vel[r, q]
