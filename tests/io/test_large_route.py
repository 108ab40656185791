"""Long routes (issue 13): a 200,000-entry route is read once by libyaml and validated column by column,
with the same result and the same problems as reading it entry by entry.

The two shortcuts are checked against the plain paths they replace, on the same text:
``documents._read_events(text, ..., None)`` (every event through PyYAML) and one pydantic model per
entry (``spec.TABLE_MIN_ENTRIES`` raised above the list's length)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

import trainsim
from trainsim.errors import InputError
from trainsim.io import documents, spec
from trainsim.io.loader import check_file

TAIL = "line_resistance:\n  curve_formula: none\n  tunnel_formula: none\n"


def route_text(entries: int, *, gradient: str = "{g}", line: int | None = None, bad: str = "") -> str:
    """A route with ``entries`` gradient sections of 10 m, gradient (i % 7) - 3 per mille; entry ``line``
    written as ``bad`` instead (a text of the mapping's inner part)."""
    length = entries * 10 + 10
    head = (
        f"schema: trainsim/route\nversion: 1\nname: long route\nlength_m: {length}\n"
        f"stations:\n  - {{name: A, position_m: 0}}\n  - {{name: B, position_m: {length}}}\n"
        "speed_limits:\n  - {from_m: 0, limit_kmh: 80}\ngradients:\n"
    )
    rows = []
    for i in range(entries):
        inner = f"from_m: {i * 10}, gradient_permille: " + gradient.format(g=(i % 7) - 3)
        rows.append(f"  - {{{bad if i == line else inner}}}\n")
    return head + "".join(rows) + TAIL


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "route.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def test_a_200000_entry_route_loads_column_by_column(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The result, not the time (benchmarks/bench_yaml_load.py times it): every section is kept, values
    in place, and no entry went through the per-entry number check of a pydantic model."""
    entries = 200_000
    path = _write(tmp_path, route_text(entries))
    calls = 0
    per_entry = spec._check_numbers

    def counted(*args: object, **kwargs: object) -> None:
        nonlocal calls
        calls += 1
        per_entry(*args, **kwargs)

    monkeypatch.setattr(spec, "_check_numbers", counted)
    route = trainsim.load_route(path)
    level = sum(1 for i in range(entries) if i % 7 == 3)  # level sections are not kept
    assert len(route.gradients) == entries - level
    kept = [i for i in range(entries) if i % 7 != 3]
    k = 123_457
    section = route.gradients[k]
    i = kept[k]
    assert (section.start_m, section.end_m, section.gradient_permille) == (i * 10, i * 10 + 10, (i % 7) - 3)
    assert route.end_m == entries * 10 + 10
    assert calls < 50, f"{calls} per-entry number checks: the gradients were validated one model each"
    report = check_file(path)
    assert report.name == "long route"


def _both_ways(text: str, file: str = "f.yaml") -> tuple[object, object]:
    """(the document through the flow-line shortcut, through every event) or the InputError texts."""
    out = []
    for flow in (True, False):
        try:
            if flow:
                out.append(documents.read_yaml_text(text, file))
            else:
                out.append(documents._read_events(text, file, documents.LIMITS, None))
        except InputError as exc:
            out.append(("error", str(exc)))
    return out[0], out[1]


ROWS = "".join(f"  - {{a: {i}, b: -{i}.5, c: yes, d: 012, e: 1e3, f: .inf, g: x_{i}}}\n" for i in range(300))


@pytest.mark.parametrize(
    "text",
    [
        "rows:\n" + ROWS,
        "rows:\n" + ROWS + "other: [1, 2]\n",
        # the same lines as text of a block scalar, or inside a quoted text: not mappings
        "text: |\n" + ROWS + "rows:\n" + ROWS,
        "text: 'a\n" + ROWS.replace("'", "") + "'\n",
        # a duplicate key in one line, an error after the lines, a flow collection around them
        "rows:\n" + ROWS + "  - {a: 1, a: 2}\n",
        "rows:\n" + ROWS + "x: [\n",
        "x: [\n" + ROWS + "]\n",
        "rows:\n" + ROWS + "rows: 2\n",
        # CRLF line breaks; lines of different lengths and indentations; a comment between runs
        ("rows:\n" + ROWS).replace("\n", "\r\n"),
        "rows:\n" + ROWS + "  - {a: 1}\n  # c\n" + ROWS + "deep:\n  - x\n" + ROWS.replace("  - ", "    - "),
    ],
    ids=[
        "list",
        "list then more",
        "block scalar",
        "quoted",
        "duplicate",
        "broken",
        "flow",
        "duplicate top",
        "crlf",
        "mixed runs",
    ],
)
def test_flow_lines_read_as_every_event_reads_them(text: str) -> None:
    fast, plain = _both_ways(text)
    assert fast == plain
    if isinstance(plain, dict) and "rows" in plain:
        assert plain == yaml.safe_load(text) | {"rows": plain["rows"]}
        assert plain["rows"][7] == {
            "a": 7,
            "b": -7.5,
            "c": True,
            "d": 10,
            "e": 1000.0,
            "f": float("inf"),
            "g": "x_7",
        }


def test_a_duplicate_key_in_a_flow_line_names_its_line() -> None:
    text = "rows:\n" + ROWS + "  - {a: 1, a: 2}\n"
    with pytest.raises(InputError, match="duplicate key 'a'") as info:
        documents.read_yaml_text(text, "f.yaml")
    assert info.value.problems[0].line == 302


@pytest.mark.parametrize(
    ("gradient", "line", "bad", "field"),
    [
        ("{g}", 1500, "from_m: 15000, gradient_permille: 250", "gradients[1500].gradient_permille"),
        ("{g}", 1500, "from_m: 15000, gradient_permille: true", "gradients[1500].gradient_permille"),
        ("{g}", 1500, "from_m: 15000, gradient_permille: '5'", "gradients[1500].gradient_permille"),
        ("{g}", 1500, "from_m: 15000, gradient_permille: .nan", "gradients[1500].gradient_permille"),
        ("{g}", 1500, "from_m: 15000, gradient_permille: ~", "gradients[1500].gradient_permille"),
        ("{g}", 1500, "from_m: 15000, to_m: 14000, gradient_permille: 1", "gradients[1500].to_m"),
        ("{g}", 1500, "from_m: 14990, gradient_permille: 1", "gradients[1500]"),
        ("{g}", 1500, "from_m: 15000, to_m: 15020, gradient_permille: 1", "gradients[1500].to_m"),
        ("{g}", 1500, "from_m: 15000, gradient: 1", "gradients[1500].gradient"),
        ("{g}", 1500, "from_m: 15000, gradient_permille: 1, grade: 2", "gradients[1500].grade"),
        ("{g}", 1500, "from_m: 1e300, gradient_permille: 1", "gradients[1500].from_m"),
        ("{g}.0", None, "", None),
    ],
)
def test_a_bad_entry_of_a_long_list_gets_the_same_problem(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    gradient: str,
    line: int | None,
    bad: str,
    field: str | None,
) -> None:
    """Column by column and one model per entry give the same route or the same problems."""
    path = _write(tmp_path, route_text(2000, gradient=gradient, line=line, bad=bad))
    results = []
    for table_min in (spec.TABLE_MIN_ENTRIES, 10**9):
        monkeypatch.setattr(spec, "TABLE_MIN_ENTRIES", table_min)
        try:
            results.append(trainsim.load_route(path))
        except InputError as exc:
            results.append(exc.to_dicts())
    assert results[0] == results[1]
    if field is None:
        assert len(results[0].gradients) == 2000 - sum(1 for i in range(2000) if i % 7 == 3)
    else:
        assert isinstance(results[0], list)
        assert any((p.get("field") or "").startswith(field) for p in results[0]), results[0]
        assert any(p.get("line") == 11 + line for p in results[0]), results[0]


def test_a_long_list_dumps_as_it_was_read(tmp_path: Path) -> None:
    from trainsim.io.trainsim_yaml import dump_yaml, read_route_spec, route_spec_from_dict

    route_spec = read_route_spec(_write(tmp_path, route_text(1200)))
    assert isinstance(route_spec.gradients, spec.SpecTable)
    again = route_spec_from_dict(yaml.safe_load(dump_yaml(route_spec)))
    assert again == route_spec
    assert route_spec.gradients[-1].gradient_permille == (1199 % 7) - 3
    assert route_spec.gradients[5].model_fields_set == {"from_m", "gradient_permille"}


def test_the_shortcut_applies_to_a_plain_long_list_only() -> None:
    """A run of flow lines is one '~' for libyaml; CRLF files and short lists take every event."""
    shortened, flow = documents._flow_lines("rows:\n" + ROWS, documents.LIMITS)
    assert list(flow) == [1] and len(flow[1][1]) == 300 and shortened.count("~") == 1
    assert documents._flow_lines(("rows:\n" + ROWS).replace("\n", "\r\n"), documents.LIMITS)[1] == {}
    assert documents._flow_lines("rows:\n" + ROWS[: ROWS.index("\n") + 1], documents.LIMITS)[1] == {}
