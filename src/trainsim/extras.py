"""Optional dependencies: which extra of ``pip install "trainsim[EXTRA]"`` brings which module.

The core install (numpy, scipy, pandas, pydantic, PyYAML, matplotlib, typer, rich, jsonschema)
runs, optimises and plots trainsim's own files and railtoolkit/TrainRuns.jl and TTOBench files; the rest
is in extras, so that a light install stays light. A command that needs a missing extra says which one.
"""

from __future__ import annotations

#: Top-level module name -> the extra that installs it.
MODULE_EXTRAS: dict[str, str] = {
    "fastapi": "web",
    "fastapi_offline": "web",
    "uvicorn": "web",
    "websockets": "web",
    "multipart": "web",
    "python_multipart": "web",
    "plotly": "web",
    "dask": "batch",
    "distributed": "batch",
    "pyarrow": "batch",
    "lxml": "interchange",
    "openpyxl": "interchange",
    "casadi": "reference",
}

#: What each extra is for, in the words of the message a user sees.
EXTRA_PURPOSE: dict[str, str] = {
    "web": "the web application (trainsim serve)",
    "batch": "studies (trainsim batch) and Parquet output",
    "interchange": "railML and Excel files",
    "reference": "the CasADi/IPOPT reference optimum (--strategy reference)",
}


def missing_extra(exc: ImportError) -> str | None:
    """The extra whose absence caused ``exc``, or None when it is not an optional dependency."""
    name = getattr(exc, "name", None) or ""
    return MODULE_EXTRAS.get(name.split(".")[0])


def missing_extra_message(exc: ImportError) -> str | None:
    """A user-facing sentence naming the extra to install, or None when ``exc`` is not about an extra."""
    extra = missing_extra(exc)
    if extra is None:
        return None
    return (
        f"{EXTRA_PURPOSE[extra]} needs the optional dependency '{exc.name}', which is not installed; "
        f'install it with: pip install "trainsim[{extra}]"'
    )
