"""``rotorbench serve``: the lab's runs in a web browser (read-only).

Binds to 127.0.0.1 by default; any other ``--host`` needs ``--token`` (required on every
request), so a bench PC never exposes its runs by accident. Behind a lab's reverse proxy,
see docs/dashboard.md.
"""

from __future__ import annotations

import argparse
import ipaddress
import os


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("serve", help="web view of the runs, fits and constants "
                              "(read-only; needs the serve extra)",
                              description=__doc__.split("\n\n")[1] if __doc__ else None)
    p.add_argument("--store", metavar="DIR|URL", default=None,
                   help="folder store or postgresql:// catalog (default: $ROTORBENCH_STORE, "
                        "else ./runs)")
    p.add_argument("--out", metavar="LOCATION", default=None,
                   help="the lab catalog's data location, if not the one store init saved")
    p.add_argument("--host", default="127.0.0.1",
                   help="address to bind (default 127.0.0.1; others need --token)")
    p.add_argument("--port", type=int, default=8765, help="port (default 8765)")
    p.add_argument("--token", default=None,
                   help="required on every request (header or /login?token=...); prefer "
                        "$ROTORBENCH_TOKEN: a --token is visible to every user in `ps`")
    p.set_defaults(func=handler)


def _loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def handler(args: argparse.Namespace) -> int:
    import sys

    from bench.errors import RigError

    if args.token is not None:
        print("rotorbench: warning: --token is visible to every user of this machine (ps, "
              "/proc); set ROTORBENCH_TOKEN instead", file=sys.stderr)
    token = args.token or os.environ.get("ROTORBENCH_TOKEN") or None
    if not 0 < args.port < 65536:
        raise RigError(f"--port {args.port}: expected 1-65535")
    if not _loopback(args.host) and not token:
        raise RigError(f"--host {args.host}: serving beyond this machine needs --token TOKEN "
                       "(or ROTORBENCH_TOKEN); without one, serve binds to 127.0.0.1 only")
    if token is not None and len(token) < 12:
        raise RigError("--token: use at least 12 characters")
    try:
        import uvicorn

        from bench.serve.app import create_app
    except ImportError as exc:
        raise RigError(f"serve needs the serve extra ({exc.name} missing): "
                       "pip install 'rotorbench[serve]'") from None
    from bench.store.stores import open_store

    store = open_store(args.store, data=args.out)
    app = create_app(store, token=token)
    print(f"serving {store.describe()} at http://{args.host}:{args.port}/ (Ctrl-C stops)",
          flush=True)
    uvicorn.run(app, host=args.host, port=args.port, log_level="warning")
    return 0
