"""One's own operation in Chromium (issue 17): upload a zipped operation with its train and route files,
see the interactive train graph with its conflicts marked (hover names trains, block, time and
overlap), the delay per station and the headway over the line; a bad upload names file, line, field."""

from __future__ import annotations

import pytest

from trainsim.web.jobs import OPERATION_EXAMPLES

from .test_web_browser import browser, page, shot  # noqa: F401 (fixtures)
from .test_web_operation_upload import _zip, single_track_files

pytestmark = pytest.mark.browser

GRAPH = "#plot-train-graph"


def test_an_uploaded_operation_shows_its_train_graph_with_conflicts(page) -> None:  # noqa: F811
    pg = page
    pg.click("button[data-tab=run]")
    # every shipped operation is offered
    options = pg.locator("#op-example option").all_inner_texts()
    assert len(options) == len(OPERATION_EXAMPLES) and any(o.startswith("single_track") for o in options)
    zipped = _zip(single_track_files())
    pg.set_input_files(
        "#op-file", files=[{"name": "mine.zip", "mimeType": "application/zip", "buffer": zipped}]
    )
    pg.wait_for_selector(f"{GRAPH} .main-svg", timeout=120_000)
    status = pg.locator("#op-status").inner_text()
    assert "conflicts: 5 trains, 8 conflicts" in status, status
    assert "bad" in (pg.locator("#op-status").get_attribute("class") or "")  # not shown as a success
    assert "8 conflicts" in pg.locator(GRAPH).inner_text()
    assert pg.locator("#op-conflicts tr").count() == 1 + 8
    # the conflict markers: one per conflict; hovering one names trains, block, time and overlap
    data = pg.evaluate(
        f"""() => document.querySelector('{GRAPH}').data
            .map((t, i) => [i, t.name, (t.x || []).length])"""
    )
    marks = [d for d in data if d[1] == "conflicts (8)"]
    assert len(marks) == 1 and marks[0][2] == 8
    pg.evaluate(
        f"() => Plotly.Fx.hover(document.querySelector('{GRAPH}'), [{{curveNumber: {marks[0][0]}, pointNumber: 0}}])"
    )
    hover = pg.locator(f"{GRAPH} .hoverlayer").text_content() or ""
    assert "conflict:" in hover and "block" in hover and "overlap" in hover, hover
    shot(pg, "operation_upload_conflicts.png")
    # zoom: the plot's own zoom-in button narrows the time axis
    before = pg.evaluate(f"() => document.querySelector('{GRAPH}').layout.xaxis.range.slice()")
    pg.locator(f"{GRAPH} .modebar-btn[data-attr=zoom][data-val=in]").click(force=True)
    pg.wait_for_timeout(300)
    after = pg.evaluate(f"() => document.querySelector('{GRAPH}').layout.xaxis.range.slice()")
    assert after != before
    # the other plots
    pg.click("#op-tabs button[data-op-plot=delays]")
    pg.wait_for_selector("#plot-op-delays .main-svg")
    assert "Delay per station" in pg.locator("#plot-op-delays").inner_text()
    assert pg.locator(GRAPH).is_hidden()
    pg.click("#op-tabs button[data-op-plot=headways]")
    pg.wait_for_selector("#plot-op-headways .main-svg")
    assert "Headway over the line" in pg.locator("#plot-op-headways").inner_text()
    # a bad upload: the file inside the zip, its line and the field, as the command line names them
    files = single_track_files()
    files["examples/operations/single_track.yaml"] = files["examples/operations/single_track.yaml"].replace(
        "direction: up", "direction: sideways", 1
    )
    pg.set_input_files(
        "#op-file", files=[{"name": "bad.zip", "mimeType": "application/zip", "buffer": _zip(files)}]
    )
    pg.wait_for_function("document.querySelector('#op-status').textContent.includes('✗')", timeout=60_000)
    text = pg.locator("#op-warnings").inner_text()
    assert "bad.zip/examples/operations/single_track.yaml:" in text and "trains[0].direction" in text
