"""Screenshots of the web view for the README and docs/dashboard.md:
docs/img/dashboard-{runs,run,compare}.png.

Records a small lab on the simulated rig into a temporary folder (a sweep, Step 1 in two
ESC modes, stored constants), serves it with ``rotorbench serve``'s app on a free loopback
port and takes the screenshots in Debian's Chromium through Playwright. The temporary
folder is removed at the end. Usage: python docs/make_dashboard_screenshots.py
"""

from __future__ import annotations

import importlib.util
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
IMG = HERE / "img"


def _browser_helpers() -> object:
    path = HERE.parent / "tests" / "serve" / "browser.py"
    spec = importlib.util.spec_from_file_location("rotorbench_tests_browser", path)
    assert spec and spec.loader
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def main() -> int:
    from bench.cli import main as cli
    from bench.serve.app import create_app
    from bench.store.stores import FolderStore

    browser = _browser_helpers()
    why = browser.chromium_missing()
    if why:
        print(f"no screenshots: {why}", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory(prefix="rotorbench-dashboard-") as tmp:
        out = Path(tmp) / "runs"
        assert cli(["sweep", "--out", str(out), "--no-save-map"]) == 0
        for mode in ("complementary", "diode"):
            assert cli(["step", "--repeats", "5", "--esc-mode", mode, "--out", str(out)]) == 0
        steps = sorted(p.parent for p in out.glob("*-step1/run.json"))
        assert cli(["constants", "--out", str(out), "--add", *map(str, steps)]) == 0
        ids = sorted(p.parent.name for p in out.glob("*/run.json"))
        sweep = next(i for i in ids if i.endswith("sweep"))
        with browser.serving(create_app(FolderStore(out))) as base, \
                browser.chromium() as chrome:
            page = chrome.new_page(viewport={"width": 1280, "height": 800})
            shots = {"runs": "/", "run": f"/runs/{steps[0].name}",
                     "compare": f"/compare?runs={steps[0].name},{steps[1].name},{sweep}"}
            for name, path in shots.items():
                page.goto(base + path)
                if name == "run":
                    page.wait_for_selector("#fits[data-done]", timeout=60_000)
                if name == "compare":
                    page.wait_for_selector("#compare[data-painted]", timeout=60_000)
                target = IMG / f"dashboard-{name}.png"
                page.screenshot(path=str(target), full_page=name != "run")
                print(f"wrote {target}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
