"""The web view in a real Chromium (Playwright), over both stores: the list shows the runs,
a filter narrows them, a run page paints its plots, the compare page overlays two runs."""

from __future__ import annotations

import sys
from collections.abc import Iterator

import pytest

from bench.serve.app import create_app

browser_mod = sys.modules["rotorbench_tests_browser"]  # browser.py, by conftest


@pytest.fixture(scope="module")
def browser() -> Iterator[object]:
    from rotorbench_tests_services import missing

    why = browser_mod.chromium_missing()
    if why:
        missing(why)
    with browser_mod.chromium() as b:
        yield b


@pytest.fixture
def page(browser: object, store: object) -> Iterator[tuple[object, str]]:
    with browser_mod.serving(create_app(store)) as base:
        ctx = browser.new_context(viewport={"width": 1280, "height": 900})
        pg = ctx.new_page()
        errors: list[str] = []
        pg.on("pageerror", lambda e: errors.append(str(e)))
        pg.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        yield pg, base
        ctx.close()
        assert errors == [], errors  # no script error, no CSP violation


def test_list_filter_run_page_and_compare(page: tuple[object, str]) -> None:
    pg, base = page
    pg.goto(base + "/")
    rows = pg.locator("#runs tbody tr[data-run]")
    assert rows.count() == 3
    pg.fill("input[name=esc_mode]", "diode")
    pg.click("#filters button[type=submit]")
    pg.wait_for_url("**/?*esc_mode=diode*")
    assert rows.count() == 1
    pg.goto(base + "/")
    ids = [rows.nth(i).get_attribute("data-run") for i in range(3)]
    # a run page paints every plot (plotly draws svg paths)
    pg.click(f"a[href='/runs/{ids[0]}']")
    pg.wait_for_selector("#plots[data-painted]", timeout=30_000)
    assert int(pg.get_attribute("#plots", "data-painted")) >= 6
    assert pg.locator("#plot-thrust_n .main-svg path.js-line").count() >= 1
    box = pg.locator("#plot-thrust_n .main-svg path.js-line").first.bounding_box()
    assert box is not None and box["width"] > 200
    pg.wait_for_selector("#fits[data-done]", timeout=30_000)
    assert pg.locator("#fit-step").count() == 1
    # compare: pick two runs on the list, overlay them
    pg.goto(base + "/")
    pg.check(f"input.pick[value='{ids[0]}']")
    pg.check(f"input.pick[value='{ids[2]}']")
    pg.click("#compare-btn")
    pg.wait_for_selector("#compare[data-painted]", timeout=30_000)
    assert pg.locator("#thrust_vs_rpm .main-svg g.trace").count() == 2
    # the step run's rising and falling means; the sweep has no steps
    assert pg.locator("#steps .main-svg g.trace").count() == 2


def test_a_flight_run_page_paints_gyro_setpoint_motors_and_erpm(browser: object,
                                                                flight_runs: object) -> None:
    from bench.store.stores import open_store

    with browser_mod.serving(create_app(open_store(str(flight_runs)))) as base:
        ctx = browser.new_context(viewport={"width": 1280, "height": 900})
        pg = ctx.new_page()
        errors: list[str] = []
        pg.on("pageerror", lambda e: errors.append(str(e)))
        pg.goto(base + "/")
        pg.click("#runs tbody tr[data-run] a")
        pg.wait_for_selector("#plots[data-painted]", timeout=30_000)
        assert int(pg.get_attribute("#plots", "data-painted")) == 5
        # one drawn line per trace, and a legend naming them
        assert pg.locator("#plot-rate_x .scatterlayer .trace path.js-line").count() == 2
        assert pg.locator("#plot-motor_rpm .scatterlayer .trace path.js-line").count() == 4
        assert pg.locator("#plot-motor_rpm .legend .traces").count() == 4
        ctx.close()
        assert errors == [], errors
