"""Waiting for a board that went away (`fruit live --reconnect`): the port is reopened
as soon as it exists again (a USB cable plugged back in; udev gives it the same
/dev/serial/by-id/... name).

Units: s.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING

from fruitcli.errors import FrameError
from fruitcli.sensing.live.serial_ports import open_port

if TYPE_CHECKING:
    from serial import SerialBase

POLL_S = 0.2  # between attempts to reopen


def wait_for_port(
    port: str, baud: int, poll_s: float = POLL_S, on_wait: Callable[[str], object] | None = None
) -> SerialBase:
    """Open `port`, retrying every `poll_s` while it does not exist or is busy; ->
    the open port. `on_wait(message)` is called once with the first failure's reason."""
    told = False
    while True:
        try:
            return open_port(port, baud)
        except FrameError as exc:
            if not told and on_wait is not None:
                on_wait(str(exc))
                told = True
        time.sleep(poll_s)
