"""Results of a study as one Parquet dataset, written chunk by chunk, and resuming from it.

Layout of an output directory::

    OUT/study.json                  what study this is (name, fingerprint, number of runs, columns)
    OUT/results/part-*.parquet      one file per chunk of runs: parameters + figures, failures included

Every chunk is written to a hidden temporary file and renamed into place when complete (a rename is
atomic), so a study killed at any moment leaves only whole part files (and perhaps a temporary file,
removed on the next start). On restart the run ids of the part files are read and only the missing
runs are computed: nothing written is lost or written twice. Only the chunks in flight when the study
was killed are computed again.

``study.json`` holds the study's fingerprint (a hash of its scenarios, axes and samples): resuming
into a directory holding another study, or the same study after its files changed, is an error rather
than a silent mix of results.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import os
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from trainsim.batch.expand import Expansion
from trainsim.batch.worker import DRIVING_METRICS, METRICS, MULTI_POINT_COLUMNS
from trainsim.errors import InputError

__all__ = ["META_FILE", "RESULTS_DIR", "MemorySink", "ParquetSink", "read_results", "result_schema"]

META_FILE = "study.json"
RESULTS_DIR = "results"
_FORMAT = "trainsim/study-results"

SECTION_TYPE = pa.struct(
    [
        ("from", pa.string()),
        ("to", pa.string()),
        ("distance_m", pa.float64()),
        ("departure_s", pa.float64()),
        ("arrival_s", pa.float64()),
        ("running_time_s", pa.float64()),
        ("dwell_s", pa.float64()),
        ("energy_net_kwh", pa.float64()),
    ]
)


def _json(value: Any) -> str:
    return json.dumps(value, sort_keys=True, ensure_ascii=False, default=str)


def _param_type(values: list[Any]) -> tuple[pa.DataType, Any]:
    """Arrow type of a parameter column and the conversion of its values: numbers stay numbers, text
    stays text; lists, mappings and mixed columns are stored as JSON text."""
    present = [v for v in values if v is not None]
    if not present:
        return pa.string(), None
    if all(isinstance(v, bool) for v in present):
        return pa.bool_(), None
    if all(isinstance(v, int | float) and not isinstance(v, bool) for v in present):
        if all(isinstance(v, int) for v in present):
            return pa.int64(), None
        return pa.float64(), float
    if all(isinstance(v, str) for v in present):
        return pa.string(), None
    return pa.string(), _json


def result_schema(expansion: Expansion) -> tuple[pa.Schema, dict[str, Any]]:
    """The Arrow schema of the study's rows and the value conversion of each parameter column."""
    fields = [
        pa.field("run_index", pa.int64(), nullable=False),
        pa.field("run_id", pa.string(), nullable=False),
    ]
    convert: dict[str, Any] = {}
    for col in expansion.columns:
        kind, conv = _param_type(expansion.values[col.name])
        fields.append(pa.field(col.name, kind))
        convert[col.name] = conv
    fields += [
        pa.field(n, pa.string()) for n in ("status", "error_type", "error", "warnings", "train", "route")
    ]
    fields += [pa.field(n, pa.float64()) for n in METRICS]
    if any(c.name == "departure_s" for c in expansion.columns):
        fields.append(pa.field("arrival_s", pa.float64()))
    if expansion.driving:
        # only studies with a driving block have them: the results of other studies are unchanged
        fields.append(pa.field("strategy", pa.string()))
        fields += [pa.field(n, pa.float64()) for n in DRIVING_METRICS]
    if expansion.multi_point:
        # only studies with multi-point runs have them, as the driving columns
        fields += [
            pa.field(n, pa.int64() if n.endswith(("_coupler", "_capacity")) else pa.float64())
            for n in MULTI_POINT_COLUMNS
        ]
    fields.append(pa.field("sections", pa.list_(SECTION_TYPE)))
    meta = {"trainsim.study": expansion.study_name, "trainsim.fingerprint": expansion.fingerprint}
    return pa.schema(fields, metadata=meta), convert


def _table(expansion: Expansion, schema: pa.Schema, convert: dict[str, Any], rows) -> pa.Table:
    """One Arrow table from (run_index, row) pairs of a chunk."""
    rows = sorted(rows, key=lambda r: r[0])
    idx = [i for i, _ in rows]
    columns: dict[str, list[Any]] = {"run_index": idx, "run_id": [expansion.run_ids[i] for i in idx]}
    for col in expansion.columns:
        vals = expansion.values[col.name]
        conv = convert[col.name]
        columns[col.name] = [vals[i] if conv is None or vals[i] is None else conv(vals[i]) for i in idx]
    for name in schema.names:
        if name not in columns:
            columns[name] = [r.get(name) for _, r in rows]
    return pa.Table.from_pydict(columns, schema=schema)


class MemorySink:
    """Keeps the rows in memory (a study run without an output directory)."""

    def __init__(self, expansion: Expansion) -> None:
        self.expansion = expansion
        self.schema, self._convert = result_schema(expansion)
        self._tables: list[pa.Table] = []

    def open(self, restart: bool = False) -> set[str]:
        return set()

    def write(self, rows: list[tuple[int, dict[str, Any]]]) -> None:
        self._tables.append(_table(self.expansion, self.schema, self._convert, rows))

    def table(self) -> pa.Table:
        table = pa.concat_tables(self._tables) if self._tables else self.schema.empty_table()
        return table.sort_by("run_index")


class ParquetSink:
    """Writes each chunk as a part of ``OUT/results/`` and knows which runs are already there."""

    def __init__(self, out: str | Path, expansion: Expansion, *, study_file: str | None = None) -> None:
        self.out = Path(out)
        self.dir = self.out / RESULTS_DIR
        self.expansion = expansion
        self.study_file = study_file
        self.schema, self._convert = result_schema(expansion)

    # -------------------------------------------------------------- opening and resuming
    def _meta(self) -> dict[str, Any]:
        return {
            "format": _FORMAT,
            "version": 1,
            "study": self.expansion.study_name,
            "study_file": self.study_file,
            "fingerprint": self.expansion.fingerprint,
            "runs": len(self.expansion),
            "parameters": [c.name for c in self.expansion.columns],
            "parameter_kinds": {c.name: c.kind for c in self.expansion.columns},
            "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        }

    def _clear(self) -> None:
        for part in list(self.dir.glob("part-*.parquet")) + list(self.dir.glob(".part-*.tmp")):
            part.unlink()
        (self.out / META_FILE).unlink(missing_ok=True)

    def open(self, restart: bool = False) -> set[str]:
        """Prepare the directory; the ids of the runs already written (empty for a new study).

        ``restart`` discards the results of a previous study in the directory (only trainsim's files).
        """
        meta_path = self.out / META_FILE
        if self.out.exists() and not self.out.is_dir():
            raise InputError("the output path is a file, not a directory", file=str(self.out))
        if meta_path.exists() and not restart:
            try:
                meta = json.loads(meta_path.read_text())
            except (OSError, ValueError) as exc:
                raise InputError(
                    f"unreadable {META_FILE} ({exc}); use --restart to start again", file=str(meta_path)
                ) from None
            if meta.get("format") != _FORMAT:
                raise InputError("not a trainsim study output", file=str(meta_path))
            if meta.get("fingerprint") != self.expansion.fingerprint:
                raise InputError(
                    f"this directory holds the results of another study ('{meta.get('study')}') or of this "
                    "study before its files, axes or samples changed; results of different studies are "
                    "never mixed",
                    file=str(self.out),
                    allowed="another output directory, or --restart to discard these results",
                )
        elif restart:
            self._clear()
        self.dir.mkdir(parents=True, exist_ok=True)
        for tmp in self.dir.glob(".part-*.tmp"):
            tmp.unlink()  # a chunk that was being written when the study was killed
        if not meta_path.exists():
            _atomic_write(meta_path, json.dumps(self._meta(), indent=2).encode())
        return self.done_ids()

    def done_ids(self) -> set[str]:
        """Run ids of every row already written."""
        parts = sorted(self.dir.glob("part-*.parquet"))
        if not parts:
            return set()
        ids: set[str] = set()
        for part in parts:
            try:
                column = pq.read_table(part, columns=["run_id"]).column("run_id")
            except (OSError, pa.ArrowException) as exc:
                raise InputError(
                    f"unreadable result file ({exc}); delete it to compute its runs again", file=str(part)
                ) from None
            ids.update(column.to_pylist())
        return ids

    # -------------------------------------------------------------- writing
    def write(self, rows: list[tuple[int, dict[str, Any]]]) -> Path:
        """Write one chunk as a part file, atomically."""
        table = _table(self.expansion, self.schema, self._convert, rows)
        first = table.column("run_index")[0].as_py()
        digest = hashlib.sha1("".join(table.column("run_id").to_pylist()).encode()).hexdigest()[:10]
        name = f"part-{first:09d}-{digest}.parquet"
        tmp = self.dir / f".{name}.tmp"
        pq.write_table(table, tmp)
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, self.dir / name)
        return self.dir / name


def _atomic_write(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def read_results(out: str | Path, *, as_table: bool = False):
    """The results of a study output directory as a pandas DataFrame (or Arrow table), one row per
    run, sorted by ``run_index``. Works on an unfinished study too (the runs written so far)."""
    directory = Path(out) / RESULTS_DIR
    if not directory.is_dir():
        raise InputError(
            "no study results here", file=str(out), allowed="an output directory of trainsim batch"
        )
    parts = sorted(directory.glob("part-*.parquet"))
    if not parts:
        table = pa.table({"run_index": pa.array([], pa.int64()), "run_id": pa.array([], pa.string())})
    else:
        table = pa.concat_tables([pq.read_table(p) for p in parts]).sort_by("run_index")
    return table if as_table else table.to_pandas()
