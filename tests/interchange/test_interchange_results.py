"""Results written for other tools: trace and summary as CSV, Parquet and JSON; running times back
into railML timetables."""

from __future__ import annotations

import json

import pandas as pd
import pytest
from interchange_cases import DATA, FORMULAS, run

from trainsim.errors import InputError
from trainsim.io import convert, railml2, railml3, results_export
from trainsim.io import railml_common as rc


@pytest.fixture(scope="module")
def result():
    scenario = convert.detect_and_load(DATA / "testline_railml2.xml", "scenario")
    return run(scenario.train, scenario.route)


def test_trace_and_summary_in_three_formats(result, tmp_path):
    written = results_export.write_results(result, tmp_path)
    assert sorted(p.name for p in written) == sorted(
        f"{k}.{f}" for k in ("trace", "summary") for f in ("csv", "parquet", "json")
    )
    csv_trace = pd.read_csv(tmp_path / "trace.csv")
    parquet_trace = pd.read_parquet(tmp_path / "trace.parquet")
    json_trace = json.loads((tmp_path / "trace.json").read_text())
    assert len(csv_trace) == len(parquet_trace) == len(result.trace) == len(json_trace["columns"]["time_s"])
    assert list(parquet_trace.columns) == list(csv_trace.columns) == list(json_trace["columns"])
    assert parquet_trace["time_s"].iloc[-1] == pytest.approx(result.total_time_s + result.trace.time_s[0])
    assert set(parquet_trace["regime"]) <= {"traction", "cruise", "coast", "brake", "dwell", "regen"} | set(
        csv_trace["regime"]
    )
    summary = pd.read_parquet(tmp_path / "summary.parquet")
    assert list(summary["from"]) == ["Aford", "Bexley", "total"]
    assert summary["running_time_s"].iloc[-1] == pytest.approx(result.running_time_s)
    assert summary["energy_net_kwh"].iloc[:-1].sum() == pytest.approx(result.energy_kwh.net)
    assert pd.read_csv(tmp_path / "summary.csv")["distance_m"].iloc[-1] == pytest.approx(result.distance_m)
    assert json.loads((tmp_path / "summary.json").read_text())["running_time_s"] == pytest.approx(
        result.running_time_s
    )


def test_unknown_format(result, tmp_path):
    with pytest.raises(Exception, match="unknown result format"):
        results_export.write_trace(result, tmp_path / "trace.xls")


def test_running_times_into_railml2(result, tmp_path):
    out = results_export.write_running_times_railml(
        result, DATA / "testline_railml2.xml", tmp_path / "rt.xml"
    )
    tree = rc.parse_xml(out)
    ocps = [o for o in tree.getroot().iter() if rc.local(o) == "ocpTT"][:4]
    runs = [rc.parse_duration(rc.descendants(o, "runTimes")[0].get("minimalTime")) for o in ocps[:3]]
    calculated = [next(t for t in rc.children(o, "times") if t.get("scope") == "calculated") for o in ocps]
    # Aford -> Bexley is one section; Bexley -> Carnforth -> Dunmore the other (Carnforth passed)
    assert runs[0] == pytest.approx(result.sections[0].running_time_s, abs=1e-3)
    assert runs[1] + runs[2] == pytest.approx(result.sections[1].running_time_s, abs=2e-3)
    # the clock starts at the scheduled departure, the dwell at Bexley is 30 s
    assert calculated[0].get("departure") == "08:00:00"
    arrive_b = rc.parse_clock(calculated[1].get("arrival"))
    assert rc.parse_clock(calculated[1].get("departure")) - arrive_b == pytest.approx(30.0)
    assert arrive_b == pytest.approx(8 * 3600 + result.sections[0].running_time_s, abs=0.06)
    assert calculated[2].get("arrival") == calculated[2].get("departure")  # passing time
    assert rc.parse_clock(calculated[3].get("arrival")) == pytest.approx(
        8 * 3600 + result.total_time_s, abs=0.06
    )
    # the scheduled times are kept, and the file still reads as before
    assert any(t.get("scope") == "scheduled" for t in rc.children(ocps[1], "times"))
    again = railml2.read_railml2(out)
    assert again.route == railml2.read_railml2(DATA / "testline_railml2.xml").route


def test_running_times_into_railml3(result, tmp_path):
    out = results_export.write_running_times_railml(
        result, DATA / "testline_railml3.xml", tmp_path / "rt.xml"
    )
    tree = rc.parse_xml(out)
    points = [
        b
        for b in tree.getroot().iter()
        if rc.local(b) == "baseItineraryPoint" and b.get("id", "").startswith("bp")
    ]
    minimal = [rc.descendants(b, "minimalTime") for b in points]
    assert rc.parse_duration(minimal[0][0].get("runTime")) == pytest.approx(
        result.sections[0].running_time_s, abs=1e-3
    )
    assert minimal[3] == []
    again = railml3.read_railml3(out, line_resistance=FORMULAS)
    assert (
        again.route["stations"]
        == railml3.read_railml3(DATA / "testline_railml3.xml", line_resistance=FORMULAS).route["stations"]
    )


def test_writer_with_times(result, yaml_route, yaml_train, tmp_path):
    """railML written from trainsim with the run's times carries them; reading it back gives the route."""
    stations = yaml_route.stations
    times = results_export.station_times(
        result,
        [s.position_m for s in stations],
        [s.stop for s in stations],
        [s.dwell_s for s in stations],
        8 * 3600,
    )
    for writer, reader in (
        (railml2.write_railml2, railml2.read_railml2),
        (railml3.write_railml3, railml3.read_railml3),
    ):
        path = tmp_path / "w.xml"
        writer(path, train=yaml_train, route=yaml_route, times=times)
        content = reader(path)
        assert [s["dwell_s"] for s in content.route["stations"]] == [s.dwell_s for s in stations]
        text = path.read_text()
        assert "calculated" in text and "08:00:00" in text


def test_mismatched_run(result, tmp_path):
    with pytest.raises(Exception, match="does not match this timetable"):
        results_export.write_running_times_railml(
            result, DATA / "testline_railml2.xml", tmp_path / "x.xml", train_id="S 9"
        )


def test_running_times_never_copy_a_doctype(result, tmp_path):
    text = (DATA / "testline_railml2.xml").read_text(encoding="utf-8")
    head, rest = text.split("?>", 1)
    hostile = tmp_path / "hostile.xml"
    hostile.write_text(head + '?>\n<!DOCTYPE railml SYSTEM "file:///etc/passwd">' + rest, encoding="utf-8")
    out = results_export.write_running_times_railml(result, hostile, tmp_path / "rt.xml")
    written = out.read_text(encoding="utf-8")
    assert "DOCTYPE" not in written and "passwd" not in written and "runTimes" in written
    # an entity declared and used is refused, with a message about the file (not libxml2's)
    hostile.write_text(
        head
        + '?>\n<!DOCTYPE railml [<!ENTITY x SYSTEM "file:///etc/passwd">]>'
        + rest.replace("Aford", "&x;", 1),
        encoding="utf-8",
    )
    with pytest.raises(InputError, match="entit") as err:
        results_export.write_running_times_railml(result, hostile, tmp_path / "rt2.xml")
    assert err.value.file == str(hostile) and "xmlCtxt" not in str(err.value)
    assert not (tmp_path / "rt2.xml").exists()
