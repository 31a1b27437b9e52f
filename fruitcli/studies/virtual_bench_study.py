"""What the virtual bench's Table I rows depend on: the skin model's assumed parameters.

One parameter of the scene's [skin] table at a time is moved off its value (the others
kept), the bench is replayed with the same seed, located and evaluated; each case gives
the Table I row per indenter, unregistered and translation-registered (the paper's
protocol). Units: mm, counts.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Iterator

    from fruitcli.scene import SkinSection

FIELD_SIGMAS_MM = (4.0, 5.0, 6.0, 7.0, 8.0)
CONTACT_COUNTS = (30.0, 45.0, 60.0, 90.0, 120.0)
GAP_DECAYS_MM = (1.0, 1.5, 2.0, 3.0, 4.0)
NOISE_STDS = (0.5, 1.0, 2.0, 3.0)
GAIN_SPREADS = (0.0, 0.1, 0.2, 0.3)
PARAMETERS = ("footprint", "contact_counts", "gap_decay_mm", "noise_std_counts", "gain_spread")
UNITS = {
    "footprint": "field sigma (mm)",
    "contact_counts": "counts at contact",
    "gap_decay_mm": "gap decay (mm)",
    "noise_std_counts": "noise std (counts; default: per taxel in 0.5-1.85)",
    "gain_spread": "taxel gain spread (+-)",
}


@dataclass(frozen=True)
class Case:
    """One skin setting: the parameter moved, its value, and the [skin] keys it sets."""

    parameter: str  # one of PARAMETERS, "default" or "project"
    value: float
    skin: dict = field(default_factory=dict)
    detection: dict = field(default_factory=dict)

    @property
    def name(self) -> str:
        if self.parameter == "default":
            return "default"
        if self.parameter == "project":
            return "detection: project = surface"
        if self.parameter == "footprint":
            feet = ", ".join(f"{k} {v:.2f}" for k, v in self.skin["footprint_sigma_mm"].items())
            return f"footprint {feet} mm"
        return f"{self.parameter} {self.value:g}"


def cases(skin: SkinSection, indenters: list[str], surface: bool = False) -> list[Case]:
    """The default, then each parameter moved alone. The footprint of an indenter of
    radius r is hypot(field sigma, r), as in `fruitcli.sensing.skin.forward`. With the body's
    `surface`, also the default skin located with ``[detection].project = "surface"``.
    `skin`: the scene's [skin] (a `fruitcli.scene.SkinSection`)."""
    from fruitcli.sensing.skin import forward

    out = [Case("default", float("nan"))]
    for f in FIELD_SIGMAS_MM:
        if f == forward.FIELD_SIGMA_MM and not skin.footprint_sigma_mm:
            continue  # that is the default
        feet = {
            i: float(np.hypot(f, forward.INDENTER_RADIUS_MM[i]))
            for i in indenters
            if i in forward.INDENTER_RADIUS_MM
        }
        out.append(Case("footprint", f, {"footprint_sigma_mm": feet}))
    for key, values in (
        ("contact_counts", CONTACT_COUNTS),
        ("gap_decay_mm", GAP_DECAYS_MM),
        ("noise_std_counts", NOISE_STDS),
        ("gain_spread", GAIN_SPREADS),
    ):
        for v in values:
            if getattr(skin, key) != v:
                # drawn gains replace measured ones
                extra = {"taxel_gain": None} if key == "gain_spread" and skin.taxel_gain else {}
                out.append(Case(key, v, {key: v, **extra}))
    if surface:
        out.append(Case("project", float("nan"), detection={"project": "surface"}))
    return out


def run_case(args: tuple[Path, Path, Path, Path | None, Path | None, str, Case]) -> dict:
    """Bench, locate and evaluate one case; a row per indenter with the Table I figures."""
    from fruitcli.evaluation.report import evaluate_pair
    from fruitcli.scene import load_scene
    from fruitcli.sensing.stages import LocateFiles, locate_inputs, run_bench, run_locate

    scene_path, work, taxels, states, surface, unit, case = args
    scene = load_scene(scene_path).with_values(
        {f"skin.{k}": v for k, v in case.skin.items()}
        | {f"detection.{k}": v for k, v in case.detection.items()}
    )
    base = Path(work) / case.name.replace(" ", "_").replace(",", "")
    bench = run_bench(
        scene, taxels, states, base / "bench", surface_path=surface, surface_unit=unit
    )
    config = scene.scene.configuration
    rows = []
    for ind in scene.bench.indenters:
        frames = base / "bench" / ind / "frames.npz"
        run_locate(
            locate_inputs(scene), LocateFiles(frames, taxels, states, base / ind, surface, unit)
        )
        s, *_ = evaluate_pair(
            base / "bench" / ind / "truth.csv",
            base / ind / "measured.csv",
            scene.bench.reference_length_mm,
            f"{config}, {ind}",
        )
        c = s["compare"]
        rows.append(
            {
                "setting": case.name,
                "parameter": case.parameter,
                "value": case.value,
                "indenter": ind,
                "label": s["label"],
                "n": s["n"],
                "dropped": bench["indenters"][ind]["dropped"],
                "mean_mm": c["none"]["mean_mm"],
                "std_mm": c["none"]["std_mm"],
                "reg_mean_mm": c["translation"]["mean_mm"],
                "reg_std_mm": c["translation"]["std_mm"],
                "reg_ci95_mm": c["translation"]["ci95_mean_mm"],
                "bias_mm": c["none"]["bias_mm"],
            }
        )
    return {"case": case.name, "rows": rows}


HEADER = [
    "setting",
    "parameter",
    "value",
    "indenter",
    "n",
    "dropped",
    "mean_mm",
    "std_mm",
    "reg_mean_mm",
    "reg_std_mm",
    "reg_ci95_low_mm",
    "reg_ci95_high_mm",
]


def csv_rows(rows: list[dict]) -> Iterator[list]:
    for r in rows:
        yield [
            r["setting"],
            r["parameter"],
            "" if np.isnan(r["value"]) else r["value"],
            r["indenter"],
            r["n"],
            r["dropped"],
            *(round(r[k], 4) for k in ("mean_mm", "std_mm", "reg_mean_mm", "reg_std_mm")),
            round(r["reg_ci95_mm"][0], 4),
            round(r["reg_ci95_mm"][1], 4),
        ]


def table_markdown(rows: list[dict], scene_name: str, paper: dict) -> str:
    """bench.md: one line per setting and indenter, the paper's row at the end."""
    lines = [
        f"# What the bench's Table I rows depend on ({scene_name})",
        "",
        "Each setting moves one parameter of the skin's forward model ([skin], see "
        "README: The skin's forward model) off its default, with the same noise seed; "
        "avg. error / std in mm. Registered: translation, the paper's protocol.",
        "",
        "| setting | indenter | n | unregistered | registered | registered 95 % CI |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        lo, hi = r["reg_ci95_mm"]
        lines.append(
            f"| {r['setting']} | {r['indenter']} | {r['n']} | {r['mean_mm']:.2f} / "
            f"{r['std_mm']:.2f} | {r['reg_mean_mm']:.2f} / {r['reg_std_mm']:.2f} | "
            f"{lo:.2f}-{hi:.2f} |"
        )
    lines.append("")
    for label in dict.fromkeys(r["label"] for r in rows):
        if label in paper:
            p = paper[label]
            lines.append(f"The paper's Table I, {label}: {p[0]:.1f} / {p[2]:.1f} mm.")
    proj = [r for r in rows if r["parameter"] == "project"]
    for r in proj:
        base = next(
            b for b in rows if b["parameter"] == "default" and b["indenter"] == r["indenter"]
        )
        lines.append(
            f"Projected onto the surface ({r['indenter']}): unregistered "
            f"{base['mean_mm']:.2f} -> {r['mean_mm']:.2f} mm, registered "
            f"{base['reg_mean_mm']:.2f} -> {r['reg_mean_mm']:.2f} mm."
        )
    lines += ["", "Range of the registered mean over each parameter's settings:", ""]
    for par in PARAMETERS:
        for ind in dict.fromkeys(r["indenter"] for r in rows):
            vals = [
                r["reg_mean_mm"]
                for r in rows
                if r["indenter"] == ind and (r["parameter"] == par or r["parameter"] == "default")
            ]
            if len(vals) > 1:
                lines.append(f"- {par}, {ind}: {min(vals):.2f}-{max(vals):.2f} mm")
    return "\n".join(lines) + "\n"


def default_value(parameter: str, skin: SkinSection) -> float:
    """The default's x position in the plot."""
    from fruitcli.sensing.skin import forward

    if parameter == "footprint":
        return forward.FIELD_SIGMA_MM
    v = getattr(skin, parameter)
    if parameter == "noise_std_counts" and isinstance(v, list):
        return float(np.mean(v))  # a per-taxel range: drawn at its middle
    return float(v)


def plot(path: Path, rows: list[dict], skin: SkinSection, paper: dict) -> None:
    """bench.png: one panel per parameter, mean error against its value per indenter,
    registered (solid) and unregistered (dashed); the default as a ring, the paper's
    Table I value as a dotted line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fruitcli.fsutil import atomic_path

    indenters = list(dict.fromkeys(r["indenter"] for r in rows))
    colors = dict(zip(indenters, ["tab:blue", "tab:orange", "tab:green", "tab:red"], strict=False))
    fig, axes = plt.subplots(1, len(PARAMETERS), figsize=(17, 4.2), sharey=True)
    for ax, par in zip(axes, PARAMETERS, strict=True):
        x0 = default_value(par, skin)
        for ind in indenters:
            mine = [r for r in rows if r["indenter"] == ind and r["parameter"] == par]
            base = next(r for r in rows if r["indenter"] == ind and r["parameter"] == "default")
            pts = sorted([(r["value"], r) for r in mine] + [(x0, base)], key=lambda t: t[0])
            xs = [p[0] for p in pts]
            ax.plot(
                xs,
                [p[1]["reg_mean_mm"] for p in pts],
                "-o",
                color=colors[ind],
                ms=4,
                label=f"{ind}, registered",
            )
            ax.plot(
                xs,
                [p[1]["mean_mm"] for p in pts],
                "--",
                color=colors[ind],
                lw=1,
                label=f"{ind}, unregistered",
            )
            ax.plot([x0], [base["reg_mean_mm"]], "o", ms=10, mfc="none", color="black")
            label = base["label"]
            if label in paper:
                ax.axhline(paper[label][0], color=colors[ind], ls=":", lw=1)
        ax.set_xlabel(UNITS[par])
        ax.grid(True, color="0.85")
    axes[0].set_ylabel("mean localization error (mm)")
    axes[0].legend(fontsize=7, loc="upper right")
    fig.suptitle(
        "Bench error against the skin model's parameters (ring: default; dotted: "
        "the paper's Table I)",
        fontsize=10,
    )
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=100, format="png")
    plt.close(fig)
