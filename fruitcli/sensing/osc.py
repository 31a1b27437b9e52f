"""OSC 1.0 encoding of messages and bundles (int32 ``i``, float32 ``f``, float64 ``d``,
string ``s``), for the live loop's hot path.

python-osc's builders re-parse every message they build; with 10 touches (44 messages
per frame) they took 4.5 ms per frame on this machine, over the 1 ms budget from board
line to bundle. Here a `Template` encodes its address, type tags and leading strings
once, and packs the numbers with one precompiled `struct.Struct`. The tests decode the
output with python-osc, an independent implementation.
"""

from __future__ import annotations

import struct

BUNDLE_HEAD = b"#bundle\x00" + (1).to_bytes(8, "big")  # time tag 1: "immediately"


def osc_string(text: str) -> bytes:
    """ASCII, NUL-terminated, padded with NULs to a multiple of 4 bytes."""
    raw = text.encode("ascii")
    return raw + b"\x00" * (4 - len(raw) % 4)


class Template:
    """Messages to `address` whose arguments are the fixed `strings`, then numbers of
    the type letters `tags` (i, f, d)."""

    def __init__(self, address: str, strings: tuple[str, ...] = (), tags: str = ""):
        self.prefix = (osc_string(address) + osc_string("," + "s" * len(strings) + tags)
                       + b"".join(osc_string(s) for s in strings))
        self._struct = struct.Struct(">" + tags)

    def pack(self, *numbers) -> bytes:
        return self.prefix + self._struct.pack(*numbers)


def bundle(messages: list[bytes]) -> bytes:
    """An OSC bundle (time tag immediately) of encoded messages."""
    out = [BUNDLE_HEAD]
    for m in messages:
        out.append(len(m).to_bytes(4, "big"))
        out.append(m)
    return b"".join(out)
