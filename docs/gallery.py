"""The gallery's pictures, drawn from a demo's outputs: the artist's mesh, the reduced body
with its tracks and taxels, the tet mesh with its chambers, the body held in its jig,
touches located on it, and Table I.

    python docs/gallery.py [--demo OUT] [--into DIR] [--hero PNG]

Without --demo the script first runs `fruit demo --scenes paper-table,fruit-rest,
fruit-deformed --out build/gallery/demo`, which reuses every stage whose inputs and code
are unchanged (a few seconds then, about a minute of CPU the first time); --demo OUT draws
from the outputs of an earlier `fruit demo` as they are. The pictures, and gallery.md
(what it cost, where it ran), go to DIR (default docs/_generated/, where docs/gallery.md
shows them); --hero also writes the touches picture, smaller, to PNG (the README's
picture). `make docs` runs it through docs/generate.py.
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
DEMO = ROOT / "build" / "gallery" / "demo"
SCENES = ("paper-table", "fruit-rest", "fruit-deformed")
NEEDS = (
    "fruit-deformed/make-tracks/reduced.stl",
    "fruit-deformed/tetra/mesh.npz",
    "fruit-deformed/simulate/states.npz",
    "fruit-deformed/evaluate/deformed-small/errors.csv",
    "fruit-rest/evaluate/summary.json",
    "paper-table/evaluate/summary.json",
)
VIEW = (60.0, -150.0)  # elevation, azimuth (degrees) of every perspective view
TRACK, TAXEL, TRUTH, MEASURED = "tab:orange", "black", "red", "blue"
FIGURE_DATA = "the paper's figure data, evaluated by fruit"


# ------------------------------------------------------------------------------ inputs
def run_demo(out: Path) -> float:
    """`fruit demo` of the scenes the pictures need, into `out`; the seconds it took."""
    import time

    print(f"gallery: fruit demo --scenes {','.join(SCENES)} --out {out}", flush=True)
    t0 = time.perf_counter()
    cmd = [sys.executable, "-c", "from fruitcli.cli.main import main; main()", "demo"]
    cmd += ["--scenes", ",".join(SCENES)]
    subprocess.run([*cmd, "--out", str(out)], check=True)
    return time.perf_counter() - t0


def missing(out: Path) -> list[str]:
    """The files the pictures read that `out` lacks."""
    return [p for p in NEEDS if not (out / p).is_file()]


def read_rows(path: Path) -> list[dict]:
    """Rows of a fruit CSV (comment lines start with #)."""
    with path.open() as f:
        return list(csv.DictReader(line for line in f if not line.startswith("#")))


def xyz(rows: list[dict], prefix: str = "") -> np.ndarray:
    """(n, 3) mm from the columns {prefix}x_mm, {prefix}y_mm, {prefix}z_mm."""
    return np.array([[float(r[f"{prefix}{a}_mm"]) for a in "xyz"] for r in rows]).reshape(-1, 3)


def tracks(path: Path) -> list[np.ndarray]:
    """Each track's centre line (n, 3) mm, in point order."""
    curves: dict[str, list] = {}
    for r in read_rows(path):
        curves.setdefault(r["track"], []).append((int(r["point"]), xyz([r])[0]))
    return [np.array([p for _, p in sorted(c, key=lambda t: t[0])]) for c in curves.values()]


def surface(path: Path) -> tuple[np.ndarray, np.ndarray]:
    from fruitcli.geometry.body_surface import body_surface

    return body_surface(path)


# ------------------------------------------------------------------------------ drawing
def stamp(fig, text: str) -> None:
    """Where and when the picture was drawn, small, bottom left."""
    fig.text(0.005, 0.005, text, fontsize=6, color="0.35", ha="left", va="bottom")


def project(points: np.ndarray) -> np.ndarray:
    from fruitcli.geometry.tracks.preview import view_matrix

    return np.asarray(points, float) @ view_matrix(*VIEW).T


def body(ax, v: np.ndarray, f: np.ndarray) -> None:
    """The shaded body, seen from VIEW, with no axes."""
    from fruitcli.geometry.tracks.preview import draw_perspective

    draw_perspective(ax, v, f, [], np.zeros((0, 3)), *VIEW)


def lines(ax, curves, label: str, **kw) -> None:
    """Curves (n, 3) seen from VIEW; one legend entry."""
    for k, c in enumerate(curves):
        q = project(c)
        ax.plot(q[:, 0], q[:, 1], **kw, label=label if k == 0 else None)


def new_figure(size=(8.0, 5.6)):
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, dpi=100)
    return fig, fig.add_axes((0.01, 0.04, 0.98, 0.88))


def save(fig, path: Path, dpi: float = 100) -> None:
    from fruitcli.fsutil import atomic_path

    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")


# ------------------------------------------------------------------------------ pictures
def artist_picture(path: Path, artist: Path, note: str) -> None:
    v, f = surface(artist)
    fig, ax = new_figure()
    body(ax, v, f)
    size = f"{np.ptp(v[:, 0]):.0f} × {np.ptp(v[:, 1]):.0f} × {np.ptp(v[:, 2]):.0f} mm"
    ax.set_title(f"The artist's mesh: {len(f):,} triangles, {size} (x × y × z)")
    stamp(fig, note)
    save(fig, path)


def tracks_picture(path: Path, run: Path, note: str) -> None:
    tr = run / "make-tracks"
    v, f = surface(tr / "reduced.stl")
    taxels = xyz(read_rows(tr / "taxels.csv"))
    fig, ax = new_figure()
    body(ax, v, f)
    lines(ax, tracks(tr / "tracks.csv"), color=TRACK, lw=1.0, label="yarn track (centre line)")
    q = project(taxels)
    ax.scatter(q[:, 0], q[:, 1], s=14, color=TAXEL, zorder=3, label="taxel (a crossing)")
    ax.legend(loc="lower right", fontsize=9)
    ax.set_title(
        f"The reduced body ({len(f):,} triangles) with its yarn tracks and {len(taxels)} taxels"
    )
    stamp(fig, note)
    save(fig, path)


def mesh_picture(path: Path, run: Path, note: str) -> None:
    """The tet mesh's outer surface as see-through edges, the chambers' walls shaded."""
    from matplotlib.collections import LineCollection

    m = np.load(run / "tetra" / "mesh.npz")
    nodes, tris = m["nodes"], m["surface_tris"]
    q = project(nodes)
    edges = np.unique(np.sort(tris[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0)
    fig, ax = new_figure()
    ax.add_collection(LineCollection(q[edges][:, :, :2], colors="0.6", linewidths=0.35))
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_axis_off()
    colors = ["tab:blue", "tab:green", "tab:purple", "tab:red"]
    for k, name in enumerate(m["chamber_names"]):
        own = m["chamber_tris"][m["chamber_tri_owner"] == k]
        ax.triplot(q[:, 0], q[:, 1], own, color=colors[k % 4], lw=0.6)
        c = q[np.unique(own)].mean(axis=0)
        height = ax.transLimits.transform((c[0], c[1]))[1]  # label level with its chamber
        ax.annotate(
            f"chamber {name}",
            (c[0], c[1]),
            xytext=(0.86, height),
            textcoords="axes fraction",
            color=colors[k % 4],
            fontsize=10,
            va="center",
            arrowprops={"arrowstyle": "-", "color": colors[k % 4], "lw": 0.8},
        )
    sicn = float(m["sicn"].min())
    ax.set_title(
        f"The tet mesh: {len(m['tets']):,} tetrahedra, {len(nodes):,} corner nodes "
        f"(SICN min {sicn:.2f}),\nits surface's edges and the chambers' walls seen through it",
        fontsize=10,
    )
    stamp(fig, note)
    save(fig, path)


def deformed(run: Path) -> dict:
    """The reduced body, its tracks and taxels at rest and carried by the FEM's state 0."""
    from fruitcli.geometry.body_surface import carried_vertices

    s = np.load(run / "simulate" / "states.npz")
    rest, tets = s["rest_nodes"], s["tets"]
    now = rest + s["displacement_mm"][0]
    v, f = surface(run / "make-tracks" / "reduced.stl")
    curves = tracks(run / "make-tracks" / "tracks.csv")
    flat = carried_vertices(rest, tets, now, np.concatenate(curves))
    cut = np.cumsum([len(c) for c in curves])[:-1]
    return {
        "rest": v,
        "faces": f,
        "now": carried_vertices(rest, tets, now, v),
        "tracks": np.split(flat, cut),
        "taxels": s["taxels_mm"][0],
    }


def deformed_picture(path: Path, d: dict, note: str) -> None:
    """Top view: the body at rest (outline) and held in its jig, coloured by how far
    each point moved."""
    fig, ax = new_figure((8.0, 6.0))
    ax.set_position((0.09, 0.11, 0.8, 0.8))
    v, f, w = d["rest"], d["faces"], d["now"]
    up = np.cross(w[f[:, 1]] - w[f[:, 0]], w[f[:, 2]] - w[f[:, 0]])[:, 2] > 0
    ax.triplot(v[:, 0], v[:, 1], f[up], color="0.8", lw=0.3)
    moved = np.linalg.norm(w - v, axis=1)
    tpc = ax.tripcolor(w[:, 0], w[:, 1], f[up], moved, cmap="viridis", shading="gouraud")
    ax.plot([], [], color="0.8", lw=1.5, label="at rest (its triangles)")
    ax.legend(loc="lower left", fontsize=9)
    cb = fig.colorbar(tpc, ax=ax, shrink=0.8, pad=0.02)
    cb.set_label("distance moved (mm)")
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.grid(alpha=0.25)
    ax.set_title(f"Held in its jig: the tip turned 30°, up to {moved.max():.0f} mm (FEM, top view)")
    stamp(fig, note)
    save(fig, path)


def touches_picture(path: Path, d: dict, run: Path, note: str, dpi: float = 100) -> None:
    """The hero: the deformed body, its tracks and taxels, where the bench touched it and
    where fruit located each touch."""
    from matplotlib.collections import LineCollection

    rows = read_rows(run / "evaluate" / "deformed-small" / "errors.csv")
    truth, measured = xyz(rows, "truth_"), xyz(rows, "measured_")
    err = np.array([float(r["error_mm"]) for r in rows])
    fig, ax = new_figure((8.0, 5.0))
    ax.set_position((0.0, 0.08, 1.0, 0.8))
    body(ax, d["now"], d["faces"])
    lines(ax, d["tracks"], color=TRACK, lw=0.9, alpha=0.9, label="yarn track")
    q = project(d["taxels"])
    ax.scatter(q[:, 0], q[:, 1], s=9, color=TAXEL, zorder=3, label="taxel")
    t, m = project(truth), project(measured)
    segs = np.stack([t[:, :2], m[:, :2]], axis=1)
    ax.add_collection(LineCollection(segs, colors="black", linewidths=0.8, zorder=4))
    ax.scatter(t[:, 0], t[:, 1], marker="s", s=26, color=TRUTH, ec="white", lw=0.5, zorder=5)
    ax.scatter(m[:, 0], m[:, 1], marker="o", s=22, color=MEASURED, ec="white", lw=0.5, zorder=6)
    ax.scatter([], [], marker="s", color=TRUTH, label="where the indenter touched")
    ax.scatter([], [], marker="o", color=MEASURED, label="where fruit located the touch")
    fig.legend(loc="lower center", ncol=4, fontsize=8.5, frameon=False, bbox_to_anchor=(0.5, 0.03))
    ax.set_title(
        f"The Fruit held in its jig: {len(truth)} touches located on the deformed body\n"
        f"(mean distance {err.mean():.1f} mm between a touch and where it was located)",
        fontsize=10.5,
    )
    stamp(fig, note)
    save(fig, path, dpi)


def table_picture(path: Path, demo: Path, note: str) -> None:
    """Table I: mean ± std of the translation-registered error per row (the paper's
    protocol), each next to the paper's published value."""
    from fruitcli.workflow.report import PAPER_TABLE_I

    bars = []
    for scene in SCENES:
        summary = json.loads((demo / scene / "evaluate" / "summary.json").read_text())
        for row in summary.values():
            if not row.get("compare") or row["label"] not in PAPER_TABLE_I:
                continue
            st = row["compare"]["translation"]
            source = FIGURE_DATA if scene == "paper-table" else "fruit's virtual bench"
            bars.append((row["label"], source, st["mean_mm"], st["std_mm"]))
    labels = list(dict.fromkeys(b[0] for b in bars))
    fig, ax = new_figure((8.0, 4.6))
    ax.set_position((0.1, 0.12, 0.87, 0.76))
    width = 0.26
    for k, label in enumerate(labels):
        p = PAPER_TABLE_I[label]
        group = [("the paper's Table I", p[0], p[2])] + [
            (b[1], b[2], b[3]) for b in bars if b[0] == label
        ]
        for j, (source, mean, std) in enumerate(group):
            x = k + (j - (len(group) - 1) / 2) * width
            color = {"the paper's Table I": "0.6", FIGURE_DATA: "tab:olive"}.get(source, "tab:blue")
            ax.bar(x, mean, width * 0.92, yerr=std, capsize=3, color=color, label=source)
            ax.text(x, mean + std + 0.15, f"{mean:.1f}", ha="center", fontsize=8)
    handles, names = ax.get_legend_handles_labels()
    keep = dict(zip(names, handles, strict=True))
    ax.legend(keep.values(), keep.keys(), fontsize=8, loc="upper left", ncol=3)
    ax.set_xticks(range(len(labels)), labels)
    ax.set_ylabel("localization error (mm):\nmean, error bar ± std")
    ax.set_ylim(0, max(b[2] + b[3] for b in bars) + 2.5)
    ax.grid(axis="y", alpha=0.3)
    ax.set_title("Table I: the error of located touches (translation-registered)", fontsize=10.5)
    stamp(fig, note)
    save(fig, path)


# ------------------------------------------------------------------------------ main
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Draw the gallery from a demo's outputs.")
    parser.add_argument("--demo", type=Path, default=None, help="an earlier demo's folder")
    parser.add_argument("--into", type=Path, default=DOCS / "_generated", help="page folder")
    parser.add_argument("--hero", type=Path, default=None, help="also the README's picture")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    import time

    from fruitcli.fsutil import write_text
    from fruitcli.studies.machine import machine_line

    demo, seconds = args.demo or DEMO, None
    if args.demo is None:
        try:
            seconds = run_demo(demo)
        except subprocess.CalledProcessError as exc:
            print(
                f"Error: gallery: fruit demo into {demo} failed (exit code {exc.returncode})",
                file=sys.stderr,
            )
            return 1
    if lack := missing(demo):
        print(
            f"Error: gallery: {demo / lack[0]}: not there (give --demo a folder written by "
            f"fruit demo --scenes {','.join(SCENES)}, or leave --demo out)",
            file=sys.stderr,
        )
        return 1
    t0 = time.perf_counter()
    note = f"Drawn by docs/gallery.py. {machine_line()}"
    run = demo / "fruit-deformed"
    pics = args.into / "gallery"
    pics.mkdir(parents=True, exist_ok=True)
    artist = Path(json.loads((run / "make-tracks" / "report.json").read_text())["artist"])
    if not artist.is_file():
        print(f"Error: gallery: {artist}: the demo's artist mesh is not there", file=sys.stderr)
        return 1
    artist_picture(pics / "artist.png", artist, note)
    tracks_picture(pics / "tracks.png", run, note)
    mesh_picture(pics / "mesh.png", run, note)
    d = deformed(run)
    deformed_picture(pics / "deformed.png", d, note)
    touches_picture(pics / "touches.png", d, run, note)
    if args.hero:
        touches_picture(args.hero, d, run, note, dpi=90)
    table_picture(pics / "table-1.png", demo, note)
    drawn = time.perf_counter() - t0
    cost = f"the pictures took {drawn:.0f} s"
    if seconds is not None:
        cost = f"the demo's stages took {seconds:.0f} s (unchanged ones reused), {cost}"
    page = f"Drawn from `fruit demo` outputs: {cost}. {machine_line()}\n"
    write_text(args.into / "gallery.md", page)
    print(f"gallery: {cost}; wrote {pics.relative_to(ROOT) if pics.is_relative_to(ROOT) else pics}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
