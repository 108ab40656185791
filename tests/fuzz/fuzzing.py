"""The input fuzzer of trainsim: seeded mutations of every shipped input kind, read through the entry
points of the CLI, classified and counted.

Each case takes a seed file of one kind (trainsim train / route / scenario / study YAML, railtoolkit
YAML, TTOBench JSON, railML 2 and 3 XML, a CSV folder, an Excel workbook), mutates it (structure-aware:
a value replaced by a hostile one, a key deleted, renamed or added, a list emptied or repeated, an
element duplicated; or text-level: bytes flipped, the file cut, an alias bomb, deep nesting, an entity
declaration, a BOM, invalid UTF-8), writes it in place of the seed in a scratch copy of the data (so
that relative file names still resolve) and reads it with:

* the reader ``trainsim run`` / ``optimize`` / ``multipoint`` use for that kind
  (``trainsim.load_train`` / ``load_route`` / ``load_scenario``, ``batch.study.load_study``), and
* ``trainsim check`` (``trainsim.io.loader.check_file``).

Outcomes: ``accepted``, ``refused`` (an InputError), ``traceback`` (any other exception: a bug),
``timeout`` (over :data:`CASE_TIMEOUT_S`). A case whose mutation is known to make the file invalid
(a number of a trainsim file replaced by true/false, text, NaN, inf or an absurd magnitude) must be
refused, with a message naming the file and the field. ``check`` and the run's reader must agree.

Run directly for a report: ``python tests/fuzz/fuzzing.py [CASES] [SEED]``.
"""

from __future__ import annotations

import copy
import csv
import dataclasses
import io
import json
import math
import os
import random
import shutil
import signal
import sys
import tempfile
import time
import traceback
import warnings
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[2]
SHARED = Path(os.environ.get("TRAINSIM_SHARED", REPO.parent / "shared"))

#: Longest a single case may take [s] before it counts as a hang.
CASE_TIMEOUT_S = 5.0

#: Hostile values put in place of a value of a YAML or JSON document.
HOSTILE: list[Any] = [
    None,
    True,
    False,
    "",
    "3",
    "1,500",
    "abc",
    "12 furlongs",
    math.nan,
    math.inf,
    -math.inf,
    0,
    -1,
    -0.0,
    3.5,
    1e308,
    -1e308,
    1e-308,
    10**400,
    2**63,
    1_000_000_000,
    "x" * 200_000,
    [],
    {},
    [1, 2],
    {"a": 1},
    [[[[]]]],
]
#: Hostile texts put in place of an XML attribute or a spreadsheet cell.
HOSTILE_TEXT = [
    "",
    "1,500",
    "1,5",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "1e-308",
    "9" * 400,
    "-1",
    "0",
    "abc",
    "true",
    "x" * 100_000,
    "P1DT",
    "25:61:61",
    " ",
    "0x1F",
    "1_000",
]
#: Replacements that make a number of a trainsim file invalid: such a file must be refused.
MUST_REFUSE = (
    True,
    False,
    "3",
    "abc",
    "1,500",
    "12 furlongs",
    math.nan,
    math.inf,
    -math.inf,
    1e308,
    -1e308,
    10**400,
)


@dataclasses.dataclass(frozen=True)
class Seed:
    """One seed input: its kind, its path in the scratch tree, and the reader of the run."""

    kind: str  # yaml, json, xml, csv, xlsx
    relative: str  # path in the scratch tree
    role: str  # train, route, scenario, study
    strict_numbers: bool = False  # trainsim's own files: every number is validated
    weight: int = 3  # visits per round (workbooks are slow to write: fewer)


def seeds() -> list[Seed]:
    """The seed files, by kind (TTOBench only where its data folder exists)."""
    out = [
        Seed("yaml", "examples/metro_b/train.yaml", "train", True),
        Seed("yaml", "examples/metro_b/route.yaml", "route", True),
        Seed("yaml", "examples/metro_b/scenario.yaml", "scenario", True),
        Seed("yaml", "examples/metro_b/scenario_eco.yaml", "scenario", True),
        Seed("yaml", "examples/loco_001/train.yaml", "train", True),
        Seed("yaml", "examples/freight_000/train.yaml", "train", True),
        Seed("yaml", "examples/freight_000/route.yaml", "route", True),
        Seed("yaml", "examples/heavy_haul/scenario_dp.yaml", "scenario", True),
        Seed("yaml", "examples/heavy_haul/train.yaml", "train", True),
        Seed("yaml", "examples/studies/metro_load_efficiency.yaml", "study"),
        Seed("yaml", "examples/studies/metro_monte_carlo.yaml", "study"),
        Seed("yaml", "examples/studies/metro_timetable.yaml", "study"),
        Seed("yaml", "trainruns/trains/freight.yaml", "train", True),
        Seed("yaml", "trainruns/trains/longdistance.yaml", "train", True),
        Seed("yaml", "trainruns/paths/const.yaml", "route", True),
        Seed("yaml", "trainruns/paths/slope.yaml", "route", True),
        Seed("xml", "interchange/testline_railml2.xml", "scenario"),
        Seed("xml", "interchange/testline_railml3.xml", "scenario"),
        Seed("csv", "interchange/testline_csv", "scenario"),
        Seed("xlsx", "interchange/testline.xlsx", "scenario", weight=1),
    ]
    if (SHARED / "data" / "ttobench" / "trains").is_dir():
        out += [
            Seed("json", "ttobench/trains/CN_Beijing_Subway.json", "train"),
            Seed("json", "ttobench/trains/NL_Intercity_VIRM6.json", "train"),
            Seed("json", "ttobench/tracks/00_reference_with_tunnels.json", "route"),
            Seed("json", "ttobench/tracks/CN_Songjiazhuang_Yizhuang.json", "route"),
            Seed("json", "ttobench/journeys/CH_StGallen_Wil_Journey_01.json", "timetable"),
        ]
    return out


def make_scratch(root: Path) -> None:
    """A scratch copy of every seed's tree under ``root`` (examples keep their relative names)."""
    shutil.copytree(REPO / "examples", root / "examples", ignore=shutil.ignore_patterns("plots", "*.py"))
    shutil.copytree(REPO / "tests" / "data" / "trainruns", root / "trainruns")
    shutil.copytree(REPO / "tests" / "interchange" / "data", root / "interchange")
    ttobench = SHARED / "data" / "ttobench"
    if ttobench.is_dir():
        shutil.copytree(ttobench, root / "ttobench")
    import trainsim
    from trainsim.io import spreadsheet

    folder = root / "interchange" / "testline_csv"
    spreadsheet.write_spreadsheet(
        root / "interchange" / "testline.xlsx",
        train=trainsim.load_train(folder),
        route=trainsim.load_route(folder),
    )


# ====================================================================== mutations
def _paths(doc: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every path (keys and indices) to a value of a parsed document."""
    out = [prefix]
    if isinstance(doc, dict):
        for key, value in doc.items():
            out += _paths(value, (*prefix, key))
    elif isinstance(doc, list):
        for i, value in enumerate(doc):
            out += _paths(value, (*prefix, i))
    return out


def _get(doc: Any, path: tuple[Any, ...]) -> Any:
    for part in path:
        doc = doc[part]
    return doc


def _set(doc: Any, path: tuple[Any, ...], value: Any) -> Any:
    if not path:
        return value
    _get(doc, path[:-1])[path[-1]] = value
    return doc


def mutate_tree(doc: Any, rng: random.Random) -> tuple[Any, bool]:
    """A structural mutation of a parsed YAML/JSON document; (new document, must be refused if the
    file's numbers are all validated)."""
    doc = copy.deepcopy(doc)
    paths = _paths(doc)
    path = rng.choice(paths)
    target = _get(doc, path)
    op = rng.random()
    if op < 0.5:  # replace a value by a hostile one
        value = rng.choice(HOSTILE)
        number = isinstance(target, int | float) and not isinstance(target, bool)
        must = (
            number
            and any(
                value is m
                or (
                    isinstance(m, float)
                    and isinstance(value, float)
                    and (value == m or (math.isnan(m) and math.isnan(value)))
                )
                for m in MUST_REFUSE
            )
            and not isinstance(value, list | dict)
        )
        if isinstance(value, str) and number and value in ("3", "abc", "1,500", "12 furlongs"):
            must = True
        if number and value is not None and not isinstance(value, int | float | str):
            must = True
        return _set(doc, path, copy.deepcopy(value)), bool(must and path)
    if op < 0.62 and path:  # delete
        parent = _get(doc, path[:-1])
        del parent[path[-1]]
        return doc, False
    if op < 0.72 and isinstance(target, dict):  # add an unknown key / rename a key
        if target and rng.random() < 0.5:
            key = rng.choice(list(target))
            target[f"{key}_x" if isinstance(key, str) else "k"] = target.pop(key)
            return doc, isinstance(key, str)  # a field name nobody knows (or a station that is not there)
        new_key = rng.choice(["colour", "mass_t", "count", "model", "schema", "x" * 300])
        known = new_key in target
        target[new_key] = rng.choice(HOSTILE[:16])
        return doc, new_key in ("colour", "x" * 300) and not known
    if op < 0.82 and isinstance(target, list):  # empty / repeat / reverse / cut a list
        choice = rng.randrange(4)
        if choice == 0:
            target.clear()
        elif choice == 1:
            target.extend(copy.deepcopy(target) * rng.choice([1, 3]))
        elif choice == 2:
            target.reverse()
        else:
            del target[rng.randrange(len(target) + 1) :]
        return doc, False
    if op < 0.9 and isinstance(target, int | float) and not isinstance(target, bool):  # scale a number
        factor = rng.choice([-1, 0, 10, 1e6, 1e-6, 1.000001])
        return _set(doc, path, target * factor), False
    # swap the value with another one of the document
    other = _get(doc, rng.choice(paths))
    return _set(doc, path, copy.deepcopy(other)), False


def mutate_text(text: str, rng: random.Random, kind: str) -> str:
    """A text-level mutation."""
    op = rng.randrange(11)
    if op == 0 and text:  # cut the file
        return text[: rng.randrange(len(text))]
    if op == 1 and text:  # flip characters
        chars = list(text)
        for _ in range(rng.randint(1, 5)):
            chars[rng.randrange(len(chars))] = rng.choice("{}[]:,-&*!|>'\"\t\n#%@`\\<&;\x00\x1b")
        return "".join(chars)
    if op == 2:  # repeat a slice
        a = rng.randrange(len(text) + 1)
        b = min(len(text), a + rng.randrange(200))
        return text[:b] + text[a:b] * rng.randint(2, 50) + text[b:]
    if op == 3:
        return "\ufeff" + text
    if op == 4:
        return text.replace("\n", "\r\n")
    if kind == "yaml":
        if op == 5:  # alias bomb
            bomb = 'a0: &a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]\n' + "".join(
                f"a{i}: &a{i} [" + ",".join([f"*a{i - 1}"] * 9) + "]\n" for i in range(1, 10)
            )
            return bomb + text if rng.random() < 0.5 else text + "\n" + bomb
        if op == 6:  # deep nesting
            depth = rng.choice([200, 2000, 50_000])
            return text + "\nextra: " + "[" * depth + "]" * depth + "\n"
        if op == 7:
            return text + "\n---\nschema: x\n"
        if op == 8:  # duplicate a line
            lines = text.splitlines()
            i = rng.randrange(len(lines))
            return "\n".join([*lines[: i + 1], lines[i], *lines[i + 1 :]])
        if op == 9:
            return text + "\nx: !!python/object/apply:os.system ['true']\n"
    if kind == "json":
        if op == 5:
            return text.replace("0", "NaN", 1)
        if op == 6:
            depth = rng.choice([200, 50_000])
            return '{"x": ' + "[" * depth + "]" * depth + ", " + text.lstrip()[1:]
        if op == 7:
            return text.replace("1", "1" + "0" * 5000, 1)
        if op == 8:
            return text.replace("}", ', "metadata": null}', 1)
    if kind == "xml":
        if op == 5:  # entity bomb
            decl = (
                '<!DOCTYPE railml [<!ENTITY a "aaaaaaaaaa">'
                + "".join(
                    f'<!ENTITY a{i} "{("&a" + (str(i - 1) if i > 1 else "") + ";") * 10}">'
                    for i in range(1, 8)
                )
                + "]>"
            )
            head, sep, rest = text.partition("?>")
            return head + sep + decl + rest.replace(">", ">&a7;", 2) if sep else decl + text
        if op == 6:
            head, sep, rest = text.partition("?>")
            return head + sep + '<!DOCTYPE railml SYSTEM "file:///etc/passwd">' + rest
        if op == 7:
            return text.replace("<", "<x>" * 300, 1)
    return text + "\n" + "#" * rng.randrange(10)


def mutate_xml(text: str, rng: random.Random) -> str:
    """A structural mutation of railML: an attribute replaced or deleted, an element deleted or
    duplicated (duplicate ids), children reordered, a tag renamed."""
    from lxml import etree

    root = etree.fromstring(text.encode("utf-8"))
    elements = [el for el in root.iter() if isinstance(el.tag, str)]
    el = rng.choice(elements)
    op = rng.random()
    if op < 0.5 and el.attrib:
        name = rng.choice(list(el.attrib))
        if rng.random() < 0.8:
            el.set(name, rng.choice(HOSTILE_TEXT))
        else:
            del el.attrib[name]
    elif op < 0.65 and el.getparent() is not None:
        el.getparent().remove(el)
    elif op < 0.8 and el.getparent() is not None:
        el.addnext(copy.deepcopy(el))
    elif op < 0.9 and len(el):
        children = list(el)
        rng.shuffle(children)
        for child in children:
            el.remove(child)
            el.append(child)
    else:
        el.tag = el.tag + "x"
    return etree.tostring(root.getroottree(), xml_declaration=True, encoding="UTF-8").decode("utf-8")


def mutate_csv_folder(folder: Path, rng: random.Random) -> bool:
    """Mutate one table of a CSV folder in place; True if the mutation must be refused."""
    files = sorted(folder.glob("*.csv"))
    target = rng.choice(files)
    op = rng.random()
    if op < 0.05:
        target.unlink()
        return False
    if op < 0.12:
        data = target.read_bytes()
        cut = rng.randrange(len(data) + 1)
        target.write_bytes(data[:cut] + rng.choice([b"\xff\xfe", b"\x00", b'"', b"\n\n,,,\n"]) + data[cut:])
        return False
    rows = list(csv.reader(io.StringIO(target.read_text(encoding="utf-8"))))
    must = False
    if op < 0.75 and len(rows) > 1:
        r = rng.randrange(1, len(rows))
        c = rng.randrange(len(rows[r]))
        value = rng.choice(HOSTILE_TEXT)
        must = value == "1,500" and _is_number(rows[r][c])
        rows[r][c] = value
    elif op < 0.85 and len(rows) > 1:
        del rows[rng.randrange(len(rows))]
    elif op < 0.92 and rows:
        rows.append(list(rng.choice(rows)))
    elif rows:
        c = rng.randrange(len(rows[0]))
        rows[0][c] = rng.choice(["", "Mass (furlongs)", rows[0][c] + " (kN)", "x" * 300])
    buffer = io.StringIO()
    csv.writer(buffer).writerows(rows)
    target.write_text(buffer.getvalue(), encoding="utf-8")
    return must


def _is_number(text: str) -> bool:
    try:
        float(text.replace(",", "."))
    except ValueError:
        return False
    return True


def mutate_xlsx(path: Path, rng: random.Random) -> None:
    """Mutate one cell of a workbook in place (or cut the file)."""
    if rng.random() < 0.1:
        data = path.read_bytes()
        path.write_bytes(data[: rng.randrange(len(data))])
        return
    import openpyxl

    book = openpyxl.load_workbook(path)
    sheet = rng.choice(book.worksheets)
    rows = sheet.max_row
    cols = sheet.max_column
    cell = sheet.cell(rng.randint(1, max(1, rows)), rng.randint(1, max(1, cols)))
    cell.value = rng.choice([*HOSTILE_TEXT[:15], None, 1e308, -1.0, 0, 10**15, True])
    book.save(path)


# ====================================================================== running the cases
class CaseTimeoutError(Exception):
    """A case ran over CASE_TIMEOUT_S."""


def _alarm(signum: int, frame: Any) -> None:
    raise CaseTimeoutError


def _readers(seed: Seed) -> tuple[Callable[[Path], Any], Callable[[Path], Any]]:
    """(the reader of the run, check)."""
    import trainsim
    from trainsim.io.loader import check_file

    if seed.role == "study":
        from trainsim.batch.study import load_study

        return load_study, lambda p: None
    if seed.kind == "xml":  # railML names no line-resistance formulas: give them, as `run --curve-formula`
        from trainsim.io import convert

        formulas = {"curve_formula": "roeckl", "tunnel_formula": "wang"}
        return (
            lambda p: convert.detect_and_load(p, "scenario", line_resistance=formulas),
            lambda p: convert.check_file(p, line_resistance=formulas),
        )
    run = {
        "train": trainsim.load_train,
        "route": trainsim.load_route,
        "scenario": trainsim.load_scenario,
        "timetable": check_file,
    }[seed.role]
    return run, check_file


@dataclasses.dataclass
class Tally:
    """Counts of one run of the fuzzer, and samples of what went wrong."""

    cases: int = 0
    accepted: int = 0
    refused: int = 0
    tracebacks: int = 0
    timeouts: int = 0
    must_refuse: int = 0
    wrongly_accepted: int = 0
    unclear_messages: int = 0
    disagreements: int = 0
    with_field: int = 0
    with_allowed: int = 0
    slowest_s: float = 0.0
    peak_rss_mb: float = 0.0
    by_kind: Counter[str] = dataclasses.field(default_factory=Counter)
    #: tracebacks by the source line that raised them ("module.py:123 TypeError")
    by_origin: Counter[str] = dataclasses.field(default_factory=Counter)
    #: timeouts by seed file
    timeouts_by_seed: Counter[str] = dataclasses.field(default_factory=Counter)
    #: unclear messages by seed file
    unclear_by_seed: Counter[str] = dataclasses.field(default_factory=Counter)
    #: seconds spent per kind (mutating, reading, restoring)
    seconds_by_kind: Counter[str] = dataclasses.field(default_factory=Counter)
    samples: list[str] = dataclasses.field(default_factory=list)
    signatures: set[str] = dataclasses.field(default_factory=set)

    def merge(self, other: Tally) -> None:
        for f in dataclasses.fields(self):
            mine, theirs = getattr(self, f.name), getattr(other, f.name)
            if f.name in ("slowest_s", "peak_rss_mb"):
                setattr(self, f.name, max(mine, theirs))
            elif f.name == "samples":
                mine.extend(theirs[: 40 - len(mine)])
            elif f.name == "signatures":
                mine |= theirs
            else:
                setattr(self, f.name, mine + theirs)

    def note(self, text: str, signature: str | None = None) -> None:
        """Keep a sample of what went wrong (one per signature)."""
        if signature is not None:
            if signature in self.signatures:
                return
            self.signatures.add(signature)
        if len(self.samples) < 40:
            self.samples.append(text[:2000])


def _peak_rss_mb() -> float:
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _call(func: Callable[[Path], Any], path: Path) -> tuple[str, Any]:
    """(outcome, the exception or the value returned)."""
    from trainsim.errors import InputError

    try:
        value = func(path)
    except InputError as exc:
        return "refused", exc
    except CaseTimeoutError as exc:
        return "timeout", exc
    except Exception as exc:
        return "traceback", exc
    return "accepted", value


def _disagree(role: str, outcome: str, check_outcome: str, report: Any) -> bool:
    """Whether ``check`` and the run's reader disagree: check refuses what the run reads, or accepts
    as the kind the run needs what the run refuses (check also reports train-only railML files)."""
    if outcome == "accepted":
        return check_outcome != "accepted"
    if check_outcome != "accepted" or role in ("study", "timetable"):
        return False
    kind = getattr(report, "kind", "")
    return kind == role or (role == "scenario" and kind in ("scenario", "train and route"))


def run_chunk(args: tuple[int, int, int, str]) -> Tally:
    """Run cases ``first .. first + count - 1`` of the fuzzer with ``seed`` in a scratch tree at ``root``
    (one process; the tree is restored after every case)."""
    first, count, seed_value, root_text = args
    warnings.simplefilter("ignore")
    root = Path(root_text)
    tally = Tally()
    all_seeds = seeds()
    schedule = [s for s in all_seeds for _ in range(s.weight)]
    originals: dict[str, bytes] = {}
    for s in all_seeds:
        p = root / s.relative
        if p.is_file():
            originals[s.relative] = p.read_bytes()
    parsed: dict[str, Any] = {}
    previous = signal.signal(signal.SIGALRM, _alarm)
    try:
        for case in range(first, first + count):
            rng = random.Random(seed_value * 1_000_003 + case)
            seed = schedule[case % len(schedule)]
            started = time.perf_counter()
            path = root / seed.relative
            backup: Path | None = None
            must = False
            try:
                if seed.kind in ("yaml", "json"):
                    text = originals[seed.relative].decode("utf-8")
                    if rng.random() < 0.7:
                        if seed.relative not in parsed:
                            import yaml

                            parsed[seed.relative] = (
                                json.loads(text) if seed.kind == "json" else yaml.safe_load(text)
                            )
                        doc, must = mutate_tree(parsed[seed.relative], rng)
                        for _ in range(rng.choice([0, 0, 0, 1, 2])):
                            doc, _m = mutate_tree(doc, rng)
                            must = False  # a later mutation may have removed the first one
                        text = _dump(doc, seed.kind)
                        must = must and seed.strict_numbers
                    else:
                        text = mutate_text(text, rng, seed.kind)
                    path.write_text(text, encoding="utf-8")
                elif seed.kind == "xml":
                    text = originals[seed.relative].decode("utf-8")
                    text = mutate_xml(text, rng) if rng.random() < 0.7 else mutate_text(text, rng, "xml")
                    path.write_text(text, encoding="utf-8")
                elif seed.kind == "csv":
                    backup = path.with_name(path.name + ".orig")
                    if not backup.exists():
                        shutil.copytree(path, backup)
                    must = mutate_csv_folder(path, rng)
                else:
                    mutate_xlsx(path, rng)
            except (ValueError, OverflowError, RecursionError):
                continue  # the mutation could not be written (e.g. YAML of a 10**400 key): no case
            tally.cases += 1
            tally.by_kind[seed.kind] += 1
            run, check = _readers(seed)
            t0 = time.perf_counter()
            signal.setitimer(signal.ITIMER_REAL, CASE_TIMEOUT_S)
            try:
                outcome, exc = _call(run, path)
                check_outcome, check_exc = _call(check, path) if seed.role != "study" else (outcome, exc)
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
            elapsed = time.perf_counter() - t0
            tally.slowest_s = max(tally.slowest_s, elapsed)
            label = f"case {case} ({seed.relative})"
            worst = "timeout" if "timeout" in (outcome, check_outcome) else outcome
            if worst == "timeout":
                tally.timeouts += 1
                tally.timeouts_by_seed[seed.relative] += 1
                tally.note(f"{label}: timeout")
            elif "traceback" in (outcome, check_outcome):
                tally.tracebacks += 1
                bad = exc if outcome == "traceback" else check_exc
                assert bad is not None
                frames = traceback.extract_tb(bad.__traceback__)
                origin = next((f for f in reversed(frames) if "/trainsim/" in f.filename), frames[-1])
                signature = f"{Path(origin.filename).name}:{origin.lineno} {type(bad).__name__}"
                tally.by_origin[signature] += 1
                tally.note(f"{label}: " + "".join(traceback.format_exception(bad)[-6:]), signature)
            else:
                if outcome == "accepted":
                    tally.accepted += 1
                else:
                    tally.refused += 1
                    if not _judge_message(tally, exc, label):
                        tally.unclear_by_seed[seed.relative] += 1
                if _disagree(seed.role, outcome, check_outcome, check_exc):
                    tally.disagreements += 1
                    tally.note(
                        f"{label}: run {outcome}, check {check_outcome}: {exc or check_exc}",
                        f"disagree {label}",
                    )
                if must:
                    tally.must_refuse += 1
                    if outcome == "accepted":
                        tally.wrongly_accepted += 1
                        tally.note(f"{label}: an invalid number was accepted")
            _restore(seed, path, originals, backup)
            tally.seconds_by_kind[seed.kind] += time.perf_counter() - started
    finally:
        signal.signal(signal.SIGALRM, previous)
    tally.peak_rss_mb = _peak_rss_mb()
    return tally


def _judge_message(tally: Tally, exc: BaseException | None, label: str) -> bool:
    """Count a refusal; whether its message is clear (names the file, one readable paragraph)."""
    from trainsim.errors import InputError

    assert isinstance(exc, InputError)
    text = str(exc)
    names_file = bool(exc.file) and all(p.file for p in exc.problems)
    clear = names_file and len(text) <= 2000 and bool(text.strip())
    if not clear:
        tally.unclear_messages += 1
        tally.note(f"{label}: unclear message: {text[:300]}", f"unclear {exc.field}")
    if exc.field:
        tally.with_field += 1
    if exc.allowed:
        tally.with_allowed += 1
    return clear


def _dump(doc: Any, kind: str) -> str:
    if kind == "json":
        return json.dumps(doc)
    import yaml

    return yaml.dump(doc, Dumper=yaml.CSafeDumper, sort_keys=False, allow_unicode=True)


def _restore(seed: Seed, path: Path, originals: dict[str, bytes], backup: Path | None) -> None:
    if backup is not None:
        shutil.rmtree(path)
        shutil.copytree(backup, path)
    elif seed.relative in originals:
        path.write_bytes(originals[seed.relative])


def scratch_parent() -> str | None:
    """Where the scratch trees go: a RAM-backed folder where the machine has one (/dev/shm), else the
    temporary folder. Every case writes its mutated file over the seed and writes the seed back; a
    write that truncates a file on a disk file system (ext4) waits for the disk, about 4 ms a write
    on the CI machine, longer than most cases take to read."""
    shm = Path("/dev/shm")
    return str(shm) if shm.is_dir() and os.access(shm, os.W_OK | os.X_OK) else None


def run(cases: int, seed_value: int, workers: int = 2) -> Tally:
    """Run ``cases`` cases in ``workers`` processes (each with its own scratch tree)."""
    import multiprocessing

    with tempfile.TemporaryDirectory(prefix="trainsim-fuzz-", dir=scratch_parent()) as tmp:
        roots = []
        for w in range(workers):
            root = Path(tmp) / f"w{w}"
            make_scratch(root)
            roots.append(root)
        share = -(-cases // workers)
        chunks = [
            (w * share, min(share, cases - w * share), seed_value, str(roots[w])) for w in range(workers)
        ]
        context = multiprocessing.get_context("spawn")
        with context.Pool(workers) as pool:
            results = pool.map_async(run_chunk, chunks).get(timeout=max(600.0, cases * 0.2))
    total = Tally()
    for r in results:
        total.merge(r)
    return total


def summary(tally: Tally, seconds: float) -> str:
    """The counts in one paragraph."""
    kinds = ", ".join(f"{k} {v}" for k, v in sorted(tally.by_kind.items()))
    return (
        f"{tally.cases} mutated inputs ({kinds}) in {seconds:.0f} s: {tally.accepted} accepted, "
        f"{tally.refused} refused ({tally.with_field} naming a field, {tally.with_allowed} saying what is "
        f"allowed), {tally.tracebacks} tracebacks, {tally.timeouts} timeouts over {CASE_TIMEOUT_S:g} s "
        f"(slowest case {tally.slowest_s:.2f} s); {tally.must_refuse} known-invalid inputs, "
        f"{tally.wrongly_accepted} of them accepted; {tally.unclear_messages} unclear messages; "
        f"{tally.disagreements} check/run disagreements; peak memory of a worker {tally.peak_rss_mb:.0f} MB"
    )


if __name__ == "__main__":
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 10_000
    seed_arg = int(sys.argv[2]) if len(sys.argv) > 2 else 13
    t0 = time.perf_counter()
    result = run(n, seed_arg)
    print(summary(result, time.perf_counter() - t0))
    print("tracebacks by origin:", dict(result.by_origin.most_common()))
    print("timeouts by seed:", dict(result.timeouts_by_seed))
    print("seconds by kind:", {k: round(v, 1) for k, v in result.seconds_by_kind.items()})
    for sample in result.samples:
        print("----", sample)
