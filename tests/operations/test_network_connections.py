"""Knock-on between lines of a network-day: a train that waits at its origin for a train of another
line leaves no earlier than that train's arrival plus the connection time."""

from __future__ import annotations

from pathlib import Path

import pytest

from trainsim.batch import network_day as nd
from trainsim.errors import InputError
from trainsim.io.operation_file import read_operation
from trainsim.io.operation_run import run_operation, run_operation_file

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "operations"
FEEDER_LINE = "Metro line B, 3-aspect fixed block, 150 s headway"
pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")


def _copy(tmp_path: Path, example: str, extra: str = "", name: str | None = None) -> Path:
    text = (EXAMPLES / example).read_text().replace("../metro_b/", f"{EXAMPLES.parent / 'metro_b'}/")
    path = tmp_path / (name or example)
    path.write_text(text + "\n" + extra + "\n")
    return path


def _waiting(tmp_path: Path, connections: str) -> Path:
    return _copy(tmp_path, "metro_cbtc.yaml", "connections:\n" + connections)


def _arrival(path: Path, train: str, station: str) -> float:
    """The train's simulated arrival at the station, from its line simulated alone."""
    res = run_operation(read_operation(path))
    out = next(t for t in res.trains if t.id == train)
    return next(s.arrival_s for s in out.stops if s.station == station)


def test_a_late_feeder_makes_the_waiting_train_late_by_the_missing_time(tmp_path: Path) -> None:
    feeder = _copy(tmp_path, "metro_fixed_block.yaml")
    # U.1 (08:00:00 from S1) waits 3600 s after D.1 of the fixed-block line reaches S1 (about 07:05);
    # U.2 waits for D.1 too, with no least time: the feeder is long there
    waiting = _waiting(
        tmp_path,
        f"  - {{train: U.1, line: '{FEEDER_LINE}', feeder: D.1, station: S1, min_s: 3600}}\n"
        f"  - {{train: U.2, line: '{FEEDER_LINE}', feeder: D.1}}\n",
    )
    arrival = _arrival(feeder, "D.1", "S1")
    departure_u1 = read_operation(waiting).services[0].departure_s
    expected = arrival + 3600.0 - departure_u1
    assert expected > 60  # the example is set up so that the feeder is late for U.1
    # the waiting line listed first: the feeder's line is still simulated first, the order kept
    summary = nd.network_day([waiting, feeder])
    assert [d["file"] for d in summary["line_days"]] == [str(waiting), str(feeder)]
    day = summary["line_days"][0]
    k1, k2 = day["knock_on"]
    assert k1["feeder_arrival_s"] == pytest.approx(arrival, abs=1e-9)
    assert k1["delay_s"] == pytest.approx(expected, abs=1e-9)
    assert k2["station"] == "S1" and k2["delay_s"] == 0.0  # its destination, in time
    delays = {t["id"]: t["delay_s"] for t in day["trains"]}
    alone = {t["id"]: t["delay_s"] for t in nd.line_day(str(waiting))["trains"]}
    assert alone["U.1"] == pytest.approx(0.0, abs=1e-6)
    # U.1 leaves its origin that much later; the trains behind it may be held by it, never earlier
    assert delays["U.1"] >= expected - 1e-6
    assert all(delays[k] >= alone[k] - 1e-6 for k in alone)
    # the feeder's line is the same as alone, and has no knock-on entry
    assert "knock_on" not in summary["line_days"][1]
    assert summary["line_days"][1] == nd.line_day(str(feeder))


def test_without_connections_every_line_day_is_its_own(tmp_path: Path) -> None:
    a, b = _copy(tmp_path, "metro_fixed_block.yaml"), _copy(tmp_path, "metro_cbtc.yaml")
    summary = nd.network_day([a, b])
    assert summary["line_days"] == [nd.line_day(str(a)), nd.line_day(str(b))]


def test_bad_connections_are_refused_with_the_field_named(tmp_path: Path) -> None:
    feeder = _copy(tmp_path, "metro_fixed_block.yaml")
    with pytest.raises(InputError, match=r"connections\[0\]\.train"):
        read_operation(_waiting(tmp_path, f"  - {{train: X.9, line: '{FEEDER_LINE}', feeder: D.1}}\n"))
    with pytest.raises(InputError, match=r"connections\[0\]\.min_s"):
        read_operation(
            _waiting(tmp_path, f"  - {{train: U.1, line: '{FEEDER_LINE}', feeder: D.1, min_s: -5}}\n")
        )
    cases = [
        ("  - {train: U.1, line: 'no such line', feeder: D.1}\n", r"connections\[0\]\.line"),
        (f"  - {{train: U.1, line: '{FEEDER_LINE}', feeder: Z.1}}\n", r"connections\[0\]\.feeder"),
        (
            f"  - {{train: U.1, line: '{FEEDER_LINE}', feeder: D.1, station: S9}}\n",
            r"connections\[0\]\.station",
        ),
    ]
    for block, field in cases:
        with pytest.raises(InputError, match=field):
            nd.network_day([_waiting(tmp_path, block), feeder])
    # two lines waiting for each other
    cbtc_name = read_operation(EXAMPLES / "metro_cbtc.yaml").name
    looped = _copy(
        tmp_path,
        "metro_fixed_block.yaml",
        f"connections:\n  - {{train: U.1, line: '{cbtc_name}', feeder: D.1}}\n",
    )
    with pytest.raises(InputError, match="cycle"):
        nd.network_day(
            [_waiting(tmp_path, f"  - {{train: U.1, line: '{FEEDER_LINE}', feeder: D.1}}\n"), looped]
        )


def test_one_file_with_connections_says_they_are_not_applied(tmp_path: Path) -> None:
    waiting = _waiting(tmp_path, f"  - {{train: U.1, line: '{FEEDER_LINE}', feeder: D.1, min_s: 3600}}\n")
    summary, _status = run_operation_file(waiting, plots=False)
    assert any("not applied" in w and "network-day" in w for w in summary["warnings"])
    plain, _ = run_operation_file(_copy(tmp_path, "metro_cbtc.yaml", name="plain.yaml"), plots=False)
    assert not any("connection" in w for w in plain["warnings"])
