"""The how-to pages that extend a table (docs/howto/add-a-detection-method.md,
add-a-material-model.md), followed step by step on a copy of the package: the page's
module is written where the page says, its table line added to the table, and nothing
else edited. A fresh interpreter on the copy then checks that the scene schema, the
command line, the generated docs and the dispatch all see the new entry."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
HOWTO = ROOT / "docs" / "howto"
GENERATE = ROOT / "docs" / "generate.py"


def follow(page: str, table_file: str, table: str, dest: Path) -> Path:
    """A copy of fruitcli under `dest` with the page's new module (its first python
    block, written to the path the page names in bold after "Create") and its table line
    (in its second python block, the line after ``...,``) as the last entry of `table`
    in `table_file`."""
    text = (HOWTO / page).read_text()
    new_path = re.search(r"Create \*\*([\w/.]+)\*\*", text).group(1)
    module, table_block = re.findall(r"```python\n(.*?)```", text, re.S)[:2]
    line = table_block.split("        ...,\n", 1)[1].splitlines()[0]
    shutil.copytree(ROOT / "fruitcli", dest / "fruitcli", ignore=shutil.ignore_patterns("*.pyc"))
    assert not (dest / new_path).exists()
    (dest / new_path).write_text(module)
    path = dest / table_file
    source = path.read_text()
    end = source.index("\n    )\n}", source.index(f"{table}: dict"))
    path.write_text(source[:end] + "\n" + line + source[end:])
    return dest


def page_scene(page: str) -> str:
    """The scene TOML of the page's "Use it" step (a MyST code-block directive, so the
    docs' check of TOML examples against the unextended package skips it)."""
    return re.findall(r"```\{code-block\} toml\n(.*?)```", (HOWTO / page).read_text(), re.S)[0]


def run_on(copy: Path, code: str, scene: str) -> dict:
    """The JSON that `code` prints, run by a fresh interpreter importing fruitcli from
    `copy`, with `scene` (TOML text) as PAGE_SCENE."""
    head = (
        "import importlib.util, json, sys\n"
        f"PAGE_SCENE = {scene!r}\n"
        "import fruitcli\n"
        f"assert fruitcli.__file__.startswith({str(copy)!r}), fruitcli.__file__\n"
        f"spec = importlib.util.spec_from_file_location('gen', {str(GENERATE)!r})\n"
        "gen = importlib.util.module_from_spec(spec)\n"
        "spec.loader.exec_module(gen)\n"
    )
    env = {"PYTHONPATH": str(copy), "PATH": "/usr/bin:/bin", "MPLBACKEND": "Agg"}
    out = subprocess.run(
        [sys.executable, "-c", head + code], capture_output=True, text=True, env=env, cwd=copy
    )
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.splitlines()[-1])


DETECTION_CHECK = """
import click
import numpy as np
from fruitcli.cli.main import cli
from fruitcli.scene import SCHEMA, parse_scene
from fruitcli.sensing.detection.frames_to_touches import Locator, Stream
from fruitcli.sensing.detection.settings import Settings
from fruitcli.sensing.frames.board import default_board
from fruitcli.tables import Taxels
from pathlib import Path

option = {p.name: p for p in cli.get_command(click.Context(cli), "locate").params}["method"]
scene = parse_scene(PAGE_SCENE, Path("s.toml"), must_exist=False)
i, j = np.divmod(np.arange(30), 6)
taxels = Taxels(np.arange(30), i, j, np.stack([16.0 * j, 12.0 * i, 0.5 * i * j], axis=1))
frames = np.full((3, 21, 12), 500, np.int64)
frames[1, 2, 3] += 80  # the brightest taxel (2, 3), neighbours that would pull an N9
frames[1, 2, 4] += 60
frames[1, 3, 3] += 70
frames[2, 4, 1] += 30
base = np.full(30, 500.0)
found = {}
for name, extra in (("batch", {}), ("stream", {"hysteresis_counts": 1.0})):
    s = Settings(baseline_frames=1, method="brightest", **extra)
    loc = Locator(taxels, default_board(), taxels.xyz_mm, s)
    if name == "batch":
        t = loc.batch(frames, base)
    else:
        stream = Stream(loc, base)
        t = [stream.step(f, frame=k) for k, f in enumerate(frames)]
        t = type(t[0]).concat(t)
    found[name] = [t.frame.tolist(), t.i.tolist(), t.j.tolist(), t.xyz_mm.tolist(), t.peak.tolist()]
print(json.dumps({
    "schema": list(SCHEMA["detection"]["method"].choices),
    "cli": list(option.type.choices),
    "help": "brightest: one touch at the brightest taxel" in option.help,
    "docs": "`brightest`" in gen.scene_page(),
    "scene": scene.detection.method,
    "xyz": taxels.xyz_mm.tolist(),
    **found,
}))
"""


@pytest.mark.slow
def test_add_a_detection_method_as_the_page_says(tmp_path):
    copy = follow(
        "add-a-detection-method.md",
        "fruitcli/sensing/detection/methods.py",
        "METHODS",
        tmp_path,
    )
    seen = run_on(copy, DETECTION_CHECK, page_scene("add-a-detection-method.md"))
    assert seen["schema"][-1] == seen["cli"][-1] == "brightest"
    assert seen["schema"] == seen["cli"]
    assert seen["help"] and seen["docs"] and seen["scene"] == "brightest"
    # frame 1's touch sits on taxel (2, 3) itself (an N9 would be pulled towards its
    # neighbours); frame 2's peak (30 counts) is above the 20-count threshold
    taxel = 2 * 6 + 3
    for path in ("batch", "stream"):
        frame, i, j, xyz, peak = seen[path]
        assert frame == [1, 2], path
        assert (i, j, peak) == ([2.0, 4.0], [3.0, 1.0], [80.0, 30.0]), path
        assert xyz == [seen["xyz"][taxel], seen["xyz"][4 * 6 + 1]], path


MATERIAL_CHECK = """
from pathlib import Path
from fruitcli.errors import SceneError
from fruitcli.fem.materials.build import from_scene
from fruitcli.fem.materials.models import MATERIAL_MODELS
from fruitcli.scene import SCHEMA, parse_scene

m = from_scene(parse_scene(PAGE_SCENE, Path("s.toml"), must_exist=False).material)
try:
    parse_scene('[material]\\nmodel = "neo-hookean-c10"\\n', Path("s.toml"), must_exist=False)
    refused = ""
except SceneError as e:
    refused = str(e)
print(json.dumps({
    "schema": list(SCHEMA["material"]["model"].choices),
    "docs": "`neo-hookean-c10`" in gen.scene_page(),
    "constants": m.constants().tolist(),
    "e_nu": [m.young_modulus_kpa, m.poisson_ratio],
    "corotational": MATERIAL_MODELS[m.model].corotational,
    "refused": refused,
}))
"""


@pytest.mark.slow
def test_add_a_material_model_as_the_page_says(tmp_path):
    copy = follow(
        "add-a-material-model.md",
        "fruitcli/fem/materials/models.py",
        "MATERIAL_MODELS",
        tmp_path,
    )
    seen = run_on(copy, MATERIAL_CHECK, page_scene("add-a-material-model.md"))
    assert seen["schema"][-1] == "neo-hookean-c10" and seen["docs"]
    assert seen["constants"] == [17.0, 0.0, 0.0, 800.0]
    mu, kappa = 34.0, 800.0  # E and nu from mu and kappa, the isotropic closed forms
    e, nu = seen["e_nu"]
    assert e == pytest.approx(9 * kappa * mu / (3 * kappa + mu), rel=1e-12)
    assert nu == pytest.approx((3 * kappa - 2 * mu) / (2 * (3 * kappa + mu)), rel=1e-12)
    assert seen["corotational"] is False
    assert "[material]" in seen["refused"] and "c10_kpa" in seen["refused"]
