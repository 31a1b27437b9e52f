"""Compiled fast path (numba) of the session matching (`sessions.SessionTracker`).

Units: mm. The matching is the optimal assignment of the previous frame's touch points to
this frame's (``linear_sum_assignment`` on their distances). When every previous point
(every current one, if there are fewer) has its nearest partner closer than all others by
a clear margin, and those partners are distinct, that assignment is the only optimal one
(any other gives some point a farther partner and none a nearer one), so it is taken
without the solver. Otherwise (near ties, points competing for one partner) the caller
runs the solver.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

MARGIN = 1e-9  # relative: nearest vs second nearest, far above the solver's rounding


@njit(cache=True, nogil=True)
def nearest_match(prev_xyz, xyz, prev_ids, gate, next_id, cost, ids, new) -> int:
    """Distances cost (m, n) = |prev_xyz[a] - xyz[b]| (as numpy sums them: dx^2 + dy^2,
    then + dz^2). When the nearest-partner rule above decides the assignment: ids (n,)
    = the previous id of each current point matched within `gate` (mm), else a new id
    from next_id on, new (n,) = which are new; -> how many are new. -1 when it does
    not decide (ids, new untouched)."""
    m, n = prev_xyz.shape[0], xyz.shape[0]
    for a in range(m):
        for b in range(n):
            dx = prev_xyz[a, 0] - xyz[b, 0]
            dy = prev_xyz[a, 1] - xyz[b, 1]
            dz = prev_xyz[a, 2] - xyz[b, 2]
            cost[a, b] = math.sqrt((dx * dx + dy * dy) + dz * dz)
    rows = m <= n  # the smaller side is fully assigned
    count = m if rows else n
    other = n if rows else m
    partner = np.full(count, -1, np.int64)
    taken = np.zeros(other, np.bool_)
    for x in range(count):
        best = np.inf
        second = np.inf
        at = -1
        for y in range(other):
            c = cost[x, y] if rows else cost[y, x]
            if c < best:
                second = best
                best = c
                at = y
            elif c < second:
                second = c
        if other > 1 and not second - best > MARGIN * (second + 1.0):
            return -1
        if at < 0 or taken[at]:  # NaN points, or two nearest to one partner
            return -1
        taken[at] = True
        partner[x] = at
    for b in range(n):
        ids[b] = -1
    for x in range(count):
        a, b = (x, partner[x]) if rows else (partner[x], x)
        if cost[a, b] <= gate:
            ids[b] = prev_ids[a]
    k = 0
    for b in range(n):
        new[b] = ids[b] < 0
        if new[b]:
            ids[b] = next_id + k
            k += 1
    return k
