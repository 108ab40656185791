"""More than 10,000 generated bad requests (seeded) against one in-process application: not one answer
>= 500, nothing invalid stored, and afterwards the server is alive and gives the CLI's figures.

Bounded: the barrage stops after 52 s of wall time (it takes about 20-25 s on an idle 2-core machine).
"""

from __future__ import annotations

import asyncio
import copy
import io
import json
import random
import re
import time
import zipfile
from collections import Counter
from typing import Any

import httpx
import pytest

import trainsim
from trainsim.web import WebSettings, create_app

from .conftest import REPO

SEED = 19
MIN_REQUESTS = 10_000
MAX_SECONDS = 52.0
CONCURRENCY = 8
HOST = "http://127.0.0.1"

HOSTILE: list[Any] = [
    float("nan"),
    float("inf"),
    -float("inf"),
    1e308,
    -1e308,
    1e30,
    10**400,
    1_000_000_000,
    -1,
    0,
    1e-320,
    "abc",
    "",
    None,
    True,
    [],
    {},
    [1] * 6000,
    "x" * 20_000,
    {"a": [{"b": [{"c": [[[[1]]]]}]}]},
]


def _leaves(node: Any, path: tuple = ()) -> list[tuple]:
    if isinstance(node, dict):
        return [p for k, v in node.items() for p in _leaves(v, (*path, k))] or [path]
    if isinstance(node, list):
        return [p for i, v in enumerate(node) for p in _leaves(v, (*path, i))] or [path]
    return [path]


def _set(doc: Any, path: tuple, value: Any) -> Any:
    doc = copy.deepcopy(doc)
    if not path:
        return value
    node = doc
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return doc


def _mutate(rng: random.Random, spec: dict[str, Any]) -> Any:
    """A spec with one to three hostile changes."""
    doc = spec
    for _ in range(rng.randint(1, 3)):
        kind = rng.random()
        leaves = _leaves(doc)
        if kind < 0.7:
            doc = _set(doc, rng.choice(leaves), rng.choice(HOSTILE))
        elif kind < 0.8:
            doc = _set(doc, rng.choice(leaves)[:-1] or ("name",), rng.choice(HOSTILE))
        elif kind < 0.9:
            doc = _set(doc, ("extra_field",), rng.choice(HOSTILE))
        else:
            # deeper than Python's json module can write: built as text
            levels = rng.choice([30, 200, 2000, 20_000])
            text = json.dumps(_set(doc, rng.choice(leaves), "__DEEP__"))
            return text.replace('"__DEEP__"', '{"a": [' * levels + "1" + "]}" * levels).encode()
    return doc


def _yaml_alias_bomb(levels: int = 12) -> bytes:
    lines = ['a0: &a0 ["x", "x", "x", "x", "x", "x", "x", "x", "x", "x"]']
    for i in range(1, levels):
        lines.append(f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]")
    return ("\n".join(lines) + "\n").encode()


XML_BOMB = b"""<?xml version="1.0"?>
<!DOCTYPE lolz [<!ENTITY lol "lol"><!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
<!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
<!ENTITY xxe SYSTEM "file:///etc/passwd">]>
<railml version="2.4"><rollingstock>&lol3;&xxe;</rollingstock></railml>"""


def _zip(entries: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in entries.items():
            zf.writestr(name, data)
    return buf.getvalue()


def _upload(rng: random.Random, train_yaml: bytes) -> tuple[str, bytes]:
    choices: list[tuple[str, bytes]] = [
        ("..", train_yaml),
        (".", train_yaml),
        ("../../etc/passwd", train_yaml),
        ("", train_yaml),
        ("a" * 500 + ".yaml", train_yaml),
        ("x.yaml", bytes(rng.getrandbits(8) for _ in range(rng.randint(0, 400)))),
        ("x.yaml", b"\xff\xfe" + "train: ü".encode("utf-16")),
        ("deep.yaml", ("[" * 5000 + "]" * 5000).encode()),
        ("deep.yaml", ("a:\n" + "".join(" " * i + "b:\n" for i in range(1, 300))).encode()),
        ("bomb.yaml", _yaml_alias_bomb()),
        ("bomb.xml", XML_BOMB),
        ("x.railml", b"<railml><rollingstock>"),
        ("t.xlsx", b"PK\x03\x04 not really a workbook"),
        ("t.zip", _zip({"../evil.csv": b"a,b\n1,2\n", "train.csv": b"name\nx\n"})),
        ("t.zip", b"not a zip"),
        ("t.csv", b"a,b\n1,2\n"),
        ("t.exe", b"MZ"),
        ("t.json", b'{"metadata": {}, "mass": "heavy"}'),
        ("t.json", b"[" * 3000),
        ("count.yaml", re.sub(rb"count: \d+", b"count: 1000000000", train_yaml, count=1)),
        ("nan.yaml", train_yaml.replace(b"mass_t:", b"mass_t: .nan #", 1)),
        ("big.yaml", train_yaml.replace(b"mass_t:", b"mass_t: 1e308 #", 1)),
    ]
    return rng.choice(choices)


class _Response:
    def __init__(self, status: int, headers: dict[str, str], content: bytes) -> None:
        self.status_code, self.headers, self.content = status, headers, content

    @property
    def text(self) -> str:
        return self.content.decode("utf-8", "replace")

    def json(self) -> Any:
        return json.loads(self.content)


class RawClient:
    """The smallest ASGI client: one call of the application per request, no HTTP library in between
    (the client shares the machine with the server; this keeps its share small)."""

    def __init__(self, app: Any) -> None:
        self.app = app

    async def request(
        self,
        method: str,
        url: str,
        *,
        headers: dict[str, Any] | None = None,
        content: Any = None,
        json: Any = None,
        files: Any = None,
        client: str = "127.0.0.1",
    ) -> _Response:
        head = {"host": "127.0.0.1"}
        head.update(headers or {})
        chunks: list[bytes] = []
        if files is not None:
            encoded = httpx.Request(method, HOST + "/", files=files)
            chunks = [encoded.read()]
            head["content-type"] = encoded.headers["content-type"]
        elif json is not None:
            chunks = [_json_bytes(json)]
            head["content-type"] = "application/json"
        elif isinstance(content, bytes):
            chunks = [content]
        elif content is not None:
            chunks = [c async for c in content]  # a chunked body: sent in its pieces, no length
        if chunks and not (content is not None and not isinstance(content, bytes)):
            head["content-length"] = str(sum(map(len, chunks)))
        raw_headers = [
            (k.lower().encode("latin-1"), v if isinstance(v, bytes) else str(v).encode("latin-1"))
            for k, v in head.items()
        ]
        path, _, query = url.partition("?")
        scope = {
            "type": "http",
            "asgi": {"version": "3.0"},
            "http_version": "1.1",
            "method": method,
            "scheme": "http",
            "path": path,
            "raw_path": path.encode("latin-1", "replace"),
            "query_string": query.encode(),
            "root_path": "",
            "headers": raw_headers,
            "client": (client, 50000),
            "server": ("127.0.0.1", 80),
            "app": self.app,
        }
        messages = [
            {"type": "http.request", "body": c, "more_body": i < len(chunks) - 1}
            for i, c in enumerate(chunks)
        ] or [{"type": "http.request", "body": b"", "more_body": False}]
        done = asyncio.Event()

        async def receive() -> dict:
            if messages:
                return messages.pop(0)
            await done.wait()
            return {"type": "http.disconnect"}

        status = 0
        out_headers: dict[str, str] = {}
        body: list[bytes] = []

        async def send(message: dict) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = message["status"]
                out_headers.update({k.decode(): v.decode("latin-1") for k, v in message.get("headers", [])})
            elif message["type"] == "http.response.body":
                body.append(message.get("body", b""))
                if not message.get("more_body"):
                    done.set()

        try:
            await self.app(scope, receive, send)
        except Exception:  # an exception out of the application is what a server answers with 500
            status = 500
        done.set()
        return _Response(status, out_headers, b"".join(body))

    async def get(self, url: str, **kw: Any) -> _Response:
        return await self.request("GET", url, **kw)

    async def post(self, url: str, **kw: Any) -> _Response:
        return await self.request("POST", url, **kw)


def _json_bytes(doc: Any) -> bytes:
    # NaN and Infinity as JavaScript's JSON.parse would never send, but Python does
    return doc if isinstance(doc, bytes) else json.dumps(doc).encode()


async def _barrage(client: RawClient, seed: int, deadline: float, counts: Counter, bad: list) -> None:
    rng = random.Random(seed)
    r = await client.post("/api/examples/metro_b")
    assert r.status_code == 200
    sid = r.headers["x-trainsim-session"]
    train = r.json()["train"]["spec"]
    route = r.json()["route"]["spec"]
    train_yaml = (await client.get("/api/train/yaml")).content
    headers = {"X-Trainsim-Session": sid}

    async def send(method: str, url: str, **kw: Any) -> _Response:
        kw.setdefault("headers", headers)
        response = await client.request(method, url, **kw)
        counts[response.status_code] += 1
        if response.status_code >= 500:
            bad.append((method, url, response.status_code, response.text[:300]))
        else:
            # every error answer is the JSON error shape
            if response.status_code >= 400 and response.headers.get("content-type") == "application/json":
                body = response.json()
                assert "message" in body, body
        return response

    while time.monotonic() < deadline and sum(counts.values()) < MIN_REQUESTS + 200:
        pick = rng.random()
        if pick < 0.22:
            await send("PUT", "/api/train", json=_mutate(rng, train))
        elif pick < 0.36:
            await send("PUT", "/api/route", json=_mutate(rng, route))
        elif pick < 0.52:
            params: dict[str, Any] = {}
            strategy = rng.choice(["fastest", "energy_efficient", "lesov", "nope", 7, None])
            if rng.random() < 0.5:
                params["section_running_times_s"] = rng.choice(
                    [
                        [rng.choice(HOSTILE[:11])] * 3,
                        [150.0, float("nan"), 120.0],
                        [1e308, 1e308, 1e308],
                        [0.001] * 3,
                        [100.0] * 2000,
                        "fast",
                    ]
                )
            else:
                params["supplement_percent"] = rng.choice(HOSTILE[:14])
            body: Any = {"strategy": strategy, "params": params}
            if rng.random() < 0.3:
                body["settings"] = {
                    "max_step_m": rng.choice(HOSTILE[:14]),
                    "braking_fraction": rng.random() * 3,
                }
            if rng.random() < 0.1:
                body["label"] = "L" * rng.choice([10, 81, 5000])
            await send("POST", "/api/runs", json=body)
        elif pick < 0.60:
            name, content = _upload(rng, train_yaml)
            kind = rng.choice(["train", "route"])
            await send("POST", f"/api/{kind}/upload", files={"file": (name, content)})
        elif pick < 0.70:
            content = rng.choice(
                [b"{not json", b"[1,2,3]", b"null", b"1e999999", b'"x"', b"[" * 100_000, b"{" * 50_000, b""]
            )
            await send(
                rng.choice(["PUT", "POST"]),
                rng.choice(["/api/train", "/api/route", "/api/runs"]),
                content=content,
                headers={**headers, "content-type": rng.choice(["application/json", "text/plain", "x/y"])},
            )
        elif pick < 0.78:
            url = rng.choice(
                [
                    "/api/runs/r999",
                    "/api/runs/../../etc/passwd",
                    "/api/runs/%00",
                    "/api/runs/r1/trace.csv",
                    "/api/runs/" + "r" * 5000,
                    "/api/examples/nope",
                    "/api/schema/../../x",
                    "/api/nothing",
                    "/static/../../../etc/passwd",
                    "/api/train/example/" + "x" * 300,
                ]
            )
            await send(rng.choice(["GET", "DELETE", "POST", "PATCH"]), url)
        elif pick < 0.86:
            await send(
                "GET",
                rng.choice(["/api/session", "/api/runs", "/api/train"]),
                headers={
                    "X-Trainsim-Session": rng.choice(
                        ["", "x" * 5000, "../../", "\u00e9".encode() * 20, "a" * 64]
                    )
                },
            )
        elif pick < 0.92:
            await send(
                "GET", "/api/health", headers={"host": rng.choice(["evil.example", "", "127.0.0.1:1:2"])}
            )
        elif pick < 0.95:

            async def chunks():
                for _ in range(40):
                    yield b"x" * 65536

            await send(
                "PUT", "/api/train", content=chunks(), headers={**headers, "content-type": "application/json"}
            )
        else:
            # the stored train and route always serve, whatever came before
            for path in ("/api/train", "/api/route", "/api/session"):
                r = await send("GET", path)
                assert r.status_code == 200, (path, r.text[:300])


@pytest.mark.slow
def test_ten_thousand_bad_requests_get_no_500_and_the_server_stays_correct() -> None:
    # every request that names no session makes one: past the client's allowance of new sessions
    # those get 429, and the barrage's own sessions (which hold a train) are never evicted
    settings = WebSettings(job_time_limit_s=3.0, max_jobs_per_session=4)
    app = create_app(settings)
    counts: Counter = Counter()
    bad: list = []

    async def main() -> dict[str, Any]:
        client = RawClient(app)
        deadline = time.monotonic() + MAX_SECONDS
        await asyncio.gather(*(_barrage(client, SEED + i, deadline, counts, bad) for i in range(CONCURRENCY)))
        # afterwards: another user (the barrage's client may still be over its allowance of new
        # sessions) gets a session, and the CLI's figures
        other = "10.0.0.2"
        r = await client.post("/api/examples/metro_b", client=other)
        assert r.status_code == 200, r.text
        sid = {"X-Trainsim-Session": r.headers["x-trainsim-session"]}
        run = await client.post("/api/runs", json={"strategy": "fastest"}, headers=sid, client=other)
        assert run.status_code == 201, run.text
        return run.json()

    started = time.monotonic()
    try:
        run = asyncio.run(main())
    finally:
        pool = app.state.pool
        stats = dict(pool.stats) if pool else {}
        if pool:
            pool.close()
    elapsed = time.monotonic() - started
    total = sum(counts.values())
    print(
        f"\n{total} bad requests in {elapsed:.1f} s; answers {dict(sorted(counts.items()))}; workers {stats}"
    )
    assert not bad, bad[:5]
    assert counts[429] > 0  # the barrage's requests without a session met the rate limit
    assert total >= MIN_REQUESTS, f"only {total} requests in {MAX_SECONDS} s"
    cli = trainsim.run(trainsim.load_scenario(REPO / "examples" / "metro_b" / "scenario.yaml"))
    assert run["running_time_s"] == pytest.approx(cli.running_time_s, rel=1e-12)
    assert run["summary"]["energy_kwh"]["net"] == pytest.approx(cli.energy_kwh.net, rel=1e-12)
    assert json.dumps(run, allow_nan=False)
