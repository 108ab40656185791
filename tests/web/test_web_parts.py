"""Parts of the web application: the session store's bounds, shipped examples, conversions, CLI."""

from __future__ import annotations

import filecmp

import numpy as np
import pytest

import trainsim
from trainsim.errors import InputError
from trainsim.web import WebSettings
from trainsim.web.convert import route_to_dict, train_to_dict
from trainsim.web.errors import input_error_detail
from trainsim.web.examples import EXAMPLES_DIR, examples
from trainsim.web.sessions import SessionStore, valid_session_id

from .conftest import REPO


class Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def test_sessions_expire_after_their_ttl() -> None:
    clock = Clock()
    store = SessionStore(WebSettings(session_ttl_s=60), clock=clock)
    s = store.create()
    clock.now += 59
    assert store.get(s.id) is s
    clock.now += 61
    assert store.get(s.id) is None and len(store) == 0


def test_the_store_drops_the_least_recently_used_session_but_not_a_driving_one() -> None:
    clock = Clock()
    store = SessionStore(WebSettings(max_sessions=2), clock=clock)
    a = store.create()
    clock.now += 1
    b = store.create()
    clock.now += 1
    store.get(a.id)  # a used last: b goes first
    c = store.create()
    assert store.get(b.id) is None and store.get(a.id) is a and store.get(c.id) is c
    a.drive_token = object()
    clock.now += 1
    store.get(c.id)
    d = store.create()  # a drives: c goes although a was used earlier
    assert store.get(a.id) is a and store.get(c.id) is None and store.get(d.id) is d


def test_session_ids_are_checked_before_lookup() -> None:
    assert valid_session_id("abcdefghijklmnop_-12")
    for bad in (None, "", "short", "x" * 65, "bad id with spaces here", "../../etc/passwd_xxxxx"):
        assert not valid_session_id(bad)


def test_shipped_examples_equal_the_repository_examples() -> None:
    if not (REPO / "examples").is_dir():
        pytest.skip("not a source checkout")
    for name in examples():
        for f in ("train.yaml", "route.yaml", "scenario.yaml"):
            assert filecmp.cmp(EXAMPLES_DIR / name / f, REPO / "examples" / name / f, shallow=False), (
                name,
                f,
            )


@pytest.mark.parametrize("name", ["metro_b", "loco_001", "freight_000"])
def test_model_to_spec_conversion_is_exact(name: str) -> None:
    from trainsim.io import trainsim_yaml as tsy

    scenario = trainsim.load_scenario(REPO / "examples" / name / "scenario.yaml")
    mapping, notes = train_to_dict(scenario.train)
    train = tsy.train_from_dict(mapping)
    route = tsy.route_from_dict(route_to_dict(scenario.route))
    v = np.linspace(0, scenario.train.max_speed_mps * 1.2, 301)
    np.testing.assert_allclose(train.traction(v), scenario.train.traction(v), rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(
        train.running_resistance_n(v), scenario.train.running_resistance_n(v), rtol=1e-9, atol=1e-9
    )
    assert train.mass_kg == pytest.approx(scenario.train.mass_kg)
    assert train.inertial_mass_kg == pytest.approx(scenario.train.inertial_mass_kg)
    assert notes
    a = trainsim.run_fastest(scenario.train, scenario.route, scenario.settings)
    b = trainsim.run_fastest(train, route, scenario.settings)
    assert b.running_time_s == pytest.approx(a.running_time_s, rel=1e-9)
    assert b.energy_kwh.net == pytest.approx(a.energy_kwh.net, rel=1e-6)


def test_error_detail_of_a_several_problem_error_keeps_value_and_allowed() -> None:
    from trainsim.io import trainsim_yaml as tsy

    with pytest.raises(InputError) as info:
        tsy.train_spec_from_dict(
            {
                "schema": "trainsim/train",
                "version": 1,
                "name": "x",
                "mass_t": -1,
                "max_speed_kmh": 900,
                "traction": {"model": "table"},
            }
        )
    detail = input_error_detail(info.value)
    assert len(detail) == len(info.value.problems) >= 1
    for d, p in zip(detail, info.value.problems, strict=True):
        assert d["field"] == p.field and d["value"] == p.value and d["allowed"] == p.allowed
        assert f"got {p.value!r}" in d["msg"] and f"allowed: {p.allowed}" in d["msg"]


def test_serve_prints_the_address_and_runs_uvicorn(monkeypatch, capsys) -> None:
    import uvicorn

    from trainsim.cli.web import serve

    seen = {}
    monkeypatch.setattr(uvicorn, "run", lambda app, **kw: seen.update(kw, app=app))
    serve()
    assert "http://127.0.0.1:8000/" in capsys.readouterr().out
    assert seen["host"] == "127.0.0.1" and seen["port"] == 8000
    serve(host="::1", port=9001)
    assert "http://[::1]:9001/" in capsys.readouterr().out


def test_serve_options_reach_the_application(monkeypatch, capsys) -> None:
    import uvicorn

    from trainsim.cli.web import serve

    seen = {}
    monkeypatch.setattr(uvicorn, "run", lambda app, **kw: seen.update(kw, app=app))
    serve(
        host="0.0.0.0",
        allowed_host=["trains.example"],
        workers=3,
        drive_hosts=1,
        time_limit_s=5,
        memory_limit_mb=256,
    )
    settings = seen["app"].state.web_settings
    assert {"127.0.0.1", "localhost", "0.0.0.0", "trains.example"} <= set(settings.allowed_hosts)
    assert (settings.workers, settings.drive_hosts, settings.job_time_limit_s) == (3, 1, 5)
    assert settings.job_memory_limit_bytes == 256 * 2**20
    assert "no login" in capsys.readouterr().err


def test_shipped_multipoint_example_files_equal_the_repository_examples() -> None:
    from trainsim.web.examples import EXAMPLES_DIR

    from .conftest import REPO

    for name in ("train.yaml", "route.yaml", "scenario_dp.yaml", "scenario_head.yaml"):
        shipped = (EXAMPLES_DIR / "heavy_haul" / name).read_text()
        assert shipped == (REPO / "examples" / "heavy_haul" / name).read_text(), name


def test_every_shipped_example_passes_the_bounds_of_put_and_upload() -> None:
    from trainsim.web import WebSettings, guard
    from trainsim.web.convert import spec_dict
    from trainsim.web.examples import examples, route_spec, train_spec

    for name in examples():
        guard.check_document(spec_dict(train_spec(name)), WebSettings())
        guard.check_document(spec_dict(route_spec(name)), WebSettings())
