"""Start-up (issue 14, stop 26): the trainsim YAML readers build only the pydantic models a file needs.

Building every spec at import was about a fifth of a warm `trainsim run` of the metro (40 models).
The specs are deferred (``defer_build``): a document's validator is built when a file of its kind is
first read, the specs nested in it are never built on their own, and a scenario builds its train and
route documents first so that their schemas are generated once. Counted in a fresh interpreter (an
earlier test would have built them), so the guard does not depend on the machine's load.
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


def test_a_scenario_builds_its_three_documents_only() -> None:
    code = f"from trainsim.io import loader; loader.load_scenario({str(METRO / 'scenario.yaml')!r})"
    built, _ = built_models(code)
    assert built == {"ScenarioSpec", "TrainSpec", "RouteSpec"}


def test_a_train_file_builds_the_train_document_only() -> None:
    code = f"from trainsim.io import loader; loader.load_train({str(METRO / 'train.yaml')!r})"
    built, _ = built_models(code)
    assert built == {"TrainSpec"}


def test_a_nested_spec_validated_on_its_own_still_validates(tmp_path: Path) -> None:
    """Settings and driving blocks are validated alone too (deferred, built on first use)."""
    from trainsim.errors import InputError
    from trainsim.io.trainsim_yaml import driving_spec_from_dict, settings_from_dict

    assert settings_from_dict({"max_step_m": 2.5}).max_step_m == 2.5
    assert driving_spec_from_dict({"strategy": "fastest"}).strategy == "fastest"
    with pytest.raises(InputError, match=r"settings\.max_step_m"):
        settings_from_dict({"max_step_m": -1})
