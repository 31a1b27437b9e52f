"""Write the documentation pages that come from the code into docs/_generated/:

- cli.md: every `fruit` subcommand with its usage, help and options (from click itself);
- scene-keys.md: every scene key with its type, default, unit and meaning (from
  `fruitcli.scene.SCHEMA` and `ARRAY_SCHEMA`);
- performance.md: the figures of `make bench` (build/bench/bench.json when present, else
  the small sample docs/bench-sample.json), and `fruit simulate` with and without PARDISO
  from docs/data/linear-solvers.json (written by
  `tests/performance/bench_linear_solver.py --docs`);
- fruit-limits.md and fruit-limits.png: the default Fruit's limit pressures and its
  chambers' pressure-volume curves, from docs/data/fruit-limits.{json,csv} (written by
  `tests/performance/bench_limits.py --docs`);
- stability-realistic.md: the stability study's rows on realistic bodies, from
  docs/data/stability-realistic.json (written by
  `tests/performance/stability_realistic.py --docs`);
- gallery.md and gallery/*.png: the pipeline's pictures, by docs/gallery.py (after
  `fruit demo` of the scenes it needs into build/gallery/demo, unchanged stages reused).

Run by `make docs` before Sphinx; `python docs/generate.py [--bench FILE]`.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

import click

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
OUT = DOCS / "_generated"
BENCH = ROOT / "build" / "bench" / "bench.json"
BENCH_SAMPLE = DOCS / "bench-sample.json"

UNITS = [  # key-name suffix -> unit (longest first)
    ("_n_per_mm", "N/mm"),
    ("_mm_min", "mm/min"),
    ("_kg_m3", "kg/m³"),
    ("_m_s2", "m/s²"),
    ("_mm3", "mm³"),
    ("_mm", "mm"),
    ("_kpa", "kPa"),
    ("_deg", "degrees"),
    ("_s", "s"),
    ("_counts", "counts"),
]
OPTION = re.compile(r"(?<![\w`-])(--[a-z][a-z0-9-]*)")
"""A long option named in plain text (--out, --dry-run)."""
KINDS = {
    "str": "text",
    "path": "file path",
    "num": "number",
    "int": "integer",
    "bool": "true / false",
    "vec2": "[x, y]",
    "vec3": "[x, y, z]",
    "box": "[xmin, ymin, zmin, xmax, ymax, zmax]",
    "list": "list",
    "table": "table",
    "range": "number or [lo, hi]",
}


def escape(text: str) -> str:
    """Plain text made safe for Markdown (MyST): no markup, no raw HTML; `code spans` kept,
    and options such as --out made code spans (Sphinx would render its two hyphens as an
    en dash)."""
    parts = re.split(r"(`[^`]+`)", text)
    for k in range(0, len(parts), 2):  # outside code spans
        parts[k] = re.sub(r"([\\*_<>\[\]|#])", r"\\\1", parts[k])
        parts[k] = OPTION.sub(r"`\1`", parts[k])
    return "".join(parts)


def unit_of(key: str) -> str:
    for suffix, unit in UNITS:
        if key.endswith(suffix):
            return unit
    return ""


# ------------------------------------------------------------------------------ CLI
def _paragraphs(text: str) -> list[str]:
    import inspect

    text = inspect.cleandoc(text or "")
    return [" ".join(p.split()) for p in text.split("\n\n") if p.strip()]


def command_section(
    cmd: click.Command, path: list[str], parent: click.Context | None, lines: list[str]
) -> None:
    ctx = click.Context(cmd, info_name=path[-1], parent=parent)
    name = " ".join(path)
    lines += [f"## {name}", "", "```text", cmd.get_usage(ctx).strip(), "```", ""]
    lines += [escape(p) + "\n" for p in _paragraphs(cmd.help)]
    args = [p for p in cmd.params if isinstance(p, click.Argument)]
    opts = [p.get_help_record(ctx) for p in cmd.params if isinstance(p, click.Option)]
    if args:
        lines += ["Arguments:", ""]
        lines += [
            f"- `{a.make_metavar(ctx)}`" + (" (optional)" if not a.required else "") for a in args
        ]
        lines.append("")
    rows = [r for r in opts if r is not None]
    if rows:
        lines += ["Options:", ""]
        for names, help_text in rows:
            lines.append(f"- `{names}`: {escape(' '.join(help_text.split()))}".rstrip(": "))
        lines.append("")
    if isinstance(cmd, click.Group):
        for sub in cmd.list_commands(ctx):
            command_section(cmd.get_command(ctx, sub), [*path, sub], ctx, lines)


def cli_page() -> str:
    from fruitcli.cli.main import cli

    lines = [
        "# Command line",
        "",
        "Generated from the `fruit` command group itself (`docs/generate.py`): every "
        "subcommand with its usage, help and options, as `fruit COMMAND --help` prints "
        "them.",
        "",
    ]
    ctx = click.Context(cli, info_name="fruit", **cli.context_settings)  # -h, --help
    lines += ["```text", cli.get_help(ctx), "```", ""]
    for name in cli.list_commands(ctx):
        command_section(cli.get_command(ctx, name), ["fruit", name], ctx, lines)
    return "\n".join(lines)


# ----------------------------------------------------------------------- scene keys
def _default(key) -> str:
    if key.required:
        return "required"
    if key.default is None:
        return "none"
    if isinstance(key.default, bool):
        return "true" if key.default else "false"
    if isinstance(key.default, str):
        return f'"{key.default}"' if key.default else '""'
    return json.dumps(key.default)


def _type(key) -> str:
    """The key's kind, with the choices or the range the schema declares."""
    text = escape(KINDS[key.kind])
    choices = getattr(key, "choices", None)
    if choices:
        text += ": one of " + ", ".join(f"`{c}`" for c in choices)
    low, high = getattr(key, "min", None), getattr(key, "max", None)
    if low is not None or high is not None:
        left = f"{low:g} {'<' if key.min_exclusive else '≤'} " if low is not None else ""
        right = f" {'<' if key.max_exclusive else '≤'} {high:g}" if high is not None else ""
        text += f", {left}value{right}"
    if getattr(key, "max_items", None) is not None:
        text += f", at most {key.max_items:,} entries"
    return text


def key_table(keys: dict, lines: list[str]) -> None:
    lines += ["| key | type | default | unit | meaning |", "|---|---|---|---|---|"]
    for name, key in keys.items():
        lines.append(
            f"| `{name}` | {_type(key)} | `{_default(key)}` | {unit_of(name)} | {escape(key.doc)} |"
        )
    lines.append("")


def scene_page() -> str:
    from fruitcli.scene import ARRAY_SCHEMA, MAX_ITEMS, SCHEMA, SUBTABLES

    lines = [
        "# Scene keys",
        "",
        "Generated from the scene schema (`fruitcli.scene.SCHEMA` and `ARRAY_SCHEMA`) by "
        "`docs/generate.py`. A scene file is TOML; a key the schema does not have is an "
        "error naming the closest valid one. The unit is the key name's suffix "
        "(`_mm`, `_kpa`, `_deg`, `_s`, `_counts`, ...). Relative file paths are resolved "
        "against the scene file's folder, then against the project root (the nearest "
        "folder above holding `pyproject.toml`). `none` means optional: the stage that "
        "reads the key then does without it or computes a default (the meaning says "
        "which). A section written with no key (`[gravity]` alone) means its defaults. "
        "Every number has its range; sizes that follow from several keys (a bench's "
        "frames, a pad's taxels, a mesh's tetrahedra, the reducer's grid) are estimated "
        "before the stage allocates, and refused in one line when they would not fit "
        "the memory available.",
        "",
    ]
    for section, keys in SCHEMA.items():
        if section in ARRAY_SCHEMA:
            lines += [f"## \\[\\[{section}\\]\\] (at most {MAX_ITEMS:,} tables)", ""]
            key_table(ARRAY_SCHEMA[section], lines)
            continue
        lines += [f"## \\[{section}\\]", ""]
        key_table(keys, lines)
        nested = f"{section}.chamber"
        if nested in ARRAY_SCHEMA:
            lines += [f"### \\[\\[{nested}\\]\\] (at most {MAX_ITEMS:,} tables)", ""]
            key_table(ARRAY_SCHEMA[nested], lines)
            for sub, subkeys in SUBTABLES.items():
                if sub in ARRAY_SCHEMA[nested]:
                    lines += [f"`{sub}` is an inline table with these keys:", ""]
                    key_table(subkeys, lines)
    return "\n".join(lines)


# ----------------------------------------------------------------------- performance
def _fmt(x: float) -> str:
    if x == 0:
        return "0"
    if abs(x) >= 1000:
        return f"{x:,.0f}"
    return f"{x:.3g}"


SOLVER_STEPS = """
## Where a quadratic state's time goes, and what the solver's steps bought

Measured on the default Fruit (`pipelines/fruit-breathing.toml`: 8,865 quadratic tets,
44,403 free dofs) on 2026-12-06, AMD EPYC, 2 cores shared with other work (load average
3-8 throughout: the wall times below compare runs taken at a like load, and are about
twice a quiet machine's).

A breathing state from the previous one (`tests/performance/bench_fem.py`, profiled with
cProfile over the first cycle's 12 states, commit 473b28b): the kept factor's triangular
solves take 51 % of the time (about 12 a state: CG's preconditioner, its factor kept
across states and refreshed when CG needs more than 12 iterations), the element kernels
29 % (the tangent, one or two a state, about 25 %), the scatter of the element blocks into
the kept sparsity pattern 6 %, the sparse products 5 %. Measured on the same states and
not adopted, as they did not pay: a CG start from the Galerkin projection on the previous
states' solutions (at most 1-2 of the 10-16 CG iterations saved); a factor refreshed at 6
CG iterations instead of 12 (80 CG iterations instead of 143 over the 12 states, but 5
factorizations instead of 2: CPU 7.8 s instead of 7.0 s); a double-precision factor (141
CG iterations instead of 143: the factor's age, not its precision, sets their number);
PARDISO's other orderings (minimum degree: 20.5 M entries in the factor instead of
METIS's 18.2 M); computing half of each element's symmetric tangent block (no change
measurable). The design's floor is then about one tangent and a dozen solves with the
kept factor a state.

`fruit limits` (every sample volume controlled: each Newton step solves for the residual
and the chamber's volume gradient):

- the two right-hand sides' CG in lockstep (one PARDISO solve with both: 60-79 ms
  against 98-128 ms for two): chamber c1's first three samples 30.8-33.1 s instead of
  36.1-37.4 s (load 7-9);
- GMRES instead of CG once the kept symmetric indefinite factor has negative pivots (past
  a limit point CG stopped at negative curvature, and each Newton step refactorized):
  c1's sample past
  its peak 3 factorizations and 17.5 s instead of 9 and 24.9 s; c1's inflation curve
  80.5 s (load 7.5) instead of 85.9 s (load 5.5);
- both, the whole `fruit limits` (`tests/performance/bench_limits.py --no-sphere`):
  506 s following the curves instead of 600 s with the code before both (commit
  38e1075; the two runs the same hour, load average 3-7), against 384 s on a quiet
  machine on 2026-12-03 (`docs/data/fruit-limits.json`).

The limits stay those of `docs/data/fruit-limits.json` within 1e-6 relative (c3's limit
38.03356 kPa instead of 38.03359), the collapse pressures within 1e-9. A pressure past a
limit is refused no sooner than before (`tests/performance/bench_refusal.py`, twice each,
load 3-4): c1 at 2000 kPa 10.8-13.6 s after the mesh against 12.4-12.9 s, at -500 kPa
18.6 s against 14.0-21.6 s; most of it is the first sample from rest under the body's
weight. The breathing's states keep their Newton steps (17) and CG iterations (143) over
the first cycle, and their nodes within 1e-7 mm.
"""


STATE_STEPS = """
## A quadratic state from the previous one, and the 100 ms target

`python tests/performance/bench_state.py --mesh DIR` solves the default Fruit's breathing
(12 states after the one from rest) and a sweep of chamber c1 (9 states after the first)
in order with one solver, and prints each path's median wall and CPU time per state,
Newton steps, CG iterations, factorizations and the time of the solver's tangent updates
(assembly, with the follower-pressure stiffness). On 2026-12-06 on AMD EPYC, 2 cores
shared with other work, the code before (commit 82334ef) and after run alternately, twice
each: A, 09:59-10:02 UTC at load average 2.8-3.8, after = commit d5d8439; B, 10:13-10:16
UTC at load average 4.2-4.8, after = commit 1be61e2 (the follower-pressure stiffness
added in the tangent's pattern too):

| | A: before | A: after | B: before | B: after |
|---|---|---|---|---|
| breathing: median, ms | 614, 496 | 477, 350 | 585, 606 | 392, 544 |
| breathing: CPU median (both cores), ms | 408, 378 | 323, 347 | 399, 391 | 328, 356 |
| breathing: tangent updates per state, ms | 119, 102 | 108, 71 | 119, 120 | 74, 89 |
| sweep: median, ms | 486, 326 | 192, 224 | 484, 468 | 301, 322 |
| sweep: CPU median (both cores), ms | 290, 296 | 176, 175 | 296, 304 | 195, 198 |
| sweep: tangent updates per state, ms | 65, 37 | 28, 30 | 75, 71 | 36, 38 |

In every run the breathing took 1.50 Newton steps and 10.3 CG iterations a state before,
1.42 and 8.4 after, and the sweep 1.11 and 7.2 before, 1.11 and 3.8 after; before, each
path refactorized once after its first state, after, neither did. On the quiet machine
earlier that day (09:32 UTC, load average 0.9-1.1) commit 82334ef took a median 309 ms
per breathing state and 218 ms per sweep state; at 17:52 UTC (load average 1.0) commit
af3b3b3 took 217 ms and 121 ms. The states of both paths (`--save`) are
within 5.1e-5 mm (breathing) and 5.5e-5 mm (sweep) of the code before, under the
displacement tolerance of 1e-4 mm; through `fruit run` the paper's model (`element =
"p1"`) within 6.2e-5 mm.

What each step bought:

- CG stops at the displacement tolerance (`LINEAR_DISPLACEMENT_SHARE`): a Newton step's
  CG stops once the kept factor estimates the error it leaves within 0.8 of what Newton's
  own estimate accepts. The breathing's first cycle took 101 CG iterations and no
  refactorization instead of 124 and one (the shorter solves no longer reach the 12
  iterations that refresh the factor); the sweep 3.8 iterations a state instead of 7.2.
- The element loop in `loop_order` (elements sorted by their centroid's x): the scatter
  of the tangent blocks into the kept sparsity pattern 10-13 ms of CPU instead of 16-19
  ms, about 1.4 times a state.
- The follower-pressure stiffness scattered into the tangent's own pattern and added to
  it in place: 3-4 ms instead of 5 ms for the stiffness and 2 ms instead of 4.4-9.6 ms
  for SciPy's sum, per Newton step.

Where a state's time still goes, from the parts timed one by one on one thread (CPU): an
element loop with the tangent 52 ms, its scatter 10-13 ms, the follower-pressure
stiffness 5-6 ms and a forces loop 9 ms per Newton step; a single-precision PARDISO
solve 15 ms and a sparse product 2 ms per CG iteration, and one more solve for Newton's
displacement estimate. With 1.42 Newton steps and 8.4 CG iterations that is about 110 ms
of element loops and assembly and 160 ms of solves: the 100 ms target is not reached. It
would take about one tangent and two solves a state; the CG iterations are set by the
kept factor's age (1-2 right after a refactorization, 9-14 four to six states later) and
a refactorization costs 0.36-0.53 s. The breathing's first six states take two Newton
steps because the predictor, with few kept states, starts them 0.009-0.029 mm from the
equilibrium (0.001-0.003 mm later in the cycle); each Newton step needs its own tangent
(the previous state's last tangent kept for the first step cut the residual to
1e-2-1e-1 instead of 1e-3: three steps instead of two). Measured state by state
(commit af3b3b3, 17:53-18:09 UTC): states 1-6 start from a relative residual of 0.14-0.47 and
take two Newton steps with 6-18 CG iterations (211-387 ms), states 7-11 start from
0.03 and take one with 11 down to 2 (238 down to 106 ms), and state 12, the cycle's
start again, none (22 ms); the first state's sensitivity solved to 1e-5 instead of
1e-2 starts states 1-6 no closer (the predictor's error there is the response's
curvature, which the few states kept do not yet fit). The state from rest (7.0-10.2 s
after, 9.0-14.2 s before, in runs A and B) was not worked on.

Measured on the same states and not adopted: the upper triangle of each element block
only (52-55 ms of CPU per tangent against 52-53 ms); packed upper triangles gathered per
CSR entry over both cores (38 ms on one thread against the scatter's 20 ms); a limited-
memory BFGS update of the preconditioner from CG's own step pairs (96-98 iterations
instead of 109 with 8-30 pairs, each preconditioning 16-60 vector operations longer);
a chord second step with a BFGS secant update (on the one state it applied to, the
residual 2.0e-5 after it instead of 2.3e-5 without the update); PARDISO's variable
block format (solves 17-18 ms instead of 15); a reverse Cuthill-McKee order for the
sparse product (2.05 ms instead of 2.16 ms).

The paper's model through `fruit run` (`element = "p1"`, corotational, 8,865 tets, the
same scene): median 9.7 ms a state from the previous one at load average 1.8-2.3 (10:03
UTC, commit d5d8439), against the 10 ms target; 20-25 ms for the code before and after
alike at load average 3.6-4.8.

### The element tangent, and where the time goes after it

The hyperelastic element loop (`fruitcli/fem/elements/integrate.py`) computes the moduli
A_iJkL at a quadrature point only for k >= i (the others follow by the symmetry A_iJkL =
A_kLiJ), contracts them with the shape gradients along contiguous rows of nodes (the
innermost loop over the 10 nodes b instead of the 3 components J) into the element's
own tangent, and writes it out once with its other half by symmetry. On the default
Fruit's 8,865 quadratic tets, one thread, the loop with forces and tangents timed alone
(old and new alternately in one process, median of 11 runs each, 2026-12-06, load
average 5.5): 39-40 ms instead of 51 ms in two runs, 45-49 ms instead of 56-62 ms in two
busier ones (the forces alone 9 ms). Of the 49 ms of one such run: the forces 9-10,
writing the 64 MB of element blocks 11 (about 6 of it page faults: the blocks are a new
array at every tangent), the moduli 7, the contraction 21.

`python tests/performance/bench_state.py --mesh DIR --save PREFIX`, the code before
(commit 1637cc4) and after (commit 27b5afb) run alternately, twice each, 13:10-13:22 UTC
at load average 5.5-6.7 (2 cores shared with other work; CPU medians of both cores):

| | before | after |
|---|---|---|
| breathing: CPU median, ms | 349, 309, 329, 353 | 281, 302, 300, 320 |
| sweep: CPU median, ms | 174, 199, 180, 222 | 160, 178, 210, 171 |

The same Newton steps (1.42 and 1.11 a state), CG iterations (8.4 and 3.8) and
factorizations (none after the first state); the states within 1.5e-6 mm (breathing)
and 6.5e-7 mm (sweep) of the code before. Through `fruit demo` the nodes of every
simulated state (fruit-breathing, fruit-deformed, touchpad-4x4) are within 6.4e-6 mm of
the code before's, the taxels within 5.1e-6 mm (the breathing's state from rest took 13
Newton steps instead of 12), and what follows from them differs in the last digits.

Where a breathing state's CPU time goes after it (cProfile with the CPU clock over the
first cycle's 12 states, before this change; per state): PARDISO's solves 153 ms (10.3
solves of 15 ms: CG's preconditioner and Newton's displacement estimate), the element
loops 100 ms (now about 85), the scatter into CSR 19 ms, CG's sparse products 19 ms,
the chambers' volumes, gradients and follower-pressure stiffness about 15 ms. A
numerical refactorization of the kept factor costs 410-460 ms of CPU, the price of 25-30
CG iterations. The 100 ms target is not reached: it needs about one tangent and two or
three solves a state, where the breathing takes 1.42 tangents and 10 solves, the sweep
1.11 and 5.

Measured in this round and not adopted:

- a chord second Newton step whenever the first cut the residual 100-fold (not only
  near the residual tolerance): on the breathing's first six states its estimate of
  the correction left was 3.4e-5-1.9e-4 mm instead of 7e-6-3.8e-5 mm with the new
  tangent, so five of the six took a third step (CPU 410-759 ms instead of 325-586 ms);
- the first Newton step's CG to a relative residual of 1e-4 instead of 1e-2: the
  breathing's states 1-6 still took two steps (the residual after the first is
  nonlinear, 1e-4-2e-3: the predictor starts them 0.009-0.029 mm off), the same 101 CG
  iterations over the cycle and one refactorization more; 3e-2 and 1e-1: 98 CG
  iterations instead of 101, the same Newton steps;
- predictors for the first states: the first state's dx/dp updated by Broyden's rule
  along each state (errors 0.029-0.048 mm instead of 0.009-0.029 mm), a quadratic fit
  around the first state with its dx/dp (0.011-0.025 mm), where the states that take
  one Newton step start within 0.001-0.003 mm;
- numba's fastmath on the element loop: no change measurable.

The benchmark also prints, per state, the kept factor's solves and Newton's force
evaluations with their mean times (`WorkCounter`). On 2026-12-07 13:12 UTC (Intel Xeon,
2 cores, load average 0.7-0.8, commit 4e14b54), two runs: the breathing 285-289 ms a
state, of it 10.3 solves of 13.8-14.0 ms and 2.4 force evaluations of 12.9-13.1 ms
(tangent updates 42-43 ms); the sweep 156 ms, 5.7 solves of 13.9-14.3 ms and 2.1 force
evaluations of 14.3 ms (updates 28 ms). The solves alone are over the 100 ms target on
the breathing.

Measured on 2026-12-07 and not adopted (Intel Xeon, 2 cores, load average 0.4-0.9, one
run each unless said):

- MKL's conditional numerical reproducibility (PARDISO's iparm[33] = 2, a trial patch)
  with the factorizations on two threads: a factor comes out the same to the last bit on
  one thread or two, the analysis and factorization take 0.35 s instead of 0.57 s and a
  refactorization 0.13 s instead of 0.23 s, but every solve takes 15.5 ms instead of
  14.0 ms, on one thread or two (medians of 20). The breathing took 296-299 ms a state
  instead of 263 ms and the sweep 163-168 ms instead of 147 ms; `bench_refusal.py
  --solver-threads 2` refused c1 at 2000 kPa 3.2 s after the mesh instead of 3.4 s and
  at -500 kPa 7.0 s instead of 7.6 s. A factor's solves on one thread and its next
  refactorization on two crashed MKL in this mode, so the solves cannot stay on one
  thread while the factorizations take two;
- refreshing the kept factor after 4, 6 or 8 CG iterations instead of 12: breathing
  medians 300, 258 and 244 ms against 263 ms, the refactorizations costing about what the
  shorter solves save;
- Newton's displacement estimate from a relative residual of 1e-2 instead of 1e-3
  (`ESTIMATE_WINDOW` 1e4) with a displacement tolerance of 1e-3 mm instead of 1e-4: five
  of the breathing's states 1-6 still took two Newton steps (median 234 ms against 295
  ms in the same busier hour), the nodes within 5.8e-4 mm of those at the default;
- for the breathing's first states, a quadratic response around the first state fitted
  to the states so far and anchored at the last (errors 0.013-0.025 mm against
  0.009-0.029 mm), or the last state's prediction error carried into the next (worse).

### The element blocks' array kept

Newton's element tangents are written over one array of blocks the model keeps (64 MB
on the default Fruit) instead of a new one at every tangent: the tangent alone 64 ms of
CPU instead of 71 ms (96 ms wall instead of 105 ms; median of 20 each, alternately in
one process, 2026-12-06 15:29 UTC, load average 2.5-2.7). `python
tests/performance/bench_state.py --mesh DIR --save PREFIX`, the code before (commit
a70ba91) and after (commit fbb5125) run alternately, four times each, 15:25-15:29 UTC at
load average 1.2-1.9 (2 cores shared with other work; CPU medians of both cores):

| | before | after |
|---|---|---|
| breathing: CPU median, ms | 284, 316, 315, 364 | 268, 329, 283, 286 |
| sweep: CPU median, ms | 159, 192, 168, 220 | 155, 192, 166, 175 |

The same Newton steps (1.42 and 1.11 a state) and CG iterations (8.4 and 3.8), and the
states of both paths equal to the last bit.
"""


FIRST_STATE_STEPS = """
## The first state from rest

The first state of `fruit simulate` is solved from rest: on the default Fruit's breathing
(its weight and 9 kPa in chambers c2 and c3) in `[solver] first_steps` = 4 load steps.
Where its time went (the code before, commit cc6262d, profiled with cProfile on
2026-12-06 15:52 UTC, load average 2.7-3.3, AMD EPYC, 2 cores shared with other work):
6.2 s in all, 13 Newton steps (3, 3, 3 and 4 a load step), 5 factorizations 2.5 s (the
first with PARDISO's analysis, 0.75 s), 146 CG iterations 2.4 s (PARDISO's solves, 15 ms
each), the tangents' assembly 0.6 s and the element loops 0.6 s. In one load step it
took 14 Newton steps (5.9 s), in two 16 (9.3 s). Each load step's first Newton step
only removes the bulk error of its start, extrapolated along straight lines (relative
residual from 0.85-0.97 to about 1e-2); two more converged it to 1e-6, and the second
ran 24 CG iterations on a factor gone stale before refactorizing all the same.

What each step bought (the state alone, `fruitcli.fem.solver.state.solve_state`, load
average 0.8-2):

- The load steps short of the state's load converged to a relative residual of 1e-2
  (`state.PATH_TOLERANCE`, set for the first state only; the last step to the
  tolerance, and the state solved again from its start with every step to it should a
  later step fail): 9 Newton steps, 4 factorizations and 92 CG iterations, 4.1-4.4 s.
- Each such step's second Newton step with its tangent factored afresh: 8 Newton steps,
  4 factorizations and 36 CG iterations, 3.0-3.2 s.
- The first state kept in the output folder (`pressure-check.npz`, next to the pressure
  check's samples; `fruitcli.fem.sample_cache.kept_first_state`): a later run on the
  same body (the same mesh, element, material, weight, supports, jigs and chambers) with
  the same first state takes it as it is while it is an equilibrium by Newton's own
  test, as Newton's start otherwise, and factors its tangent there for the next state.

`python tests/performance/bench_state.py --mesh DIR --first` (the first state as
`fruit simulate` solves it, after the pressure check's compliance at rest, which makes
the first factorization; into a new folder, then again into the same one), the code
before (commit cc6262d) and after (commit 2ddf676) run alternately, twice each,
16:11-16:12 UTC at load average 1.8-1.9:

| | before | after |
|---|---|---|
| new folder: the state, ms | 5292, 5429 | 2527, 2579 |
| new folder: Newton steps, factorizations, CG (the check's too) | 13, 5, 151 | 8, 4, 40 |
| new folder: `run_simulate`, s | 7.2, 7.3 | 4.2, 4.2 |
| same folder: the state, ms | 5206, 5279 | 596, 618 |
| same folder: `run_simulate`, s | 6.3, 6.4 | 1.7, 1.8 |

The run into the same folder takes one Newton step from the kept state (kept at the
displacement tolerance, above the residual tolerance) and keeps the result: a third run
takes it as it is, 489-515 ms (0 Newton steps; one factorization at the state, for the
next one's start). Without the check (`bench_state.py --only breathing`, alternately,
16:10 UTC, load 1.8-2.0) the state from rest took 3305-3325 ms instead of 6086-6277 ms;
the 12 states after it kept their Newton steps (1.42 a state), CG iterations (8.4) and
median (275-281 ms against 273-286 ms).

The first state is within 5.1e-5 mm of the code before's, and within 2.9e-5 mm of the
equilibrium solved to a relative residual of 1e-11 (the code before's: 5.6e-5 mm);
through `run_simulate` every breathing state is within 5.1e-5 mm of the code before's,
and a second run into the same folder within 1.4e-4 mm of the first (each within the
displacement tolerance of 1e-4 mm of the equilibrium). On that machine the 2 s target
is reached by a later run on the same body, not by a first run (2.5 s: 8 Newton steps, 3
factorizations after the check's; below for another machine). Starting from the body's
equilibrium under its weight does not apply here: `fruit simulate` solves it only when
its pressure check follows a curve on to its limit, which the breathing's pressures do
not ask for.

Through the command itself, `fruit simulate pipelines/fruit-breathing.toml --out DIR`
(its own mesh, refined at the taxels: 8,865 tets), on a quiet machine (16:27-16:32 UTC,
load average 0.1-0.9): the code before (commit cc6262d) took 4895-5126 ms for the
first state (13 Newton steps) and 7.7-7.9 s for all 13; after (commit 49d6314) 2224 ms
(8 Newton steps) and 5.0 s into a new folder, 586 ms (1 Newton step) and 3.4 s again
into the same folder, 499 ms (0 Newton steps) and 3.3 s a third time; every state
within 5.8e-5 mm of the code before's. The solver's Newton constant, which sets the
next states' first linear tolerance (`LinearSolver.newton_c`), is kept with the first
state: without it the 12 later states of a run with a kept first state took 3.2-3.3 s
instead of 2.8-2.9 s, one of them refactorizing (0.8 s).

The pressure check's first sample of a curve from rest (the weight and the first
volume step, 3 load steps) takes the same path tolerance and refactorization
(`fruitcli.fem.curve_start.first_sample`, commit 8e0b1a9). `python
tests/performance/bench_refusal.py`, after and before (commit cc6262d) alternately,
twice each, 16:17-16:20 UTC at load average 1.1-2.1: chamber c1 at 2000 kPa refused 5.0
and 4.8 s after the mesh instead of 5.6 and 5.4 s, at -500 kPa 8.1 and 8.2 s instead of
9.2 and 9.2 s, in the same words (the limit's bound 140.9 kPa, the collapse -24.0 kPa);
the thick sphere (no weight: one load step) as before. The 3 s target is not reached.
The body's equilibrium under its weight that `fruit limits` solves once
(`curve_start.start_state`) moved by 0.014 mm with the path tolerance (within the
check's tolerance of 1e-3) and was left as it was then; it takes the path tolerance
since commit f90d870 (10 Newton steps, 8 without the chord step described below).

The upper triangle PARDISO factors is taken from the tangent by positions found once per
sparsity pattern (`linsolve.upper_triangle`) instead of SciPy's `triu`: 5-9 ms instead
of 37-56 ms at every factorization, the same matrix entry for entry
(`tests/fem/solver/test_assemble.py`). `python tests/performance/bench_state.py --mesh
DIR --first`, the code before (commit ee1bc33) and after (commit 19f4516) alternately,
three times each, on 2026-12-06 18:53-18:55 UTC on a quiet Intel Xeon, 2 cores (load
average 0.3-0.7): the first state into a new folder 1931-1981 ms instead of
2033-2098 ms (a run's second and third state from rest in the same process: 1847-1888
ms), with the same 8 Newton steps, 4 factorizations and 40 CG iterations.
`tests/performance/bench_refusal.py` on the same machine (commit 19f4516, 18:50-18:53
UTC, load average 0.8-1.0): chamber c1 at 2000 kPa refused 4.1 s after the mesh, at
-500 kPa 7.7 s; the thick sphere at 2000 kPa 2.4 s, at -500 kPa 4.8 s.

Measured and not adopted: a path tolerance of 0.1 (one factorization fewer on the
Fruit, but a beam turning far under its weight took 85 Newton steps instead of 58,
`tests/fem/solver/test_path_tolerance.py`; 1e-2 takes 54); 2e-2-5e-2 (before the
refactorization at the second step: 8-10 Newton steps and 3-4 factorizations, as 1e-2
or one fewer); 3, 6 and 2 load steps with both changes (9, 11 and 21 Newton
steps); the factor refreshed at each load step's start instead of its second Newton
step (6 factorizations, 41 CG iterations, 3.9 s).

A pressure far past the limit is refused after the check's first sample
(`curve_peak.levels_off_bound` with the slope at rest from the check's rest compliance,
`curve_peak.ONE_SAMPLE_MARGIN`): `python tests/performance/bench_refusal.py`, the code
before (commit e8d3f1c) and after (commit 8d80799) alternately, twice each, on
2026-12-06 23:15-23:18 UTC on a quiet Intel Xeon, 2 cores (load average 0.7-1.1):
chamber c1 at 2000 kPa refused 3.5 and 3.4 s after the mesh instead of 4.1 and 4.1 s
(the bound in the line 167.8 kPa instead of 140.9 kPa), the thick sphere at 2000 kPa
2.0 and 1.9 s instead of 2.4 and 2.3 s; the suction cases as before (c1 at -500 kPa
7.3-7.5 s, the sphere 4.5-5.1 s). The 3 s target is still missed on the Fruit: of its
3.4 s, building the model takes about 0.6 s, the compliance at rest 0.8 s (the tangent's
analysis and first factorization) and the first sample from rest under the weight 2.0-2.2
s (3 load steps, 7 Newton steps, 3 factorizations).

A suction that levels off is refused with a bound of its collapse, as an inflation is
with a bound of its limit (`curve_peak.levels_off_bound`, continued down to 0.09 V0 for
a suction): the Fruit's flat chambers level off under suction (c1's slopes, 81 down to
19 kPa per unit of mean stretch from 0.9 to 0.5) where a spherical cavity's steepen. On
chamber c1, -500 kPa is refused after the first sample, below twice the bound of -44.7
kPa (the collapse `fruit limits` computes: -24.0 kPa). `python
tests/performance/bench_refusal.py`, the code before (commit 502fc27) and after (commit
b12287f) alternately, twice each, on 2026-12-07 17:03-17:05 UTC on the Intel Xeon
(2 cores, load average 0.8-1.2): c1 at -500 kPa refused 4.3 and 4.1 s after the mesh
instead of 9.4 and 9.6 s; c1 at 2000 kPa (4.1-4.4 s) and the thick sphere (2.3-2.5 s at
2000 kPa, 5.7-6.0 s at -500 kPa, its cavity buckling in) as before. The 3 s target is
still missed: the first sample from rest under the weight takes 2.5 s of it.

A sample of a limit curve after its first gives up once four Newton steps in a row cut
its residual by less than 10 % in all (`SolverOptions.stall_steps`,
`limits.STALL_STEPS`, `tolerances.STALL_CUT`), as a sample past its time budget did:
past chamber c3's collapse (at 0.22 V0) Newton went from a relative residual of 2.6e-2
to 2.4e-2 in ten steps until the budget ran out, where every converging sample on the
Fruit's seven curves cut it by at least 25 % every four steps. Every curve's limit and
collapse is that of the code before to the last digit, and c3's suction took 6.9 s
instead of 11.1 s (its seven curves in one process, commit 0740d9c against 8f3a446).
Chamber c2's failing sample first runs a long line search and meets an indefinite
tangent: in one process its budget ran out before four steps showed the stall, in
`fruit limits`' worker processes (its samples slower, its budget longer) it ended at
the stall too (`docs/data/fruit-limits.json`). `python
tests/performance/bench_limits.py --no-sphere`, before and after alternately,
2026-12-07 17:20-17:26 UTC, Intel Xeon, 2 cores, load average 0.6-2.0: `fruit limits`
61.7 and 60.0 s after the mesh (125.1 and 121.5 s of CPU) before, 59.9, 58.9 and 59.9 s
(118.7, 117.0 and 118.4 s) after: the two worker processes wait on the longest curves,
the chambers together and the inflations.

Past a collapse the tangent is indefinite, and its solves run GMRES preconditioned by
the kept factor, column by column (the displacement's and the chamber's). With a stale
factor, the columns after the first that GMRES does not converge on now wait for the
refactorization instead of running their own 24 iterations first
(`ContinuumSolver._krylov`): on the thick sphere sucked past its collapse the second
column took 0.55 s to fail as the first had. `python tests/performance/bench_refusal.py`,
the code before (commit 74f5662) and after (commit dc944b3) alternately, twice each,
2026-12-07 17:35-17:37 UTC on the Intel Xeon (load average 0.8-1.1): the thick sphere
at -500 kPa refused 5.1 and 5.5 s after the mesh instead of 5.7 and 5.7 s; the other
cases as before (the Fruit's c1 at -500 and 2000 kPa 4.0-4.2 s, the sphere at 2000 kPa
2.3-2.4 s). `fruit limits` on the default Fruit gives the same limits and collapses
(59.3 s after the mesh, 17:40 UTC). Of the sphere's 5.1-5.5 s, its failing sample
takes about 1.7 s: the stale factor's GMRES, a refactorization, then a new analysis
in double precision (0.86 s) where the single-precision factor misses its probe.

The pressure check solves the first sample of each curve it follows to a relative
residual of 0.1 first (`curve_start.SCREEN_TOLERANCE`, `first_kept_or_solved`), in every
one of its 3 load steps, refuses at once when the bound after that sample refuses the
pressure asked, and converges the sample on from there otherwise: the Fruit's
chamber c1 under its weight took 4 Newton steps and 2 factorizations instead of 7 and
4 (1.8 s instead of 2.7-2.8 s), its pressure -8.124 kPa against -8.1245 kPa converged
(at 0.729 V0) and 8.383 against 8.392 kPa (at 1.331 V0), and the bound in the line
-44.7 kPa and 167.7 kPa against -44.7 and 167.8 kPa. A sample converged on from there
(a pressure the bound does not refuse, such as -30 kPa) takes the same 7 Newton steps in
all (4 and 3), 2.8-3.1 s against 2.8 s before. `python
tests/performance/bench_refusal.py`, the code before (commit d525886, from a worktree,
numba's cache warmed) and after (commit ed3cde3)
alternately, twice each, on 2026-12-07 19:47-19:50 UTC on the Intel Xeon (2 cores, load
average 1.0-1.1): the Fruit's c1 refused 3.4 and 3.2 s after the mesh at -500 kPa
instead of 4.5 and 4.4 s, 3.2 and 3.3 s at 2000 kPa instead of 4.5 and 4.5 s; the thick
sphere 5.1 and 5.3 s at -500 kPa instead of 5.8 s, 2.3 and 2.3 s at 2000 kPa instead of
2.5-2.7 s. With `--again` (the samples kept in the output folder) the Fruit's c1 is
refused 1.4-1.6 s after the mesh. The 3 s target is still missed by a few tenths on the
Fruit: building the model takes 0.7-0.8 s of it (about 0.4 s of that numba's start-up
in a fresh process), the compliance at rest 1.0 s, the screened sample 1.8 s.

Along loose load steps (`SolverOptions.path_tolerance`) each load step's second Newton
step asks for a refactorization (`NewtonStep.refactor_second`); a chord step, which
keeps the tangent, skipped it where the residual after the first step was already near
a loose tolerance. Newton no longer takes a chord step there (`newton._chord_step`).
The default Fruit's equilibrium under its weight (`curve_start.start_state`, tolerance
1e-3) took 8 Newton steps instead of 10: in its last load step the chord step had cut
the residual from 9.8e-3 to 8.6e-3 only (3.2 s instead of 3.8-4.0 s). The first state of
`fruit simulate` (8 Newton steps, 39 CG iterations) and the pressure check's first
samples take the same steps as before. `fruit limits` (`bench_limits.py --no-sphere`,
the code before, commit 6a08797, and after, commit 652df4e, alternately, twice each,
2026-12-07 20:35-20:40 UTC on the Intel Xeon, load average 0.2-2.0) took 57.7 and 57.3 s
after the mesh against 56.8 and 57.4 s: no change beyond the run-to-run spread, the
worker processes waiting on the longest curves. Its limits moved by 2.3e-6 relative at
most (the chambers together: 29.82336 kPa instead of 29.82330 kPa) and its collapses by
less than 1e-9.

The free dofs' CSR pattern is built by compiled passes over each node's elements
(`assemble.CsrPattern.build`: `_node_pairs`, `_dof_slots`) instead of sorting the
886,500 node pairs of the Fruit's elements with NumPy: the same arrays
(`tests/fem/solver/test_assemble.py` checks them against the dof-pair definition), 0.08
s instead of 0.26-0.85 s in one process; in a fresh process, with numba's start-up
(about 0.18 s, paid by whichever compiled function runs first), building the default
Fruit's model took 0.43-0.45 s instead of 0.54-0.81 s (three runs each, commit
9968fc3 against d0c5794, 2026-12-06 23:53 UTC, the quiet Intel Xeon). Chamber c1 at
2000 kPa was then refused 3.3 and 3.5 s after the mesh against 3.8 and 3.5 s
(`bench_refusal.py`, alternately, load average 0.4-1.1): within the run-to-run spread.

A new PARDISO analysis takes its fill-reducing order from the body's nodes
(`pardiso.node_order`, `fruitcli/fem/solver/node_order.py`): the tangent's rows come in
runs with one pattern, a node's free dofs, and METIS (PARDISO's own, called on that
graph alone) orders the 14,801 runs of the quadratic default Fruit instead of its 44,403
rows; each node's rows then stay together. The order is kept for the pattern, so a
second analysis of the same tangent (positive definite to indefinite, single to double
precision) does not order it again. Timed alone on the Fruit's tangent at rest (4 times
each, alternately, 14:38 UTC): the order and the analysis with the first factorization
0.55-0.56 s instead of 0.60-0.62 s, a refactorization 0.23-0.24 s instead of 0.25-0.26
s, a factor of 18.0 M entries instead of 18.4 M. `python
tests/performance/bench_state.py --mesh DIR [--first]` and `bench_refusal.py`, the
code before (commit 10891da) and after (commit 0304ef9) alternately, twice each, on
2026-12-07 14:34-14:38 UTC on the quiet Intel Xeon (load average 0.6-1.2):

| | before | after |
|---|---|---|
| breathing: median, ms; a solve, ms | 291, 281; 13.7, 13.2 | 287, 273; 13.7, 12.3 |
| sweep: median, ms | 161, 156 | 156, 154 |
| from rest: breathing, sweep, ms | 3656, 3299; 2831, 2910 | 2812, 2612; 2739, 2575 |
| `--first`, new folder: the state, ms | 2179, 2078 | 2108, 2019 |
| thick sphere refused, -500; 2000 kPa, s | 5.4, 5.1; 2.2, 2.2 | 4.8, 5.0; 1.9, 2.1 |
| Fruit's c1 refused, -500; 2000 kPa, s | 8.0, 7.9; 3.6, 3.5 | 7.7, 8.0; 3.6, 3.6 |

"From rest" is each path's first state with the solver's first analysis in it (a run's
breathing, then its sweep). The same Newton steps on both paths (1.42 and 1.11 a state)
and the same CG iterations (8.4 and 3.8); the first state from rest 39 CG iterations
instead of 40. The states are
within 2.7e-5 mm (breathing) and 6.6e-7 mm (sweep) of the code before's (`--save`), under
the displacement tolerance of 1e-4 mm. `fruit limits` on the default Fruit
(`bench_limits.py --no-sphere`, 15:10-15:13 UTC, load average 0.7-1.9) took 58.9 s after
the mesh against the code before's 61.4 s, the limits the same to the digits printed.
What it buys is a tenth of a second or less per analysis: the first state as `fruit
simulate` solves it (its analysis is the check's) stays at about 2 s, and the Fruit's
refusals (seconds after the mesh) stay above the 3 s target.

Measured and not adopted: the order and the analysis of the tangent's pattern made
ahead, on a thread of their own, from the moment the model's pattern is known (PARDISO
releases the GIL, and the analysis of a positive definite matrix reads only the
pattern, so the factor came out the same to the last bit; commit 80bc832, reverted in
f74409e). The first factorization then took 0.27-0.29 s instead of 0.61 s, but the
thread took a core from numba's loops while the model was built: from the mesh loaded
to the compliance at rest 1.18-1.22 s against 1.22-1.27 s (four runs each, alternately,
2026-12-07 22:30 UTC, Intel Xeon, 2 cores, load average 1.0-1.5). `bench_refusal.py`
gave the same on both sides (the Fruit's c1 2.5-2.7 s after the mesh, the thick sphere
4.1-4.3 s at -500 kPa and 1.8-1.9 s at 2000 kPa), and `bench_limits.py --no-sphere`
54.9 and 55.0 s after the mesh against 53.9 and 54.5 s (the thread started in each
worker process too, where the other worker holds the second core).
"""


THREADS_STEPS = """
## PARDISO on two threads: `fruit --solver-threads 2`

MKL PARDISO runs on one thread by default, so that every run gives the same bits. With
`fruit --solver-threads N` it runs on N (`fruitcli.fem.solver.pardiso.use_threads`: MKL's
OpenMP layer, chosen before MKL is loaded, its threads put to sleep after each call
unless `KMP_BLOCKTIME` says otherwise).
Timed alone on an idle Intel Xeon, 2 cores, on 2026-12-06, a single-precision solve of
the quadratic default Fruit's tangent took 5.0-5.4 ms instead of 9.1-10.4 ms and a
refactorization 0.10-0.12 s instead of 0.21 s; with the other core kept busy, 10-12 ms
and 0.18-0.27 s, nothing gained.

`make bench` runs `tests/performance/bench_solver_threads.py`, which prints the
breathing, the sweep and the first state on one thread and then on two.
`python tests/performance/bench_state.py --mesh DIR [--first] --solver-threads N` and
`python tests/performance/bench_refusal.py --solver-threads N` (commit da0e65a,
2026-12-06 19:05-19:12 UTC, the same Intel Xeon, load average 0.7-1.3; one and two
threads alternately):

| | one thread | two threads |
|---|---|---|
| breathing, a state from the previous one: median, ms | 268, 261 | 215, 204 |
| sweep of c1: median, ms | 154, 144 | 117, 116 |
| CPU median of both cores, breathing; sweep, ms | 313, 306; 177, 174 | 312, 302; 176, 172 |
| first state from rest as `fruit simulate` solves it, new folder, ms | 1924, 2005 | 1471, 1448 |
| the same, again into the same folder, ms | 418, 417 | 298, 302 |
| chamber c1 at 2000 kPa refused after the mesh, s | 4.2 | 4.1 |
| chamber c1 at -500 kPa refused after the mesh, s | 7.6 | 6.6 |

The Newton steps (1.42 and 1.11 a state) and CG iterations (8.4 and 3.8) are the same.
The states are not the same bits: two runs on two threads, and a run on one thread
against one on two, differ by up to 2.0e-6 mm on the breathing and 6.5e-7 mm on the sweep
(`--save`; the displacement tolerance is 1e-4 mm), and a first state from rest took 39
CG iterations instead of 40 in one run of five. The 100 ms target for a state from the
previous one is still missed on two threads: 116-117 ms on the sweep, 204-215 ms on the
breathing.

What the second thread buys depends on the machine. On an Intel Xeon with 2 cores two
days later (`python tests/performance/bench_solver_threads.py --mesh DIR`, commit
ec980b7, 2026-12-08 03:52 and 03:53 UTC, load average 0.7-0.9) only the factorizations
gained: a solve took 15.3-15.9 ms on two threads against 14.3-14.7 ms on one, so the
breathing's median was 305 and 307 ms a state against 298 and 296 ms, and the sweep's
176 and 165 ms against 159 and 167 ms, while the first state from rest, with its four
factorizations, took 1929 and 1902 ms against 2113 and 2166 ms. The benchmark tells what
it buys on yours.

Measured and not adopted: MKL's conditional numerical reproducibility mode on two
threads (`MKL_CBWR=AUTO` set before MKL loads; MKL then reports that branch). Two runs
gave the same bits on the breathing, the sweep and the first state from rest (without
it they differed by up to 9.6e-7 mm), but it took the second thread's gain away.
`python tests/performance/bench_state.py --mesh DIR [--first] --solver-threads 2 --save
PREFIX` with the mode and without it (commit 301bba2), alternately, twice each, on
2026-12-07 02:43-02:45 UTC on the quiet Intel Xeon (load average 0.0-0.9): the
breathing's median 295 and 297 ms a state instead of 214 and 219 ms, the sweep's 159 and
163 ms instead of 121 and 124 ms, the first state from rest 1827 and 1832 ms instead of
1456 and 1459 ms (one thread, in the table above: 261-268 ms, 144-154 ms and 1.92-2.01
s). One thread stays the way to the same bits on every run.
"""


LIMITS_STEPS = """
## `fruit limits`: what each step bought

Measured on the default Fruit (`pipelines/fruit-breathing.toml`, 8,865 quadratic tets) on
2026-12-06, AMD EPYC, 2 cores shared with other work, each curve followed in-process as
`fruit limits` does (`python tests/performance/bench_limits.py --no-sphere --curves`),
CPU seconds of all threads (the wall time is up to twice that at the loads below). The
code before (commit 0f5fd7f), 12:13-12:21 UTC at load average 1.5-4.3: 239 s of CPU and
419 s wall in all; each chamber's first sample from rest took 10 Newton steps (5.5-6.6
s), the sample past each peak 7-10, and the suction samples of chambers c2 and c3 that
find no equilibrium 29 s and 18 s (their budget, 4 times the longest sample so far, the
first).

- The body's equilibrium under its weight solved once (9 Newton steps, 5.0-5.3 s) and
  each curve's first sample from the linear response there (3 Newton steps, 1.4-1.8 s):
  chamber c1's suction 7.3 s instead of 12.3 s, its inflation 24.8 s instead of 29.7 s.
- An inflation ends at the vertex ahead of its last three samples instead of a sample
  past the peak, samples the vertex when it is less than a step ahead, and brackets a
  vertex already passed with half a step; a sample after the first has at most two
  load-step halvings: chamber c3's inflation 22.6 s instead of 31.2 s (10 samples
  instead of 11), its suction 12.5 s instead of 27.5 s, the chambers together 31.1 s
  instead of 72.3 s (their failed sample at 4.9 V₀, 34 s, is no longer tried: the
  vertex behind the sample at 4.1 V₀ takes half a step at once).
- Samples at a relative residual of 10⁻³ instead of 10⁻⁴: chamber c3's inflation 34
  Newton steps and 18.0 s instead of 42 and 22.6 s, the pressures the same to four
  digits.
- All: 111 s of CPU and 145 s wall at load 1.7-3.7 (12:31-12:33 UTC, commit 731c87d);
  119 s of CPU and 192 s wall at load 6-7 (13:01-13:04 UTC, commit a9ff186: the body
  under its weight 5.0 s, c1 6.9 + 18.2 s, c2 10.9 + 19.7 s, c3 15.1 + 17.6 s
  (suction + inflation), the chambers together 25.7 s). The whole `fruit limits`
  (`bench_limits.py --no-sphere --docs`, meshing included) took 205 s wall and 116 s of
  CPU at load 5.9-7.2, against 391 s wall on a quiet machine on 2026-12-03.

The limits are those of the code before within 0.03 % (c1 29.823 kPa instead of 29.828,
c2 39.100 instead of 39.108, c3 38.022 instead of 38.034, together 29.8234 instead of
29.8235), the collapse pressures within 0.001 %; the volume growth at each chamber's
limit moves by up to 1.5 % (the peak is flat: its place is far less certain than its
pressure). In one process what is left is about 30 Newton steps a chamber's inflation,
15 a suction and 40 the chambers together, each 0.4-0.7 s of CPU (PARDISO's solves and
refactorizations with two right-hand sides, 70 % of it).

The curves share nothing but the body under its weight, so `fruit limits` follows them
in worker processes (`--jobs`, every core by default; the chambers together first, then
the other inflations, then the suctions, so the longest start first), and solves the
body under its weight with its load steps short of the weight converged to the path
tolerance (8 Newton steps, 2.9 s, instead of 10 and 3.6-3.7 s). The whole command
(`python tests/performance/bench_limits.py --no-sphere [--jobs 1]`, make-tracks and
tetra included) on 2026-12-06 17:45-17:50 UTC, load average 1.1-1.8, run one after the
other: 56.6 s wall and 103 s of CPU over two worker processes (51.6 s after the mesh);
90.8 s and 99 s with `--jobs 1` (85.7 s after the mesh); 108.8 s and 118 s for the code
before (commit b9ba0ad). Each worker peaked at 740 MB. The limits are those of one
process to every digit, and those of the code before within 1.3e-6 relative (the
chambers together 29.82342 kPa instead of 29.82346, c2 39.10044 instead of 39.10041),
the collapse pressures within 1e-8. On a machine with fewer free cores than curves
the time is about the CPU time over the free cores. The `limits` stage of `fruit run`
follows its curves the same way (`python tests/performance/bench_limits.py --no-sphere
--stage [--jobs 1]`: the default Fruit's mesh with every chamber at 20 kPa, four curves
on to their limits, the chambers together included): 40.5 s wall and 72 s of CPU over
two worker processes against 62.0 s and 68 s in one (2026-12-06 18:16-18:17 UTC, commit
2062861, load average 0.4-1.1), the same limits to six digits.

Measured and not adopted: one solver (one PARDISO analysis) shared by all the curves
(107 s of CPU against 111 s, within the run-to-run spread); the factor refreshed at
each sample's start (chamber c3's inflation 18.1 s against 17.2-17.7 s); the secant over
the kept samples as the start of an inflation sample far from the peak (1-2 Newton
steps a sample at half the step, but the third sample at the full step found no
equilibrium within its budget twice); a double step after a sample of at most 3
Newton steps (c3's inflation 17.2 s with 8 samples against 18.3 s, c2's 19.6 s against
18.4 s); a suction budget of twice the longest sample (c3's suction 7.2 s against
10.3-11.1 s, c2's unchanged; a wall-time budget that tight could end a converging
sample on a loaded machine and move a collapse pressure).

A pressure past a limit is refused as soon as before
(`python tests/performance/bench_refusal.py`, 12:52-12:56 UTC, load average 4.9-5.7):
chamber c1 at 2000 kPa 12.3 s after the mesh (10.0 s of CPU for the whole command)
against 10.5 s (11.2 s); at -500 kPa 16.3 s (16.8 s) against 16.5 s (19.0 s). The
check follows one curve from rest; most of it is the first sample carrying the body's
weight (10 Newton steps). The 3 s target is not reached.

Where the refusal of chamber c1 at 2000 kPa goes after the mesh (cProfile of `fruit
simulate`, 2026-12-06 15:30 UTC, load average 3.3, commit de40eac): 6.0 s in all, of it
the model 0.75 s (its sparsity pattern 0.57 s), the chambers' compliance at rest for
the screen 0.90 s (PARDISO's analysis and first factorization), the curve's first
sample from rest 3.5 s (the weight and the first volume step together: 9 Newton steps
in 3 load steps of 1.4, 1.0 and 0.9 s, 2 factorizations and 133 CG iterations) and its
second sample 0.7 s, after which the curve levels off below 141 kPa. The first sample
from the linear response at rest (the weight's and the pressure's) instead took 17
Newton steps, 15 factorizations and 29.6 s: the 20 mm sag is far from linear. Below 3 s
the first run would need the weight carried in 2-3 Newton steps.

The check's samples are now kept in the output folder (`pressure-check.npz`,
`fruitcli/fem/sample_cache.py`): a later `fruit simulate` of the same body (the same
mesh, element, material, weight, supports, jigs and chambers; any pressures) takes a
kept sample as it is when it is still an equilibrium by Newton's own test, as Newton's
start otherwise, and refuses or passes the same pressures
(`python tests/performance/bench_refusal.py --again`, 15:39-15:41 UTC, load average
1.5-1.9, commit bc338da; the code before, commit de40eac, the same minutes):

| default Fruit, c1 at | before | first run | again, same folder |
|---|---|---|---|
| 2000 kPa: s after the mesh | 5.7 | 6.1 | 2.8 |
| -500 kPa: s after the mesh | 9.3 | 9.4 | 1.6 |

The second run at 2000 kPa took one Newton step from its second sample (kept at a
relative residual of 2e-3 of its own forces: the first run's Newton had measured it
against the larger elastic force of its start) and keeps the result: a third run
took both samples as they are, 1.6 s after the mesh (15:41 UTC, load average 2.2).
"""


def performance_page(result: dict, source: str) -> str:
    load0 = ", ".join(f"{v:.2f}" for v in result["load_average_before"])
    load1 = ", ".join(f"{v:.2f}" for v in result.get("load_average_after", []))
    lines = [
        "# Performance",
        "",
        f"Generated by `docs/generate.py` from `{source}`, the result file "
        "`make bench` writes (`tests/performance/run_all.py --json`). Every speed figure in "
        "this documentation is here; run `make bench` on your machine and `make docs` "
        "to see yours. Each line is printed as a benchmark printed it, with every "
        "number replaced by its median over the runs; the table under it gives the "
        "numbers that differed between runs (min / median / max).",
        "",
        "| | |",
        "|---|---|",
        f"| date | {result['date']} |",
        f"| commit | `{result['commit']}` |",
        f"| cores | {result['cores']} |",
        f"| processor | {escape(result['processor'])} |",
        f"| Python | {result.get('python', '')} |",
        f"| runs of each benchmark | {result['runs']} |",
        f"| load average before (1, 5, 15 min) | {load0} |",
        f"| load average after | {load1} |",
        "",
    ]
    lines += SOLVER_STEPS.strip().splitlines() + [""]
    lines += STATE_STEPS.strip().splitlines() + [""]
    lines += FIRST_STATE_STEPS.strip().splitlines() + [""]
    lines += THREADS_STEPS.strip().splitlines() + [""]
    lines += LIMITS_STEPS.strip().splitlines() + [""]
    if "sample" in source:
        lines += [
            "This is the small sample shipped with the sources (two benchmarks, "
            "`python tests/performance/run_all.py --only bench_evaluate,bench_muca_formats "
            "--runs 2 --json docs/bench-sample.json`); `make bench` runs them all.",
            "",
        ]
    for script in result["scripts"]:
        wall = script["wall_s"]
        lines += [
            f"## {script['name']}",
            "",
            f"`python tests/performance/{script['name']}.py`: wall time "
            f"{_fmt(wall['median'])} s "
            f"(min {_fmt(wall['min'])}, max {_fmt(wall['max'])}); exit codes "
            f"{', '.join(map(str, script['exit_codes']))}.",
            "",
            "```text",
        ]
        varying = []
        for fig in script["figures"]:
            medians = [_fmt(n["median"]) for n in fig["numbers"]]
            count = fig["line"].count("{}")
            medians += ["?"] * (count - len(medians))
            text = fig["line"].replace("{{", "\0").replace("}}", "\1")
            text = text.format(*medians[:count]).replace("\0", "{").replace("\1", "}")
            lines.append(text)
            for k, n in enumerate(fig["numbers"]):
                if n["min"] != n["max"]:
                    varying.append((fig["line"], k, n))
        lines += ["```", ""]
        if varying:
            lines += ["| line | number | min | median | max |", "|---|---|---|---|---|"]
            for line, k, n in varying:
                excerpt = line.strip().replace("{}", "#").replace("{{", "{").replace("}}", "}")
                lines.append(
                    f"| {escape(' '.join(excerpt.split())[:70])} | {k + 1} | "
                    f"{_fmt(n['min'])} | "
                    f"{_fmt(n['median'])} | {_fmt(n['max'])} |"
                )
            lines.append("")
    return "\n".join(lines)


SOLVERS = DOCS / "data" / "linear-solvers.json"


def solvers_section(info: dict) -> str:
    """The performance page's section on the optional extra `pardiso`: `fruit simulate`
    with and without MKL PARDISO (`tests/performance/bench_linear_solver.py --docs`)."""
    load0 = ", ".join(f"{v:.2f}" for v in info["load_average_before"])
    load1 = ", ".join(f"{v:.2f}" for v in info["load_average_after"])
    lines = [
        "## With and without PARDISO",
        "",
        "MKL PARDISO factorizes the FEM's tangent when the optional extra is installed "
        "(`pip install 'fruit-touch[pardiso]'`; Linux and Windows: MKL has no macOS wheels); "
        "the default install uses SciPy's SuperLU in symmetric mode (and cholespy's "
        "Cholesky for the paper's linear elements). "
        f"`fruit simulate {info['scene']}` on the same mesh and taxels, each path once:",
        "",
        "| linear solver | wall s | states' solves s | states | Newton iterations | "
        "largest node difference from the first row (mm) |",
        "|---|---|---|---|---|---|",
    ]
    for r in info["rows"]:
        lines.append(
            f"| {escape(r['what'])} | {r['wall_s']:.0f} | {r['solve_s']:.0f} | {r['states']} | "
            f"{r['newton_iterations']} | {r['max_node_difference_mm']:.1g} |"
        )
    if info.get("refusals"):
        lines += [
            "",
            "The hard cases: the default Fruit with chamber c1 at -500 kPa (past its "
            "collapse) and at 2000 kPa (past its limit), refused by the limits check "
            "(`tests/performance/bench_refusal.py`):",
            "",
            "| linear solver | c1 | s from the mesh to the refusal | exit code | "
            "the same refusal line as the first path's |",
            "|---|---|---|---|---|",
        ]
        for r in info["refusals"]:
            after = "–" if r["after_mesh_s"] is None else f"{r['after_mesh_s']:.0f}"
            lines.append(
                f"| {escape(r['what'])} | {r['c1_kpa']:g} kPa | {after} | {r['exit_code']} | "
                f"{'yes' if r['same_line'] else 'no'} |"
            )
    command = (
        "bench_linear_solver.py --refusals --docs"
        if info.get("refusals")
        else ("bench_linear_solver.py --docs")
    )
    lines += [
        "",
        f"`python tests/performance/{command}` on {info['machine']} "
        f"(shared with other work: load average {load0} before, {load1} after), "
        f"{info['date']}, commit `{info['commit'][:12]}`.",
        "",
    ]
    return "\n".join(lines)


LIMITS = DOCS / "data" / "fruit-limits"


def limits_page(info: dict) -> str:
    """The table of the default Fruit's limits and how far the breathing is from them."""
    rows = [
        "| chamber | limit pressure | volume growth there | collapse (suction) | "
        "breathing's largest pressure |",
        "|---|---|---|---|---|",
    ]
    for name, ch in info["chambers"].items():
        lim, col = ch["limit_pressure_kpa"], ch["collapse_pressure_kpa"]
        top = info["breathing_max_kpa"].get(name, 0.0)
        share = "" if lim is None else f" ({100 * top / lim:.0f} % of the limit)"
        rows.append(
            f"| {name} | {'none reached' if lim is None else f'{lim:.1f} kPa'} | "
            + (
                "–"
                if lim is None
                else f"{ch['limit_volume_growth_mm3']:.0f} mm³ "
                f"({ch['limit_volume_growth_mm3'] / ch['rest_volume_mm3'] + 1:.1f} V₀)"
            )
            + f" | {'none reached' if col is None else f'{col:.1f} kPa'} | {top:g} kPa{share} |"
        )
    together = info.get("together")
    if together:
        lim = together["limit_pressure_kpa"]
        ratios = ", ".join(f"{c} : {r:g}" for c, r in together["ratios"].items())
        if lim is None:
            found = f"not found ({together['inflation_end']})"
        else:
            found = f"{lim:.1f} kPa (each chamber)"
        rows.append(
            f"| together ({ratios}) | {found}"
            + " | – | – | "
            + f"{max(info['breathing_max_kpa'].values()):g} kPa |"
        )
    mesh = info["mesh"]
    rows.append("")
    rows.append(
        f"`fruit limits {info['scene']}` on {info['machine']}, {info['date']}, commit "
        f"`{info['commit'][:12]}`: {info['wall_seconds']:.0f} s in all "
        + (f"and {info['cpu_seconds']:.0f} s of CPU " if "cpu_seconds" in info else "")
        + (f"over {info['jobs']} worker processes " if "jobs" in info else "")
        + f"({info['seconds']:.0f} s after the mesh; {info['element']} element, "
        f"{mesh['elements']} tetrahedra)"
        + (
            f"; load average {info['load_average'][0]} before, {info['load_average'][1]} "
            "after (the machine shared)."
            if "load_average" in info
            else "."
        )
    )
    return "\n".join(rows)


def limits_figure(info: dict, csv_path: Path, png: Path) -> None:
    """fruit-limits.png: pressure against volume growth per chamber, the limits marked,
    the breathing's largest pressure as a line; date, commit and machine in the title."""
    import csv

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curves: dict[str, list[tuple[float, float]]] = {}
    with csv_path.open() as f:
        for row in csv.DictReader(f):
            curves.setdefault(row["chamber"], []).append(
                (float(row["volume_growth_mm3"]), float(row["pressure_kpa"]))
            )
    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    for name, pts in curves.items():
        g, p = zip(*sorted(pts), strict=True)
        together = name == "together"
        (line,) = ax.plot(
            g, p, ".--" if together else ".-", label="together" if together else f"chamber {name}"
        )
        ch = info["together"] if together else info["chambers"][name]
        if ch["limit_pressure_kpa"] is not None:
            ax.plot(
                ch["limit_volume_growth_mm3"],
                ch["limit_pressure_kpa"],
                "^",
                ms=9,
                color=line.get_color(),
            )
    top = max(info["breathing_max_kpa"].values())
    ax.axhline(top, color="0.3", lw=1, ls=":", label=f"breathing's largest pressure ({top:g} kPa)")
    ax.axhline(0.0, color="0.7", lw=0.8)
    ax.axvline(0.0, color="0.7", lw=0.8)
    ax.set_xlabel("chamber volume growth (mm³; together: the sum)")
    ax.set_ylabel("chamber pressure (kPa)")
    ax.set_title(
        f"Default Fruit, volume control (▲ limit pressure)\n{info['date'][:10]}, "
        f"commit {info['commit'][:8]}, {info['machine']}",
        fontsize=9,
    )
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


STABILITY = DOCS / "data" / "stability-realistic.json"


def stability_page(info: dict) -> str:
    """The stability study's realistic rows: case, outcome, time."""
    rows = ["| body | case | outcome | s |", "|---|---|---|---|"]
    for r in info["rows"]:
        body = r["group"].split(",")[0]
        case = r["case"].rsplit(" (", 1)[0]
        status = r["status"].removeprefix("failed: ")
        if r["status"] == "converged" and r["note"]:
            status = f"converged: {r['note']}"
        rows.append(f"| {body} | {case} | {escape(status)} | {r['seconds']:.0f} |")
    rows.append("")
    rows.append(
        f"`python tests/performance/stability_realistic.py --jobs {info['jobs']}` on "
        f"{info['machine']}, {info['date']}, commit `{info['commit'][:12]}`: "
        f"{info['wall_seconds']:.0f} s in all."
    )
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Write docs/_generated/*.md from the code.")
    parser.add_argument(
        "--bench",
        type=Path,
        default=None,
        help=f"bench result (default: {BENCH.relative_to(ROOT)} if present, "
        f"else {BENCH_SAMPLE.relative_to(ROOT)})",
    )
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    bench = args.bench or (BENCH if BENCH.exists() else BENCH_SAMPLE)
    try:
        result = json.loads(bench.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        print(f"Error: {bench}: cannot read the bench result: {exc}", file=sys.stderr)
        return 1
    source = bench.relative_to(ROOT).as_posix() if bench.is_relative_to(ROOT) else str(bench)
    OUT.mkdir(exist_ok=True)
    pages = {
        "cli.md": cli_page(),
        "scene-keys.md": scene_page(),
        "performance.md": performance_page(result, source),
    }
    if SOLVERS.exists():
        try:
            solvers = json.loads(SOLVERS.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            print(
                f"Error: {SOLVERS}: cannot read the linear solvers' figures: {exc}", file=sys.stderr
            )
            return 1
        pages["performance.md"] = (
            pages["performance.md"].rstrip() + "\n\n" + solvers_section(solvers)
        )
    try:
        limits = json.loads(LIMITS.with_suffix(".json").read_text())
    except (OSError, json.JSONDecodeError) as exc:
        print(f"Error: {LIMITS}.json: cannot read the limits: {exc}", file=sys.stderr)
        return 1
    pages["fruit-limits.md"] = limits_page(limits)
    try:
        stability = json.loads(STABILITY.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        print(f"Error: {STABILITY}: cannot read the stability rows: {exc}", file=sys.stderr)
        return 1
    pages["stability-realistic.md"] = stability_page(stability)
    limits_figure(limits, LIMITS.with_suffix(".csv"), OUT / "fruit-limits.png")
    from fruitcli.fsutil import write_text

    for name, text in pages.items():
        write_text(OUT / name, text.rstrip() + "\n")
    print(f"wrote {', '.join(pages)} into {OUT.relative_to(ROOT)}/")
    sys.path.insert(0, str(DOCS))
    from gallery import main as gallery  # the gallery's pictures, from a demo's outputs

    return gallery([])


if __name__ == "__main__":
    sys.exit(main())
