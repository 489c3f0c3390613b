"""``rotorbench decode``: JSON lines for each protocol, stats line, bad files -> exit 2."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bench.cli import main

T = Path(__file__).resolve().parents[2] / "fixtures" / "transcripts"


def _run(capsys, *argv: str) -> tuple[int, list[dict], str]:
    code = main(["decode", *argv])
    out, err = capsys.readouterr()
    return code, [json.loads(line) for line in out.splitlines()], err


@pytest.mark.parametrize(("protocol", "path", "types"), [
    ("msp", "msp/replies.hex", ["RawImu", "Attitude", "Motor", "Ack", "ErrorReply"]),
    ("gx3", "gx3/replies.hex", ["ContinuousAck", "AccelRate", "Euler"]),
    ("vesc-can", "vesc/examples.log", ["SetDuty", "SetCurrent", "SetCurrentBrake", "SetRpm",
                                       "Status1", "Status4", "Status5"]),
    ("dronecan", "dronecan/examples.log", ["RawCommand", "EscStatus"]),
    ("gcs", "gcs/replies.txt", ["GcsReply"] * 5),
])
def test_decodes_each_transcript(capsys, protocol, path, types):
    code, recs, err = _run(capsys, "--protocol", protocol, str(T / path))
    assert code == 0 and err == ""
    assert [r["type"] for r in recs] == [*types, "stats"]
    assert recs[-1]["messages"] == len(types)


def test_fields_are_si_and_json_clean(capsys):
    _, recs, _ = _run(capsys, "--protocol", "gx3", str(T / "gx3/replies.hex"))
    assert recs[1]["acc_m_s2"] == pytest.approx([0, 0, -9.80665])
    assert recs[1]["timer_s"] == 1.0 and recs[1]["offset"] == 8
    _, recs, _ = _run(capsys, "--protocol", "dronecan", str(T / "dronecan/examples.log"))
    assert recs[1]["temperature_k"] == 300.0 and recs[1]["source_node_id"] == 21


def test_raw_binary_capture_and_noisy_stats(capsys, tmp_path):
    from drivers.codecs.transcript import parse_hex_dump

    cap = tmp_path / "capture.bin"
    cap.write_bytes(parse_hex_dump((T / "msp/noisy.hex").read_text()))
    code, recs, _ = _run(capsys, "--protocol", "msp", str(cap))
    assert code == 0
    stats = recs[-1]
    assert (stats["messages"], stats["bad_checksums"], stats["truncated"]) == (3, 1, 2)
    code, recs, _ = _run(capsys, "--protocol", "msp", "--no-stats", str(cap))
    assert [r["type"] for r in recs] == ["Attitude", "Ack", "RawImu"]


def test_gcs_host_side(capsys):
    code, recs, _ = _run(capsys, "--protocol", "gcs", "--side", "host", str(T / "gcs/commands.txt"))
    assert code == 0
    assert recs[2] == {"offset": 11, "type": "GcsCommand", "name": "MOV",
                       "args": ["X", "1", "Y", "0.5", "Z", "0", "U", "0", "V", "0", "W", "0"]}


def test_nan_becomes_null(capsys, tmp_path):
    from drivers.codecs import dronecan
    from drivers.codecs.can_log import format_line

    frames = dronecan.encode(dronecan.EscStatus(0, float("nan"), 1.0, 300.0, 0, 0, 0), 5, 0)
    log = tmp_path / "nan.log"
    log.write_text("".join(format_line(f) + "\n" for f in frames))
    _, recs, _ = _run(capsys, "--protocol", "dronecan", str(log))
    assert recs[0]["voltage_v"] is None


@pytest.mark.parametrize(("protocol", "content", "expect"), [
    ("vesc-can", b"this is not a log\n", "not a candump line"),
    ("dronecan", b"\xff\xfe\x00binary", "binary"),
    ("msp", None, "cannot read"),
])
def test_bad_file_is_one_line_exit_2(capsys, tmp_path, protocol, content, expect):
    path = tmp_path / "bad.log"
    if content is not None:
        path.write_bytes(content)
    code = main(["decode", "--protocol", protocol, str(path if content else tmp_path / "nope")])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and expect in err and "Traceback" not in err


def test_bad_hex_dump_names_the_line(capsys, tmp_path):
    path = tmp_path / "x.hex"
    path.write_text("24 4D\n# fine\n24 ZZ\n")
    code = main(["decode", "--protocol", "msp", str(path)])
    _, err = capsys.readouterr()
    assert code == 2 and "x.hex:3" in err and "'ZZ'" in err


def test_gcs_random_bytes_are_garbage_not_replies(capsys, tmp_path):
    """4 kB of random bytes used to give 22 'messages' (one per line feed)."""
    import random

    noise = tmp_path / "noise.bin"
    noise.write_bytes(random.Random(10).randbytes(4096))
    code, recs, _ = _run(capsys, "--protocol", "gcs", str(noise))
    stats = recs[-1]
    assert code == 0 and stats["messages"] == len(recs) - 1 <= 1
    assert stats["garbage_bytes"] >= 4096 - 8 and stats["bytes_in"] == 4096
    # real replies around the noise still decode, noise between them is garbage
    real = (T / "gcs/replies.txt").read_bytes()
    mixed = tmp_path / "mixed.bin"
    mixed.write_bytes(real + random.Random(10).randbytes(4096) + b"\n" + real)
    code, recs, _ = _run(capsys, "--protocol", "gcs", str(mixed))
    kinds = [r["kind"] for r in recs[:-1]]
    assert kinds.count("axis_values") == 2 and kinds.count("data_array") == 2
