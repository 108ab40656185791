"""Bounded reading of YAML, JSON and XML (trainsim.io.documents): hostile documents are refused fast
with an InputError naming the file and the line, and ordinary ones read as PyYAML's safe loader reads them."""

from __future__ import annotations

import resource
import time
from pathlib import Path

import pytest
import yaml

from trainsim.errors import InputError
from trainsim.io import documents
from trainsim.io.documents import read_document, read_json, read_xml, read_yaml, read_yaml_text

#: a 1.3 KB "billion laughs": 10 levels of 9 aliases each expand to 9**10 (3.5e9) strings
ALIAS_BOMB = 'a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]\n' + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [{','.join([f'*{chr(97 + i)}'] * 9)}]\n" for i in range(9)
)


def _short(value: object) -> str:
    """A short test id for long generated texts."""
    return repr(value)[:24]


def _write(tmp_path: Path, text: str, name: str = "f.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize(
    "text",
    [
        "a: 1\nb: [1, 2, {c: yes}]\n",
        "x: &A {p: 1}\ny: *A\nz:\n  <<: *A\n  q: 2\n",
        "m:\n  <<: [{a: 1}, {a: 2, b: 3}]\n  c: 4\n",
        "a: 1_000\nb: 0x1F\nc: .inf\nd: 2001-12-14\ne: '5'\nf: ~\ng: !!str 5\nh: 012\ni: 190:20:30\n",
        "- &x [1, 2]\n- *x\n- -0.5\n- +3.25\n- 1.\n- .5\n- 99999999999999999999\n",
        "{}",
        "",
        "a:\n  - b\n  -\n  - c: d\n",
        "text: |\n  two\n  lines\nfolded: >\n  a\n  b\n",
    ],
)
def test_reads_as_pyyaml_safe_loader(text: str) -> None:
    assert read_yaml_text(text) == yaml.safe_load(text)


def test_exponent_without_dot_is_a_number() -> None:
    # YAML 1.1 (PyYAML) reads 1e3 as text; a number is what a writer of `mass_t: 1e3` means
    assert read_yaml_text("a: [1e3, 1E-3, .5e2, e3, 1e, '1e3']")["a"] == [
        1000.0,
        0.001,
        50.0,
        "e3",
        "1e",
        "1e3",
    ]


def test_alias_bomb_refused_at_once(tmp_path: Path) -> None:
    path = _write(tmp_path, ALIAS_BOMB)
    assert path.stat().st_size < 1400
    t0 = time.perf_counter()
    with pytest.raises(InputError, match="alias") as err:
        read_yaml(path)
    assert time.perf_counter() - t0 < 0.5
    assert err.value.file == str(path) and err.value.line is not None


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("[" * 100_000 + "]" * 100_000, "nested too deep"),  # crashes libyaml's composer (C stack)
        ("a:\n" + "".join(" " * (i + 1) + "a:\n" for i in range(300)), "nested too deep"),
        ("a: 1\nb: 2\na: 3\n", r"duplicate key 'a' \(first at line 1\)"),
        ("--- 1\n--- 2\n", "several YAML documents"),
        ("a: !!python/object/apply:os.system [ls]\n", "tags are not allowed"),
        ("a: *nowhere\n", "unknown alias"),
        ("&a [*a]", "refers to itself"),
        ("? [1, 2]\n: x\n", "key must be text or a number"),
        ("a: [1, 2\n", "invalid YAML"),
        ("a: 2001-13-45\n", "invalid YAML"),
    ],
    ids=_short,
)
def test_hostile_or_malformed_yaml(tmp_path: Path, text: str, match: str) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(InputError, match=match) as err:
        read_yaml(path)
    assert err.value.file == str(path)
    assert all(p.file == str(path) for p in err.value.problems)


def test_error_lines(tmp_path: Path) -> None:
    with pytest.raises(InputError) as err:
        read_yaml(_write(tmp_path, "a: 1\nb:\n  c: [1,\n"))
    assert err.value.line is not None and err.value.line >= 3
    with pytest.raises(InputError) as err:
        read_yaml(_write(tmp_path, "a: 1\nb:\n  - 1\n  - x: 1\n    x: 2\n"))
    assert err.value.line == 5


def test_yaml_line_finds_keys_and_items() -> None:
    text = "a: 1\nformation:\n  - {mass_t: 1}\n  - name: b\n    mass_t: -2\nz: [1, 2]\n"
    assert documents.yaml_line(text, ["formation", 1, "mass_t"]) == 5
    assert documents.yaml_line(text, ["formation", 0, "mass_t"]) == 3
    assert documents.yaml_line(text, ["formation", 7, "mass_t"]) == 2  # deepest existing parent
    assert documents.yaml_line(text, ["z"]) == 6


def test_size_limit(tmp_path: Path) -> None:
    path = _write(tmp_path, "a: " + "x" * 5000 + "\n")
    with pytest.raises(InputError, match="too large") as err:
        read_yaml(path, documents.DocumentLimits(max_bytes=1000))
    assert "at most 1000 bytes" in str(err.value)


def test_missing_directory_and_binary(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="not found"):
        read_yaml(tmp_path / "none.yaml")
    with pytest.raises(InputError, match="directory"):
        read_yaml(tmp_path)
    bad = tmp_path / "bin.yaml"
    bad.write_bytes(b"a: 1\n\xff\xfe\x00")
    with pytest.raises(InputError, match="not UTF-8") as err:
        read_yaml(bad)
    assert err.value.line == 2


# ====================================================================== JSON
@pytest.mark.parametrize(
    ("text", "match"),
    [
        ('{"a": NaN}', "'NaN' is not a number"),
        ('{"a": [1, Infinity]}', "'Infinity' is not a number"),
        ('{"a": -Infinity}', "Infinity' is not a number"),
        ('{"a": 1, "a": 2}', "duplicate key 'a'"),
        ("[" * 100_000 + "]" * 100_000, "nested too deep"),
        ('{"a": ' * 150 + "1" + "}" * 150, "nested too deep"),
        ('{"a": 1', "invalid JSON"),
        ('{"a": 1' + "0" * 5000 + "}", "invalid JSON"),  # more digits than int() takes
    ],
    ids=_short,
)
def test_hostile_or_malformed_json(tmp_path: Path, text: str, match: str) -> None:
    path = _write(tmp_path, text, "f.json")
    with pytest.raises(InputError, match=match) as err:
        read_json(path)
    assert err.value.file == str(path)
    assert len(str(err.value)) < 400


def test_json_files_read_as_json(tmp_path: Path) -> None:
    path = _write(tmp_path, '{"a": [1, 2.5, "x", null, true]}', "f.json")
    assert read_document(path) == {"a": [1, 2.5, "x", None, True]}
    with pytest.raises(InputError, match="NaN"):
        read_document(_write(tmp_path, '{"a": NaN}', "g.json"))


# ====================================================================== XML
XML_BOMB = (
    '<?xml version="1.0"?>\n<!DOCTYPE lolz [\n <!ENTITY lol "lol">\n'
    + "".join(
        f' <!ENTITY lol{i} "{("&lol" + str(i - 1 if i > 1 else "") + ";") * 10}">\n' for i in range(1, 10)
    )
    + "]>\n<railml>&lol9;</railml>\n"
)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        (XML_BOMB, "entit"),
        (
            '<?xml version="1.0"?>\n<!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]>\n<railml>&x;</railml>',
            "entit",
        ),
        ("<a>" * 300 + "</a>" * 300, "nested too deep"),
        ("<a><b></a>", "malformed XML"),
        ("", "malformed XML"),
    ],
    ids=_short,
)
def test_hostile_or_malformed_xml(tmp_path: Path, text: str, match: str) -> None:
    path = _write(tmp_path, text, "f.xml")
    t0 = time.perf_counter()
    with pytest.raises(InputError, match=match) as err:
        read_xml(path)
    assert time.perf_counter() - t0 < 1.0
    assert "xmlCtxt" not in str(err.value) and err.value.file == str(path)


def test_external_dtd_is_not_loaded(tmp_path: Path) -> None:
    path = _write(
        tmp_path,
        '<?xml version="1.0"?>\n<!DOCTYPE railml SYSTEM "http://example.invalid/x.dtd">\n<railml a="1"/>',
        "f.xml",
    )
    assert read_xml(path).getroot().get("a") == "1"  # read without fetching anything


def test_large_yaml_reads_within_memory(tmp_path: Path) -> None:
    # 50,000 entries: the parsed document, not a multiple of it (the old reader composed twice)
    path = _write(
        tmp_path, "g:\n" + "".join(f"  - {{from_m: {i * 10}, g: {i % 7}}}\n" for i in range(50_000))
    )
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    data = read_yaml(path)
    grown_mb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1024
    assert len(data["g"]) == 50_000 and data["g"][-1] == {"from_m": 499_990, "g": 5}
    assert grown_mb < 100


def test_long_route_loads_in_less_cpu_than_pyyaml_alone(tmp_path: Path) -> None:
    # benchmarks/bench_yaml_load.py at a twentieth of its size: the whole load (bounded reading, validation,
    # the Route) costs less CPU than PyYAML's C loader alone on the same text (measured: a third)
    import trainsim

    n = 10_000
    lines = [
        "schema: trainsim/route",
        "version: 1",
        "name: long",
        f"length_m: {n * 10 + 10}",
        f"stations: [{{name: A, position_m: 0}}, {{name: B, position_m: {n * 10 + 10}}}]",
        "speed_limits: [{from_m: 0, limit_kmh: 80}]",
        "gradients:",
        *(f"  - {{from_m: {i * 10}, gradient_permille: {(i % 7) - 3}}}" for i in range(n)),
        "line_resistance: {curve_formula: none, tunnel_formula: none}",
    ]
    path = _write(tmp_path, "\n".join(lines) + "\n")
    text = path.read_text(encoding="utf-8")
    ours, base = [], []
    for _ in range(2):
        c0 = time.process_time()
        route = trainsim.load_route(path)
        ours.append(time.process_time() - c0)
        c0 = time.process_time()
        yaml.load(text, Loader=yaml.CSafeLoader)
        base.append(time.process_time() - c0)
    assert len(route.gradients) == n - sum(1 for i in range(n) if i % 7 == 3)
    assert min(ours) < 0.8 * min(base), (ours, base)


def test_timetable_named_by_a_scenario_is_read_within_bounds(tmp_path: Path) -> None:
    import shutil

    import trainsim

    repo = Path(__file__).resolve().parents[2] / "examples" / "metro_b"
    for name in ("train.yaml", "route.yaml"):
        shutil.copy(repo / name, tmp_path / name)
    scenario = (repo / "scenario.yaml").read_text(encoding="utf-8")
    (tmp_path / "scenario.yaml").write_text(
        scenario + "driving: {strategy: optimal, timetable: timetable.yaml}\n", encoding="utf-8"
    )
    # the timetable reader (optimize) parses with PyYAML alone: 5000 levels give it a RecursionError
    nested = "sections: " + "[" * 5000 + "]" * 5000 + "\n"
    _write(tmp_path, "schema: trainsim/timetable\nversion: 1\n" + nested, "timetable.yaml")
    with pytest.raises(InputError, match="nested too deep") as err:
        trainsim.load_scenario(tmp_path / "scenario.yaml")
    assert err.value.file == str(tmp_path / "timetable.yaml")
