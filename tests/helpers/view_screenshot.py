"""The README's screenshot of `fruit live --view`, made as the browser test does (headless
Chromium over the DevTools pipe), on the default Fruit breathing (its taxels follow the
FEM states at the pressures a pty sends) with two touches held on the emulated board:

    python tests/helpers/view_screenshot.py data/figures/live-view.png
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import threading
import time
import tty
from pathlib import Path

import numpy as np

from tests.sensing.outputs.test_live_view import Chromium, free_port

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # as a script
from fruitcli.scene import load_scene
from fruitcli.sensing.live.board_emulator import BoardEmulator
from fruitcli.tables import read_taxels
from fruitcli.workflow.scene_outputs import scene_products

SCENE = "pipelines/fruit-breathing.toml"


def pressure_pty(line: str, stop: threading.Event) -> str:
    master, slave = os.openpty()
    tty.setraw(slave)

    def run():
        while not stop.is_set():
            try:
                os.write(master, (line + "\r\n").encode())
            except OSError:
                return
            time.sleep(0.05)

    threading.Thread(target=run, daemon=True).start()
    return os.ttyname(slave)


def main(out: str) -> None:
    taxels_csv, states = scene_products(load_scene(SCENE))
    tx = read_taxels(taxels_csv)
    rng = np.random.default_rng(2)
    f = 500 + rng.normal(0, 0.8, (6000, 21, 12))
    r, c = np.meshgrid(np.arange(21), np.arange(12), indexing="ij")
    order = np.lexsort((tx.j, tx.i))
    for k, counts in ((order[len(order) // 4], 55.0), (order[3 * len(order) // 4], 38.0)):
        f[20:] += counts * np.exp(
            -((r - tx.i[k] - 0.3) ** 2 + (c - tx.j[k] + 0.2) ** 2) / (2 * 0.8**2)
        )
    em = BoardEmulator(np.round(f).astype(np.int64), fps=30, wait_for_reader=True)
    th = em.start()
    stop = threading.Event()
    ppty = pressure_pty("P c1=6.0 c2=3.5 c3=9.0", stop)
    port = free_port()
    live = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "from fruitcli.cli.main import main; main()",
            "live",
            SCENE,
            "--port",
            em.path,
            "--taxels",
            str(taxels_csv),
            "--states",
            str(states),
            "--pressure-port",
            ppty,
            "--view",
            f"127.0.0.1:{port}",
        ],
        stdout=subprocess.DEVNULL,
    )
    with tempfile.TemporaryDirectory() as profile:
        browser = Chromium(profile)
        try:
            time.sleep(3)
            browser.open(f"http://127.0.0.1:{port}/")
            browser.wait_for("document.querySelectorAll('#markers .touch').length == 2")
            browser.wait_for("document.getElementById('pressures').rows.length == 3")
            time.sleep(1.0)
            Path(out).write_bytes(browser.screenshot())
        finally:
            browser.close()
            live.send_signal(2)
            live.wait(10)
            stop.set()
            em.stop.set()
            th.join(5)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "data/figures/live-view.png")
