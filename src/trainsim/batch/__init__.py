"""Studies at scale: sweeps, Monte Carlo samples and a day's timetable, run in parallel or on Dask.

::

    from trainsim.batch import load_study, run_study, read_results

    study = load_study("examples/studies/metro_load_efficiency.yaml")
    outcome = run_study(study, "out/metro_sweep", executor="processes", progress=True)
    df = read_results("out/metro_sweep")        # one row per run: parameters + figures
    write_report("out/metro_sweep")             # plots and tables of the study

The study format, the result columns and the executors are described in docs/BATCH.md.
"""

from trainsim.batch.executors import EXECUTORS, ClusterLostError, configured_scheduler, default_workers
from trainsim.batch.expand import Expansion, expand, run_id
from trainsim.batch.paths import get_values, parse_path, set_value
from trainsim.batch.runner import StudyOutcome, auto_chunk_size, run_study
from trainsim.batch.sink import read_results
from trainsim.batch.study import Study, load_study, study_from_dict

__all__ = [
    "EXECUTORS",
    "ClusterLostError",
    "Expansion",
    "Study",
    "StudyOutcome",
    "auto_chunk_size",
    "configured_scheduler",
    "default_workers",
    "expand",
    "get_values",
    "load_study",
    "parse_path",
    "read_results",
    "run_id",
    "run_study",
    "set_value",
    "study_from_dict",
    "write_report",
]


def write_report(out, **kwargs):
    """Plots and tables of a study output directory (see :func:`trainsim.batch.report.write_report`)."""
    from trainsim.batch.report import write_report as _write

    return _write(out, **kwargs)
