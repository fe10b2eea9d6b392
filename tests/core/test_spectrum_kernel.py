"""The compiled resampler (rv_te_bench/core/_lagrange.c) against the numpy path and closed forms.

The kernel promises the numpy path's values bit for bit (same IEEE operations, same order,
no fused multiply-add). Checked on irregular nodes, with and without the steps given, on
views the kernel must not read wrongly (reversed, strided), and through the public
``resample_to_output_angle``. Independently of both paths: a cubic is reproduced exactly
(to rounding), which any cubic Lagrange interpolant must do.
"""

from __future__ import annotations

import math
import shutil
import sysconfig

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rv_te_bench.core import spectrum
from rv_te_bench.core.spectrum import SpectrumWorkspace, resample_to_output_angle

kernel = pytest.mark.skipif(spectrum._KERNEL is None,
                            reason='the C extension rv_te_bench.core._lagrange is not built')


def _nodes(n: int, seed: int, *, jitter: float = 0.45) -> tuple[np.ndarray, np.ndarray]:
    """n irregular, strictly increasing nodes from 0 over about one revolution, and values."""
    rng = np.random.default_rng(seed)
    step = 2 * math.pi / n
    x = np.cumsum(step * (1.0 + jitter * rng.uniform(-1.0, 1.0, n)))
    x -= x[0]
    y = 1e-4 * np.cos(25 * x + 0.3) + 1e-6 * rng.standard_normal(n)
    return x, y


def test_kernel_is_built_where_a_c_compiler_is() -> None:
    """`make venv` (pip install -e .) compiles the kernel when the machine has a C compiler."""
    cc = (sysconfig.get_config_var('CC') or 'cc').split()[0]
    if shutil.which(cc) is None:
        pytest.skip(f'no C compiler {cc!r} here: the numpy path is the designed fallback')
    assert spectrum.RESAMPLER == 'compiled'
    assert spectrum._KERNEL is not None


@kernel
@settings(max_examples=60, deadline=None)
@given(n=st.integers(4, 3000), seed=st.integers(0, 2**32 - 1),
       grid_ratio=st.floats(0.3, 3.0), with_dx=st.booleans())
def test_kernel_equals_numpy_bit_for_bit(n: int, seed: int, grid_ratio: float,
                                         with_dx: bool) -> None:
    x, y = _nodes(n, seed)
    n_grid = max(1, int(n * grid_ratio))
    spacing = float(x[-1]) / n_grid * (1.0 + 1e-9)      # the grid stays within the nodes' span
    dx = np.diff(x) if with_dx else None
    want = spectrum._lagrange4_numpy(x, y, spacing, n_grid, dx=dx)
    got = spectrum._lagrange4_uniform(x, y, spacing, n_grid, dx=dx)
    np.testing.assert_array_equal(got, want)


@kernel
def test_kernel_equals_numpy_with_grid_points_on_nodes_and_beyond_the_ends() -> None:
    """Nodes exactly on grid points (the ceil edge case) and a grid past the last node."""
    x = np.arange(200, dtype=np.float64) * 0.25          # every 4th grid point is a node
    y = np.sin(x) + 0.01 * x**2
    for n_grid, spacing in ((797, 0.0625), (1000, 0.0625), (50, 1.0), (10, 7.0)):
        want = spectrum._lagrange4_numpy(x, y, spacing, n_grid)
        got = spectrum._lagrange4_uniform(x, y, spacing, n_grid)
        np.testing.assert_array_equal(got, want)


@kernel
def test_kernel_equals_numpy_through_the_public_function_both_senses() -> None:
    """resample_to_output_angle: falling phi hands the kernel reversed (strided) views."""
    x, y = _nodes(20_000, 7)
    phi = x + 0.4
    for sign in (1.0, -1.0):
        ws = SpectrumWorkspace()
        compiled = resample_to_output_angle(sign * phi, y, workspace=ws).te_rad.copy()
        kept = spectrum._KERNEL
        spectrum._KERNEL = None
        try:
            plain = resample_to_output_angle(sign * phi, y).te_rad
        finally:
            spectrum._KERNEL = kept
        np.testing.assert_array_equal(compiled, plain)


@kernel
def test_kernel_reads_strided_inputs_correctly() -> None:
    x, y = _nodes(1001, 3)
    wide = np.empty((x.size, 2))
    wide[:, 0] = y
    y_strided = wide[:, 0]                                # stride 16 bytes
    assert not y_strided.flags.c_contiguous
    got = spectrum._lagrange4_uniform(x, y_strided, 0.004, 1500)
    np.testing.assert_array_equal(got, spectrum._lagrange4_numpy(x, y, 0.004, 1500))


@pytest.mark.parametrize('path', ['uniform', 'numpy'])
def test_cubic_reproduced_exactly(path: str) -> None:
    """A cubic Lagrange interpolant of a cubic is the cubic (closed form, to rounding)."""
    x, _ = _nodes(5000, 11, jitter=0.6)

    def cubic(t: np.ndarray) -> np.ndarray:
        return 0.3 - 1.7 * t + 0.45 * t**2 - 0.06 * t**3

    spacing = 2 * math.pi / 7001
    n_grid = int(float(x[-1]) / spacing)
    fn = spectrum._lagrange4_uniform if path == 'uniform' else spectrum._lagrange4_numpy
    got = fn(x, cubic(x), spacing, n_grid, dx=np.diff(x))
    want = cubic(np.arange(n_grid) * spacing)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


@kernel
@pytest.mark.parametrize(('args', 'error', 'match'), [
    ((np.zeros(8, np.float32), np.zeros(8), None, 0.1, np.empty(4)), TypeError, 'x must be'),
    ((np.zeros(8), np.zeros(8, np.int64), None, 0.1, np.empty(4)), TypeError, 'y must be'),
    ((np.zeros(8), np.zeros(8), np.zeros((7, 1)), 0.1, np.empty(4)), TypeError, 'dx must be'),
    ((np.zeros(3), np.zeros(3), None, 0.1, np.empty(4)), ValueError, 'got 3, 3, 0'),
    ((np.zeros(8), np.zeros(7), None, 0.1, np.empty(4)), ValueError, 'got 8, 7, 0'),
    ((np.zeros(8), np.zeros(8), np.zeros(5), 0.1, np.empty(4)), ValueError, 'got 8, 8, 5'),
    ((np.zeros(8), np.zeros(8), None, 0.0, np.empty(4)), ValueError,
     'spacing must be > 0, got 0.0'),
])
def test_kernel_names_bad_arguments(args: tuple, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        spectrum._KERNEL.lagrange4_uniform(*args)


@kernel
def test_kernel_refuses_a_read_only_output() -> None:
    out = np.empty(4)
    out.setflags(write=False)
    with pytest.raises((BufferError, ValueError), match=r'(?i)read.only|not writ'):
        spectrum._KERNEL.lagrange4_uniform(np.arange(8.0), np.zeros(8), None, 0.5, out)
