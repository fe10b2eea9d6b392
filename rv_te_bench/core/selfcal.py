"""The scale's own error, separated from the reducer's: head differences and reversal.

**Self-calibration from several heads.** The differences ``r_j - r_0`` of heads on one scale
hold no reducer TE, only the scale error seen from two places (:mod:`.heads`)::

    D_jk = c_k (e^{-ik beta_j} - e^{-ik beta_0}) = c_k a_jk

for each harmonic k of the scale revolution. With the differences' noise covariance C
(pooled in-bin scatter, :mod:`.harmonic_fold`), the generalised least-squares estimate and
its standard uncertainty (of the real and of the imaginary part) are::

    c_k = (a^H C^-1 D) / (a^H C^-1 a),        u(c_k) = (a^H C^-1 a)^-1/2

Order k is observable when ``a_k`` is not small (:meth:`.HeadLayout.observability`); for N
equally spaced heads the multiples of N are not (the same orders their mean leaves).

**Reversal.** One head, two (or more) sessions of the same unit with the scale re-mounted
on its shaft at the index angles ``iota_s`` (e.g. 0 and 180 deg). Folded on the shaft
angle theta (the output reading, zeroed to the shaft), session s holds at order k::

    TE_sk = T_k + S_k e^{-ik iota_s}

(T the reducer's TE, S the scale's error in its own coordinate ``u = theta - iota``: the
scale's error moves with the scale, the reducer's stays with the output). Two unknowns per
order, one equation per session, solved by weighted least squares; order k is observable
when the sessions' ``e^{-ik iota_s}`` differ (``|1 - e^{-ik iota}| >= 2 MIN_OBSERVABILITY``
for two sessions: 180 deg resolves the odd orders, 120 deg every order not a multiple of 3).
The reducer must repeat between the sessions (same speed, load and temperature): the
uncertainty given is that of the noise within each session only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.core.harmonic_fold import DEFAULT_HARMONIC_BINS, ChannelHarmonics, HarmonicFold
from rv_te_bench.core.heads import MIN_OBSERVABILITY, HeadLayout
from rv_te_bench.core.units import rad_to_arcsec, rad_to_deg
from rv_te_bench.errors import TeConfigError, TeInputError

if TYPE_CHECKING:
    from collections.abc import Sequence

    import numpy.typing as npt

__all__ = ['DEFAULT_MAX_ORDER', 'HarmonicEstimate', 'HeadSelfCalibration', 'ReversalFold',
           'ReversalResult', 'ReversalSession', 'reversal_separation']

#: Orders of the scale revolution estimated by default.
DEFAULT_MAX_ORDER = 32
_TWO_PI = 2.0 * math.pi


def _orders(max_order: int) -> np.ndarray:
    if isinstance(max_order, bool) or not isinstance(max_order, int | np.integer) \
            or not 1 <= max_order <= 256:
        msg = f'max_order must be an integer in 1..256, got {max_order!r}'
        raise TeConfigError(msg)
    return np.arange(1, int(max_order) + 1)


@dataclass(frozen=True)
class HarmonicEstimate:
    """Harmonics of an angle error function ``e(u) = sum_k Re(c_k e^{iku})`` with their
    standard uncertainties (SI: rad).

    Attributes:
        orders: Orders k, shape (K,).
        c_rad: Complex amplitudes [rad]; NaN where not observable.
        u_rad: Standard uncertainty of the real and of the imaginary part of c_k [rad]
            (the amplitude's standard uncertainty); inf where not observable.
        observable: Whether order k was determined.
        observability: 0 .. 1 per order (how well the method sees it).
        method: What produced it.
    """

    orders: np.ndarray
    c_rad: np.ndarray
    u_rad: np.ndarray
    observable: np.ndarray
    observability: np.ndarray
    method: str
    details: dict[str, Any] = field(default_factory=dict)

    @property
    def observable_orders(self) -> tuple[int, ...]:
        """Orders determined."""
        return tuple(int(k) for k in self.orders[self.observable])

    @property
    def unobservable_orders(self) -> tuple[int, ...]:
        """Orders the method could not see (they stay ambiguous with the reducer)."""
        return tuple(int(k) for k in self.orders[~self.observable])

    def error_rad(self, u_rad: npt.ArrayLike) -> np.ndarray:
        """The error function at ``u`` over the observable orders [rad]."""
        u = np.asarray(u_rad, dtype=np.float64)
        ks = self.orders[self.observable]
        cs = self.c_rad[self.observable]
        out = np.zeros_like(u)
        for k, c in zip(ks.tolist(), cs.tolist(), strict=True):
            out += c.real * np.cos(k * u) - c.imag * np.sin(k * u)
        return out

    def to_plain(self) -> dict[str, Any]:
        """JSON-friendly: per order amplitude and phase of ``a sin(k u + phi)`` (arcsec,
        deg) and the SI complex parts."""
        rows = []
        for k, c, u, ok, ob in zip(self.orders.tolist(), self.c_rad.tolist(),
                                   self.u_rad.tolist(), self.observable.tolist(),
                                   self.observability.tolist(), strict=True):
            if ok:
                amp = abs(c)
                rows.append({'order': k, 'amplitude_arcsec': float(rad_to_arcsec(amp)),
                             'phase_deg': float(rad_to_deg(np.angle(c * 1j))),
                             'u_arcsec': float(rad_to_arcsec(u)),
                             're_rad': c.real, 'im_rad': c.imag, 'u_rad': u,
                             'observability': ob})
        return {'method': self.method, 'harmonics': rows,
                'unobservable_orders': list(self.unobservable_orders), **self.details}


class HeadSelfCalibration:
    """The scale's error from the differences of its heads, streamed block by block.

    Args:
        layout: The heads (two or more).
        max_order: Highest order estimated (<= n_bins / 2 - 1).
        n_bins: Bins per revolution of the fold.

    Raises:
        TeConfigError: One head only (nothing to difference), or a bad order.
    """

    def __init__(self, layout: HeadLayout, *, max_order: int = DEFAULT_MAX_ORDER,
                 n_bins: int = DEFAULT_HARMONIC_BINS) -> None:
        """See the class docstring."""
        if layout.n_heads < 2:
            msg = 'self-calibration needs two or more read heads on the scale'
            raise TeConfigError(msg)
        self.layout = layout
        self.orders = _orders(max_order)
        if self.orders[-1] >= n_bins // 2:
            msg = f'max_order {max_order} needs n_bins > {2 * max_order}'
            raise TeConfigError(msg)
        self._fold = HarmonicFold(layout.n_heads - 1, n_bins=n_bins)

    def add(self, readings_rad: npt.ArrayLike) -> None:
        """Fold one block of head readings, shape (n_heads, n) [rad], heads in layout order.

        Raises:
            TeInputError: Not one row per head.
        """
        r = np.asarray(readings_rad, dtype=np.float64)
        if r.ndim != 2 or r.shape[0] != self.layout.n_heads:
            msg = f'readings must be ({self.layout.n_heads}, n), got shape {r.shape}'
            raise TeInputError(msg)
        self._fold.add(self.layout.combine(r), r[1:] - r[0])

    @property
    def revolutions(self) -> float:
        """Scale revolutions folded so far."""
        return self._fold.revolutions

    def result(self) -> HarmonicEstimate:
        """The scale error's harmonics, in the scale coordinate of head 0.

        Raises:
            TeInputError: Less than one whole revolution folded.
        """
        h = self._fold.harmonics(self.orders)
        return _gls_heads(h, self.layout)


def _gls_heads(h: ChannelHarmonics, layout: HeadLayout) -> HarmonicEstimate:
    ks = h.orders
    a = layout.difference_vectors(ks)                       # (K, m)
    obs = layout.observability(ks)
    cov = np.asarray(h.cov, dtype=np.float64)
    scale = float(np.trace(cov)) / cov.shape[0] if cov.size else 0.0
    if not (math.isfinite(scale) and scale > 0):
        cinv = np.eye(cov.shape[0])
        scale = 0.0
    else:
        cinv = np.linalg.pinv(cov / scale)
    c = np.full(ks.size, np.nan + 0j)
    u = np.full(ks.size, np.inf)
    ok = obs >= MIN_OBSERVABILITY
    for i in np.flatnonzero(ok):
        ai = a[i]
        den = float(np.real(np.conj(ai) @ cinv @ ai))
        c[i] = (np.conj(ai) @ cinv @ h.c[:, i]) / den
        u[i] = math.sqrt(scale / den)
    plain_layout = layout.to_plain(int(ks[-1]))
    return HarmonicEstimate(
        orders=ks, c_rad=c, u_rad=u, observable=ok, observability=obs,
        method=f'self-calibration from {layout.n_heads} read heads',
        details={'layout': plain_layout, 'revolutions': h.revolutions,
                 'n_samples': h.n_samples,
                 'coordinate': 'scale coordinate u = reading of head 0 - scale index'})


@dataclass(frozen=True)
class ReversalSession:
    """One session of a reversal: the TE folded on the shaft angle, and the scale's index.

    Build the harmonics with :meth:`fold` (or a :class:`HarmonicFold` of one channel fed
    with the output reading and the TE).

    Attributes:
        harmonics: One channel: the TE's harmonics of the shaft angle.
        index_rad: The angle the scale was turned on its shaft for this session [rad].
        label: Name for messages (e.g. the bag).
    """

    harmonics: ChannelHarmonics
    index_rad: float
    label: str = ''

    @staticmethod
    def fold(theta_out_rad: npt.ArrayLike, te_rad: npt.ArrayLike, *, index_rad: float,
             max_order: int = DEFAULT_MAX_ORDER, n_bins: int = DEFAULT_HARMONIC_BINS,
             label: str = '') -> ReversalSession:
        """A session from its output reading (shaft angle) and TE, whole arrays [rad].

        Raises:
            TeInputError: Shapes differ or less than one whole revolution.
        """
        f = HarmonicFold(1, n_bins=n_bins)
        te = np.asarray(te_rad, dtype=np.float64)
        f.add(theta_out_rad, te[None, :])
        return ReversalSession(f.harmonics(_orders(max_order)), float(index_rad), label)


class ReversalFold:
    """One reversal session streamed block by block: TE (Wang 2020 Eq. 22) folded on the
    output reading (the shaft angle).

    Args:
        gear_ratio: i.
        max_order: Highest order estimated.
        n_bins: Bins per revolution.
    """

    def __init__(self, *, gear_ratio: float, max_order: int = DEFAULT_MAX_ORDER,
                 n_bins: int = DEFAULT_HARMONIC_BINS) -> None:
        """See the class docstring."""
        if not (math.isfinite(gear_ratio) and gear_ratio > 0):
            msg = f'gear_ratio must be finite and > 0, got {gear_ratio!r}'
            raise TeConfigError(msg)
        self.gear_ratio = float(gear_ratio)
        self.orders = _orders(max_order)
        self._fold = HarmonicFold(1, n_bins=n_bins)

    def add(self, theta_in_rad: npt.ArrayLike, theta_out_rad: npt.ArrayLike) -> None:
        """Fold a block of encoder readings [rad].

        Raises:
            TeInputError: Shapes differ.
        """
        th_in = np.asarray(theta_in_rad, dtype=np.float64)
        th_out = np.asarray(theta_out_rad, dtype=np.float64)
        if th_in.shape != th_out.shape or th_in.ndim != 1:
            msg = (f'theta_in and theta_out must be 1-D of one length, got {th_in.shape}, '
                   f'{th_out.shape}')
            raise TeInputError(msg)
        self._fold.add(th_out, (th_out - th_in / self.gear_ratio)[None, :])

    @property
    def revolutions(self) -> float:
        """Output revolutions folded."""
        return self._fold.revolutions

    def session(self, index_rad: float, label: str = '') -> ReversalSession:
        """The session for :func:`reversal_separation`.

        Raises:
            TeInputError: Less than one whole output revolution.
        """
        return ReversalSession(self._fold.harmonics(self.orders), float(index_rad), label)


@dataclass(frozen=True)
class ReversalResult:
    """The scale error and the reducer's TE at each order, separated by reversal.

    Attributes:
        scale: The scale's error (scale coordinate) per order.
        reducer: The reducer's TE (shaft angle, as in session 1) per order.
        indices_rad: The sessions' scale index angles [rad].
    """

    scale: HarmonicEstimate
    reducer: HarmonicEstimate
    indices_rad: tuple[float, ...]

    def to_plain(self) -> dict[str, Any]:
        """JSON-friendly."""
        return {'indices_deg': [float(rad_to_deg(i)) for i in self.indices_rad],
                'scale': self.scale.to_plain(), 'reducer': self.reducer.to_plain()}


def reversal_separation(sessions: Sequence[ReversalSession]) -> ReversalResult:
    """Separate the scale's error from the reducer's TE (see the module docstring).

    Args:
        sessions: Two or more sessions of the same unit, same orders, the scale at
            different index angles.

    Raises:
        TeConfigError: Fewer than two sessions, orders that differ, or indices that make
            no order observable (e.g. all the same angle).
    """
    if len(sessions) < 2:
        msg = f'reversal needs two or more sessions, got {len(sessions)}'
        raise TeConfigError(msg)
    ks = sessions[0].harmonics.orders
    for s in sessions[1:]:
        if not np.array_equal(s.harmonics.orders, ks):
            msg = 'the sessions were folded to different orders'
            raise TeConfigError(msg)
    iota = np.array([s.index_rad for s in sessions])
    y = np.array([s.harmonics.c[0] for s in sessions])            # (S, K)
    var = np.array([float(s.harmonics.cov[0, 0]) for s in sessions])
    w = np.where(np.isfinite(var) & (var > 0), 1.0 / np.where(var > 0, var, 1.0), 1.0)
    t = np.full(ks.size, np.nan + 0j)
    s_ = np.full(ks.size, np.nan + 0j)
    ut = np.full(ks.size, np.inf)
    us = np.full(ks.size, np.inf)
    obs = np.zeros(ks.size)
    for i, k in enumerate(ks.tolist()):
        e = np.exp(-1j * k * iota)
        a = np.column_stack([np.ones(len(sessions)), e])           # (S, 2)
        # observability: spread of the sessions' phasors (1 for two at 180 deg)
        obs[i] = float(np.sqrt(np.mean(np.abs(e - e.mean()) ** 2)))
        if obs[i] < MIN_OBSERVABILITY:
            continue
        n_mat = (a.conj().T * w) @ a
        cov = np.linalg.inv(n_mat)
        sol = cov @ ((a.conj().T * w) @ y[:, i])
        t[i], s_[i] = sol
        noisy = 1.0 if bool(np.all(var > 0)) else 0.0    # noise-free sessions: u = 0
        ut[i] = math.sqrt(max(float(cov[0, 0].real), 0.0) * noisy)
        us[i] = math.sqrt(max(float(cov[1, 1].real), 0.0) * noisy)
    ok = obs >= MIN_OBSERVABILITY
    if not ok.any():
        msg = (f'scale index angles {[round(float(rad_to_deg(x)), 3) for x in iota]} deg make '
               'no order observable: re-mount the scale at a different angle')
        raise TeConfigError(msg)
    details = {'indices_deg': [float(rad_to_deg(x)) for x in iota],
               'sessions': [s.label for s in sessions]}
    how = f'reversal ({len(sessions)} sessions, index {details["indices_deg"]} deg)'
    return ReversalResult(
        scale=HarmonicEstimate(ks, s_, us, ok, obs, how,
                               {**details, 'coordinate': 'scale coordinate u = reading - '
                                'scale index'}),
        reducer=HarmonicEstimate(ks, t, ut, ok, obs, how,
                                 {**details, 'coordinate': 'shaft angle (output reading)'}),
        indices_rad=tuple(float(x) for x in iota))
