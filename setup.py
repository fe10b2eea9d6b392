"""The compiled part of the pip distribution; everything else is in pyproject.toml.

One optional C extension, ``rv_te_bench.core._lagrange`` (the cubic resampler of the order
spectra; issue 23). ``optional=True``: without a C compiler the install still succeeds and
``rv_te_bench.core.spectrum`` uses its numpy path, which gives the same values bit for bit
(``rv_te_bench.core.spectrum.RESAMPLER`` says which one runs).
"""

from __future__ import annotations

import sys

from setuptools import Extension, setup

# -ffp-contract=off: no fused multiply-add, so the kernel rounds as numpy does (bit-identical
# results with the numpy path); -O3 lets the compiler vectorise the divided differences.
_FLAGS = [] if sys.platform == 'win32' else ['-O3', '-ffp-contract=off']

setup(ext_modules=[Extension('rv_te_bench.core._lagrange', ['rv_te_bench/core/_lagrange.c'],
                             extra_compile_args=_FLAGS, optional=True)])
