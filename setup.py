"""Builds trainsim's compiled hot path: every ``src/trainsim/**/*.pyx`` becomes an extension module
(Cython, C compiler of the machine). The rest of the package is described in pyproject.toml."""

from pathlib import Path

from Cython.Build import cythonize
from setuptools import Extension, setup

SOURCES = sorted(Path("src").rglob("*.pyx"))

# Plain IEEE arithmetic, so that every build gives the same bits (those of the numba kernels the
# modules were ported from, stop 25): no -ffast-math, no contraction into fused multiply-adds.
COMPILE_ARGS = ["-O2", "-ffp-contract=off", "-fno-fast-math"]

extensions = [
    Extension(
        ".".join(path.relative_to("src").with_suffix("").parts),
        [str(path)],
        extra_compile_args=COMPILE_ARGS,
    )
    for path in SOURCES
]

setup(
    ext_modules=cythonize(
        extensions,
        compiler_directives={
            "language_level": "3",
            "boundscheck": False,
            "wraparound": False,
            "cdivision": True,
        },
        include_path=["src"],
    )
)
