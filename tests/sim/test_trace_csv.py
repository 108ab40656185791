"""trace.csv is written without pandas, byte for byte what pandas wrote before."""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import trainsim
from trainsim.io.export import write_trace_csv
from trainsim.model.scenario import RunSettings
from trainsim.sim.fastest import run_fastest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
TRAINRUNS = ROOT / "tests" / "data" / "trainruns"


def _result(case: str):
    if case == "trainruns_freight":  # no electrics: the currents are NaN, empty fields in the CSV
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            train = trainsim.load_train(TRAINRUNS / "trains" / "freight.yaml")
        route = trainsim.load_route(TRAINRUNS / "paths" / "realworld.yaml", mass_model="mass_point")
        return run_fastest(train, route, RunSettings())
    scenario = trainsim.load_scenario(EXAMPLES / case / "scenario.yaml")
    return run_fastest(scenario.train, scenario.route, scenario.settings)


@pytest.mark.parametrize("case", ["metro_b", "freight_000", "trainruns_freight"])
def test_trace_csv_is_pandas_bytes(case, tmp_path):
    result = _result(case)
    ours = write_trace_csv(result, tmp_path / "out" / "trace.csv").read_bytes()
    result.to_dataframe().to_csv(tmp_path / "pandas.csv", index=False)
    assert ours == (tmp_path / "pandas.csv").read_bytes()
    if case == "trainruns_freight":
        assert np.isnan(result.trace.line_current_a).all()  # the empty fields were exercised
        assert b",," in ours


def test_trace_csv_of_a_summary_only_run_says_so(tmp_path):
    scenario = trainsim.load_scenario(EXAMPLES / "metro_b" / "scenario.yaml")
    bare = run_fastest(scenario.train, scenario.route, scenario.settings, trace=False)
    with pytest.raises(ValueError, match="without its trace"):
        write_trace_csv(bare, tmp_path / "trace.csv")


def test_trace_csv_does_not_import_pandas(tmp_path):
    code = (
        "import sys, trainsim\n"
        "from trainsim.io.export import write_trace_csv\n"
        f"r = trainsim.run(trainsim.load_scenario({str(EXAMPLES / 'metro_b' / 'scenario.yaml')!r}))\n"
        f"write_trace_csv(r, {str(tmp_path / 'trace.csv')!r})\n"
        "print('pandas' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
