"""Named tolerances of the mechanics, each with its reason."""

SLIVER_QUALITY = 1e-3
"""Tets whose normalized volume quality 6*sqrt(2)*V/l_rms^3 (1 for a regular tet) is
below this are slivers: their stiffness is ill-conditioned, so they are refused."""

MIN_DET_F = 0.05
"""A Newton step that squeezes a tet below this volume ratio J = det F is rejected
(line search, then load subdivision): linear tets past it are as good as inverted."""

FORCE_FLOOR = 1e-6
"""Reference force scale floor (relative to E * L^2 in mN) so that an unloaded
state converges on round-off instead of an impossible relative criterion."""

LINE_SEARCH_STEPS = 8
"""Backtracking halvings tried before a Newton step is declared a failure."""

PCG_MAX_ITERATIONS = 40
"""Preconditioned CG iterations per Newton step before the cached factorization of
the tangent is considered stale and refreshed."""

PCG_RELATIVE_TOLERANCE = 1e-2
"""Inexact Newton: each linear solve only needs to reduce the residual this much."""

INSIDE_VOLUME_MM3 = 1e-6
"""A chamber poking out of the solid by less than this volume (relative to the
chamber's volume) is treated as round-off of the mesh boolean."""

BARY_INSIDE = -1e-9
"""A point whose smallest barycentric coordinate is above this lies in the tet."""

ARMIJO = 1e-4
"""Sufficient decrease of the total potential energy asked of a line-search step."""

REFRESH_RATIO = 0.3
"""Modified Newton refactorizes the tangent when one step reduces the residual by
less than this factor (a stale factorization converges too slowly)."""
