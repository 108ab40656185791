"""End-to-end tests in a real browser: Playwright driving Debian's Chromium against uvicorn on 127.0.0.1.

Screenshots of each page go to tests/web/artifacts/. Skipped (with the reason) without the
``playwright`` package or a ``chromium`` executable (``apt-get install chromium``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from urllib.parse import urlsplit

import pytest

from .conftest import ARTIFACTS, CHROMIUM_ARGS, chromium_path

pytestmark = pytest.mark.browser

sync_api = pytest.importorskip("playwright.sync_api", reason="the playwright package is not installed")
if chromium_path() is None:
    pytest.skip(
        "no chromium executable (install Debian's package: apt-get install chromium)", allow_module_level=True
    )


@pytest.fixture(scope="module")
def browser() -> Iterator:
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=chromium_path(), headless=True, args=CHROMIUM_ARGS)
        yield b
        b.close()


@pytest.fixture
def page(browser, live_server) -> Iterator:
    """A fresh browser context (its own session cookie); any request off this machine fails the test."""
    # Playwright evaluates its wait predicates as strings, which the page's CSP forbids: bypassed
    # here; test_the_page_works_under_its_content_security_policy runs without the bypass
    context = browser.new_context(viewport={"width": 1500, "height": 1000}, bypass_csp=True)
    outside: list[str] = []
    errors: list[str] = []

    def guard(route) -> None:
        host = urlsplit(route.request.url).hostname
        if host in ("127.0.0.1", "localhost"):
            route.continue_()
        else:
            outside.append(route.request.url)
            route.abort()

    context.route("**/*", guard)
    pg = context.new_page()
    pg.on("pageerror", lambda exc: errors.append(str(exc)))
    pg.set_default_timeout(20_000)
    pg.goto(live_server.url + "/")
    pg.wait_for_selector("body[data-ready=true]")
    yield pg
    context.close()
    assert outside == [], f"the page fetched from outside this machine: {outside}"
    assert errors == [], f"JavaScript errors: {errors}"


def shot(pg, name: str) -> None:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    pg.wait_for_timeout(300)  # let Plotly finish its transitions
    pg.screenshot(path=str(ARTIFACTS / name), full_page=True)


def load_metro(pg) -> None:
    pg.select_option("#example-select", "metro_b")
    pg.click("#example-load")
    pg.wait_for_function("document.querySelector('#current-route').textContent.includes('metro line')")


def summary_value(pg, key: str, column: str = "a") -> float:
    cell = pg.locator(f"#summary-table tr[data-key='{key}'] td.{column}")
    return float(cell.inner_text())


def test_train_page_edits_show_curves_and_field_errors(page) -> None:
    pg = page
    load_metro(pg)
    pg.wait_for_selector("#train-plot .main-svg")
    assert pg.locator("#train-figures").inner_text().count("288.2 t") == 1
    shot(pg, "train.png")
    # a valid edit: the first traction point, 93.25 kN per motor -> 100
    cell = pg.locator("[data-path='traction.force_kn[0]']")
    cell.fill("100")
    cell.press("Tab")
    pg.wait_for_function("document.querySelector('#train-status').textContent.includes('valid')")
    assert "400.0 kN" in pg.locator("#train-figures").inner_text()
    # an invalid one: the message of the core's validation next to the field
    mass = pg.locator("[data-path='formation[1].mass_t']")
    mass.fill("-3")
    mass.press("Tab")
    error = pg.locator(".field-error[data-field='formation[1].mass_t']")
    error.wait_for()
    assert "out of range" in error.inner_text() and "> 0" in error.inner_text()
    assert "problem" in pg.locator("#train-status").inner_text()
    assert "formation[1].mass_t" in pg.locator("#train-errors").inner_text()
    shot(pg, "train-invalid.png")
    mass.fill("44.5")
    mass.press("Tab")
    pg.wait_for_function("document.querySelector('#train-status').textContent.includes('valid')")
    assert pg.locator(".field-error").count() == 0


def test_changing_a_speed_limit_changes_the_run(page) -> None:
    pg = page
    load_metro(pg)
    pg.click("button[data-tab=track]")
    pg.wait_for_selector("#route-plot .main-svg")
    shot(pg, "track.png")
    pg.click("button[data-tab=run]")
    pg.wait_for_selector("#summary-table tr[data-key='running_time_s'] td.a")
    assert summary_value(pg, "running_time_s") == pytest.approx(279.0, abs=0.05)
    # the one speed limit of the line, 80 -> 60 km/h, in the track table
    pg.click("button[data-tab=track]")
    limit = pg.locator("[data-path='speed_limits[0].limit_kmh']")
    limit.fill("60")
    limit.press("Tab")
    pg.wait_for_function("document.querySelector('#route-status').textContent.includes('valid')")
    pg.click("button[data-tab=run]")
    pg.wait_for_function(
        "document.querySelector(\"#summary-table tr[data-key='running_time_s'] td.b\") !== null"
    )
    assert summary_value(pg, "running_time_s", "a") == pytest.approx(329.9, abs=0.05)
    assert summary_value(pg, "running_time_s", "b") == pytest.approx(279.0, abs=0.05)
    assert summary_value(pg, "max_speed_kmh", "a") == pytest.approx(60.0, abs=0.05)
    for plot in ("#plot-speed-distance", "#plot-speed-time", "#plot-power", "#plot-energy"):
        pg.wait_for_selector(f"{plot} .main-svg")
        assert pg.locator(f"{plot} .scatterlayer .trace, {plot} .barlayer .trace").count() >= 2, plot
    assert pg.locator("#sections-table").inner_text().count("S2") == 2
    shot(pg, "run.png")
    # downloads of the shown run
    with pg.expect_download() as dl:
        pg.locator("#runs-table a", has_text="trace CSV").first.click()
    assert dl.value.suggested_filename.endswith(".trace.csv")


def _drive_state(pg) -> dict:
    return pg.evaluate(
        """() => ({
            v: Number(document.querySelector('#drive-speed').dataset.value || 0),
            d: Number(document.querySelector('#drive-next-stop').dataset.distance || NaN),
            dwell: Number(document.querySelector('#drive-dwell').dataset.value || 0),
        })"""
    )


def _wait(pg, predicate, timeout_s: float, what: str) -> dict:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        s = _drive_state(pg)
        if predicate(s):
            return s
        pg.wait_for_timeout(50)
    raise AssertionError(f"timed out waiting for {what}: {_drive_state(pg)}")


def _lever(pg, notch: int) -> None:
    pg.locator("#drive-lever").fill(str(notch))


def test_live_drive_accelerate_brake_and_stop_at_the_station(page) -> None:
    pg = page
    load_metro(pg)
    pg.click("button[data-tab=drive]")
    pg.check("input[name=scale][value='5']")
    pg.click("#drive-start")
    pg.wait_for_selector("#drive-accel:not([disabled])")
    # accelerator: four notches up, speed rises
    for _ in range(4):
        pg.click("#drive-accel")
    assert pg.locator("#drive-notch").inner_text() == "P4"
    fast = _wait(pg, lambda s: s["v"] > 35, 20, "the speed to rise")
    # brake with the keyboard: from P4 down to B4, speed falls
    pg.locator("#drive-plot").click()  # focus off the buttons
    for _ in range(8):
        pg.keyboard.press("ArrowDown")
    assert pg.locator("#drive-notch").inner_text() == "B4"
    slower = _wait(pg, lambda s: s["v"] < fast["v"] - 10, 10, "the speed to fall")
    assert slower["v"] > 0
    # speed up again, coast on towards S2 at 20x, then brake to stop there at 5x / 1x
    _lever(pg, 3)
    _wait(pg, lambda s: s["v"] > 40, 20, "speed again")
    _lever(pg, 0)
    pg.keyboard.press("2")
    _wait(pg, lambda s: s["d"] < s["v"] ** 2 / 3.6**2 / (2 * 0.6) + 200, 60, "the approach to S2")
    pg.keyboard.press("5")
    _stop_at_station(pg)
    stopped = _wait(pg, lambda s: s["dwell"] > 0, 10, "the dwell at S2")
    assert stopped["dwell"] <= 51
    assert "stopped at S2" in pg.locator("#drive-message").inner_text()
    shot(pg, "drive.png")
    later = _wait(pg, lambda s: 0 < s["dwell"] < stopped["dwell"] - 1, 10, "the dwell countdown")
    assert later["v"] == 0
    # record the drive and compare it with the fastest run
    pg.click("#drive-finish")
    pg.wait_for_selector("#drive-result:not([hidden])")
    pg.click("#drive-compare")
    pg.wait_for_function(
        "document.querySelector(\"#summary-table tr[data-key='running_time_s'] td.b\") !== null"
    )
    head = pg.locator("#summary-table tr").first.inner_text()
    assert "Drive 1" in head and "Fastest" in head
    shot(pg, "drive-compare.png")


def _stop_at_station(pg) -> None:
    """Brake so as to stop at the next station: a driver reading the cab display.

    The driver holds the braking that the remaining distance asks for, turns the time scale down to
    1x only for the last 15 m (braking later and harder there), creeps on if stopped short and
    brakes to a stand at the stopping point: the drive does not crawl to the stop in real time.
    """
    slow_scale = False
    deadline = time.monotonic() + 90
    while time.monotonic() < deadline:
        s = _drive_state(pg)
        if s["dwell"] > 0:
            _lever(pg, 0)
            return
        v, d = s["v"] / 3.6, s["d"] - 1.0
        if d < 15 and not slow_scale:
            pg.keyboard.press("1")
            slow_scale = True
        if d < -4:
            raise AssertionError(f"overran the station: {s}")
        a_max = 0.95 if v > 6 / 3.6 else 0.42  # service braking of the metro above / below 5 km/h
        if v < 0.05:
            notch = 1 if d > 3 else -4  # stopped short: creep on
        elif d < 0.5:
            notch = -4  # at the stopping point: brake to a stand rather than roll on at walking pace
        else:
            need = v * v / (2 * max(d, 0.2))
            if need > (0.3 if slow_scale else 0.15):  # at 1x the driver can brake later and harder
                notch = -min(4, math.ceil(4 * need / a_max))
            else:
                notch = 1 if v < 1.0 and d > 3 else 0  # creep on rather than roll to a stop short of it
        _lever(pg, notch)
        pg.wait_for_timeout(50)
    raise AssertionError(f"did not stop at the station: {_drive_state(pg)}")
