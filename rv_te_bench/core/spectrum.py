"""Order spectrum of the TE in the output-angle domain.

The TE of a reducer is, to first order, a periodic function of the member angles, i.e. of
the output-shaft angle. Sampling in time at a varying speed (Hu 2020 drives the input with
V = A sin(Bt) + C) smears its harmonics over many FFT bins. Here the TE is first resampled
onto a uniform grid of the output-shaft angle covering a whole number R of output
revolutions, then transformed with a real FFT: order k of the output rotation then lies
exactly on bin k * R, whatever the speed profile.

Angle reference. The grid is built on the *input* encoder angle divided by the ratio,
phi = theta_in / i, not on the output encoder: it is i times finer (79 times for the Wang
2020 2K-V) and contains no TE (theta_out = phi + TE), so the reference does not distort
the quantity being analysed.

Resampling. Four-point (cubic) Lagrange interpolation on the non-uniform samples,
vectorised. For a sinusoid with s samples per period its amplitude error is about
0.015 (2 pi / s)^4 (5e-4 at s = 15); keep at least ~12 samples per period of the highest
order of interest. The record is taken to cover its angle span plus one (largest)
sample step, as a periodic record does (N samples of one revolution with the end point
left out cover exactly one revolution).

Scaling (like ``scipy.signal.periodogram``, for TE in rad): with X = rfft(te_grid) / N,

- ``amplitude_rad[0] = |X[0]|`` is |mean| (``mean_rad`` keeps the sign),
- ``amplitude_rad[m] = 2 |X[m]|`` for 0 < m < N/2 is the *peak* amplitude a of a component
  a cos(k phi + phase) [rad] with k = m / R,
- ``amplitude_rad[N/2] = |X[N/2]|`` for even N (Nyquist bin),

so Parseval reads mean(te_grid**2) = a_0**2 + sum_{0<m<N/2} a_m**2 / 2 + a_{N/2}**2.
Phases are those of the cosine, referred to phi = 0 (absolute, not to the window start),
so they are comparable between windows: TE(phi) ~ sum a_k cos(k phi + phase_k).
No detrending and no taper window: the mean goes into order 0, and a record over whole
revolutions of a periodic TE needs no window.
"""

from __future__ import annotations

import functools
import importlib
import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, NotRequired, TypedDict

import numpy as np

from rv_te_bench.core.units import json_deg, json_float, rad_to_arcmin
from rv_te_bench.errors import TeInputError

if TYPE_CHECKING:
    from types import ModuleType

    import numpy.typing as npt

    from rv_te_bench.core.orders import OrderSet

    FloatArray = npt.NDArray[np.float64]

__all__ = ['AngleResampled', 'AveragedLineJson', 'OrderSpectrum', 'OrderSpectrumJson',
           'SpectrumAverager', 'SpectrumLine', 'SpectrumLineJson', 'SpectrumSummary',
           'SpectrumWorkspace', 'order_spectrum', 'resample_to_output_angle',
           'spectrum_line_json']

_TWO_PI = 2.0 * math.pi


@functools.lru_cache(maxsize=256)
def _next_fast_len(n: int) -> int:
    """The smallest 5-smooth number (2^a 3^b 5^c) >= ``n``: a fast real FFT length.

    The lengths ``scipy.fft.next_fast_len(n, real=True)`` gives (tested against it). The
    spectra use numpy's FFT, the same pocketfft code as scipy's (bit for bit equal with
    numpy 2.4), so that importing this module does not import scipy (0.15-0.25 s of the
    start-up of every command and node that computes spectra).

    Raises:
        ValueError: ``n`` < 1.
    """
    if n < 1:
        msg = f'next_fast_len needs n >= 1, got {n}'
        raise ValueError(msg)
    best = 1 << (n - 1).bit_length()   # the power of 2 at or above n
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            m = p35
            while m < n:
                m *= 2
            best = min(best, m)
            p35 *= 3
        p5 *= 5
    return best


_REV_TOL = 1e-9
_EMPTY_F = np.empty(0, dtype=np.float64)
_EMPTY_F.setflags(write=False)
_EMPTY_C = np.empty(0, dtype=np.complex128)
_EMPTY_C.setflags(write=False)


class SpectrumLineJson(TypedDict):
    """:meth:`SpectrumLine.to_json_dict`: a labelled line of one spectrum."""

    label: str
    output_order: float
    crank_order: float
    frequency_hz: float | None
    amplitude_rad: float
    amplitude_arcmin: float
    phase_rad: float


class OrderSpectrumJson(TypedDict):
    """:meth:`OrderSpectrum.to_json_dict`: the lines of one spectrum (None: not finite)."""

    output_hz: float | None
    crank_hz: float | None
    revolutions: float
    samples_per_rev: int
    mean_rad: float
    lines: list[SpectrumLineJson]


class AveragedLineJson(TypedDict):
    """:func:`spectrum_line_json`: an averaged line in the analysis JSON (None: not
    finite; the spread of the per-window amplitudes only when known)."""

    label: str
    output_order: float | None
    crank_order: float | None
    frequency_hz: float | None
    amplitude_arcmin: float | None
    amplitude_rad: float | None
    phase_rad: float | None
    phase_deg: float | None
    amplitude_spread_arcmin: NotRequired[float | None]


@dataclass(frozen=True)
class SpectrumLine:
    """One reported line of the order spectrum.

    Attributes:
        output_order: Order of the output rotation (cycles per output revolution).
        crank_order: Same frequency as a multiple of the crank frequency f_w.
        frequency_hz: Frequency at the window's mean speed [Hz] (NaN if unknown).
        amplitude_rad: Peak amplitude a of a cos(order * phi + phase) [rad].
        phase_rad: Phase of that cosine, referred to phi = theta_in / i = 0, in (-pi, pi].
        label: E.g. ``'f_out'``, ``'2 f_w'``, ``'f_w + f_out'``, ``'52 f_w'``.
    """

    output_order: float
    crank_order: float
    frequency_hz: float
    amplitude_rad: float
    phase_rad: float
    label: str

    def to_json_dict(self) -> SpectrumLineJson:
        """JSON-friendly dict (units in the keys; NaN becomes None)."""
        def fin(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None
        return {'label': self.label, 'output_order': self.output_order,
                'crank_order': self.crank_order, 'frequency_hz': fin(self.frequency_hz),
                'amplitude_rad': self.amplitude_rad,
                'amplitude_arcmin': float(rad_to_arcmin(self.amplitude_rad)),
                'phase_rad': self.phase_rad}


@dataclass(frozen=True)
class OrderSpectrum:
    """Order spectrum of one TE record over whole output revolutions.

    Attributes:
        output_hz: Mean output rotation frequency over the record [Hz] (NaN if unknown).
        crank_hz: Mean crank frequency f_w [Hz] (NaN if unknown).
        revolutions: Whole output revolutions R analysed.
        lines: The :class:`OrderSet` lines that fall at or below the Nyquist order.
        orders: Output order of each bin, m / R, read-only.
        amplitude_rad: One-sided peak amplitude per bin [rad] (scaling in the module
            docstring), read-only.
        bins: rfft(TE on the angle grid) / N, complex, phases referred to the grid start
            ``phi0_rad``, read-only (``phase_rad`` is derived from it on first use).
        mean_rad: Mean TE over the grid [rad] (signed order 0).
        samples_per_rev: Grid points per output revolution.
        phi0_rad: Output angle of the first grid point [rad].

    ``orders``, ``amplitude_rad`` and ``bins`` are empty in a copy made by
    :meth:`lines_only` (the lines and scalars are kept).
    """

    output_hz: float
    crank_hz: float
    revolutions: float
    lines: tuple[SpectrumLine, ...]
    orders: np.ndarray = field(repr=False)
    amplitude_rad: np.ndarray = field(repr=False)
    bins: np.ndarray = field(repr=False)
    mean_rad: float
    samples_per_rev: int
    phi0_rad: float = 0.0

    @functools.cached_property
    def phase_rad(self) -> np.ndarray:
        """Cosine phase per bin referred to phi = 0 [rad], in (-pi, pi], read-only.

        Computed on first use (the lines carry their phases already; the full array is
        rarely needed and costs an angle and a wrap per bin).
        """
        phase: npt.NDArray[np.float64] = np.angle(self.bins)
        phase -= self.orders * self.phi0_rad  # refer the phase to phi = 0, not the grid start
        _wrap_pi_inplace(phase)
        phase.setflags(write=False)
        return phase

    def lines_only(self) -> OrderSpectrum:
        """A copy without the per-bin arrays (a few hundred bytes instead of ~2 MB for a
        one-revolution window at 10 kHz): what a long offline analysis keeps per window."""
        return replace(self, orders=_EMPTY_F, amplitude_rad=_EMPTY_F, bins=_EMPTY_C)

    def line(self, label: str) -> SpectrumLine:
        """The line with this label.

        Raises:
            KeyError: No such line in this spectrum.
        """
        for ln in self.lines:
            if ln.label == label:
                return ln
        raise KeyError(label)

    def to_json_dict(self) -> OrderSpectrumJson:
        """JSON-friendly summary (the lines, not the full spectrum)."""
        def fin(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None
        return {'output_hz': fin(self.output_hz), 'crank_hz': fin(self.crank_hz),
                'revolutions': self.revolutions, 'samples_per_rev': self.samples_per_rev,
                'mean_rad': self.mean_rad,
                'lines': [ln.to_json_dict() for ln in self.lines]}


@dataclass(frozen=True)
class AngleResampled:
    """TE on a uniform output-angle grid.

    Attributes:
        phi0_rad: Angle of the first grid point (the record's smallest phi) [rad].
        revolutions: Whole revolutions R covered.
        samples_per_rev: Grid points per revolution; the grid has R * samples_per_rev points
            phi0 + 2 pi j / samples_per_rev, the end point left out.
        te_rad: TE at the grid points [rad].
    """

    phi0_rad: float
    revolutions: int
    samples_per_rev: int
    te_rad: np.ndarray


_CHUNK = 16384  # grid points per pass: keeps the temporaries in cache and off mmap

try:   # the compiled resampler (pyproject.toml ext-modules; optional: else numpy does it)
    _KERNEL: ModuleType | None = importlib.import_module('rv_te_bench.core._lagrange')
except ImportError:   # pragma: no cover - depends on how the package was installed
    _KERNEL = None
#: Which resampler :func:`order_spectrum` uses: ``'compiled'`` or ``'numpy'`` (same values).
RESAMPLER = 'numpy' if _KERNEL is None else 'compiled'


class SpectrumWorkspace:
    """Work arrays kept between spectra of windows of about one size (not thread-safe).

    :func:`order_spectrum` given one writes its ~12 window-long intermediate arrays (angle
    offsets, steps, divided differences, stencil indices, the angle grid) into these
    instead of allocating them per window: the streaming analysis holds one per analyzer.
    The arrays grow to the largest window seen and are not shrunk. It also keeps the
    read-only order grid m / R of the last window length, which spectra of windows of that
    length then share (``OrderSpectrum.orders``: one array instead of one per window, e.g.
    0.6 MB and its fresh pages for a 10 kHz one-revolution window).
    """

    __slots__ = ('_arrays', '_orders')

    def __init__(self) -> None:
        """Start empty."""
        self._arrays: dict[str, np.ndarray] = {}
        self._orders: tuple[int, int, np.ndarray] | None = None

    def orders(self, n_bins: int, revolutions: int) -> np.ndarray:
        """The read-only order of each bin, ``arange(n_bins) / revolutions`` (shared)."""
        if self._orders is None or self._orders[:2] != (n_bins, revolutions):
            grid = np.arange(n_bins, dtype=np.float64) / revolutions
            grid.setflags(write=False)
            self._orders = (n_bins, revolutions, grid)
        return self._orders[2]

    def array(self, name: str, size: int, dtype: type = np.float64) -> np.ndarray:
        """A 1-D array ``name`` of ``size`` elements (contents undefined)."""
        arr = self._arrays.get(name)
        if arr is None or arr.size < size:
            arr = np.empty(size + size // 8, dtype=dtype)   # room for a slightly longer one
            self._arrays[name] = arr
        return arr[:size]


def _lagrange4_uniform(x: np.ndarray, y: np.ndarray, spacing: float, n_grid: int, *,
                       dx: np.ndarray | None = None,
                       work: SpectrumWorkspace | None = None) -> np.ndarray:
    """Cubic Lagrange interpolation of (x, y) at the grid 0, spacing, ..., (n_grid-1) spacing.

    The compiled kernel (``_lagrange``) when it was built, else :func:`_lagrange4_numpy`:
    the same operations in the same order, so the same values bit for bit (the kernel is
    about 3x faster and runs without the GIL). Arguments and result as there.
    """
    if _KERNEL is None or x.size < 4:
        return _lagrange4_numpy(x, y, spacing, n_grid, dx=dx, work=work)
    out = work.array('grid', n_grid) if work is not None else np.empty(n_grid)
    _KERNEL.lagrange4_uniform(np.ascontiguousarray(x), np.ascontiguousarray(y),
                              None if dx is None else np.ascontiguousarray(dx), spacing, out)
    return out


def _lagrange4_numpy(x: np.ndarray, y: np.ndarray, spacing: float, n_grid: int, *,
                     dx: np.ndarray | None = None,
                     work: SpectrumWorkspace | None = None) -> np.ndarray:
    """Cubic Lagrange interpolation of (x, y) at the grid 0, spacing, ..., (n_grid-1) spacing.

    ``x`` increases strictly from 0; ``dx`` is ``np.diff(x)`` when the caller has it (read
    only). Each grid point uses the four nodes around it (two at or below, two above; the
    end intervals use the first/last four nodes). The node index is found by counting nodes
    per grid cell (bincount + cumsum, O(n)). The cubic through nodes j..j+3 is evaluated in
    Newton form,

        p(x) = y_j + (x - x_j) (f[j,j+1] + (x - x_j+1) (f[j..j+2] + (x - x_j+2) f[j..j+3])),

    with the divided differences f[...] computed once per node (the same polynomial as the
    Lagrange form, about half the arithmetic and no division per grid point); the
    evaluation runs in chunks of the grid so that temporaries stay small. With ``work`` the
    intermediate arrays and the result live in its arrays (the result is overwritten by the
    next call with the same workspace); the values are the same either way.
    """
    n = x.size
    if n < 4:
        resampled: npt.NDArray[np.float64] = np.interp(np.arange(n_grid) * spacing, x, y)
        return resampled
    ws = work if work is not None else SpectrumWorkspace()
    # count[m] = number of nodes with x <= m * spacing: a node in ((m-1) s, m s] goes to
    # cell m (ceil; a node that rounds onto a grid point may land one cell off, which only
    # shifts the 4-node stencil by one)
    cell_f = np.multiply(x, 1.0 / spacing, out=ws.array('cell_f', n))
    np.ceil(cell_f, out=cell_f)
    np.minimum(cell_f, n_grid, out=cell_f)
    cell = ws.array('cell', n, np.intp)
    np.copyto(cell, cell_f, casting='unsafe')
    j_all = np.cumsum(np.bincount(cell, minlength=n_grid + 1)[:n_grid],
                      out=ws.array('j_all', n_grid, np.intp))
    j_all -= 2
    np.clip(j_all, 0, n - 4, out=j_all)
    out = ws.array('grid', n_grid) if work is not None else np.empty(n_grid)
    # the grid in chunks, each with the nodes its stencils use (j_all is non-decreasing):
    # the divided differences of those nodes and the evaluation stay in cache (the same
    # element-wise operations as over the whole record, so the same values). The gathers
    # use mode='clip' (j is within 0..k-4 by construction): with out= and the default
    # mode='raise' numpy gathers into a temporary and copies (about twice the time).
    firsts = j_all[0:n_grid:_CHUNK]
    lasts = j_all[np.minimum(np.arange(_CHUNK, n_grid + _CHUNK, _CHUNK), n_grid) - 1]
    k_max = int((lasts - firsts).max()) + 4
    dd1_buf = ws.array('dd1', k_max)
    dd2_buf = ws.array('dd2', k_max)
    dd3_buf = ws.array('dd3', k_max)
    span_buf = ws.array('span', k_max)
    steps = np.arange(_CHUNK, dtype=np.float64)
    xq_buf = ws.array('xq', _CHUNK)
    acc_buf = ws.array('acc', _CHUNK)
    t_buf = ws.array('t', _CHUNK)
    jl_buf = ws.array('jl', _CHUNK, np.intp)
    for c, a in enumerate(range(0, n_grid, _CHUNK)):
        b = min(a + _CHUNK, n_grid)
        m = b - a
        lo = int(firsts[c])
        k = int(lasts[c]) + 4 - lo           # nodes lo .. lo + k - 1
        xs, ys = x[lo:lo + k], y[lo:lo + k]
        dd1 = np.subtract(ys[1:], ys[:-1], out=dd1_buf[:k - 1])
        if dx is None:
            dd1 /= np.subtract(xs[1:], xs[:-1], out=span_buf[:k - 1])
        else:
            dd1 /= dx[lo:lo + k - 1]
        dd2 = np.subtract(dd1[1:], dd1[:-1], out=dd2_buf[:k - 2])
        dd2 /= np.subtract(xs[2:], xs[:-2], out=span_buf[:k - 2])
        dd3 = np.subtract(dd2[1:], dd2[:-1], out=dd3_buf[:k - 3])
        dd3 /= np.subtract(xs[3:], xs[:-3], out=span_buf[:k - 3])
        j = np.subtract(j_all[a:b], lo, out=jl_buf[:m])
        xq = np.add(steps[:m], a, out=xq_buf[:m])
        xq *= spacing
        acc = xs[2:].take(j, out=acc_buf[:m], mode='clip')      # x[j + 2]
        np.subtract(xq, acc, out=acc)
        acc *= dd3.take(j, out=t_buf[:m], mode='clip')
        acc += dd2.take(j, out=t_buf[:m], mode='clip')
        t = xs[1:].take(j, out=t_buf[:m], mode='clip')          # x[j + 1]
        np.subtract(xq, t, out=t)
        acc *= t
        acc += dd1.take(j, out=t_buf[:m], mode='clip')
        xs.take(j, out=t, mode='clip')
        np.subtract(xq, t, out=t)
        acc *= t
        np.add(acc, ys.take(j, out=t, mode='clip'), out=out[a:b])
    return out


def resample_to_output_angle(
    phase_out_rad: npt.ArrayLike, te_rad: npt.ArrayLike, *,
    revolutions: int | None = None, samples_per_rev: int | None = None,
    workspace: SpectrumWorkspace | None = None,
) -> AngleResampled:
    """Resample TE onto a uniform output-angle grid over whole revolutions.

    Args:
        phase_out_rad: Reference output angle phi = theta_in / i at each sample [rad],
            strictly monotonic (either sense of rotation), shape (n,).
        te_rad: TE at each sample [rad], shape (n,).
        revolutions: Whole revolutions R to use (>= 1), counted from the smallest phi; the
            record must cover them (span plus one sample step). None: as many as covered.
        samples_per_rev: Grid points per revolution; None keeps the record's mean density
            (rounded up to a fast FFT length).
        workspace: Work arrays to reuse (:class:`SpectrumWorkspace`); the returned
            ``te_rad`` is then one of them, overwritten by the next call with it.

    Returns:
        The resampled record.

    Raises:
        TeInputError: Shapes differ, fewer than 2 samples, non-finite values, phi not
            strictly monotonic, or less than one (or fewer than ``revolutions``)
            revolution covered.

    Examples:
        Samples already on the grid come back unchanged:

        >>> import numpy as np
        >>> phi = 2 * np.pi * np.arange(8) / 8
        >>> r = resample_to_output_angle(phi, np.cos(phi), samples_per_rev=8)
        >>> (r.revolutions, bool(np.allclose(r.te_rad, np.cos(phi))))
        (1, True)
    """
    phi = np.asarray(phase_out_rad, dtype=np.float64)
    te = np.asarray(te_rad, dtype=np.float64)
    if phi.ndim != 1 or phi.shape != te.shape:
        msg = f'phase_out_rad and te_rad must be 1-D of equal length: {phi.shape=}, {te.shape=}'
        raise TeInputError(msg)
    if phi.size < 2:
        msg = f'need at least 2 samples, got {phi.size}'
        raise TeInputError(msg)
    # a NaN or inf makes the sum non-finite (one pass, no temporary)
    if not (math.isfinite(float(np.add.reduce(phi))) and math.isfinite(float(np.add.reduce(te)))):
        msg = 'phase_out_rad or te_rad holds NaN or infinite values (or values beyond 1e300)'
        raise TeInputError(msg)
    n = phi.size
    step = np.subtract(phi[1:], phi[:-1],
                       out=None if workspace is None else workspace.array('dx', n - 1))
    if step[0] < 0.0:
        phi, te, step = phi[::-1], te[::-1], -step[::-1]
    if not float(np.minimum.reduce(step)) > 0.0:
        msg = 'phase_out_rad must be strictly monotonic (no stop or reversal in the record)'
        raise TeInputError(msg)
    phi0 = float(phi[0])
    covered_rev = (float(phi[-1]) - phi0 + float(np.maximum.reduce(step))) / _TWO_PI
    n_rev = math.floor(covered_rev + _REV_TOL)
    if revolutions is not None:
        if isinstance(revolutions, bool) or int(revolutions) != revolutions or revolutions < 1:
            msg = f'revolutions must be a whole number >= 1, got {revolutions!r}'
            raise TeInputError(msg)
        if int(revolutions) > n_rev:
            msg = (f'record covers {covered_rev:.6g} output revolutions, '
                   f'fewer than revolutions={revolutions}')
            raise TeInputError(msg)
        n_rev = int(revolutions)
    if n_rev < 1:
        msg = f'record covers {covered_rev:.6g} output revolutions; need at least 1'
        raise TeInputError(msg)
    if samples_per_rev is None:
        density = phi.size / covered_rev
        spr = _next_fast_len(max(4, math.ceil(density - 1e-6)))
    else:
        if isinstance(samples_per_rev, bool) or int(samples_per_rev) != samples_per_rev \
                or samples_per_rev < 2:
            msg = f'samples_per_rev must be an int >= 2, got {samples_per_rev!r}'
            raise TeInputError(msg)
        spr = int(samples_per_rev)
    x = np.subtract(phi, phi0, out=None if workspace is None else workspace.array('x', n))
    te_grid = _lagrange4_uniform(x, te, _TWO_PI / spr, n_rev * spr, dx=step, work=workspace)
    return AngleResampled(phi0_rad=phi0, revolutions=n_rev, samples_per_rev=spr, te_rad=te_grid)


def _wrap_pi_inplace(x: np.ndarray) -> np.ndarray:
    """Wrap to (-pi, pi] in place: pi - ((pi - x) mod 2 pi)."""
    np.subtract(np.pi, x, out=x)
    np.mod(x, _TWO_PI, out=x)
    np.subtract(np.pi, x, out=x)
    return x


def order_spectrum(
    phase_out_rad: npt.ArrayLike, te_rad: npt.ArrayLike, orders: OrderSet, *,
    duration_s: float | None = None, samples_per_rev: int | None = None,
    revolutions: int | None = None, workspace: SpectrumWorkspace | None = None,
) -> OrderSpectrum:
    """Order spectrum of TE over whole output revolutions, with the lines of ``orders``.

    Scaling and phase convention: see the module docstring (peak amplitude in rad of
    a cos(k phi + phase), phi = theta_in / i; order 0 is the mean).

    Args:
        phase_out_rad: Reference output angle theta_in / i per sample [rad], strictly
            monotonic.
        te_rad: TE per sample [rad].
        orders: The lines to report; a line reads the bin nearest to order * R (exact when
            order * R is a whole number); lines above the Nyquist order are left out.
        duration_s: Time from the first to the last sample [s], for ``output_hz``,
            ``crank_hz`` and each line's ``frequency_hz`` (NaN when None).
        samples_per_rev: Grid points per output revolution (None: record density).
        revolutions: Whole revolutions to analyse (None: as many as the record covers).
        workspace: Work arrays to reuse between calls (:class:`SpectrumWorkspace`; the
            returned spectrum holds none of them); None allocates them per call.

    Returns:
        The spectrum.

    Raises:
        TeInputError: See :func:`resample_to_output_angle`; ``duration_s`` <= 0.

    Examples:
        A 2-arcmin line at the crank frequency (order 25) of the Wang 2020 2K-V:

        >>> import numpy as np
        >>> from rv_te_bench.core.orders import OrderSet
        >>> from rv_te_bench.core.units import arcmin_to_rad, rad_to_arcmin
        >>> phi = 2 * np.pi * np.arange(4096) / 4096
        >>> te = arcmin_to_rad(2.0) * np.cos(25 * phi + 0.3)
        >>> spec = order_spectrum(phi, te, OrderSet(79.0, 25.0), duration_s=15.8)
        >>> ln = spec.line('1 f_w')
        >>> round(float(rad_to_arcmin(ln.amplitude_rad)), 9), round(ln.phase_rad, 9)
        (2.0, 0.3)
    """
    res = resample_to_output_angle(phase_out_rad, te_rad, revolutions=revolutions,
                                   samples_per_rev=samples_per_rev, workspace=workspace)
    phi = np.asarray(phase_out_rad, dtype=np.float64)
    if duration_s is None:
        output_hz = math.nan
    else:
        if not (math.isfinite(duration_s) and duration_s > 0.0):
            msg = f'duration_s must be finite and > 0, got {duration_s!r}'
            raise TeInputError(msg)
        output_hz = abs(float(phi[-1]) - float(phi[0])) / _TWO_PI / float(duration_s)
    n_grid = res.te_rad.size
    spec = np.fft.rfft(res.te_rad)
    spec *= 1.0 / n_grid
    amplitude = np.abs(spec)
    amplitude *= 2.0
    amplitude[0] *= 0.5
    if n_grid % 2 == 0:
        amplitude[-1] *= 0.5
    if workspace is None:
        bin_orders = np.arange(spec.size, dtype=np.float64) / res.revolutions
    else:
        bin_orders = workspace.orders(spec.size, res.revolutions)
    # the lines below the Nyquist order, each at its bin m; one pass over all of them
    # (issue 41), element by element the same operations as one line at a time
    kept = [(order, label, m) for order, label in orders.lines()
            if (m := round(order * res.revolutions)) < spec.size]
    bins = [m for _, _, m in kept]
    at = spec[bins].tolist()
    # phase referred to phi = 0, not to the grid start
    phase = np.array([math.atan2(z.imag, z.real) for z in at])
    phase -= bin_orders[bins] * res.phi0_rad
    phases = _wrap_pi_inplace(phase).tolist()
    amps = amplitude[bins].tolist()
    lines = [SpectrumLine(output_order=order, crank_order=orders.crank_order(order),
                          frequency_hz=order * output_hz, amplitude_rad=a, phase_rad=p,
                          label=label)
             for (order, label, _), a, p in zip(kept, amps, phases, strict=True)]
    for arr in (bin_orders, amplitude, spec):
        if arr.flags.writeable:
            arr.setflags(write=False)
    return OrderSpectrum(
        output_hz=output_hz, crank_hz=output_hz * orders.crank_per_output,
        revolutions=float(res.revolutions), lines=tuple(lines), orders=bin_orders,
        amplitude_rad=amplitude, bins=spec, mean_rad=float(spec[0].real),
        samples_per_rev=res.samples_per_rev, phi0_rad=res.phi0_rad)


# --------------------------------------------------------------------------------------
# the averaged spectrum of a recording (the complete windows of a bag)


@dataclass(frozen=True)
class SpectrumSummary:
    """Order spectrum of a bag: the complete windows, averaged.

    Attributes:
        method: How the lines were combined, in words (shown in reports).
        n_windows: Complete windows averaged.
        output_hz: Mean output rotation frequency f_out over those windows [Hz].
        crank_hz: Mean absolute crank frequency f_w [Hz].
        revolutions: Output revolutions covered by the averaged windows.
        lines: Averaged labelled lines (peak amplitude [rad], phase of the cosine [rad]).
        amplitude_spread_rad: Per line, the standard deviation of the per-window amplitudes.
        orders: Output orders of the full spectrum (for plots), read-only.
        amplitude_rad: Mean peak amplitude at ``orders`` [rad], read-only.
    """

    method: str
    n_windows: int
    output_hz: float
    crank_hz: float
    revolutions: float
    lines: tuple[SpectrumLine, ...]
    amplitude_spread_rad: tuple[float, ...]
    orders: FloatArray = field(repr=False)
    amplitude_rad: FloatArray = field(repr=False)

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-friendly dict; line amplitudes in rad and arcmin, phases in rad and deg."""
        return {
            'method': self.method, 'n_windows': self.n_windows,
            'output_hz': json_float(self.output_hz), 'crank_hz': json_float(self.crank_hz),
            'revolutions': json_float(self.revolutions),
            'lines': [spectrum_line_json(ln, spread) for ln, spread in
                      zip(self.lines, self.amplitude_spread_rad, strict=True)],
        }


class SpectrumAverager:
    """Running average of the spectra of complete windows (memory of one window's bins).

    Line amplitudes: arithmetic mean of the per-window peak amplitudes (robust to the phase
    reference of each window). Line phases: angle of the mean phasor a*exp(j*phase). The
    full amplitude spectrum is averaged bin by bin when every window has the same order
    grid; otherwise the spectrum of the longest window is shown (the method says so).

    Examples:
        >>> import numpy as np
        >>> from rv_te_bench.core.orders import OrderSet
        >>> from rv_te_bench.core.spectrum import order_spectrum
        >>> phi = 2 * np.pi * np.arange(512) / 512
        >>> avg = SpectrumAverager()
        >>> for a in (1e-4, 3e-4):
        ...     avg.add(order_spectrum(phi, a * np.cos(25 * phi), OrderSet(79.0, 25.0)))
        >>> s = avg.result()
        >>> line = next(ln for ln in s.lines if ln.label == '1 f_w')
        >>> s.n_windows, round(line.amplitude_rad, 12), round(float(s.amplitude_rad[25]), 12)
        (2, 0.0002, 0.0002)
    """

    def __init__(self) -> None:
        """Start with no window."""
        self._first: OrderSpectrum | None = None
        self._line_amps: list[dict[str, float]] = []
        self._line_phases: list[dict[str, float]] = []
        self._revs: list[float] = []
        self._out_hz: list[float] = []
        self._crank_hz: list[float] = []
        self._sum: FloatArray | None = None
        self._ref_orders: FloatArray | None = None
        self._same_grid = True
        self._longest: tuple[float, FloatArray, FloatArray] | None = None

    def add(self, spectrum: OrderSpectrum) -> None:
        """Fold in the spectrum of one complete window (it is not kept)."""
        if self._first is None:
            self._first = spectrum.lines_only()
        self._line_amps.append({ln.label: ln.amplitude_rad for ln in spectrum.lines})
        self._line_phases.append({ln.label: ln.phase_rad for ln in spectrum.lines})
        self._revs.append(float(spectrum.revolutions))
        self._out_hz.append(float(spectrum.output_hz))
        self._crank_hz.append(float(spectrum.crank_hz))
        orders = np.asarray(spectrum.orders, dtype=np.float64)
        amp = np.asarray(spectrum.amplitude_rad, dtype=np.float64)
        if self._longest is None or spectrum.revolutions > self._longest[0]:
            self._longest = (float(spectrum.revolutions), orders.copy(), amp.copy())
        if self._sum is None or self._ref_orders is None:
            self._sum = amp.copy()
            self._ref_orders = orders.copy()
            return
        # windows of the same length share the order grid m / R up to their own Nyquist order
        size = min(self._sum.size, amp.size)
        # (windows of one length have bit-equal grids m / R: the exact test settles them
        # in one pass; allclose, ~8 passes, only when they differ)
        if self._same_grid and not np.array_equal(orders[:size], self._ref_orders[:size]) \
                and not np.allclose(orders[:size], self._ref_orders[:size]):
            self._same_grid = False
        self._sum = self._sum[:size] + amp[:size]
        self._ref_orders = self._ref_orders[:size]

    def result(self) -> SpectrumSummary | None:
        """The average so far, or None when no window was added."""
        first = self._first
        if first is None or self._sum is None or self._ref_orders is None \
                or self._longest is None:
            return None
        n = len(self._revs)
        # lines are matched by label: a line above a window's Nyquist order is missing there
        labels = [ln.label for ln in first.lines
                  if all(ln.label in d for d in self._line_amps)]
        amps = np.array([[d[lab] for lab in labels] for d in self._line_amps],
                        dtype=np.float64).reshape(n, len(labels))
        phases = np.array([[d[lab] for lab in labels] for d in self._line_phases],
                          dtype=np.float64).reshape(n, len(labels))
        mean_amp = amps.mean(axis=0)
        phasor = (amps * np.exp(1j * phases)).mean(axis=0)
        revs = np.array(self._revs)
        out_hz = float(np.mean(self._out_hz))
        crank_hz = float(np.mean(self._crank_hz))
        by_label = {ln.label: ln for ln in first.lines}
        lines = tuple(
            replace(by_label[lab], amplitude_rad=float(mean_amp[k]),
                    phase_rad=float(np.angle(phasor[k])),
                    frequency_hz=float(by_label[lab].output_order * out_hz))
            for k, lab in enumerate(labels))
        what = 'the one complete window' if n == 1 else f'{n} complete windows'
        if self._same_grid:
            orders = self._ref_orders.copy()
            amp = self._sum / n
            method = (f'mean of {what} ({revs.sum():.3g} output revolution(s)): line amplitude '
                      '= mean of the per-window peak amplitudes, phase = angle of the mean '
                      'phasor')
        else:
            orders = self._longest[1].copy()
            amp = self._longest[2].copy()
            method = (f'lines: mean of {what}; full spectrum: the longest window '
                      f'({float(revs.max()):.3g} output revolutions; window grids differ)')
        orders.setflags(write=False)
        amp.setflags(write=False)
        return SpectrumSummary(
            method=method, n_windows=n, output_hz=out_hz, crank_hz=crank_hz,
            revolutions=float(revs.sum()), lines=lines,
            amplitude_spread_rad=tuple(float(x) for x in amps.std(axis=0)),
            orders=orders, amplitude_rad=amp)


def spectrum_line_json(line: SpectrumLine, spread_rad: float) -> AveragedLineJson:
    """A line as JSON: amplitude in rad and arcmin, phase in rad and deg, and the spread of
    the per-window amplitudes [arcmin] when ``spread_rad`` is finite (None for NaN)."""
    out: AveragedLineJson = {
        'label': line.label,
        'output_order': json_float(line.output_order),
        'crank_order': json_float(line.crank_order),
        'frequency_hz': json_float(line.frequency_hz),
        'amplitude_arcmin': json_float(rad_to_arcmin(line.amplitude_rad)),
        'amplitude_rad': json_float(line.amplitude_rad),
        'phase_rad': json_float(line.phase_rad),
        'phase_deg': json_deg(line.phase_rad),
    }
    if math.isfinite(spread_rad):
        out['amplitude_spread_arcmin'] = json_float(rad_to_arcmin(spread_rad))
    return out
