"""``rotorbench decode``: a captured byte stream or candump log -> JSON lines on stdout.

For users debugging a bench: what did the device really send? Each decoded message is
one JSON object (``type`` = message class, SI fields, the byte ``offset`` in the capture
or the CAN ``timestamp``/``can_id``); the last line is ``{"type": "stats", ...}`` with the
decoder's counters (garbage bytes, bad checksums, truncated frames, ...). Byte captures
are raw binary, or hex dumps when the file name ends in ``.hex``; CAN captures are
candump-style text logs. An unreadable file prints one error line and exits with 2.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any, TextIO

from drivers.codecs import dronecan, gcs, gx3, msp, vesc_can
from drivers.codecs.can_log import CanLogError, read_lines
from drivers.codecs.stream import Located
from drivers.codecs.transcript import read_bytes

PROTOCOLS = ("msp", "gx3", "vesc-can", "dronecan", "gcs")


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "decode", help="decode a captured device byte stream or CAN log to JSON lines",
        description="Decode a capture to JSON lines (one message per line, then a stats line). "
                    "msp/gx3/gcs read raw bytes (or a hex dump if FILE ends in .hex); "
                    "vesc-can/dronecan read a candump log ('candump -L' or screen form).")
    p.add_argument("--protocol", required=True, choices=PROTOCOLS)
    p.add_argument("--side", choices=("device", "host"), default="device",
                   help="gcs only: decode the controller's replies (device, default) "
                        "or the host's commands")
    p.add_argument("--no-stats", action="store_true", help="omit the final stats line")
    p.add_argument("file", type=Path, metavar="FILE")
    p.set_defaults(func=handler)


def handler(args: argparse.Namespace) -> int:
    from bench.cli_args.option_values import refuse_unused

    if args.protocol != "gcs":  # the other protocols tell host and device frames apart
        refuse_unused(args, ("--side",), f"for --protocol {args.protocol} (only gcs has sides)")
    out = sys.stdout
    if args.protocol in ("vesc-can", "dronecan"):
        records, stats = _decode_can(args.protocol, args.file)
    else:
        records, stats = _decode_bytes(args.protocol, args.side, read_bytes(args.file))
    for rec in records:
        _emit(out, rec)
    if not args.no_stats:
        _emit(out, {"type": "stats", **stats.as_dict()})
    return 0


# ---------------------------------------------------------------------------- byte streams


def _decode_bytes(protocol: str, side: str, data: bytes) -> tuple[list[dict[str, Any]], Any]:
    if protocol == "msp":
        dec: Any = msp.MspDecoder()
        located = dec.feed_located(data) + dec.flush_located()
        return [r for loc in located if (r := _msp_record(loc, dec)) is not None], dec.stats
    if protocol == "gx3":
        dec = gx3.Gx3Decoder()
        located = dec.feed_located(data) + dec.flush_located()
        return [{"offset": loc.offset, **_fields(loc.message)} for loc in located], dec.stats
    dec = gcs.GcsReplyDecoder(strict=True) if side == "device" else gcs.GcsCommandDecoder()
    located = dec.feed_located(data) + dec.flush_located()
    return [_gcs_record(loc) for loc in located], dec.stats


def _msp_record(loc: Located, dec: msp.MspDecoder) -> dict[str, Any] | None:
    frame: msp.MspFrame = loc.message
    head = {"offset": loc.offset, "version": frame.version, "direction": frame.direction,
            "cmd": frame.cmd}
    try:
        return {**head, **_fields(msp.parse(frame))}
    except msp.PayloadError as exc:
        dec.stats.malformed += 1
        return {**head, "type": "Malformed", "error": str(exc), "payload_hex": frame.payload.hex()}


def _gcs_record(loc: Located) -> dict[str, Any]:
    msg = loc.message
    rec: dict[str, Any] = {"offset": loc.offset, **_fields(msg)}
    if isinstance(msg, gcs.GcsReply):
        kind = gcs.reply_kind(msg)
        rec["kind"] = kind
        if kind == "axis_values":
            rec["values"] = gcs.parse_axis_values(msg)
        elif kind == "integer":
            code = int(msg.lines[0])
            rec["value"] = code
            if code in gcs.ERRORS:
                rec["if_error_code"] = gcs.ERRORS[code]
    return rec


# ---------------------------------------------------------------------------- CAN logs


def _can_frames(path: Path) -> Iterator:
    try:
        with path.open(encoding="utf-8") as fh:
            yield from read_lines(fh, source=str(path))
    except UnicodeDecodeError:
        raise CanLogError(f"{path}: not a text candump log (binary data)") from None
    except OSError as exc:
        raise CanLogError(f"{path}: cannot read ({exc.strerror or exc})") from None


def _decode_can(protocol: str, path: Path) -> tuple[list[dict[str, Any]], Any]:
    records: list[dict[str, Any]] = []
    frames = list(_can_frames(path))  # read it all first: a bad line prints nothing else
    if protocol == "vesc-can":
        vdec = vesc_can.VescDecoder()
        for f in frames:
            for m in vdec.feed(f):
                records.append({"timestamp": f.timestamp, "can_id": f"0x{f.arbitration_id:08X}",
                                **_fields(m)})
        return records, vdec.stats
    ddec = dronecan.DroneCanDecoder()
    for f in frames:
        for r in ddec.feed(f):
            records.append({"timestamp": r.timestamp, "can_id": f"0x{f.arbitration_id:08X}",
                            "source_node_id": r.source_node_id, "priority": r.priority,
                            "transfer_id": r.transfer_id, **_fields(r.message)})
    ddec.flush()
    return records, ddec.stats


# ---------------------------------------------------------------------------- JSON


def _fields(msg: object) -> dict[str, Any]:
    out: dict[str, Any] = {"type": type(msg).__name__}
    for f in dataclasses.fields(msg):  # type: ignore[arg-type]
        out[f.name] = _jsonable(getattr(msg, f.name))
    if isinstance(msg, gx3.Timed):
        out["timer_s"] = msg.timer_s
    return out


def _jsonable(v: Any) -> Any:
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    if isinstance(v, (tuple, list)):
        return [_jsonable(x) for x in v]
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, (bytes, bytearray)):
        return v.hex()
    return v


def _emit(out: TextIO, rec: dict[str, Any]) -> None:
    out.write(json.dumps(_jsonable(rec), allow_nan=False) + "\n")
