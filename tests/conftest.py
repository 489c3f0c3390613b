"""Shared test fixtures: paths to the repo's fixtures and to the open data sets it ships."""

from __future__ import annotations

import importlib.util
import signal
import sys
from pathlib import Path
from typing import Any

import pytest
from xdist.scheduler import LoadFileScheduling


def _load_helper(name: str, path: Path) -> None:
    """Register a test helper module by path as ``name`` (tests use importlib mode)."""
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, path)
        assert spec is not None and spec.loader is not None
        sys.modules[name] = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(sys.modules[name])


_HERE = Path(__file__).parent
#: Every test helper module, loaded here once by path (the one place that does it), in an
#: order where each comes after the helpers it imports. A test reads one as
#: ``sys.modules["rotorbench_tests_..."]`` or imports it by that name.
_HELPERS = {
    "rotorbench_tests_services": "services.py",  # real PostgreSQL, S3; free ports
    "rotorbench_tests_blackbox_writer": "analysis/blackbox_writer.py",  # flight-log encoders
    "rotorbench_tests_dataflash_writer": "analysis/dataflash_writer.py",
    "rotorbench_tests_logfamily": "analysis/logfamily.py",  # esc_test-family log writer
    "rotorbench_tests_bench_fakes": "bench/fakes.py",  # fake devices and rigs
    "rotorbench_tests_browser": "bench/serve/browser.py",  # Chromium through Playwright
    "rotorbench_tests_drivers_stepfit": "drivers/stepfit.py",  # the step-fit checks
    "rotorbench_tests_codec_props": "drivers/codec_props.py",  # the codec fuzz checks
    "rotorbench_tests_expected_protocol": "drivers/expected_protocol.py",  # transcripts
    "rotorbench_tests_factory_rigs": "drivers/factory_rigs.py",  # rig files for the factory
    "rotorbench_tests_sitl": "sitl.py",  # Betaflight SITL as a real peer
}
for _name, _file in _HELPERS.items():
    _load_helper(_name, _HERE / _file)
from rotorbench_tests_services import pg_cluster, pg_url, s3, s3_env  # noqa: E402, F401

REPO = Path(__file__).resolve().parents[1]
FIXTURES = REPO / "fixtures"
#: The open test data (BROAD trial 07, esc_test logs, PX4 ULogs), each with LICENSE and SOURCE.md.
#: The name is historical: they lived in a folder beside the repository before they shipped.
SHARED_DATA = FIXTURES / "data"
#: the files the package ships (package data, not test fixtures)
RIGS = REPO / "bench" / "data" / "rigs"
CATALOGS = REPO / "optimizer" / "data" / "catalogs"
SIZINGLAB = REPO / "optimizer" / "data" / "sizinglab"


def run_bad(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    """Run the CLI in-process; assert the user-error contract (exit code 2, one line on
    stderr, no traceback); return the stderr line."""
    from bench.cli import main

    code = main(list(argv))
    raw = capsys.readouterr().err
    assert code == 2, raw
    assert raw.count("\n") == 1 and raw.endswith("\n"), repr(raw)  # one line, no blank
    assert raw.startswith("rotorbench: error: "), repr(raw)
    return raw.strip()


@pytest.fixture
def fixtures_dir() -> Path:
    return FIXTURES


@pytest.fixture
def shared_data() -> Path:
    """fixtures/data: shipped, so a test that needs it fails (never skips) when it is gone."""
    return SHARED_DATA


def pytest_configure(config: pytest.Config) -> None:
    # A shell starts a background job (`make test &`, `setsid make test`, some CI runners)
    # with SIGINT ignored, and an ignored signal stays ignored through fork and exec: the
    # `rotorbench` children of the Ctrl-C tests never saw their Ctrl-C and ran to the end.
    # Ctrl-C is what those tests are about, so this run and its children get it back.
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--run-hardware", action="store_true", help="run tests that need devices")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    _longest_files_first(items)
    if config.getoption("--run-hardware"):
        return
    skip = pytest.mark.skip(reason="needs hardware; pass --run-hardware")
    for item in items:
        if "hardware" in item.keywords:
            item.add_marker(skip)


#: the wall time a ``slow`` mark without ``wall_s`` stands for
SLOW_WALL_S = 10.0


#: the unit of work the files that run device stand-ins make together (see below)
DEVICE_LANE = "tests::device stand-ins on the wall clock, one file at a time"


def _in_device_lane(path: str | Path) -> bool:
    """A test file that runs the Betaflight SITL or wire-level simulated devices on the
    wall clock: ``sitl``, ``wire`` or ``tcp`` (a ``tcp://sim`` hexapod's world) in its
    name."""
    name = Path(path).name
    return any(word in name for word in ("sitl", "wire", "tcp"))


def _longest_files_first(items: list[pytest.Item]) -> None:
    """Order the test files by the wall time their ``slow`` marks announce, longest first,
    each file's tests kept together and in order; the firmware lane's files as one unit of
    their summed wall time. ``make test`` hands files to its processes in this order
    (``--dist loadfile --no-loadscope-reorder``): a two-minute file started last would run
    alone after the others had finished."""
    wall: dict[Path, float] = {}
    for item in items:
        mark = item.get_closest_marker("slow")
        here = float(mark.kwargs.get("wall_s", SLOW_WALL_S)) if mark is not None else 0.0
        wall[item.path] = max(wall.get(item.path, 0.0), here)
    lane = sum(w for p, w in wall.items() if _in_device_lane(p))

    def order(item: pytest.Item) -> tuple[float, int]:
        if not _in_device_lane(item.path):
            return -wall[item.path], 0
        # in the lane the firmware's files first: the suite's start, with the long files
        # beside them, took them better than its middle's bursts of short processes
        return -lane, 0 if "sitl" in item.path.name else 1

    items.sort(key=order)  # stable: files stay whole


def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    """``--dist loadfile``, with every file that runs the Betaflight SITL or wire-level
    simulated devices in one unit of work, run by one process one file after another. The
    firmware, the worlds and their feeders run on the wall clock at a raised priority, as
    devices do (``drivers.device_priority``): two of them at once on the machine's two
    cores each had only part of a core, and starved by each other they answered late (the
    firmware IMU's rows all late for 5 s beside the 6x wire calibration, a port not open
    within 5 s, a load-cell board's lines 0.26 s apart against the runner's 0.25 s), which
    no real device beside a bench does."""
    if config.getoption("dist") != "loadfile":
        return None
    return DeviceLane(config, log)


class DeviceLane(LoadFileScheduling):
    """Files as units of work, the firmware lane's files one unit."""

    def _split_scope(self, nodeid: str) -> str:
        path = super()._split_scope(nodeid)
        return DEVICE_LANE if _in_device_lane(path) else path


@pytest.fixture(autouse=True, scope="module")
def _qt_objects_end_with_their_module():
    """Qt widgets a test module made (pytest-qt windows, pyqtgraph's plots and their
    parentless menus) are destroyed when the module ends, while the QApplication is there
    to do it. Left to Python's cyclic garbage collector they died inside whatever test of
    the same xdist worker came later: once a pyqtgraph QMenu's destructor hung on a Qt
    mutex in the middle of a hexapod upload of the wire-level calibration (a hung CI)."""
    yield
    qt_widgets = sys.modules.get("PySide6.QtWidgets")
    app = qt_widgets.QApplication.instance() if qt_widgets is not None else None
    widgets = app.topLevelWidgets() if app is not None else []
    if not widgets:  # nothing of Qt's left: no collection (a full one costs a big heap)
        return
    import gc

    from PySide6 import QtCore

    for widget in widgets:
        widget.close()
        widget.deleteLater()
    QtCore.QCoreApplication.sendPostedEvents(None, QtCore.QEvent.Type.DeferredDelete)
    app.processEvents()
    gc.collect()


def pytest_collection_finish(session: pytest.Session) -> None:
    """Freeze what collection built (the imported libraries, every test item: most of the
    session's heap) out of the cyclic garbage collector's reach. It lives to the end anyway,
    and scanning it made each full collection a pause of 0.2-0.6 s in which every thread of
    the process stopped: the simulated devices of the paced wire-level rigs too, past their
    hosts' reply timeouts (a 0.25 s MSP reply), as on a stalled host. (Fewer full
    collections, a higher third threshold, saved no time and made each pause longer.)"""
    import gc

    gc.collect()
    gc.freeze()
