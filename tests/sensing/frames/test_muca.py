"""The stock MuCa firmware's ASCII and binary formats: exact round trips, packet-boundary
recovery, the trailing comma, shifted lines, and both formats over real pseudo-terminals."""

import numpy as np
import pytest
from click.testing import CliRunner

from fruitcli.cli.main import cli
from fruitcli.errors import FrameError
from fruitcli.sensing.frames.muca import (
    AsciiDecoder,
    BinaryDecoder,
    decode_bytes,
    encode_packet,
    format_ascii_line,
    packet_counts,
)
from fruitcli.sensing.frames.muca_line import parse_line
from fruitcli.sensing.frames.recording import read_muca_log, read_recording
from fruitcli.sensing.live.board_emulator import (
    BANNER,
    BoardEmulator,
    pacing_line,
    synthetic_frames,
)

START = b"".join(line.encode() + b"\r\n" for line in BANNER)


def board_frames(n, seed=0, rows=21, cols=12, spread=30.0, noise=2.0):
    """A board's frames: per-cell baselines 500 +- spread, Gaussian noise, one touch of up
    to 120 counts moving over the middle third."""
    rng = np.random.default_rng(seed)
    base = 500 + rng.uniform(-spread, spread, (rows, cols))
    f = base + rng.normal(0, noise, (n, rows, cols))
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    for k in range(n // 3, 2 * n // 3):
        r0, c0 = 3 + (k % 10), 2 + (k % 7)
        f[k] += 120 * np.exp(-((r - r0) ** 2 + (c - c0) ** 2) / 2.0)
    return np.round(f).astype(np.int64)


def binary_stream(frames, damage=None):
    """START + packets; `damage` maps frame index -> (kind, byte position in the packet)."""
    out = bytearray(START)
    for k, f in enumerate(frames):
        p = encode_packet(f)
        kind, at = (damage or {}).get(k, (None, 0))
        if kind == "lose":
            p = p[:at] + p[at + 1 :]
        elif kind == "extra":
            p = p[:at] + b"\x07" + p[at:]
        elif kind == "reset":
            p = p[:at] + START
        out += p
    return bytes(out)


def test_binary_packet_layout_is_the_firmwares():
    f = np.full((21, 12), 700)
    f[3, 4] = 650
    f[0, 0] = 900
    p = encode_packet(f)
    assert len(p) == 254 and p[:2] == bytes([650 >> 8, 650 & 0xFF])  # big-endian minimum
    assert p[2] == 250 and p[2 + 3 * 12 + 4] == 0 and p[3] == 50  # count - minimum, Tx-major
    assert np.array_equal(packet_counts(p), f.ravel())
    f[5, 5] = 1000  # spread above 255 wraps, as in the firmware
    assert packet_counts(encode_packet(f))[5 * 12 + 5] == 650 + (350 & 0xFF)


@pytest.mark.parametrize("rows, cols", [(21, 12), (17, 10), (4, 4)])
def test_binary_round_trip_exact_with_start_up_lines(rows, cols):
    frames = board_frames(40, rows=rows, cols=cols)
    got, dec = decode_bytes(binary_stream(frames), "binary", rows, cols)
    assert np.array_equal(got, frames)
    assert dec.skipped == 0 and dec.syncs == 1 and dec.skipped_bytes == len(START)


def assert_only_whole_frames(got, frames, damage):
    """`got` is `frames` in order without the damaged ones and, for damage in a header
    byte, possibly without the frame before (an extra byte before the header byte 0 is
    one after the previous packet: that one is lost instead): never a wrong frame."""
    may_lose = {k - 1 for k, (_, at) in damage.items() if at < 2}
    idx = [next(j for j in range(len(frames)) if np.array_equal(frames[j], g)) for g in got]
    assert idx == sorted(idx)
    missing = set(range(len(frames))) - set(idx)
    assert missing <= set(damage) | may_lose, (missing, damage)
    assert all(k in missing or k - 1 in missing for k in damage), (missing, damage)
    return missing


@pytest.mark.parametrize("kind", ["lose", "extra"])
@pytest.mark.parametrize("at", [2, 3, 100, 253])
def test_a_lost_or_extra_data_byte_costs_exactly_its_frame(kind, at):
    frames = board_frames(30, seed=1)
    got, dec = decode_bytes(binary_stream(frames, {12: (kind, at)}), "binary", 21, 12)
    assert np.array_equal(got, np.delete(frames, 12, axis=0))
    assert dec.syncs == 2 and dec.skipped == 1


@pytest.mark.parametrize("kind", ["lose", "extra"])
@pytest.mark.parametrize("at", [0, 1])
def test_a_lost_or_extra_header_byte_costs_at_most_two_frames(kind, at):
    frames = board_frames(30, seed=1)
    got, _ = decode_bytes(binary_stream(frames, {12: (kind, at)}), "binary", 21, 12)
    assert_only_whole_frames(got, frames, {12: (kind, at)})


@pytest.mark.parametrize("spread, noise", [(30.0, 2.0), (0.0, 1.0)])
def test_many_random_lost_and_extra_bytes(spread, noise):
    """Damage every 12th frame at a random byte (flat boards too, where a one-cell shift
    would look almost right): every frame that comes out is exact, and only the damaged
    frames (and the one before a damaged header) are missing. (Damage within the
    SYNC_PACKETS = 8 packets after a synchronization costs those packets: not tested here.)"""
    frames = board_frames(400, seed=2, spread=spread, noise=noise)
    rng = np.random.default_rng(3)
    damage = {k: (("lose", "extra")[k % 2], int(rng.integers(0, 254))) for k in range(10, 400, 12)}
    got, _ = decode_bytes(binary_stream(frames, damage), "binary", 21, 12)
    assert_only_whole_frames(got, frames, damage)


def test_a_reset_mid_packet_costs_the_cut_frame():
    frames = board_frames(30, seed=4)
    got, dec = decode_bytes(binary_stream(frames, {12: ("reset", 90)}), "binary", 21, 12)
    assert np.array_equal(got, np.delete(frames, 12, axis=0))
    assert "1 resynchronization" in dec.skip_reasons()


def test_binary_stream_fed_in_small_chunks_equals_one_feed():
    frames = board_frames(25, seed=5)
    data = binary_stream(frames, {9: ("lose", 40)})
    dec = BinaryDecoder(21, 12)
    out = []
    for k in range(0, len(data), 37):
        out += dec.feed(data[k : k + 37])
    out += dec.finish()
    assert np.array_equal(np.stack(out), np.delete(frames, 9, axis=0))


def test_ascii_trailing_comma_reads_the_right_cells():
    counts = np.arange(252) + 100
    line = format_ascii_line(counts, trailing_comma=True).decode().rstrip()
    assert len(line.split(",")) == 253
    got, t, why = parse_line(line, 252)
    assert t is None and np.array_equal(got, counts), why
    got, t, _ = parse_line("12.5," + line, 252)  # host timestamp + trailing comma
    assert t == 12.5 and np.array_equal(got, counts)


def test_one_field_too_many_without_a_timestamp_is_refused(tmp_path):
    line = ",".join(str(v) for v in range(253))
    counts, _, why = parse_line(line, 252)
    assert counts is None and why.startswith("shifted") and "'0'" in why
    (tmp_path / "a.log").write_text("[Muca] Set TEST mode\n" + line + "\n")
    with pytest.raises(
        FrameError,
        match=r"a\.log: line 2: 253 fields, one more than the 252 "
        r"counts, and the first \('0'\) is not a host "
        r"timestamp .*refusing shifted counts",
    ):
        read_muca_log(tmp_path / "a.log")
    dec = AsciiDecoder(21, 12)
    assert dec.feed((line + "\r\n").encode()) == [] and dec.shifted == 1
    assert "1 of 253 fields without a host timestamp" in dec.skip_reasons()


def test_timestamps_that_go_backwards_are_not_a_timestamp_column(tmp_path):
    body = ",".join(["500"] * 252)
    (tmp_path / "a.log").write_text(f"1.5,{body}\n2.5,{body}\n0.5,{body}\n")
    with pytest.raises(
        FrameError,
        match=r"line 3: host timestamp 0\.5 is earlier than line "
        r"2's 2\.5: the first column is not a timestamp",
    ):
        read_muca_log(tmp_path / "a.log")


def test_auto_detects_each_format_and_says_when_neither_fits(tmp_path):
    frames = board_frames(12, seed=6)
    ascii_bytes = START + b"".join(format_ascii_line(f) for f in frames)
    for data, fmt in ((ascii_bytes, "ascii"), (binary_stream(frames), "binary")):
        got, dec = decode_bytes(data, "auto", 21, 12)
        assert dec.format == fmt and np.array_equal(got, frames)
    (tmp_path / "c.bin").write_bytes(binary_stream(frames))
    rec = read_recording(tmp_path / "c.bin")
    assert np.array_equal(rec.frames, frames) and rec.meta["format"] == "binary"
    (tmp_path / "c.raw").write_bytes(ascii_bytes)
    assert np.array_equal(read_recording(tmp_path / "c.raw").frames, frames)
    (tmp_path / "junk.bin").write_bytes(START + bytes(range(1, 256)) * 10)
    with pytest.raises(
        FrameError,
        match=r"junk\.bin: no 21 x 12 frame in the board's auto "
        r"format \(neither format found in \d+ bytes: ASCII: "
        r".*binary: no run of 8 agreeing packets of 254",
    ):
        read_recording(tmp_path / "junk.bin")
    with pytest.raises(FrameError, match=r"c\.bin: no 17 x 12 frame"):  # skipLine'd wrongly
        read_recording(tmp_path / "c.bin", rows=17, cols=12, fmt="binary")


def invoke(args):
    return CliRunner().invoke(cli, args)


def play(tmp_path, frames, args=(), **kw):
    em = BoardEmulator(frames, fps=0, wait_for_reader=True, **kw)
    th = em.start()
    out = tmp_path / "rec.npz"
    res = invoke(["record", "--port", em.path, "--out", str(out), *args])
    em.stop.set()
    th.join(5)
    return res, out


@pytest.mark.parametrize("fmt", ["binary", "ascii"])
def test_record_both_formats_over_a_pty_with_damage_and_a_reset(tmp_path, fmt):
    frames = board_frames(50, seed=7)
    damaged = [10, 34] if fmt == "ascii" else [10, 22, 34]
    kw = (
        {"cut_at": [10], "reset_at": [34], "trailing_comma": True}
        if fmt == "ascii"
        else {"lose_byte_at": [10], "extra_byte_at": [22], "reset_at": [34]}
    )
    res, out = play(tmp_path, frames, ["--frames", "40"], fmt=fmt, **kw)
    assert res.exit_code == 0, res.output
    rec = read_recording(out)
    assert np.array_equal(rec.frames, np.delete(frames, damaged, axis=0)[:40])
    assert rec.meta["format"] == fmt and f"40 {fmt} frames" in res.output


def test_record_binary_port_vanishing_keeps_the_whole_packets(tmp_path):
    frames = board_frames(20, seed=8)
    res, out = play(tmp_path, frames, fmt="binary", vanish_after=14)
    assert res.exit_code == 1 and "port closed after 14 frames" in res.output, res.output
    assert np.array_equal(read_recording(out).frames, frames[:14])


def test_record_a_board_in_neither_format_says_so_and_writes_nothing(tmp_path):
    frames = board_frames(10, seed=9)
    res, out = play(tmp_path, frames, ["--rows", "17", "--seconds", "1.5"], fmt="binary")
    assert res.exit_code == 1 and res.output.count("\n") == 1, res.output
    assert "no frame received" in res.output and "neither format found in" in res.output
    assert "no run of 8 agreeing packets of 206 bytes (2 + 17 x 12)" in res.output
    assert list(tmp_path.iterdir()) == []


def test_emulator_pacing_is_the_lines_byte_rate():
    assert pacing_line("binary", 115200) == (
        "115200 baud 8N1 = 11520 bytes/s: 254-byte binary packets, at most 45.4 frames/s"
    )
    frames = synthetic_frames(30)
    assert pacing_line("ascii", 115200, frames=frames) == (  # 3-digit counts
        "115200 baud 8N1 = 11520 bytes/s: 1,009-byte ASCII lines, at most 11.4 frames/s"
    )
    import time

    import serial

    em = BoardEmulator(frames, fps=0, wait_for_reader=True, fmt="binary", baud=115200)
    th = em.start()
    port = serial.Serial(em.path, 115200, timeout=0.2)
    t0 = time.monotonic()
    data = bytearray()
    while len(data) < len(START) + 30 * 254 and time.monotonic() - t0 < 10:
        data += port.read(max(1, port.in_waiting))  # as FrameReader reads
    dt = time.monotonic() - t0
    port.close()
    th.join(5)
    assert np.array_equal(decode_bytes(bytes(data), "binary", 21, 12)[0], frames)
    assert dt >= (len(data) - 2 * 254) / 11520  # never faster than the line carries


def test_live_and_locate_read_binary(tmp_path):
    from tests.sensing.live.test_serial import SCENE, live_lines, touch_frames
    from tests.sensing.skin.test_virtual_bench import pad_taxel_csv

    frames = touch_frames()
    frames = np.concatenate([frames, frames[-1:]])  # the last packet waits for a successor
    (tmp_path / "s.toml").write_text(SCENE + '[board]\nformat = "binary"\n')
    taxels = pad_taxel_csv(tmp_path / "t.csv")
    em = BoardEmulator(frames, fps=0, wait_for_reader=True, fmt="binary")
    th = em.start()
    res = invoke(
        [
            "live",
            str(tmp_path / "s.toml"),
            "--port",
            em.path,
            "--taxels",
            str(taxels),
            "--frames",
            "30",
        ]
    )
    th.join(5)
    assert res.exit_code == 0, res.output
    (tmp_path / "cap.bin").write_bytes(binary_stream(frames))
    res2 = invoke(
        [
            "locate",
            str(tmp_path / "cap.bin"),
            "--taxels",
            str(taxels),
            "--scene",
            str(tmp_path / "s.toml"),
            "--out",
            str(tmp_path / "loc"),
        ]
    )
    assert res2.exit_code == 0, res2.output
    from fruitcli.tables import read_table

    touched = read_table(tmp_path / "loc" / "touches.csv", ["frame"])["frame"]
    live_frames = [ln["frame"] for ln in live_lines(res.output) if ln["touches"]]
    assert sorted(set(touched.astype(int).tolist())) == live_frames == list(range(10, 20))


def test_decoders_report_each_frames_stream_offset():
    """The printer bench matches frames to moves by the offset of their first byte."""
    frames = board_frames(12, seed=10)
    lines = [format_ascii_line(f) for f in frames]
    data = START + b"".join(lines)
    dec = AsciiDecoder(21, 12)
    starts = []
    for k in range(0, len(data), 500):
        dec.feed(data[k : k + 500])
        starts += dec.starts
    assert starts == [len(START) + sum(map(len, lines[:k])) for k in range(12)]
    dec = BinaryDecoder(21, 12)
    data = binary_stream(board_frames(30, seed=10), {15: ("lose", 50)})
    starts = []
    for k in range(0, len(data), 300):
        dec.feed(data[k : k + 300])
        starts += dec.starts
    dec.finish()
    starts += dec.starts
    assert starts == [len(START) + 254 * k - (k > 15) for k in range(30) if k != 15]


def test_emulate_board_command_speaks_binary_and_says_its_pacing(tmp_path):
    import subprocess
    import sys

    proc = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "from fruitcli.cli.main import main; main()",
            "emulate-board",
            "--format",
            "binary",
            "--frames",
            "30",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        path = proc.stdout.readline().strip()
        res = invoke(
            [
                "record",
                "--port",
                path,
                "--out",
                str(tmp_path / "r.npz"),
                "--frames",
                "29",
                "--format",
                "binary",
            ]
        )
    finally:
        _, err = proc.communicate(timeout=20)
    assert res.exit_code == 0, res.output
    assert np.array_equal(read_recording(tmp_path / "r.npz").frames, synthetic_frames(30)[:29])
    assert (
        "30 21 x 12 frames, binary; pacing: 115200 baud 8N1 = 11520 bytes/s: 254-byte "
        "binary packets, at most 45.4 frames/s"
    ) in err
    assert "29 binary frames" in res.output and "frames/s" in res.output
