"""GUM budgets of the whole-reducer results (issue 38 step kinds; issue 35 s.1).

Each budget names its inputs, their distributions and sources (the engine is
:mod:`rv_te_bench.core.uncertainty`: the coverage factor from the convolved distribution,
U at 95.45 %):

* **torque transducer class** ``c`` (% of the nominal torque FS; DIN 51309 / VDI/VDE 2646
  usage): the zero, sensitivity and linearity deviations together within +-c/100 FS, read
  as rectangular; it does not average out over a plateau;
* **type A over a plateau**: the mean of a steady window by batch means (the samples of a
  torque ripple are correlated, so s/sqrt(n) of the samples would understate it): the
  window cut into ``BATCHES`` consecutive blocks, u = s(block means) / sqrt(b), b - 1 dof;
* **speed ratio** of an efficiency point: d theta_out / d theta_in from two readings of
  each encoder, each +-q/2 (rectangular): the difference of two is triangular of
  half-width q;
* **detection of a breakaway**: the torque at the first sample past the angle threshold
  reads high by up to the ramp's increment per sample (rate / f_s), an uncorrected
  one-sided bias added to U (GUM F.2.4.5); the torque noise of that one sample is the
  ramp's residual scatter (type A);
* **temperature sensor** of a rise (one sensor, a difference of its readings): a Pt100's
  constant tolerance term (IEC 60751 class A: 0.15 K) cancels; its slope term (0.002 |t|)
  bounds the rise's error by 0.002 x rise, rectangular; the start (a parabola through the
  first window, at its start) and the settled value (a line's centre) carry the sensor
  noise through their fits (type A, the residual scatter).

Pure numpy, no rclpy; SI units (N m, K, efficiency as a fraction).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from rv_te_bench.core.uncertainty import Budget, UncertaintyInput, combine, type_b

if TYPE_CHECKING:
    import numpy.typing as npt

__all__ = ['BATCHES', 'breakaway_budget', 'efficiency_budget', 'mean_torque_budget',
           'plateau_type_a', 'temperature_rise_budget']

#: Blocks of a plateau for the batch-means type A of its mean.
BATCHES = 10
_CLASS_SOURCE = ('bench record: torque transducer accuracy class (DIN 51309 / VDI/VDE 2646: '
                 '% of the nominal torque), read as rectangular')


def plateau_type_a(name: str, samples: npt.ArrayLike, *, sensitivity: float = 1.0,
                   unit: str = 'N m', batches: int = BATCHES) -> UncertaintyInput | None:
    """Type A of the mean of a steady window by batch means (None: < 2 blocks of >= 2).

    Examples:
        >>> x = plateau_type_a('T', [1.0] * 5 + [3.0] * 5, batches=2)
        >>> round(x.u, 6), x.dof
        (1.0, 1.0)
    """
    x = np.asarray(samples, dtype=np.float64).ravel()
    x = x[np.isfinite(x)]
    b = min(int(batches), x.size // 2)
    if b < 2:
        return None
    m = x[: (x.size // b) * b].reshape(b, -1).mean(axis=1)
    s = float(np.std(m, ddof=1))
    return UncertaintyInput(name=name, kind='A', u=s / math.sqrt(b), sensitivity=sensitivity,
                            distribution='t', dof=float(b - 1), unit=unit,
                            source=f'this record: {b} block means of the plateau',
                            note='batch means (correlated samples)')


def _class_input(name: str, half_width_nm: float, sensitivity: float) -> UncertaintyInput:
    return type_b(name, sensitivity=sensitivity, distribution='rectangular',
                  half_width=half_width_nm, unit='N m', source=_CLASS_SOURCE)


def efficiency_budget(efficiency: float, *, torque_in_nm: npt.ArrayLike,
                      torque_out_nm: npt.ArrayLike, d_theta_in_rad: float,
                      d_theta_out_rad: float, class_in_nm: float, class_out_nm: float,
                      q_in_rad: float = 0.0, q_out_rad: float = 0.0) -> Budget:
    """eta = T_out d theta_out / (T_in d theta_in): each input at its relative
    sensitivity (eta / T_out, -eta / T_in, eta / d theta_out, -eta / d theta_in).

    Args:
        efficiency: The point's eta.
        torque_in_nm, torque_out_nm: The plateau's samples (means and type A).
        d_theta_in_rad, d_theta_out_rad: The shafts' travel over the window.
        class_in_nm, class_out_nm: Half-widths of the transducers' class bands
            (c / 100 FS) [N m].
        q_in_rad, q_out_rad: The encoders' reading increments.
    """
    tin, tout = np.asarray(torque_in_nm, float), np.asarray(torque_out_nm, float)
    t_in, t_out = float(np.mean(tin)), float(np.mean(tout))
    eta = float(efficiency)
    c_in, c_out = -eta / t_in, eta / t_out
    xs: list[UncertaintyInput | None] = [
        _class_input('input torque transducer: class', class_in_nm, c_in),
        _class_input('output torque transducer: class', class_out_nm, c_out),
        plateau_type_a('input torque: mean over the plateau', tin, sensitivity=c_in),
        plateau_type_a('output torque: mean over the plateau', tout, sensitivity=c_out)]
    for which, q, d in (('input', q_in_rad, d_theta_in_rad), ('output', q_out_rad,
                                                                d_theta_out_rad)):
        if q > 0:
            xs.append(type_b(f'{which} encoder: travel over the window (two readings)',
                             sensitivity=eta / d, distribution='triangular', half_width=q,
                             source='bench record: encoder increment, +-q/2 per reading'))
    return combine('efficiency', eta, xs, unit='1', notes=(
        'the time base cancels (speeds from the angles over one window)',
        'a temperature-dependent efficiency is a property of the unit, not an error: the '
        'case temperature is stated beside it'))


def mean_torque_budget(measurand: str, value_nm: float, samples_nm: npt.ArrayLike, *,
                       class_nm: float, channel: str = 'input') -> Budget:
    """A mean torque over a plateau (the no-load running torque): class + type A."""
    return combine(measurand, value_nm, [
        _class_input(f'{channel} torque transducer: class', class_nm, 1.0),
        plateau_type_a(f'{channel} torque: mean over the plateau', samples_nm)], unit='N m')


def breakaway_budget(measurand: str, value_nm: float, *, class_nm: float,
                     ramp_rate_nm_s: float, sample_rate_hz: float,
                     ramp_residual_nm: tuple[float, int] | None = None,
                     channel: str = 'input') -> Budget:
    """The torque read at the first sample past the threshold: class, the sample's noise
    (the ramp's residual scatter, one observation) and the detection's bias bound (the
    ramp's increment per sample, reads high)."""
    xs: list[UncertaintyInput | None] = [
        _class_input(f'{channel} torque transducer: class', class_nm, 1.0)]
    if ramp_residual_nm is not None and ramp_residual_nm[1] >= 1 and ramp_residual_nm[0] > 0:
        xs.append(UncertaintyInput(name=f'{channel} torque: noise of one reading', kind='A',
                                   u=ramp_residual_nm[0], sensitivity=1.0, distribution='t',
                                   dof=float(ramp_residual_nm[1]), unit='N m',
                                   source='this record: residuals of the ramp before it turned'))
    step = abs(float(ramp_rate_nm_s)) / float(sample_rate_hz) \
        if math.isfinite(ramp_rate_nm_s) and sample_rate_hz > 0 else 0.0
    return combine(measurand, value_nm, xs, unit='N m', bias_bound=step, notes=(
        f'read at the first sample past the angle threshold: high by up to the ramp\'s '
        f'increment per sample, {step:.3g} N m, not corrected (GUM F.2.4.5)',
        'the torque the ramp adds while the shaft travels the threshold after breakaway '
        'is a property of the test (state ramp rate and threshold), not in U'))


def temperature_rise_budget(rise_k: float, time_s: npt.ArrayLike, temp_degc: npt.ArrayLike,
                            *, window_s: float, slope_tolerance: float = 0.002,
                            sensor: str = 'Pt100 IEC 60751 class A') -> Budget:
    """The rise from the start (a parabola through the first window, at t[0]) to the
    settled value (a line's centre over one window): the sensor's slope term and the
    noise through the two fits (thermal_metrics.temperature_rise)."""
    t = np.asarray(time_s, dtype=np.float64)
    y = np.asarray(temp_degc, dtype=np.float64)
    dt = float(np.median(np.diff(t)))
    n = max(round(window_s / dt) + 1, 4)
    x = t[:n] - t[0]
    xc = x - np.mean(x)
    line = np.polyfit(xc, y[:n], 1)
    sigma = float(np.std(y[:n] - np.polyval(line, xc), ddof=2))
    vand = np.vander(x / max(float(x[-1]), 1e-12), 3)          # [x^2, x, 1], scaled
    h0 = float(np.linalg.solve(vand.T @ vand, np.array([0.0, 0.0, 1.0])) @ np.array(
        [0.0, 0.0, 1.0]))                                     # leverage of the fit at t[0]
    xs: list[UncertaintyInput | None] = [
        type_b(f'temperature sensor: slope term ({sensor})', sensitivity=1.0,
               distribution='rectangular', half_width=slope_tolerance * abs(float(rise_k)),
               unit='K', source='IEC 60751: tolerance +-(0.15 + 0.002 |t|) K; the constant '
                                 'term cancels in a rise read by one sensor'),
        UncertaintyInput(name='start: parabola through the first window, at its start',
                         kind='A', u=sigma * math.sqrt(h0), sensitivity=-1.0,
                         distribution='t', dof=float(n - 2), unit='K',
                         source='this record: residual scatter about the first window'),
        UncertaintyInput(name='settled: centre of the settled window\'s line', kind='A',
                         u=sigma / math.sqrt(n), sensitivity=1.0, distribution='t',
                         dof=float(n - 2), unit='K',
                         source='this record: residual scatter about the first window')]
    return combine('temperature_rise_k', rise_k, xs, unit='K', notes=(
        'the rise still to come after the rate fell below its limit is a property of the '
        'test (rate limit, window), not in U',))
