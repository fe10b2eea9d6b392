"""Advice only where the data holds it (issue 33 s.4): the one gate of ``rv-te analyze`` and
the live compensation node.

Two conditions, both from what the compensations are defined on:

* **Whole revolutions.** Hu 2020 compensates the TE "value for a period", Wang 2020's phases
  are identified from the TE folded over whole output revolutions: a record without one
  complete output revolution (no gap) gets no advice (:func:`withheld_without_revolution`).
  The compensation node acts on complete windows only (whole revolutions, no gap), which is
  this condition live.
* **The advice names the diagnosed cause.** A tooth-profile modification (Hu 2020 Eq. 27
  assigns the whole TE p-p to cycloid-mesh factors: pin radius, shifting modification,
  circular pitch) is withheld when the dominant line of the spectrum is not a mesh line
  (crank eccentricity at 1 f_w, carrier run-out at f_out, ...), naming both; assembly phases
  (Wang 2020) act on the eccentricity lines: when a mesh line dominates, the advice stays
  and says it does not address that line (:func:`check_cause`).

No rclpy: the node passes the lines of its ``te/spectrum`` messages, the report its averaged
spectrum (:func:`dominant_line`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from sim.units import rad_to_arcmin

if TYPE_CHECKING:
    from collections.abc import Sequence

    from rv_te_bench.core.orders import OrderSet

__all__ = ['ORDER_RTOL', 'AdviceGate', 'check_cause', 'dominant_line', 'is_mesh_line',
           'likely_source', 'withheld_without_revolution']

#: Relative tolerance when matching a line's output order to a known order.
ORDER_RTOL = 1e-6


@dataclass(frozen=True)
class AdviceGate:
    """What the gate says about one piece of advice.

    Attributes:
        withheld: Why the advice is withheld (one sentence), or None: it may be given.
        note: A note the advice carries when it is given ('' for none).
    """

    withheld: str | None = None
    note: str = ''


def withheld_without_revolution(revolutions: float, whole_revolution: bool) -> str | None:
    """Why a record without one whole output revolution (no gap) gets no advice, or None.

    Args:
        revolutions: Output revolutions the record covers (NaN if unknown).
        whole_revolution: At least one complete window (a whole revolution, no gap).

    Examples:
        >>> withheld_without_revolution(0.25, False)[:58]
        'advice withheld: the record holds no whole output revoluti'
        >>> withheld_without_revolution(3.0, True) is None
        True
    """
    if whole_revolution:
        return None
    covered = (f'{revolutions:.2f} output revolutions' if math.isfinite(revolutions)
               else 'its samples')
    return (f'advice withheld: the record holds no whole output revolution without a gap '
            f'({covered}); the compensation is defined on the TE of whole revolutions '
            '(record at least one output revolution)')


def is_mesh_line(output_order: float, orders: OrderSet) -> bool:
    """True when ``output_order`` is one of the reducer's mesh orders."""
    o = abs(float(output_order))
    return any(abs(o - mo) <= ORDER_RTOL * max(1.0, mo) for mo in orders.mesh_orders_out)


def dominant_line(orders_out: Sequence[float],
                  amplitudes_rad: Sequence[float]) -> int | None:
    """Index of the largest finite amplitude (the dominant line), None without one."""
    best, k_best = -math.inf, None
    for k, (o, a) in enumerate(zip(orders_out, amplitudes_rad, strict=True)):
        if math.isfinite(o) and math.isfinite(a) and a > best:
            best, k_best = a, k
    return k_best


def check_cause(method: str, *, label: str, amplitude_rad: float, source: str,
                mesh: bool) -> AdviceGate:
    """Does advice of ``method`` act on the dominant line's cause?

    Args:
        method: The advice's method (``tooth-profile``, ``assembly-phases``,
            ``identified-assembly-phases``).
        label: The dominant line's label (``1 f_w``, ``mesh 936 f_out``...).
        amplitude_rad: Its peak amplitude [rad].
        source: Its likely source in words (:func:`likely_source`, with any note).
        mesh: It is a mesh line (:func:`is_mesh_line`).

    Returns:
        Withheld (tooth profile against a line that is not a mesh line), a note (assembly
        phases against a mesh line), or neither.
    """
    shown = f'{label} ({rad_to_arcmin(amplitude_rad):.4g} arcmin)'
    if method == 'tooth-profile' and not mesh:
        return AdviceGate(withheld=(
            f'tooth-profile advice withheld: the dominant line {shown} points to {source}, '
            'not to the tooth profile; a profile change (Hu 2020 Eq. 27 assigns the whole TE '
            'p-p to cycloid-mesh factors) would not remove it: check that cause first'))
    if method.endswith('assembly-phases') and mesh:
        return AdviceGate(note=(
            f'note: the dominant line {shown} is a mesh line ({source}): assembly phases act '
            'on the eccentricity lines, not on it'))
    return AdviceGate()


def likely_source(output_order: float, orders: OrderSet, reducer_type: str = '') -> str:
    """Name the likely physical source of a TE harmonic.

    Args:
        output_order: Cycles per output revolution of the harmonic.
        orders: Crank order and mesh orders of the reducer.
        reducer_type: ``'2kv'``, ``'rv'``, ``'other'`` or '' (unknown).

    Returns:
        One sentence for people.
    """
    o = abs(float(output_order))
    cpo = orders.crank_per_output

    def near(a: float, b: float) -> bool:
        return abs(a - b) <= ORDER_RTOL * max(1.0, abs(b))

    for mo, label in zip(orders.mesh_orders_out, orders.mesh_labels, strict=False):
        if near(o, mo):
            return f'tooth profile / pitch error of the {label or "gear mesh"} (mesh order)'
    crank = 'crankshaft (eccentric) eccentricity or crank bearing clearance'
    if reducer_type == '2kv' or not reducer_type:
        crank = 'crank / 2nd-stage planet eccentricity (eccentric error, crank bearing clearance)'
    if near(o, cpo):
        return f'{crank} (once per crank revolution, 1 f_w)'
    if near(o, 1.0):
        return ('output-wheel (carrier) eccentricity or pin-circle / ring run-out '
                '(once per output revolution, f_out)')
    if near(o, cpo - 1.0) or near(o, cpo + 1.0):
        return ('crank eccentricity modulated by output-wheel eccentricity or pin-circle error '
                '(f_w +/- f_out sideband)')
    ratio = o / cpo
    if ratio > 1.5 and near(ratio, round(ratio)):
        return (f'{round(ratio)}x per crank revolution: phase mismatch between the crank '
                'eccentrics, eccentric form error or crank bearing waviness')
    if near(o, round(o)):
        return (f'{round(o)}x per output revolution: output bearing / pin-circle form error')
    return 'not assigned to a known order'
