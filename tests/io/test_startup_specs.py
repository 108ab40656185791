"""Start-up (issue 14, stop 26): the trainsim YAML readers build only the pydantic models a file needs.

Building every spec at import was about a fifth of a warm `trainsim run` of the metro (40 models).
The specs are deferred (``defer_build``): a plainly valid file is read by the quick reader
(``spec.quick_spec``) without any validator; pydantic's validator of a document is built when a file
needs it (a problem to report, a value to convert), the specs nested in it are never built on their
own, and a scenario builds its train and route documents first so that their schemas are generated
once. Counted in a fresh interpreter (an earlier test would have built them), so the guard does not
depend on the machine's load.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
METRO = REPO / "examples" / "metro_b"

# Prints the trainsim pydantic models whose validator was built, after running the given code.
PROBE = """
import json, sys
from pydantic import BaseModel
{code}
def subclasses(cls):
    for sub in cls.__subclasses__():
        yield sub
        yield from subclasses(sub)
models = {{c for c in subclasses(BaseModel) if c.__module__.startswith("trainsim.")}}
print(json.dumps({{"built": sorted(c.__name__ for c in models if c.__pydantic_complete__),
                  "defined": len(models)}}))
"""


def built_models(code: str) -> tuple[set[str], int]:
    """(names of the built trainsim models, number of trainsim models defined) after ``code``."""
    proc = subprocess.run(
        [sys.executable, "-c", PROBE.format(code=code)], capture_output=True, text=True, cwd=REPO, timeout=300
    )
    if proc.returncode != 0:
        pytest.fail(f"the probe failed:\n{proc.stderr[-3000:]}")
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    return set(report["built"]), report["defined"]


def test_importing_the_readers_builds_no_model() -> None:
    built, defined = built_models("import trainsim.io.loader")
    assert defined >= 30  # the train, route and scenario specs are all defined...
    assert built == set()  # ...and none is built


def test_a_valid_scenario_builds_no_model() -> None:
    """The metro's scenario, train and route are plainly valid: the quick reader reads all three."""
    code = f"from trainsim.io import loader; loader.load_scenario({str(METRO / 'scenario.yaml')!r})"
    built, _ = built_models(code)
    assert built == set()


def test_a_scenario_with_a_problem_builds_its_three_documents_only(tmp_path: Path) -> None:
    """pydantic reports the problem: the scenario's validator is built, after its train and route."""
    for name in ("train.yaml", "route.yaml"):
        (tmp_path / name).write_text((METRO / name).read_text())
    text = (METRO / "scenario.yaml").read_text().replace("max_step_m: 5", "max_step_m: -5")
    (tmp_path / "scenario.yaml").write_text(text)
    code = (
        "from trainsim.io import loader\n"
        "from trainsim.errors import InputError\n"
        "try:\n"
        f"    loader.load_scenario({str(tmp_path / 'scenario.yaml')!r})\n"
        "except InputError as exc:\n"
        "    assert 'settings.max_step_m' in str(exc), exc\n"
        "else:\n"
        "    raise SystemExit('no error')\n"
    )
    built, _ = built_models(code)
    assert built == {"ScenarioSpec", "TrainSpec", "RouteSpec"}


def test_a_nested_spec_validated_on_its_own_still_validates(tmp_path: Path) -> None:
    """Settings and driving blocks are validated alone too (deferred, built on first use)."""
    from trainsim.errors import InputError
    from trainsim.io.trainsim_yaml import driving_spec_from_dict, settings_from_dict

    assert settings_from_dict({"max_step_m": 2.5}).max_step_m == 2.5
    assert driving_spec_from_dict({"strategy": "fastest"}).strategy == "fastest"
    with pytest.raises(InputError, match=r"settings\.max_step_m"):
        settings_from_dict({"max_step_m": -1})


# ---------------------------------------------------------------------- the quick reader
# The quick reader makes a spec without building pydantic's validator, for plainly valid mappings only;
# it must give the spec pydantic gives, and leave to pydantic (return None) whatever pydantic refuses.

TRAINSIM_FILES = sorted(
    p
    for folder in (REPO / "examples", REPO / "tests")
    for p in folder.rglob("*.yaml")
    if any(
        f"schema: trainsim/{kind}" in p.read_text(errors="replace") for kind in ("train", "route", "scenario")
    )
)


def _spec_class(data: dict) -> type:
    from trainsim.io.trainsim_yaml import RouteSpec, ScenarioSpec, TrainSpec

    return {"trainsim/train": TrainSpec, "trainsim/route": RouteSpec, "trainsim/scenario": ScenarioSpec}[
        data["schema"]
    ]


def _fields_set_tree(value: object) -> object:
    """The fields set of every spec in a spec tree (model_construct and validation must agree)."""
    from pydantic import BaseModel

    if isinstance(value, BaseModel):
        return (
            type(value).__name__,
            sorted(value.model_fields_set),
            {k: _fields_set_tree(v) for k, v in value.__dict__.items()},
        )
    if isinstance(value, list | tuple):
        return [_fields_set_tree(v) for v in value]
    if isinstance(value, dict):
        return {k: _fields_set_tree(v) for k, v in value.items()}
    return type(value).__name__


def _same_as_pydantic(cls: type, data: object) -> bool:
    """True if the quick reader read ``data``; asserts it agrees with pydantic's validation."""
    from pydantic import ValidationError

    from trainsim.io.spec import built, quick_spec

    quick = quick_spec(cls, data)
    try:
        full = built(cls).model_validate(data)
    except ValidationError:
        assert quick is None, f"the quick reader accepted what pydantic refuses: {data!r}"
        return False
    except Exception:  # an InputError of a before-validator (e.g. a unit): pydantic refuses too
        assert quick is None
        return False
    if quick is None:
        return False
    assert quick == full
    assert _fields_set_tree(quick) == _fields_set_tree(full)
    assert quick.model_dump() == full.model_dump()
    return True


def test_the_files_of_the_repository_are_read_quickly_and_as_pydantic_reads_them() -> None:
    from trainsim.io.trainsim_yaml import read_yaml

    assert len(TRAINSIM_FILES) >= 20
    quick = {path.relative_to(REPO).as_posix() for path in TRAINSIM_FILES if _read_one(path, read_yaml)}
    # every document a fastest run of an example reads goes the quick way
    for example in ("metro_b", "freight_000", "loco_001", "heavy_haul"):
        assert {f"examples/{example}/train.yaml", f"examples/{example}/route.yaml"} <= quick
    assert {"examples/metro_b/scenario.yaml", "examples/freight_000/scenario.yaml"} <= quick


def _read_one(path: Path, read_yaml: object) -> bool:
    data = read_yaml(path)  # type: ignore[operator]
    return _same_as_pydantic(_spec_class(data), data)


def _mutations(value: object) -> list[tuple[object, object]]:
    """(path, mutated document) pairs: every leaf replaced by other kinds of values, every key of a
    mapping removed, every list emptied."""
    out: list[tuple[object, object]] = []
    replacements = (-1, 0, 1.5, 10**20, True, None, "text", "5 km", [], {})

    def walk(node: object, rebuild: object) -> None:
        if isinstance(node, dict):
            for key in node:
                out.append((key, rebuild({k: v for k, v in node.items() if k != key})))  # type: ignore[operator]
                walk(node[key], lambda new, key=key: rebuild({**node, key: new}))  # type: ignore[operator]
        elif isinstance(node, list):
            out.append(("[]", rebuild([])))  # type: ignore[operator]
            for i, item in enumerate(node):
                walk(item, lambda new, i=i: rebuild([*node[:i], new, *node[i + 1 :]]))  # type: ignore[operator]
        else:
            for r in replacements:
                if r != node or type(r) is not type(node):
                    out.append((node, rebuild(r)))  # type: ignore[operator]

    walk(value, lambda new: new)
    return out


@pytest.mark.parametrize(
    "name",
    [
        "metro_b/train.yaml",
        "metro_b/route.yaml",
        "metro_b/scenario.yaml",
        "freight_000/train.yaml",
        "loco_001/train.yaml",
        "heavy_haul/route.yaml",
    ],
)
def test_mutated_files_are_read_as_pydantic_reads_them_or_left_to_it(name: str) -> None:
    """Every leaf of the document replaced by numbers of other kinds, true, null, text, text with a
    unit, empty lists and mappings; every key removed: the quick reader agrees with pydantic or
    declines."""
    from trainsim.io.trainsim_yaml import read_yaml

    data = read_yaml(REPO / "examples" / name)
    cls = _spec_class(data)
    mutated = _mutations(data)
    assert len(mutated) > 50
    read = sum(_same_as_pydantic(cls, doc) for _, doc in mutated)
    assert read > 0  # some mutations stay valid (e.g. another plausible number) and go the quick way


def test_a_document_kind_read_many_times_gets_its_validator_built() -> None:
    """The quick reader costs about 3 x a built validator per document: after
    ``QUICK_READS_BEFORE_BUILD`` plainly valid trains (a batch worker building one per run) the
    train's validator is built and used; every read gives the same spec."""
    code = (
        "from trainsim.io import spec, trainsim_yaml as tsy\n"
        "from trainsim.io.yaml_train import TrainSpec\n"
        f"data = spec.read_yaml({str(METRO / 'train.yaml')!r})\n"
        "first = [tsy.train_spec_from_dict(data, 'train') for _ in range(spec.QUICK_READS_BEFORE_BUILD)]\n"
        "assert not TrainSpec.__pydantic_complete__\n"
        "later = [tsy.train_spec_from_dict(data, 'train') for _ in range(2)]\n"
        "assert TrainSpec.__pydantic_complete__\n"
        "assert all(s == first[0] for s in first + later)\n"
    )
    built, _ = built_models(code)
    assert "TrainSpec" in built
