"""The user tasks of issue 19 in Chromium: layout at 1280 and 1920 px under the page's CSP, uploads of
other formats, valid new rows, cell messages, plot downloads and legends, auto re-run, and the
driver's desk (readouts, ATP, comparison with the fastest run of the same train and line).

The 1280 px screenshots of docs/WEB.md are taken here: into tests/web/artifacts/, or into
docs/screenshots/ with ``TRAINSIM_UPDATE_SCREENSHOTS=1`` (so that a test run changes no tracked file)."""

from __future__ import annotations

import os
import time
from collections.abc import Iterator

import pytest

from .conftest import ARTIFACTS, REPO
from .test_web_browser import browser, load_metro, page, shot  # noqa: F401 (fixtures)

pytestmark = pytest.mark.browser

sync_api = pytest.importorskip("playwright.sync_api", reason="the playwright package is not installed")

DOCS_SHOTS = REPO / "docs" / "screenshots" if os.environ.get("TRAINSIM_UPDATE_SCREENSHOTS") else ARTIFACTS
DATA = REPO / "tests" / "interchange" / "data"


def _until(check, timeout_s: float = 20.0, what: str = "") -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if check():
            return
        time.sleep(0.05)
    raise AssertionError(f"timed out: {what}")


def doc_shot(pg, name: str, selector: str) -> None:
    """A docs screenshot of the view around ``selector`` at 1280 px (the width the docs show)."""
    pg.set_viewport_size({"width": 1280, "height": 900})
    pg.locator(selector).scroll_into_view_if_needed()
    pg.wait_for_timeout(600)  # let Plotly relayout to the new width
    DOCS_SHOTS.mkdir(parents=True, exist_ok=True)
    pg.screenshot(path=str(DOCS_SHOTS / name))


@pytest.fixture
def strict_page(browser, live_server) -> Iterator:  # noqa: F811
    """A page under its own Content-Security-Policy (no bypass), 1280 px wide; CSP reports fail the test."""
    context = browser.new_context(viewport={"width": 1280, "height": 900})
    pg = context.new_page()
    problems: list[str] = []
    pg.on("pageerror", lambda exc: problems.append(str(exc)))
    pg.on(
        "console",
        lambda m: (
            problems.append(m.text) if m.type == "error" and "Content Security Policy" in m.text else None
        ),
    )
    pg.goto(live_server.url + "/")
    _until(lambda: pg.locator("body[data-ready=true]").count() == 1, what="the page to start")
    yield pg
    context.close()
    assert problems == [], problems


def _no_overflow(pg) -> None:
    width = pg.evaluate("document.documentElement.scrollWidth")
    inner = pg.evaluate("window.innerWidth")
    assert width <= inner, f"page {width} px wide in a {inner} px window"


def test_every_view_fits_1280_and_1920_px_under_the_csp(strict_page) -> None:
    pg = strict_page
    box = pg.locator("#example-load").bounding_box()
    assert box is not None and box["x"] + box["width"] <= 1280, box
    pg.select_option("#example-select", "metro_b")
    pg.click("#example-load")
    _until(lambda: "metro line" in pg.locator("#current-route").inner_text(), what="the example")
    DOCS_SHOTS.mkdir(parents=True, exist_ok=True)
    for tab in ("train", "track", "run", "drive"):
        pg.click(f"button[data-tab={tab}]")
        if tab == "run":
            pg.click("#run-button")
            _until(lambda: pg.locator("#plot-speed-distance .main-svg").count() > 0, 60, "the run's plots")
        pg.wait_for_timeout(600)
        _no_overflow(pg)
        if tab != "drive":
            pg.screenshot(path=str(DOCS_SHOTS / f"{tab}.png"))
    pg.set_viewport_size({"width": 1920, "height": 1000})
    for tab in ("train", "track", "run", "drive"):
        pg.click(f"button[data-tab={tab}]")
        pg.wait_for_timeout(300)
        _no_overflow(pg)


def test_open_railml_and_a_bad_xml_file(page) -> None:  # noqa: F811
    pg = page
    pg.set_input_files("#train-file", str(DATA / "testline_railml2.xml"))
    pg.wait_for_function("document.querySelector('#train-status').textContent.includes('opened')")
    assert "Test IC" in pg.locator("#current-train").inner_text()
    pg.set_input_files(
        "#train-file", files=[{"name": "page.xml", "mimeType": "text/xml", "buffer": b"<html/>"}]
    )
    pg.wait_for_function("document.querySelector('#train-errors').textContent.includes('not a railML file')")
    assert "YAML" not in pg.locator("#train-errors").inner_text()


def test_new_rows_are_valid_and_cell_messages_speak_of_cells(page) -> None:  # noqa: F811
    pg = page
    load_metro(pg)
    pg.click("button[data-tab=track]")
    pg.locator("fieldset.section[data-path='stations'] > button.add").click()
    pg.wait_for_function("document.querySelector('#route-status').textContent.includes('valid')")
    assert pg.locator(".field-error").count() == 0
    # a copy of the last station, half-way between the last two, named uniquely
    assert pg.locator("[data-path='stations[3].name']").input_value() == "S4 (2)"
    pg.click("button[data-tab=train]")
    mass = pg.locator("[data-path='formation[0].mass_t']")
    mass.fill("abc")
    mass.press("Tab")
    error = pg.locator(".field-error[data-field='formation[0].mass_t']")
    error.wait_for()
    assert "enter a number in t" in error.inner_text() and "YAML" not in error.inner_text()


def test_legends_mark_curves_and_tunnels_and_plots_download_as_svg(page) -> None:  # noqa: F811
    pg = page
    pg.select_option("#example-select", "freight_000")
    pg.click("#example-load")
    pg.wait_for_function("document.querySelector('#current-route').textContent !== 'none'")
    pg.click("button[data-tab=track]")
    pg.wait_for_selector("#route-plot .main-svg")
    legend = " ".join(pg.locator("#route-plot .legendtext").all_text_contents())
    assert "curve" in legend and "tunnel" in legend
    pg.locator("#route-plot").hover()
    with pg.expect_download() as dl:
        pg.locator("#route-plot .modebar-btn[data-title='Download plot as SVG']").click()
    assert dl.value.suggested_filename.endswith(".svg")


def test_auto_rerun_skips_no_op_edits_and_keeps_the_baseline(page) -> None:  # noqa: F811
    pg = page
    load_metro(pg)
    pg.click("button[data-tab=run]")
    # loading the example runs it once on its own (re-run is on)
    pg.wait_for_function("document.querySelectorAll('#runs-table tr[data-run]').length >= 1")
    pg.wait_for_timeout(1000)
    before = pg.locator("#runs-table tr[data-run]").count()
    baseline = pg.locator("#runs-table tr.a").get_attribute("data-run")
    header = pg.locator("#runs-table tr").first.inner_text()
    assert "train" in header and "line" in header
    pg.click("button[data-tab=track]")
    limit = pg.locator("[data-path='speed_limits[0].limit_kmh']")
    for value in ("70", "60", "60", "50"):
        limit.fill(value)
        limit.press("Tab")
        pg.wait_for_function("document.querySelector('#route-status').textContent.includes('valid')")
        pg.wait_for_timeout(700)
    pg.click("button[data-tab=run]")
    # three edits that changed something, one that did not: the table keeps the baseline and the
    # latest automatic run (an earlier automatic run is replaced), never one row per edit
    pg.wait_for_function(
        "document.querySelector(\"#summary-table tr[data-key='max_speed_kmh'] td.a\")?.textContent.trim() === '50.0'"
    )
    pg.wait_for_timeout(500)
    assert 2 <= pg.locator("#runs-table tr[data-run]").count() <= before + 1
    assert pg.locator("#runs-table tr.b").get_attribute("data-run") == baseline
    assert "metro line" in pg.locator("#runs-table").inner_text()
    # the energy-efficient strategy's energy-time curve
    pg.click("#curve-button")
    pg.wait_for_selector("#plot-energy-time .main-svg", timeout=60_000)
    assert "Energy against running time" in pg.locator("#plot-energy-time").inner_text()
    doc_shot(pg, "energy_time.png", "#plot-energy-time")


def test_driver_desk_readouts_atp_and_comparison(page) -> None:  # noqa: F811
    pg = page
    load_metro(pg)
    pg.click("button[data-tab=drive]")
    assert pg.locator("#drive-atp").is_checked()
    pg.check("input[name=scale][value='20']")
    pg.click("#drive-start")
    pg.wait_for_selector("#drive-accel:not([disabled])")
    pg.locator("#drive-lever").fill("4")
    pg.wait_for_function("Number(document.querySelector('#drive-speed').dataset.value) > 30")
    text = pg.locator(".dials").inner_text().lower()
    for label in (
        "acceleration",
        "effort",
        "gradient",
        "time since departure",
        "stop accuracy",
        "next limit",
    ):
        assert label in text
    assert float(pg.locator("#drive-effort").inner_text()) > 0
    assert float(pg.locator("#drive-time").inner_text()) > 0
    assert "between S1 and S2" in pg.locator("#drive-message").inner_text()
    pg.set_viewport_size({"width": 1280, "height": 900})
    pg.wait_for_timeout(300)
    _no_overflow(pg)
    pg.screenshot(path=str(DOCS_SHOTS / "drive.png"))
    pg.set_viewport_size({"width": 1500, "height": 1000})
    # past S2 at full power (ATP holds the line limit), then record and compare
    pg.wait_for_function(
        "document.querySelector('#drive-next-stop').textContent.startsWith('S3')", timeout=60_000
    )
    # paused at once: at 20x the train covers the 1.5 km to S3 in 4 s of wall time, less than a
    # loaded machine may take to click the next button
    pg.click("#drive-pause")
    assert float(pg.locator("#drive-speed").inner_text()) <= 80 + 2
    pg.click("#drive-finish")
    pg.wait_for_selector("#drive-result:not([hidden])")
    pg.click("#drive-compare")
    pg.wait_for_function(
        "document.querySelector(\"#summary-table tr[data-key='running_time_s'] td.b\") !== null"
    )
    head = pg.locator("#summary-table tr").first.inner_text()
    assert "Drive 1" in head and "Fastest to S2" in head
    assert pg.locator("#runs-table").inner_text().count("metro line") >= 2
    shot(pg, "drive-compare-same-line.png")


def test_multipoint_heavy_haul_heat_map_and_extreme_couplers(page) -> None:  # noqa: F811
    pg = page
    pg.click("button[data-tab=run]")
    pg.select_option("#mp-example", "heavy_haul_dp")
    pg.click("#mp-run")
    pg.wait_for_selector("#plot-couplers .main-svg", timeout=180_000)
    extremes = pg.locator("#mp-extremes").inner_text()
    # the largest forces sit behind the middle locomotive (vehicle 53), as the CLI's run says
    assert "largest draft" in extremes and "largest buff" in extremes and "coupling 53" in extremes
    assert "ok" in pg.locator("#mp-status").inner_text()
    assert pg.locator("#plot-couplers .heatmaplayer, #plot-couplers .hm").count() >= 1
    pg.locator("#plot-couplers").scroll_into_view_if_needed()
    shot(pg, "multipoint.png")
    doc_shot(pg, "multipoint.png", "#plot-couplers")


def test_timing_points_with_speed_windows_in_the_optimisation_form(page) -> None:  # noqa: F811
    pg = page
    load_metro(pg)
    pg.click("button[data-tab=run]")
    pg.wait_for_selector("#summary-table tr[data-key='running_time_s'] td.a")
    pg.select_option("#run-strategy", "energy_efficient")
    points = pg.locator("#run-params [data-param=timing_points]")
    assert "km/h" in (points.get_attribute("placeholder") or "")
    # at 1000 m (between S1 and S2): by 120 s after S1's departure, at most 40 km/h
    points.fill("1000: -120 @ -40 km/h")
    with pg.expect_request(lambda r: r.url.endswith("/api/runs") and r.method == "POST") as sent:
        pg.click("#run-button")
    body = sent.value.post_data_json
    assert body["params"]["timing_points"] == [{"position_m": 1000, "latest_s": 120, "max_speed_kmh": 40}]
    # the optimizer's run passes faster than the window allows: said as a warning of the run
    pg.wait_for_function(
        "document.querySelector('#run-warnings').textContent.includes('above its maximum 40.0 km/h')",
        timeout=120_000,
    )
    assert "timing point at 1000 m" in pg.locator("#run-warnings").inner_text()
    # a speed window alone, and an unreadable one: the server's message names the field
    points.fill("1000: @ 30-; 1200: @ x")
    pg.click("#run-button")
    pg.wait_for_function("document.querySelector('#run-errors').textContent.trim() !== ''", timeout=60_000)
    assert "timing_points" in pg.locator("#run-errors").inner_text()


def test_upload_ones_own_multipoint_scenario(page) -> None:  # noqa: F811
    import yaml

    from .test_web_multipoint_upload import small_scenario

    pg = page
    pg.click("button[data-tab=run]")
    scenario = small_scenario()
    pg.set_input_files(
        "#mp-file",
        files=[
            {
                "name": "mine.yaml",
                "mimeType": "application/x-yaml",
                "buffer": yaml.safe_dump(scenario).encode(),
            }
        ],
    )
    pg.wait_for_function("document.querySelector('#mp-status').textContent.includes('✓')", timeout=120_000)
    pg.wait_for_selector("#plot-couplers .main-svg")
    assert "largest draft" in pg.locator("#mp-extremes").inner_text()
    # an invalid wagon mass: the message names the file and the field, as the command line does
    scenario["train"]["formation"][1]["mass_t"] = -20
    pg.set_input_files(
        "#mp-file",
        files=[
            {
                "name": "bad.yaml",
                "mimeType": "application/x-yaml",
                "buffer": yaml.safe_dump(scenario).encode(),
            }
        ],
    )
    pg.wait_for_function("document.querySelector('#mp-status').textContent.includes('✗')", timeout=60_000)
    text = pg.locator("#mp-extremes").inner_text()
    assert "bad.yaml" in text and "formation[1].mass_t" in text


def test_operation_train_graph_with_blocking_time_stairs(page) -> None:  # noqa: F811
    pg = page
    pg.click("button[data-tab=run]")
    pg.select_option("#op-example", "metro_fixed_block")
    pg.click("#op-run")
    pg.wait_for_selector("#plot-train-graph .main-svg", timeout=180_000)
    assert "14 trains" in pg.locator("#op-status").inner_text()
    # 14 trains: a filled stairs trace, an operated and a planned (timetable) path each, no conflict
    # marks (the timetable has none); the station names label the position axis
    assert pg.locator("#plot-train-graph .scatterlayer .trace").count() == 42
    assert "Train graph with blocking times" in pg.locator("#plot-train-graph").inner_text()
    for station in ("S1", "S2", "S3", "S4"):
        assert station in pg.locator("#plot-train-graph").inner_text()
    pg.locator("#plot-train-graph").scroll_into_view_if_needed()
    shot(pg, "train_graph.png")
    doc_shot(pg, "train_graph.png", "#plot-train-graph")
