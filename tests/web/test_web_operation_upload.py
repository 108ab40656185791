"""One's own operation in the web application (issue 17): an uploaded ``trainsim/operation`` file (YAML,
or a zip with the files it names) runs as ``trainsim operate`` runs it; every hostile upload gets a 4xx
naming the file inside the upload, the line and the field."""

from __future__ import annotations

import io
import zipfile
from collections.abc import Iterator

import pytest
import yaml
from fastapi.testclient import TestClient

from trainsim.io.operation_file import read_operation
from trainsim.io.operation_run import run_operation
from trainsim.web import WebSettings, create_app

from .conftest import REPO

OPS = REPO / "examples" / "operations"
TRAINS = REPO / "tests" / "data" / "trainruns" / "trains"


def _zip(files: dict[str, bytes | str]) -> bytes:
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in files.items():
            zf.writestr(name, data)
    return out.getvalue()


def single_track_files(operation: str | None = None) -> dict[str, bytes | str]:
    """examples/operations/single_track.yaml with the files it names, at their places in the repository
    (so that its ``../../tests/data/trainruns/trains/local.yaml`` resolves inside the zip)."""
    return {
        "examples/operations/single_track.yaml": operation or (OPS / "single_track.yaml").read_text(),
        "examples/operations/single_track_route.yaml": (OPS / "single_track_route.yaml").read_text(),
        "tests/data/trainruns/trains/local.yaml": (TRAINS / "local.yaml").read_text(),
        "tests/data/trainruns/trains/freight.yaml": (TRAINS / "freight.yaml").read_text(),
        "README.txt": "not read: only operation, train, route and line files are taken from the zip",
    }


@pytest.fixture(scope="module")
def client() -> Iterator[TestClient]:
    with TestClient(create_app(WebSettings(workers=0, drive_hosts=0))) as c:
        yield c


def upload(client: TestClient, name: str, content: bytes):
    return client.post("/api/operations/upload", files={"file": (name, content)})


def test_an_uploaded_zip_runs_as_the_cli_runs_it(client: TestClient) -> None:
    r = upload(client, "mine.zip", _zip(single_track_files()))
    assert r.status_code == 200, r.text
    op = r.json()
    cli = run_operation(read_operation(OPS / "single_track.yaml"))
    assert op["status"] == cli.status == "conflicts"
    assert [t["id"] for t in op["trains"]] == [t.id for t in cli.trains]
    assert [c["trains"] for c in op["conflicts"]] == [[c.first, c.second] for c in cli.conflicts]
    assert len(op["blocking"]) == len(cli.blocking) and len(op["headways"]) == len(cli.headways)
    # the TrainRuns freight train has no braking given: the reader's default is a warning of the run,
    # naming the file inside the upload, never the server's temporary folder
    assert any("mine.zip/tests/data/trainruns/trains/freight.yaml" in w for w in op["warnings"])
    assert not any("trainsim-web-" in w for w in op["warnings"])


def test_an_invalid_field_names_the_file_inside_the_zip_its_line_and_field(client: TestClient) -> None:
    text = (OPS / "single_track.yaml").read_text().replace("direction: up", "direction: sideways", 1)
    r = upload(client, "mine.zip", _zip(single_track_files(text)))
    assert r.status_code == 422, r.text
    d = r.json()["detail"][0]
    assert d["file"] == "mine.zip/examples/operations/single_track.yaml"
    assert (
        d["field"] == "trains[0].direction"
        and d["line"] == text.splitlines().index(next(x for x in text.splitlines() if "sideways" in x)) + 1
    )


def test_a_train_file_with_an_error_is_named_inside_the_zip(client: TestClient) -> None:
    files = single_track_files()
    files["tests/data/trainruns/trains/local.yaml"] = (
        "schema: trainsim/train\nversion: 1\nname: x\nmass_t: -5\n"
    )
    r = upload(client, "mine.zip", _zip(files))
    assert r.status_code == 422, r.text
    assert any(d["file"] == "mine.zip/tests/data/trainruns/trains/local.yaml" for d in r.json()["detail"])


def _expect(r, status: int, *words: str) -> dict:
    assert r.status_code == status, r.text
    body = r.json()
    text = body["message"] + " " + " ".join(str(d) for d in body.get("detail", []))
    for w in words:
        assert w in text, (w, text)
    return body


def test_a_reference_outside_the_upload_is_refused_with_its_line(client: TestClient) -> None:
    # a plain YAML upload holds no other file: the metro's '../metro_b/train.yaml' lies outside it
    text = (OPS / "metro_fixed_block.yaml").read_text()
    body = _expect(upload(client, "metro.yaml", text.encode()), 422, "outside the upload", "zip")
    fields = {d["field"]: d for d in body["detail"]}
    assert fields["line.route"]["file"] == "metro.yaml"
    assert fields["line.route"]["line"] == 9 and fields["trains[0].train"]["line"] == 33
    # absolute paths and paths out of the zip's folder: refused before anything is read
    files = single_track_files()
    for bad in ("/etc/passwd", "../../../../../etc/passwd", "../../../outside.yaml", '"x\\0y"', "x/" * 3000):
        op = (
            (OPS / "single_track.yaml")
            .read_text()
            .replace("../../tests/data/trainruns/trains/local.yaml", bad)
        )
        files["examples/operations/single_track.yaml"] = op
        _expect(upload(client, "mine.zip", _zip(files)), 422, "outside the upload", "trains[0].train")


def test_hostile_zips_are_refused(client: TestClient) -> None:
    _expect(upload(client, "mine.zip", b"PK\x03\x04 not really a zip"), 422, "not a readable zip")
    _expect(
        upload(client, "mine.zip", _zip({"../evil.yaml": "a: 1"})), 422, "leaves its folder", "../evil.yaml"
    )
    _expect(upload(client, "mine.zip", _zip({"a/../../evil.yaml": "a: 1"})), 422, "leaves its folder")
    _expect(upload(client, "mine.zip", _zip({"/etc/evil.yaml": "a: 1"})), 422, "absolute path")
    _expect(upload(client, "mine.zip", _zip({"C:\\evil.yaml": "a: 1"})), 422, "absolute path")
    # a zip bomb: 64 MiB of zeros in 64 KiB; refused on its declared size before anything is unpacked
    bomb = io.BytesIO()
    with zipfile.ZipFile(bomb, "w", zipfile.ZIP_DEFLATED, compresslevel=9) as zf:
        zf.writestr("op.yaml", b"\0" * (64 * 2**20))
    assert len(bomb.getvalue()) < 2**20
    _expect(upload(client, "bomb.zip", bomb.getvalue()), 422, "too large")
    # a bomb that lies about its size: stopped at the declared size
    liar = bytearray(_zip({"op.yaml": "x" * 100_000}))
    for header, offset in ((b"PK\x03\x04", 22), (b"PK\x01\x02", 24)):
        at = liar.index(header) + offset
        liar[at : at + 4] = (10).to_bytes(4, "little")
    body = _expect(upload(client, "liar.zip", bytes(liar)), 422, "liar.zip")
    assert "larger than it says" in body["message"] or "cannot be read" in body["message"]
    # a symbolic link entry
    link = io.BytesIO()
    with zipfile.ZipFile(link, "w") as zf:
        info = zipfile.ZipInfo("op.yaml")
        info.external_attr = (0o120777 << 16) | 0
        zf.writestr(info, "/etc/passwd")
    _expect(upload(client, "link.zip", link.getvalue()), 422, "symbolic link")
    many = _zip({f"f{i}.yaml": "a: 1" for i in range(65)})
    _expect(upload(client, "many.zip", many), 422, "too many files", "at most 64")
    # no operation file, or two
    _expect(upload(client, "none.zip", _zip({"a.yaml": "a: 1"})), 422, "exactly one operation file")
    two = (OPS / "single_track.yaml").read_text()
    _expect(
        upload(client, "two.zip", _zip({"a.yaml": two, "b.yaml": two})), 422, "exactly one operation file"
    )


def test_hostile_files_are_refused(client: TestClient) -> None:
    _expect(upload(client, "big.yaml", b"#" * (2 * 2**20 + 10)), 413, "too large")
    _expect(upload(client, "op.exe", b"MZ"), 422, "not an operation file", ".exe")
    _expect(
        upload(client, "op.yaml", b"schema: trainsim/operation\nversion: 1\nname: [unclosed\n"),
        422,
        "op.yaml",
    )
    deep = "a: " + "[" * 200 + "]" * 200
    _expect(upload(client, "deep.yaml", deep.encode()), 422)
    # too many trains: a repeat count over the web's bound is refused before any train is built
    text = (OPS / "single_track.yaml").read_text()
    data = yaml.safe_load(text)
    data["trains"][0]["repeat"] = {"count": 500, "every_s": 600}
    r = upload(client, "mine.zip", _zip(single_track_files(yaml.safe_dump(data, sort_keys=False))))
    body = _expect(r, 422, "too many trains", "at most 200")
    assert body["detail"][0]["file"] == "mine.zip/examples/operations/single_track.yaml"
    assert body["detail"][0]["field"] == "trains"


def test_an_upload_runs_in_the_worker_pool_within_its_time_limit() -> None:
    # a pool whose time limit no run meets: the upload is stopped and answered 422, never 500
    settings = WebSettings(workers=1, drive_hosts=0, job_time_limit_s=0.05)
    with TestClient(create_app(settings)) as c:
        body = _expect(upload(c, "mine.zip", _zip(single_track_files())), 422, "longer than the limit")
        assert "0.05 s" in body["message"]
