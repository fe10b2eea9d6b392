"""Is what came in a reducer on this bench? The measured ratio and the sample rate.

Two checks that catch the mistakes of a first day at a real bench before they become a
result (issue 33 s.2):

* :func:`check_measured_ratio`: the input encoder's advance over the record divided by
  the output encoder's must be the bench's ratio ``i``. Swapped input and output columns
  give ``1 / i`` (and a TE of millions of arcmin), an encoder counting the other way
  ``-i``. A reducer's TE is arcminutes against an output advance of at least
  ``360 deg / i`` per input revolution: 10 % off the ratio is tens of degrees of "TE" per
  output revolution, not a transmission error. Records in which neither encoder turned a
  whole revolution (a hysteresis / stiffness test: input locked, output twisted) are not
  judged.
* :func:`check_sample_rate`: a rate taken from a time column that is a factor
  :data:`RATE_FACTOR_MAX` or more away from the bench's nominal rate is a wrong time unit
  (``--time-unit ms`` on a seconds column gives 1000 times the rate), not a DAQ setting.

Pure functions, no ROS; the messages are one line naming both numbers.
"""

from __future__ import annotations

import math

__all__ = ['RATE_FACTOR_MAX', 'RATIO_TOLERANCE', 'check_measured_ratio', 'check_sample_rate']

#: Relative deviation of the measured from the bench's ratio that is refused.
RATIO_TOLERANCE = 0.10
#: A rate this many times above or below the bench's nominal rate is refused.
RATE_FACTOR_MAX = 20.0
_TIME_FACTORS = {'s': 1.0, 'ms': 1e-3, 'us': 1e-6, 'ns': 1e-9, 'min': 60.0, 'h': 3600.0}


def check_measured_ratio(advance_in_rad: float, advance_out_rad: float, gear_ratio: float, *,
                         names: tuple[str, str] = ('input', 'output')) -> str | None:
    """The reason the record is not a reducer of ratio ``gear_ratio``, or None.

    Args:
        advance_in_rad: Input-encoder angle at the end minus at the start [rad].
        advance_out_rad: Output-encoder angle at the end minus at the start [rad].
        gear_ratio: The bench's overall ratio i (input revolutions per output revolution).
        names: How the two angles are called in the message (column names, topics).

    Returns:
        None when the ratio holds (or neither encoder turned a whole revolution: nothing
        to judge); else one line naming the measured and the bench's ratio and the likely
        cause.

    Examples:
        >>> check_measured_ratio(2 * math.pi * 79, 2 * math.pi, 79.0) is None
        True
        >>> check_measured_ratio(2 * math.pi, 2 * math.pi * 79, 79.0)[:44]
        'measured ratio 0.01266 (input advance 6.283 '
        >>> check_measured_ratio(1e-3, 2e-4, 79.0) is None       # a locked input: not judged
        True
    """
    a_in, a_out, i = float(advance_in_rad), float(advance_out_rad), float(gear_ratio)
    if not (math.isfinite(a_in) and math.isfinite(a_out) and math.isfinite(i) and i > 0):
        return None
    if max(abs(a_in), abs(a_out)) < 2.0 * math.pi:
        return None
    measured = a_in / a_out if a_out != 0.0 else math.copysign(math.inf, a_in)
    if abs(measured / i - 1.0) <= RATIO_TOLERANCE:
        return None
    n_in, n_out = names
    if math.isfinite(measured) and measured != 0 and abs(measured * i - 1.0) <= RATIO_TOLERANCE:
        cause = (f'input and output look swapped (the ratio is 1/i): exchange {n_in!r} and '
                 f'{n_out!r}')
    elif abs(measured / i + 1.0) <= RATIO_TOLERANCE:
        cause = ('one encoder counts the other way (the ratio is -i): reverse its sign in the '
                 'DAQ or the export')
    else:
        cause = ('a wrong angle unit, encoder resolution or preset? (the gear ratio is the '
                 "bench description's / BenchInfo's gear_ratio)")
    return (f'measured ratio {measured:.4g} (input advance {a_in:.4g} rad of {n_in!r} / output '
            f'advance {a_out:.4g} rad of {n_out!r}) is not the bench ratio {i:.4g}: {cause}')


def check_sample_rate(rate_hz: float, bench_rate_hz: float, *, time_unit: str | None,
                      source: str) -> str | None:
    """The reason a sample rate read from a time column is absurd for the bench, or None.

    Args:
        rate_hz: The rate the time column gives [Hz].
        bench_rate_hz: The bench's nominal rate (its description's ``sample_rate_hz``).
        time_unit: The unit the time column was read in (a key of the import's units).
        source: Where the unit came from, for the message (``--time-unit``, the column name).

    Returns:
        None within a factor :data:`RATE_FACTOR_MAX` of the bench's rate; else one line
        naming both rates, the unit and the unit that would give the bench's rate.

    Examples:
        >>> check_sample_rate(1000.0, 1000.0, time_unit='s', source='--time-unit') is None
        True
        >>> check_sample_rate(1e6, 1000.0, time_unit='ms', source='--time-unit')[:40]
        'sample rate 1e+06 Hz with the time colum'
    """
    r, b = float(rate_hz), float(bench_rate_hz)
    if not (math.isfinite(r) and math.isfinite(b) and r > 0 and b > 0):
        return None
    if 1.0 / RATE_FACTOR_MAX < r / b < RATE_FACTOR_MAX:
        return None
    hint = ''
    if time_unit in _TIME_FACTORS:
        # the unit in which the same column gives the rate nearest the bench's
        best = min(_TIME_FACTORS, key=lambda u: abs(math.log(
            r * _TIME_FACTORS[time_unit] / _TIME_FACTORS[u] / b)))
        alt = r * _TIME_FACTORS[time_unit] / _TIME_FACTORS[best]
        if best != time_unit and 1.0 / RATE_FACTOR_MAX < alt / b < RATE_FACTOR_MAX:
            hint = f'; in {best} it would be {alt:.4g} Hz: --time-unit {best}?'
    return (f'sample rate {r:.4g} Hz with the time column in {time_unit} (from {source}) is '
            f'not plausible for the bench\'s {b:.4g} Hz (more than {RATE_FACTOR_MAX:g} times '
            f'off){hint} (if the DAQ really samples at {r:.4g} Hz, set sample_rate_hz in the '
            'bench description)')
