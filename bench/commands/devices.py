"""``rotorbench devices``: the serial ports and CAN interfaces this host can see."""

from __future__ import annotations

import argparse
import json
import math

from rich.console import Console
from rich.table import Table

from bench.errors import RigError


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "devices", help="list serial ports and CAN interfaces this host can see",
        description="Serial ports (pyserial's list_ports) and CAN channels python-can "
                    "detects, with the URL to put in a rig file. NI-DAQmx devices are "
                    "listed by NI MAX / `nidaqmx` itself.")
    p.add_argument("--json", action="store_true", help="print JSON lines instead of tables")
    p.add_argument("--no-can", action="store_true", help="skip the CAN detection")
    p.add_argument("--can-timeout", type=float, default=5.0,
                   help="seconds the CAN detection may take (default 5)")
    p.set_defaults(func=handler)


def handler(args: argparse.Namespace) -> int:
    from drivers.discovery import can_configs, serial_ports

    if not (math.isfinite(args.can_timeout) and 0 < args.can_timeout <= 3600):
        raise RigError(f"--can-timeout: expected seconds > 0 (at most 3600), "
                       f"got {args.can_timeout:g}")
    ports, port_note = serial_ports()
    cans, can_note = ([], "skipped (--no-can)") if args.no_can else \
        can_configs(timeout_s=args.can_timeout)
    if args.json:
        for p in ports:
            print(json.dumps({"kind": "serial", "url": p.url, "device": p.device,
                              "description": p.description, "hwid": p.hwid}))
        for c in cans:
            print(json.dumps({"kind": "can", "url": c.url, "interface": c.interface,
                              "channel": c.channel}))
        return 0
    console = Console(width=160, soft_wrap=True)
    table = Table(title="serial ports", box=None)
    for col in ("url", "description", "hardware id"):
        table.add_column(col)
    for p in ports:
        table.add_row(p.url, p.description, p.hwid)
    console.print(table if ports else f"serial ports: none found {_paren(port_note)}")
    table = Table(title="CAN interfaces", box=None)
    for col in ("url", "interface", "channel"):
        table.add_column(col)
    for c in cans:
        table.add_row(c.url, c.interface, c.channel)
    console.print(table if cans else f"CAN interfaces: none found {_paren(can_note)}")
    if cans and can_note:
        console.print(f"note: {can_note}")
    return 0


def _paren(note: str) -> str:
    return f"({note})" if note else ""
