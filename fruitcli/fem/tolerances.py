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

STALL_CUT = 0.1
"""Newton has stalled (`SolverOptions.stall_steps`, the samples of a limit curve) when
its last `stall_steps` steps cut the relative residual by less than this fraction in
all. On the default Fruit's seven curves (`fruit limits`) no converging sample's four
steps in a row cut it by less than 25 %; the sample past chamber c3's collapse cut it
by 4-8 % every four steps, from 2.6e-2 on, until its time budget ran out."""

STALL_FAR = 10.0
"""A stall counts only with the residual above this many times the tolerance (closer
to it, round-off may keep the residual from falling: `_stalled`)."""

PCG_MAX_ITERATIONS = 40
"""Preconditioned CG iterations per linear solve before it gives up (the kept
factorization is then refreshed and the solve retried)."""

PCG_REFRESH_ITERATIONS = 12
"""A linear solve that needs more CG iterations than this says the kept factorization
is stale: it is refreshed at the current configuration."""

PCG_RELATIVE_TOLERANCE = 1e-2
"""Inexact Newton: a linear solve never needs to reduce the residual more than this
far from equilibrium; near it Newton asks for PCG_TARGET * tolerance / merit."""

PCG_TARGET = 0.3
"""Newton asks each linear solve for a residual of this fraction of the nonlinear
tolerance (relative to |b|: rtol = PCG_TARGET tolerance / merit, capped by
PCG_RELATIVE_TOLERANCE), so that one exact-enough step can finish the state."""

CHORD_CONTRACTION = 0.01
"""Newton keeps the tangent for its last step near the tolerance (a chord step, see
`linsolve.NEAR_TOLERANCE`) only when the step before cut the residual at least this
much (the quadratic regime, where the tangent barely moves), and never twice in a row.
The touchpad's jig turn, whose last steps contract by 0.01-0.3, took 106 Newton steps
and 20-23 s with chord steps allowed anywhere near the tolerance, 80 and 17 s without;
a first version that allowed them in a row stalled at 10 times the tolerance."""

ESTIMATE_WINDOW = 1e3
"""Newton estimates the correction left at an iterate (`[solver]
displacement_tolerance_mm`, one solve with the kept factor) only once the relative
residual is within this factor of the tolerance; farther away the correction is far
above any useful displacement tolerance (on the default Fruit's breathing a relative
residual of 1e-5 meant nodes within 3e-5 mm; on the touchpad's jig bend 0.09 mm)."""

ESTIMATE_SAFETY = 2.0
"""The kept factor's estimate of the correction left must be within the displacement
tolerance divided by this: the factor is that of an earlier tangent (and single
precision), and on the default Fruit's breathing its estimate fell short of the
remaining correction by up to 1.4x (nodes 7e-5 mm from the converged solution when
the estimate alone was asked to be within 5e-5 mm)."""

LINEAR_DISPLACEMENT_SHARE = 0.8
"""With a displacement tolerance (`[solver] displacement_tolerance_mm`), a Newton step's
linear solve also stops once the kept factor estimates the error CG leaves to move no
node by more than this share of what `_close_enough` accepts (the displacement
tolerance / ESTIMATE_SAFETY): the rest is left to the step's nonlinear error, and
solving further would not let Newton stop any sooner. Newton's own estimate still
decides whether the state has converged. On the default Fruit's breathing (first cycle,
12 states; `tests/performance/bench_state.py`, 2026-12-06) CG took 101 iterations with
0.8, 109 with 0.5 and 100 with 1.0, the same Newton steps each time; with CG not
stopped by this test, 124 iterations and one refactorization."""

LINEAR_MARGIN = 0.1
"""Inexact Newton: a linear solve aims at this fraction of the residual the Newton step
is expected to leave from the nonlinearity (C merit^2, C observed on earlier steps);
solving further would not lower the next residual."""

INSIDE_VOLUME_MM3 = 1e-6
"""A chamber poking out of the solid by less than this volume (relative to the
chamber's volume) is treated as round-off of the mesh boolean."""

ARMIJO = 1e-4
"""Sufficient decrease of the total potential energy asked of a line-search step."""

STEP_TOLERANCE = 1e-9
"""Round-off stall guard: a Newton correction that moves no node by more than this
fraction of the body size (mm/mm) changes nothing measurable ..."""

STALL_RESIDUAL_FACTOR = 100.0
"""... and is accepted as convergence when the relative residual is within this factor
of the tolerance (a residual that round-off keeps just above the tolerance, e.g.
1.6e-6 against 1e-6, would otherwise stall Newton)."""
