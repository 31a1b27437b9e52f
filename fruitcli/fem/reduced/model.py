"""The reduced model: chamber pressures (kPa) -> taxel positions, node positions and
chamber volumes (mm, mm^3) without solving the FEM, from polynomial response surfaces
fitted to full solves (`fruitcli.fem.reduced.build`).

The taxels and the chamber volumes are fitted directly (the live loop's path: one
small matrix product per pressure vector). Every node follows through a POD of the
solved displacements: the displacement is a sum of a few modes whose amplitudes are
themselves response surfaces. File: reduced.npz (arrays only), which also holds the
build's held-out validation (`validation_*` arrays and the bound figures).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fruitcli.errors import FruitError, SolverError
from fruitcli.fem import io
from fruitcli.fem.reduced import response_surface
from fruitcli.tables import read_npz_arrays

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

TAXEL_BOUND_MM = 0.05
"""Largest taxel error (mm) against the full model at held-out pressures for the
reduced model to be within its bound (the bench printer is accurate to 0.1 mm)."""
VOLUME_BOUND_PCT = 1.0
"""Largest chamber-volume error (% of the full model's volume) at held-out pressures."""

RANGE_SLACK = 1e-9
"""Pressures this far (kPa) past the box still count as inside (round-off of a CSV)."""


@dataclass
class ReducedModel:
    """Response surfaces over the pressure box [lo, hi] (K,) kPa. `coef_taxels` (M, 3T),
    `coef_volume` (M, K), `coef_modes` (M, r) and `modes` (r, 3N) for the nodes' mm
    displacements; `arrays` keeps everything read from reduced.npz (mesh, validation)."""

    chamber_names: list[str]
    lo: np.ndarray
    hi: np.ndarray
    exps: np.ndarray
    coef_taxels: np.ndarray
    coef_volume: np.ndarray
    coef_modes: np.ndarray
    modes: np.ndarray
    rest_nodes: np.ndarray
    arrays: dict

    @property
    def degree(self) -> int:
        return int(self.exps.sum(axis=1).max())

    def __post_init__(self):
        # one vector's basis in Python floats (the live loop's path: a few us instead of
        # the array code's tens), through these precomputed constants
        k, d = self.exps.shape[1], self.degree
        self._flat = (self.exps + (d + 1) * np.arange(k)).ravel()
        self._a = (2.0 / (self.hi - self.lo)).tolist()
        self._b = ((self.lo + self.hi) / (self.hi - self.lo)).tolist()
        self._rec = [((2 * n + 1) / (n + 1), n / (n + 1)) for n in range(1, d)]

    def phi(self, pressure_kpa: ArrayLike) -> np.ndarray:
        """Basis at one pressure vector (K,) -> (M,), or at (n, K) -> (n, M)."""
        p = np.asarray(pressure_kpa, float)
        if p.ndim == 1 and self.degree >= 1:
            vals: list[float] = []
            for x, a, b in zip(p.tolist(), self._a, self._b, strict=True):
                x = x * a - b  # scaled to [-1, 1]
                l0, l1 = 1.0, x
                vals += (l0, l1)
                for c1, c2 in self._rec:  # Legendre's three-term recurrence
                    l0, l1 = l1, c1 * x * l1 - c2 * l0
                    vals.append(l1)
            return np.array(vals)[self._flat].reshape(-1, len(self._a)).prod(axis=1)
        return response_surface.basis(response_surface.scale(p, self.lo, self.hi), self.exps)

    def taxels(self, pressure_kpa: ArrayLike) -> np.ndarray:
        """Taxel positions (T, 3) mm at one pressure vector (K,), or (n, T, 3) at (n, K)."""
        y = self.phi(pressure_kpa) @ self.coef_taxels
        return y.reshape(*y.shape[:-1], -1, 3)

    def volumes(self, pressure_kpa: ArrayLike) -> np.ndarray:
        """Chamber volumes (K,) mm^3 at (K,) kPa, or (n, K) at (n, K)."""
        return self.phi(pressure_kpa) @ self.coef_volume

    def nodes(self, pressure_kpa: ArrayLike) -> np.ndarray:
        """Node positions (N, 3) mm at (K,) kPa, or (n, N, 3) at (n, K)."""
        amp = self.phi(pressure_kpa) @ self.coef_modes
        u = amp @ self.modes
        return self.rest_nodes + u.reshape(*u.shape[:-1], -1, 3)

    def surface_nodes(self, pressure_kpa: ArrayLike) -> np.ndarray:
        """Positions (S, 3) mm of the body's surface nodes (`surface_node_index`)."""
        return self.nodes(pressure_kpa)[..., self.arrays["surface_node_index"], :]

    def outside(self, pressure_kpa: ArrayLike) -> np.ndarray:
        """(n,) bool: the rows of (n, K) kPa that lie outside the box."""
        p = np.atleast_2d(np.asarray(pressure_kpa, float))
        return np.any((p < self.lo - RANGE_SLACK) | (p > self.hi + RANGE_SLACK), axis=1)

    def check_range(
        self,
        pressure_kpa: ArrayLike,
        where: str = "pressures",
        rows: Sequence[int] | np.ndarray | None = None,
    ) -> None:
        """SolverError naming the first row of (n, K) kPa outside the box; `rows` (n,)
        are the numbers to name (default 1..n)."""
        bad = np.flatnonzero(self.outside(pressure_kpa))
        if len(bad):
            i = int(bad[0])
            p = np.atleast_2d(np.asarray(pressure_kpa, float))[i]
            row = rows[i] if rows is not None else i + 1
            box = ", ".join(
                f"{n} {a:g}..{b:g}"
                for n, a, b in zip(self.chamber_names, self.lo, self.hi, strict=True)
            )
            raise SolverError(
                f"{where}: row {row}: pressures {np.round(p, 4).tolist()} kPa "
                f"outside the reduced model's range ({box} kPa; "
                f"{len(bad)} row(s) outside): use --model full, or widen "
                "[reduced].pressure_range_kpa"
            )

    def validation(self) -> dict:
        """The build's held-out figures: taxel error max/median (mm), volume error
        max/median (%), vectors, build seconds, and whether the bounds hold."""
        a = self.arrays
        tax, vol = a["validation_taxel_error_mm"], a["validation_volume_error_pct"]
        out = {
            "vectors": int(tax.shape[0]),
            "degree": self.degree,
            "taxel_max_mm": float(tax.max()),
            "taxel_median_mm": float(np.median(tax)),
            "volume_max_pct": float(vol.max()),
            "volume_median_pct": float(np.median(vol)),
            "surface_max_mm": float(a["validation_surface_error_mm"].max()),
            "build_s": float(a["build_s"]),
            "full_solves": int(a["full_solves"]),
        }
        out["within_bound"] = bool(
            out["taxel_max_mm"] <= TAXEL_BOUND_MM and out["volume_max_pct"] <= VOLUME_BOUND_PCT
        )
        return out

    def describe(self) -> str:
        """One line: degree, samples, held-out errors; a warning when past the bound."""
        v = self.validation()
        text = (
            f"reduced model: degree {v['degree']} over {len(self.arrays['sample_kpa'])} "
            f"samples, held-out at {v['vectors']} pressure vectors: taxels max "
            f"{v['taxel_max_mm']:.2g} mm (median {v['taxel_median_mm']:.2g}), volumes max "
            f"{v['volume_max_pct']:.2g} % (median {v['volume_median_pct']:.2g}), built in "
            f"{v['build_s']:.0f} s"
        )
        if not v["within_bound"]:
            text += (
                f"; WARNING: outside the bound ({TAXEL_BOUND_MM} mm, "
                f"{VOLUME_BOUND_PCT} %): use --model full or a denser "
                "[reduced].points_per_axis / narrower pressure_range_kpa"
            )
        return text

    def save(self, path: Path) -> None:
        io.save_npz(Path(path), self.arrays)

    @classmethod
    def from_arrays(cls, arrays: dict) -> ReducedModel:
        return cls(
            [str(n) for n in arrays["chamber_names"]],
            arrays["range_lo_kpa"],
            arrays["range_hi_kpa"],
            arrays["exponents"],
            arrays["coef_taxels"],
            arrays["coef_volume"],
            arrays["coef_modes"],
            arrays["modes"],
            arrays["rest_nodes"],
            arrays,
        )


REQUIRED = (
    "chamber_names",
    "range_lo_kpa",
    "range_hi_kpa",
    "exponents",
    "coef_taxels",
    "coef_volume",
    "coef_modes",
    "modes",
    "rest_nodes",
    "surface_node_index",
    "validation_taxel_error_mm",
    "validation_volume_error_pct",
    "validation_surface_error_mm",
    "sample_kpa",
    "build_s",
    "full_solves",
)


def load(path: str | Path) -> ReducedModel:
    """reduced.npz as a ReducedModel; one FruitError line naming a missing array."""
    path = Path(path)
    arrays = read_npz_arrays(
        path, "reduced model .npz", FruitError, " (run `fruit run SCENE --until reduce`)"
    )
    missing = [k for k in REQUIRED if k not in arrays]
    if missing:
        raise FruitError(f"{path}: not a reduced model: missing array(s) {', '.join(missing)}")
    return ReducedModel.from_arrays(arrays)


def states_arrays(reduced: ReducedModel, pressure_kpa: ArrayLike) -> dict:
    """states.npz arrays (as `fruitcli.fem.stage.run_simulate` writes them) of the
    reduced model at (S, K) kPa; `solve_ms` is the time per vector of the taxels, nodes
    and volumes together, and no Newton ran (iterations 0, residual and det F nan)."""
    import time

    p = np.atleast_2d(np.asarray(pressure_kpa, float))
    a, s = reduced.arrays, len(p)
    ms = np.empty(s)
    taxels, nodes, vols = [], [], []
    for i, row in enumerate(p):
        t0 = time.perf_counter()
        taxels.append(reduced.taxels(row))
        nodes.append(reduced.nodes(row))
        vols.append(reduced.volumes(row))
        ms[i] = 1e3 * (time.perf_counter() - t0)
    x = np.stack(nodes)
    return {
        "model": np.array("reduced"),
        "reduced_degree": np.array(reduced.degree),
        "rest_nodes": reduced.rest_nodes,
        "tets": a["tets"],
        "surface_tris": a["surface_tris"],
        "element": a["element"],
        "material_model": a["material_model"],
        "elements": a["elements"],
        "displacement_mm": x - reduced.rest_nodes,
        "pressure_kpa": p,
        "chamber_volume_mm3": np.stack(vols),
        "chamber_names": np.array(reduced.chamber_names, dtype=str).reshape(-1),
        "chamber_rest_volume_mm3": a["chamber_rest_volume_mm3"],
        "iterations": np.zeros(s, np.int64),
        "residual": np.full(s, np.nan),
        "solve_ms": ms,
        "subdivisions": np.zeros(s, np.int64),
        "min_det_f": np.full(s, np.nan),
        "taxel_tet": a["taxel_tet"],
        "taxel_bary": a["taxel_bary"],
        "taxel_outside": a["taxel_outside"],
        "taxels_mm": np.stack(taxels),
    }
