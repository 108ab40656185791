"""The JSON API of the web application (the page uses nothing else; OpenAPI at ``/docs``).

Every endpoint works on the caller's session (cookie ``trainsim_session`` or header
``X-Trainsim-Session``; a new session is made and returned in both when none is given). Errors are
JSON ``{"message", "detail": [{"field", "loc", "msg"}...]}`` (see :mod:`trainsim.web.errors`).
"""

from __future__ import annotations

import dataclasses
import functools
import json
import re
import time
from typing import Annotated, Any

from fastapi import APIRouter, Body, File, Request, UploadFile
from fastapi.concurrency import run_in_threadpool
from fastapi.responses import JSONResponse, PlainTextResponse, Response
from pydantic import BaseModel, ConfigDict, Field, ValidationError

import trainsim
from trainsim.errors import InputError, TrainsimError
from trainsim.io import trainsim_yaml as tsy
from trainsim.model.scenario import RunSettings
from trainsim.web import guard, strategies
from trainsim.web.cache import identity
from trainsim.web.config import WebSettings
from trainsim.web.convert import spec_dict
from trainsim.web.errors import ApiError, format_loc, input_error
from trainsim.web.examples import examples, route_spec, train_spec
from trainsim.web.payloads import route_payload, run_brief, run_payload, train_payload
from trainsim.web.sessions import Loaded, SessionStore, StoredRun, WebSession
from trainsim.web.workers import (
    STARTING,
    ClientGoneError,
    JobFailedError,
    JobLimitError,
    PoolBusyError,
    WorkerPool,
    run_job,
    unwrap,
)

router = APIRouter(prefix="/api")

_ERRORS: dict[int | str, dict[str, Any]] = {
    422: {"description": "invalid input: `message` and field-level `detail` with the core's messages"},
}


# ====================================================================== helpers
def store_of(request: Request) -> SessionStore:
    return request.app.state.store


def settings_of(request: Request) -> WebSettings:
    return request.app.state.web_settings


def session_of(request: Request) -> WebSession:
    """The caller's session (made by the session middleware on first use)."""
    return request.app.state.session_for(request)


async def work(
    request: Request,
    session: WebSession,
    name: str,
    *args: Any,
    local: bool = False,
    time_limit_s: float | None = None,
) -> Any:
    """Run ``trainsim.web.jobs.<name>(*args)`` in a worker process, within the limits of the
    application; every failure becomes a 4xx or 503 answer (never a 500). ``local``: in a thread of
    the server process instead (strategies registered after start-up, which workers do not know)."""
    limits = settings_of(request)
    with session.lock:
        if session.jobs >= limits.max_jobs_per_session:
            raise ApiError(
                429,
                f"this session already has {session.jobs} requests in progress; "
                f"allowed: at most {limits.max_jobs_per_session} at once",
            )
        session.jobs += 1
    try:
        pool: WorkerPool | None = request.app.state.pool
        if pool is None or local:
            return unwrap(await run_in_threadpool(run_job, name, args))
        return await pool.call(name, *args, gone=request.is_disconnected, time_limit_s=time_limit_s)
    except InputError as exc:
        raise input_error(exc) from exc
    except TrainsimError as exc:
        raise ApiError(422, str(exc)) from exc
    except JobLimitError as exc:
        raise ApiError(422, exc.message, [{"field": None, "loc": [], "msg": exc.message}]) from exc
    except PoolBusyError as exc:
        reason = str(exc) if str(exc) == STARTING else "every worker is in use and the queue is full"
        raise ApiError(503, f"the server is busy: {reason}; try again shortly") from exc
    except ClientGoneError as exc:
        raise ApiError(499, "the client closed the request; its work was stopped") from exc
    except JobFailedError as exc:
        raise ApiError(
            422, f"trainsim could not compute this input (internal error: {exc}); please report it"
        ) from exc
    finally:
        with session.lock:
            session.jobs -= 1


def _cached(loaded: Loaded, build: Any) -> bytes:
    """The answer body of a loaded train or route (computed once)."""
    if loaded.payload is None:
        loaded.payload = json.dumps(build(spec_dict(loaded.spec), loaded), separators=(",", ":")).encode()
    return loaded.payload


def _json(payload: Any, status: int = 200) -> JSONResponse:
    # straight to json.dumps: FastAPI's generic encoder is slow on the long lists of a trace
    return JSONResponse(payload, status_code=status)


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", name).strip("_")[:60] or "trainsim"


def _settings_dict(s: RunSettings) -> dict[str, Any]:
    return {"max_step_m": s.max_step_m, "braking_fraction": s.braking_fraction}


def _raw(body: bytes, status: int = 200) -> Response:
    return Response(body, status_code=status, media_type="application/json")


def _train_out(session: WebSession) -> Any:
    if session.train is None:
        raise ApiError(404, "no train loaded: load an example, open a file or PUT a train")
    return _raw(_cached(session.train, train_payload))


def _route_out(session: WebSession) -> Any:
    if session.route is None:
        raise ApiError(404, "no route loaded: load an example, open a file or PUT a route")
    return _raw(_cached(session.route, route_payload))


@functools.lru_cache(maxsize=16)
def _example_train(name: str) -> Loaded:
    """An example's train, validated and with its answer body (one shared object: never modified)."""
    spec = train_spec(name)
    loaded = Loaded(spec, spec.to_train(name), f"example {name}", spec.notes(), spec.warnings())
    _cached(loaded, train_payload)
    return loaded


@functools.lru_cache(maxsize=16)
def _example_route(name: str) -> Loaded:
    """An example's route (one shared object: never modified)."""
    spec = route_spec(name)
    loaded = Loaded(spec, spec.to_route(name), f"example {name}", spec.notes())
    _cached(loaded, route_payload)
    return loaded


def _example(name: str):
    found = examples().get(name)
    if found is None:
        raise ApiError(
            404,
            f"no example named '{name}'; allowed: {', '.join(examples())}",
            [{"field": "name", "loc": ["name"], "msg": f"unknown example; allowed: {', '.join(examples())}"}],
        )
    return found


async def _read_upload(file: UploadFile, limits: WebSettings) -> tuple[bytes, str]:
    content = await file.read(limits.max_body_bytes + 1)
    if len(content) > limits.max_body_bytes:
        raise ApiError(413, f"file too large; allowed: at most {limits.max_body_bytes} bytes")
    name = (file.filename or "upload.yaml")[:200]
    return content, name


# ====================================================================== models (for the docs)
class SessionInfo(BaseModel):
    id: str
    train: str | None = Field(description="name of the session's train")
    route: str | None = Field(description="name of the session's route")
    settings: dict[str, float] = Field(description="run settings: max_step_m, braking_fraction")
    runs: list[dict[str, Any]]


class ExampleInfo(BaseModel):
    name: str
    title: str
    description: str


class RunRequest(BaseModel):
    """A run of the session's train over its route."""

    model_config = ConfigDict(extra="forbid")

    strategy: str = Field("fastest", description="a name from GET /api/strategies")
    params: dict[str, Any] = Field(default_factory=dict, description="the strategy's parameters")
    settings: dict[str, Any] | None = Field(
        None,
        description="run settings (max_step_m [m], braking_fraction [-]); default: the session's",
        examples=[{"max_step_m": 5, "braking_fraction": 1.0}],
    )
    label: str | None = Field(None, max_length=80, description="name shown in the page")


_TRAIN_BODY = Body(
    description="a `trainsim/train` mapping (docs/FORMAT.md; JSON schema at GET /api/schema/train)",
    openapi_examples={
        "minimal": {
            "summary": "a train given by its mass",
            "value": {
                "schema": "trainsim/train",
                "version": 1,
                "name": "Test train",
                "mass_t": 200,
                "length_m": 100,
                "gamma": 0.1,
                "max_speed_kmh": 80,
                "traction": {"model": "table", "speed_kmh": [0, 40, 80], "force_kn": [200, 200, 100]},
                "braking": {"model": "deceleration", "deceleration_mps2": 0.8},
                "resistance": [
                    {
                        "family": "davis_kn_kmh",
                        "applies_to": "train",
                        "a_kn": 2,
                        "b_kn_per_kmh": 0.02,
                        "c_kn_per_kmh2": 0.0006,
                    }
                ],
            },
        }
    },
)
_ROUTE_BODY = Body(
    description="a `trainsim/route` mapping (docs/FORMAT.md; JSON schema at GET /api/schema/route)",
    openapi_examples={
        "minimal": {
            "summary": "two stations 2 km apart",
            "value": {
                "schema": "trainsim/route",
                "version": 1,
                "name": "Test line",
                "length_m": 2000,
                "stations": [{"name": "A", "position_m": 0}, {"name": "B", "position_m": 2000}],
                "speed_limits": [{"from_m": 0, "limit_kmh": 80}],
                "line_resistance": {"curve_formula": "tbt1407", "tunnel_formula": "tbt1407"},
            },
        }
    },
)


# ====================================================================== session, examples, schemas
@router.get("/health", tags=["session"], summary="Server status")
def health(request: Request) -> dict[str, Any]:
    return {"status": "ok", "version": trainsim.__version__}


@router.get("/session", tags=["session"], response_model=SessionInfo, summary="The caller's session")
def get_session(request: Request) -> dict[str, Any]:
    session = session_of(request)
    with session.lock:
        return {
            "id": session.id,
            "train": session.train.model.name if session.train else None,
            "route": session.route.model.name if session.route else None,
            "settings": _settings_dict(session.settings),
            "runs": [run_brief(r) for r in list(session.runs.values())],
        }


@router.get("/examples", tags=["examples"], response_model=list[ExampleInfo], summary="Shipped examples")
def list_examples() -> list[dict[str, Any]]:
    return [{"name": e.name, "title": e.title, "description": e.description} for e in examples().values()]


@router.post(
    "/examples/{name}",
    tags=["examples"],
    responses={404: {"description": "unknown example"}},
    summary="Load an example's train, route and run settings into the session",
)
def load_example(name: str, request: Request) -> Any:
    ex = _example(name)
    session = session_of(request)
    train, route = _example_train(ex.name), _example_route(ex.name)
    assert train.payload is not None and route.payload is not None
    with session.lock:
        session.train, session.route, session.settings = train, route, ex.settings
    settings = json.dumps(_settings_dict(ex.settings)).encode()
    return _raw(
        b'{"train":' + train.payload + b',"route":' + route.payload + b',"settings":' + settings + b"}"
    )


@router.get(
    "/schema/{kind}", tags=["examples"], summary="JSON schema of a trainsim/train or trainsim/route mapping"
)
def schema(kind: str) -> dict[str, Any]:
    models = {"train": tsy.TrainSpec, "route": tsy.RouteSpec}
    if kind not in models:
        raise ApiError(404, f"no schema '{kind}'; allowed: train, route")
    return models[kind].model_json_schema(by_alias=True)


# ====================================================================== train
@router.get(
    "/train",
    tags=["train"],
    responses={404: {"description": "no train loaded"}},
    summary="The session's train: spec, figures, effort and resistance curves",
)
def get_train(request: Request) -> Any:
    session = session_of(request)
    with session.lock:
        return _train_out(session)


@router.put("/train", tags=["train"], responses=_ERRORS, summary="Replace the session's train (validated)")
async def put_train(request: Request, spec: Annotated[dict[str, Any], _TRAIN_BODY]) -> Any:
    session = session_of(request)
    try:  # size bounds first, here: most hostile documents never cost a worker round trip
        guard.check_document(spec, settings_of(request))
    except InputError as exc:
        raise input_error(exc) from exc
    with session.lock:
        source = session.train.source if session.train else "edited"
    shown = source if source.endswith("(edited)") else f"{source} (edited)"
    loaded, payload = await work(
        request, session, "train_from_mapping", spec, "edited train", settings_of(request), shown
    )
    loaded.payload = payload
    with session.lock:
        session.train = loaded
        return _train_out(session)


@router.post(
    "/train/example/{name}",
    tags=["train"],
    responses={404: {"description": "unknown example"}},
    summary="Load an example's train",
)
def train_example(name: str, request: Request) -> Any:
    ex = _example(name)
    loaded = _example_train(ex.name)
    session = session_of(request)
    with session.lock:
        session.train = loaded
        return _train_out(session)


@router.post(
    "/train/upload",
    tags=["train"],
    responses={**_ERRORS, 413: {"description": "file too large"}},
    summary="Open a train file of any format trainsim reads",
)
async def train_upload(
    request: Request,
    file: Annotated[
        UploadFile,
        File(description="a train/route file: YAML, TTOBench JSON, railML, Excel, zipped CSV tables"),
    ],
) -> Any:
    limits = settings_of(request)
    content, name = await _read_upload(file, limits)
    session = session_of(request)
    loaded, payload = await work(request, session, "upload", "train", content, name, limits)
    loaded.payload = payload
    with session.lock:
        session.train = loaded
        return _train_out(session)


def _yaml_attachment(loaded: Any, kind: str) -> Response:
    """The loaded train or route (``kind``) as a trainsim YAML file to download (404 if none)."""
    if loaded is None:
        raise ApiError(404, f"no {kind} loaded")
    return PlainTextResponse(
        tsy.dump_yaml(loaded.spec),
        media_type="application/yaml",
        headers={"Content-Disposition": f'attachment; filename="{_slug(loaded.model.name)}.{kind}.yaml"'},
    )


@router.get(
    "/train/yaml",
    tags=["train"],
    response_class=PlainTextResponse,
    responses={404: {"description": "no train loaded"}},
    summary="The train as a trainsim YAML file",
)
def train_yaml(request: Request) -> Response:
    session = session_of(request)
    with session.lock:
        return _yaml_attachment(session.train, "train")


# ====================================================================== route
@router.get(
    "/route",
    tags=["route"],
    responses={404: {"description": "no route loaded"}},
    summary="The session's route: spec, figures and line profile",
)
def get_route(request: Request) -> Any:
    session = session_of(request)
    with session.lock:
        return _route_out(session)


@router.put("/route", tags=["route"], responses=_ERRORS, summary="Replace the session's route (validated)")
async def put_route(request: Request, spec: Annotated[dict[str, Any], _ROUTE_BODY]) -> Any:
    session = session_of(request)
    try:  # size bounds first, here: most hostile documents never cost a worker round trip
        guard.check_document(spec, settings_of(request))
    except InputError as exc:
        raise input_error(exc) from exc
    with session.lock:
        source = session.route.source if session.route else "edited"
    shown = source if source.endswith("(edited)") else f"{source} (edited)"
    loaded, payload = await work(
        request, session, "route_from_mapping", spec, "edited route", settings_of(request), shown
    )
    loaded.payload = payload
    with session.lock:
        session.route = loaded
        return _route_out(session)


@router.post(
    "/route/example/{name}",
    tags=["route"],
    responses={404: {"description": "unknown example"}},
    summary="Load an example's route (and its run settings)",
)
def route_example(name: str, request: Request) -> Any:
    ex = _example(name)
    loaded = _example_route(ex.name)
    session = session_of(request)
    with session.lock:
        session.route, session.settings = loaded, ex.settings
        return _route_out(session)


@router.post(
    "/route/upload",
    tags=["route"],
    responses={**_ERRORS, 413: {"description": "file too large"}},
    summary="Open a route file of any format trainsim reads",
)
async def route_upload(
    request: Request,
    file: Annotated[
        UploadFile,
        File(description="a train/route file: YAML, TTOBench JSON, railML, Excel, zipped CSV tables"),
    ],
) -> Any:
    limits = settings_of(request)
    content, name = await _read_upload(file, limits)
    session = session_of(request)
    loaded, payload = await work(request, session, "upload", "route", content, name, limits)
    loaded.payload = payload
    with session.lock:
        session.route = loaded
        return _route_out(session)


@router.get(
    "/route/yaml",
    tags=["route"],
    response_class=PlainTextResponse,
    responses={404: {"description": "no route loaded"}},
    summary="The route as a trainsim YAML file",
)
def route_yaml(request: Request) -> Response:
    session = session_of(request)
    with session.lock:
        return _yaml_attachment(session.route, "route")


# ====================================================================== runs
@router.get("/strategies", tags=["runs"], summary="Strategies a run can use, with their parameter schemas")
def list_strategies() -> list[dict[str, Any]]:
    return [s.describe() for s in strategies.available()]


def run_settings_for(session: WebSession, given: dict[str, Any] | None, limits: WebSettings) -> RunSettings:
    """Validated run settings (the session's when not given), within the run-length bound."""
    if given is None:
        settings = session.settings
    else:
        merged = {**_settings_dict(session.settings), **given}
        try:
            settings = tsy.settings_from_dict(merged, "run settings")
        except InputError as exc:
            raise input_error(exc) from exc
    if session.route is not None:
        length = session.route.model.length_m
        if length / settings.max_step_m > limits.max_grid_points:
            least = length / limits.max_grid_points
            msg = (
                f"integration step too small for a {length:g} m route in the web application "
                f"(got {settings.max_step_m:g}); allowed: >= {least:.3g} m"
            )
            raise ApiError(
                422, msg, [{"field": "settings.max_step_m", "loc": ["settings", "max_step_m"], "msg": msg}]
            )
    return settings


@router.post(
    "/runs",
    tags=["runs"],
    status_code=201,
    responses={**_ERRORS, 409: {"description": "no train or route"}},
    summary="Run the session's train over its route with a strategy",
)
async def create_run(request: Request, body: RunRequest) -> Response:
    limits = settings_of(request)
    session = session_of(request)
    strategy = strategies.get(body.strategy)
    if strategy is None:
        names = ", ".join(s.name for s in strategies.available())
        raise ApiError(
            422,
            f"unknown strategy '{body.strategy}'; allowed: {names}",
            [
                {
                    "field": "strategy",
                    "loc": ["strategy"],
                    "msg": f"unknown strategy; allowed: {names}",
                    "value": body.strategy[:80],
                }
            ],
        )
    try:
        params = strategy.params.model_validate(body.params)
    except ValidationError as exc:
        detail = [
            {"field": format_loc(["params", *e["loc"]]), "loc": ["params", *e["loc"]], "msg": e["msg"]}
            for e in exc.errors(include_url=False)
        ][:20]
        raise ApiError(
            422,
            "invalid strategy parameters: " + "; ".join(f"{d['field']}: {d['msg']}" for d in detail),
            detail,
        ) from exc
    with session.lock:
        if session.train is None or session.route is None:
            raise ApiError(409, "load a train and a route before running")
        settings = run_settings_for(session, body.settings, limits)
        train_loaded, route_loaded = session.train, session.route
        train, route = train_loaded.model, route_loaded.model
    built_in = strategy.name in strategies.BUILT_IN and strategies.get(strategy.name) is strategy
    params_dict = params.model_dump()

    def compute() -> Any:
        return work(
            request,
            session,
            "run",
            strategy.name if built_in else strategy,
            params_dict,
            train,
            route,
            settings,
            limits.max_plot_points,
            local=not built_in,
        )

    if built_in:
        key = json.dumps(
            [identity(train_loaded), identity(route_loaded), repr(settings), strategy.name, params_dict],
            sort_keys=True,
            default=str,
        )
        result, body_json = await request.app.state.run_cache.get(key, compute)
    else:
        result, body_json = await compute()
    with session.lock:
        run_id = session.next_run_id()
        run = StoredRun(
            id=run_id,
            label=body.label or f"{strategy.label} ({run_id})",
            strategy=strategy.name,
            created=time.time(),
            result=result,
            route=route,
            train=train,
            params={"strategy": params.model_dump(), "settings": _settings_dict(settings)},
        )
        store_of(request).add_run(session, run)
    head = json.dumps({**run_brief(run), "params": run.params}, separators=(",", ":")).encode()
    return _raw(head[:-1] + b"," + body_json[1:], 201)


@router.get("/runs", tags=["runs"], summary="The session's runs and recorded drives")
def list_runs(request: Request) -> list[dict[str, Any]]:
    session = session_of(request)
    with session.lock:
        return [run_brief(r) for r in list(session.runs.values())]


def _run(session: WebSession, run_id: str) -> StoredRun:
    run = session.runs.get(run_id)
    if run is None:
        raise ApiError(404, f"no run '{run_id}' in this session (runs: {', '.join(session.runs) or 'none'})")
    return run


@router.get(
    "/runs/{run_id}",
    tags=["runs"],
    responses={404: {"description": "no such run"}},
    summary="A run: summary, plot data and line profile",
)
def get_run(run_id: str, request: Request) -> Response:
    session = session_of(request)
    with session.lock:
        return _json(run_payload(_run(session, run_id), settings_of(request).max_plot_points))


@router.delete(
    "/runs/{run_id}",
    tags=["runs"],
    status_code=204,
    responses={404: {"description": "no such run"}},
    summary="Forget a run",
)
def delete_run(run_id: str, request: Request) -> Response:
    session = session_of(request)
    with session.lock:
        _run(session, run_id)
        del session.runs[run_id]
    return Response(status_code=204)


@router.get(
    "/runs/{run_id}/trace.csv",
    tags=["runs"],
    response_class=PlainTextResponse,
    responses={404: {"description": "no such run"}},
    summary="The run's full trace as CSV",
)
def run_trace_csv(run_id: str, request: Request) -> Response:
    session = session_of(request)
    with session.lock:
        run = _run(session, run_id)
    text = run.result.to_dataframe().to_csv(index=False)
    return PlainTextResponse(
        text,
        media_type="text/csv",
        headers={"Content-Disposition": f'attachment; filename="{_slug(run.label)}.trace.csv"'},
    )


@router.get(
    "/runs/{run_id}/summary.json",
    tags=["runs"],
    responses={404: {"description": "no such run"}},
    summary="The run's summary (as `trainsim run --json`)",
)
def run_summary_json(run_id: str, request: Request) -> Response:
    import json

    session = session_of(request)
    with session.lock:
        run = _run(session, run_id)
    text = json.dumps(run.result.summary(), indent=2, allow_nan=False)
    return Response(
        text,
        media_type="application/json",
        headers={"Content-Disposition": f'attachment; filename="{_slug(run.label)}.summary.json"'},
    )


def route_prefix(route: Any, end_m: float) -> Any:
    """The route cut at ``end_m`` [m] (a station's position): stations up to it, every section
    clipped to it (a tunnel crossing ``end_m`` keeps its full length, which sets its resistance)."""

    def clip(sections: tuple, keep_length: bool = False) -> tuple:
        out = []
        for x in sections:
            if x.start_m >= end_m:
                continue
            out.append(x if keep_length or x.end_m <= end_m else dataclasses.replace(x, end_m=end_m))
        return tuple(out)

    return dataclasses.replace(
        route,
        end_m=end_m,
        stations=tuple(s for s in route.stations if s.position_m <= end_m + 1e-9),
        speed_limits=clip(route.speed_limits),
        gradients=clip(route.gradients),
        curves=clip(route.curves),
        tunnels=clip(route.tunnels, keep_length=True),
        electrification=clip(route.electrification),
    )


@router.post(
    "/runs/{run_id}/fastest",
    tags=["runs"],
    status_code=201,
    responses={**_ERRORS, 404: {"description": "no such run"}},
    summary="The fastest run of a run's own train and line, over the same distance (to compare a drive with)",
)
async def fastest_for(run_id: str, request: Request) -> Response:
    limits = settings_of(request)
    session = session_of(request)
    with session.lock:
        base = _run(session, run_id)
        settings = session.settings
    route = base.route
    trace = base.result.trace
    reached = float(trace.position_m[-1]) if len(trace) else route.start_m
    stops = [s for s in route.stations if s.position_m <= reached + 5.0]
    note = ""
    if reached < route.end_m - 5.0 and len(stops) >= 2:
        route = route_prefix(route, stops[-1].position_m)
        note = f" to {stops[-1].name}"
    elif reached < route.end_m - 5.0:
        raise ApiError(422, f"run '{run_id}' did not reach a second station: nothing to compare")
    result, body_json = await work(
        request, session, "run", "fastest", {}, base.train, route, settings, limits.max_plot_points
    )
    with session.lock:
        new_id = session.next_run_id()
        run = StoredRun(
            id=new_id,
            label=f"Fastest{note} ({base.label}'s train and line)"[:80],
            strategy="fastest",
            created=time.time(),
            result=result,
            route=route,
            train=base.train,
            params={"strategy": {}, "settings": _settings_dict(settings), "compared_with": run_id},
        )
        store_of(request).add_run(session, run)
    head = json.dumps({**run_brief(run), "params": run.params}, separators=(",", ":")).encode()
    return _raw(head[:-1] + b"," + body_json[1:], 201)


class CurveRequest(BaseModel):
    """Line supplements of an energy-time curve."""

    model_config = ConfigDict(extra="forbid")

    supplements_percent: list[Annotated[float, Field(ge=0, le=100, allow_inf_nan=False)]] = Field(
        default_factory=lambda: [0.0, 2.0, 5.0, 10.0, 15.0, 20.0, 30.0],
        min_length=1,
        max_length=12,
        description="running-time supplements over the fastest run [%]",
    )


@router.post(
    "/curves/energy-time",
    tags=["runs"],
    responses={**_ERRORS, 409: {"description": "no train or route"}},
    summary="Energy against running time of the energy-efficient strategy for line supplements",
)
async def energy_time_curve(request: Request, body: CurveRequest) -> Response:
    session = session_of(request)
    with session.lock:
        if session.train is None or session.route is None:
            raise ApiError(409, "load a train and a route first")
        train, route, settings = session.train.model, session.route.model, session.settings
        run_settings_for(session, None, settings_of(request))
    body_json = await work(
        request, session, "energy_time", train, route, settings, sorted(body.supplements_percent)
    )
    return _raw(body_json)


@router.post(
    "/multipoint/upload",
    tags=["runs"],
    responses={**_ERRORS, 413: {"description": "file too large"}},
    summary="Run one's own multi-point scenario: coupler-force heat map and extreme couplers",
)
async def multipoint_upload(
    request: Request,
    file: Annotated[
        UploadFile,
        File(
            description="a scenario YAML with `model: multi_point` (train and route inline), or a zip of a "
            "scenario folder: scenario*.yaml with the train, route and profile files it names"
        ),
    ],
) -> Response:
    limits = settings_of(request)
    content, name = await _read_upload(file, limits)
    session = session_of(request)
    body_json = await work(request, session, "multipoint_upload", content, name, limits)
    return _raw(body_json)


@router.post(
    "/multipoint/{name}",
    tags=["runs"],
    responses={**_ERRORS, 404: {"description": "no such multi-point example"}},
    summary="Run a shipped multi-point scenario: coupler-force heat map and extreme couplers",
)
async def multipoint_example(name: str, request: Request) -> Response:
    from trainsim.web.jobs import MULTIPOINT_EXAMPLES

    if name not in MULTIPOINT_EXAMPLES:
        raise ApiError(
            404, f"no multi-point example '{name[:80]}'; allowed: {', '.join(MULTIPOINT_EXAMPLES)}"
        )
    session = session_of(request)

    async def compute() -> Any:
        # a shipped scenario (trusted, fixed): a longer limit than a user's request
        limit = max(settings_of(request).job_time_limit_s, 300.0)
        return None, await work(request, session, "multipoint_example", name, time_limit_s=limit)

    # the example never changes: computed once, shared by every session
    _, body_json = await request.app.state.run_cache.get(f"multipoint:{name}", compute)
    return _raw(body_json)


@router.get("/operations", tags=["runs"], summary="Shipped operation examples (name, description)")
def list_operations() -> list[dict[str, str]]:
    from trainsim.web.jobs import OPERATION_EXAMPLES

    return [{"name": k, "description": v[1]} for k, v in OPERATION_EXAMPLES.items()]


@router.post(
    "/operations/upload",
    tags=["runs"],
    responses={**_ERRORS, 413: {"description": "file too large"}},
    summary="Run one's own operation: train graph, conflicts, delays per station, headways",
)
async def operation_upload(
    request: Request,
    file: Annotated[
        UploadFile,
        File(
            description="an operation YAML (`schema: trainsim/operation`), or a zip holding it with the "
            "train, route, railML or spreadsheet files it names (folders kept; every path inside the zip)"
        ),
    ],
) -> Response:
    limits = settings_of(request)
    content, name = await _read_upload(file, limits)
    session = session_of(request)
    return _raw(await work(request, session, "operation_upload", content, name, limits))


@router.post(
    "/operations/{name}",
    tags=["runs"],
    responses={**_ERRORS, 404: {"description": "no such operation example"}},
    summary="Run a shipped operation: train graph, conflicts, delays per station, headways",
)
async def operation_example(name: str, request: Request) -> Response:
    from trainsim.web.jobs import OPERATION_EXAMPLES

    if name not in OPERATION_EXAMPLES:
        raise ApiError(404, f"no operation example '{name[:80]}'; allowed: {', '.join(OPERATION_EXAMPLES)}")
    session = session_of(request)

    async def compute() -> Any:
        limit = max(settings_of(request).job_time_limit_s, 300.0)  # a shipped file: trusted, fixed
        return None, await work(request, session, "operation_example", name, time_limit_s=limit)

    # the example never changes: computed once, shared by every session
    _, body_json = await request.app.state.run_cache.get(f"operation:{name}", compute)
    return _raw(body_json)
