"""Which spectral lines of the TE to report, as orders of the output rotation.

An order is a frequency divided by the output-shaft rotation frequency f_out; order k of
the output rotation repeats k times per output revolution. For the Wang 2020 2K-V
(i = 79) the absolute crank (2nd-stage planet) speed is 25 times the output speed, so the
crankshaft rotation frequency of the papers' FFT figures is f_w = 25 f_out and its
harmonics k f_w sit at output orders 25 k; the 2nd-stage mesh is at 52 f_w = order 1300.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from rv_te_bench.core._checks import finite_positive
from rv_te_bench.errors import TeConfigError

if TYPE_CHECKING:
    from sim.bench_info import BenchInfoData

__all__ = ['MAX_CRANK_HARMONICS', 'OrderSet']

#: Most crank harmonics k f_w reported (the TE node's parameter, the CLI flags, the library).
MAX_CRANK_HARMONICS = 200

_DUPLICATE_TOL = 1e-9


def _positive(name: str, value: float) -> float:
    return finite_positive(value, name, TeConfigError)


@dataclass(frozen=True)
class OrderSet:
    """The spectral lines of interest for one reducer.

    Attributes:
        gear_ratio: Overall ratio i, input revolutions per output revolution (> 0).
        crank_per_output: Absolute crank revolutions per output revolution, |.| (> 0);
            25 for the Wang 2020 2K-V (f_w = 25 f_out).
        mesh_orders_out: Mesh frequencies as output orders (each > 0).
        mesh_labels: One label per mesh order, or empty for ``'mesh 1'``, ``'mesh 2'``...
        n_crank_harmonics: K, number of crank harmonics k f_w reported (k = 1..K, >= 0).

    Raises:
        TeConfigError: A value breaks the rule stated above.

    Examples:
        >>> s = OrderSet(gear_ratio=79.0, crank_per_output=25.0, n_crank_harmonics=2,
        ...              mesh_orders_out=(1300.0,), mesh_labels=('52 f_w',))
        >>> s.lines()
        [(1.0, 'f_out'), (25.0, '1 f_w'), (50.0, '2 f_w'), (24.0, 'f_w - f_out'), \
(26.0, 'f_w + f_out'), (1300.0, '52 f_w')]
    """

    gear_ratio: float
    crank_per_output: float
    mesh_orders_out: tuple[float, ...] = ()
    mesh_labels: tuple[str, ...] = ()
    n_crank_harmonics: int = 10

    def __post_init__(self) -> None:
        """Validate and normalise (tuples of float / str)."""
        object.__setattr__(self, 'gear_ratio', _positive('gear_ratio', self.gear_ratio))
        object.__setattr__(self, 'crank_per_output',
                           _positive('crank_per_output', self.crank_per_output))
        mesh = tuple(_positive(f'mesh_orders_out[{j}]', m)
                     for j, m in enumerate(self.mesh_orders_out))
        object.__setattr__(self, 'mesh_orders_out', mesh)
        labels = tuple(str(x) for x in self.mesh_labels)
        if labels and len(labels) != len(mesh):
            msg = (f'mesh_labels must be empty or match mesh_orders_out: got {len(labels)} '
                   f'labels for {len(mesh)} orders')
            raise TeConfigError(msg)
        object.__setattr__(self, 'mesh_labels', labels)
        k = self.n_crank_harmonics
        if isinstance(k, bool) or not isinstance(k, int) or not 0 <= k <= MAX_CRANK_HARMONICS:
            msg = f'n_crank_harmonics must be an int in 0..{MAX_CRANK_HARMONICS}, got {k!r}'
            raise TeConfigError(msg)

    @classmethod
    def from_bench_info(cls, info: BenchInfoData, n_crank_harmonics: int = 10, *,
                        gear_ratio: float | None = None,
                        crank_per_output: float | None = None) -> OrderSet:
        """The lines of the bench that ``info`` describes (``BenchInfo``'s record).

        The one place where the crank order of the wire (``crank_per_input``, absolute crank
        revolutions per input revolution, signed) becomes the order of the output rotation:
        ``crank_per_output = |crank_per_input| x gear_ratio`` (:meth:`crank_per_output_of`,
        with the record's own ratio).

        Args:
            info: The bench's record (:class:`sim.bench_info.BenchInfoData`).
            n_crank_harmonics: K.
            gear_ratio: The ratio to use instead of the record's (a command-line override).
            crank_per_output: The crank order to use instead of the record's, likewise.

        Raises:
            TeConfigError: A ratio or crank order that is not finite and > 0, or mesh
                orders / labels that do not match.

        Examples:
            >>> from sim.bench import BenchSimulator, BenchConfig
            >>> from sim.drive import ConstantSpeed
            >>> info = BenchSimulator(BenchConfig(preset='wang2020-2kv',
            ...                                   drive=ConstantSpeed(300.0))).info
            >>> OrderSet.from_bench_info(info).crank_per_output
            25.0
        """
        if crank_per_output is None:
            crank_per_output = cls.crank_per_output_of(info.crank_per_input, info.gear_ratio)
        return cls(gear_ratio=info.gear_ratio if gear_ratio is None else gear_ratio,
                   crank_per_output=crank_per_output, mesh_orders_out=info.mesh_orders,
                   mesh_labels=info.mesh_labels, n_crank_harmonics=n_crank_harmonics)

    @staticmethod
    def crank_per_output_of(crank_per_input: float, gear_ratio: float) -> float:
        """|Absolute crank revolutions per output revolution| from the wire's crank order.

        Examples:
            >>> OrderSet.crank_per_output_of(-25.0 / 79.0, 79.0)
            25.0
        """
        return abs(float(crank_per_input)) * float(gear_ratio)

    def crank_per_input(self, sign: float = -1.0) -> float:
        """The wire's crank order (``BenchInfo.crank_per_input``) of these lines.

        Args:
            sign: Which way the cranks turn relative to the input: -1 (against it, as in
                both shipped reducer kinds) or +1.

        Examples:
            >>> OrderSet(gear_ratio=79.0, crank_per_output=25.0).crank_per_input()
            -0.31645569620253167
        """
        return math.copysign(self.crank_per_output / self.gear_ratio, sign)

    def crank_order(self, output_order: float) -> float:
        """Output order expressed as a multiple of the crank frequency f_w."""
        return float(output_order) / self.crank_per_output

    def lines(self) -> list[tuple[float, str]]:
        """The lines to report, ``(output_order, label)``, de-duplicated.

        In this order: ``'f_out'`` (order 1); ``'k f_w'`` at k * crank_per_output for
        k = 1..K; the sidebands ``'f_w - f_out'`` and ``'f_w + f_out'``; then the mesh
        orders with their labels. An order equal (to 1e-9) to an earlier one keeps the
        earlier label; orders <= 0 are left out.
        """
        return list(self._lines)

    @functools.cached_property
    def _lines(self) -> tuple[tuple[float, str], ...]:
        # once per OrderSet (frozen): every window's spectrum asks (issue 41: 4,400 Python
        # comparisons per 10-minute analysis); cached_property writes the instance's
        # __dict__ directly, which a frozen dataclass allows
        c = self.crank_per_output
        cand: list[tuple[float, str]] = [(1.0, 'f_out')]
        cand += [(k * c, f'{k} f_w') for k in range(1, self.n_crank_harmonics + 1)]
        cand += [(c - 1.0, 'f_w - f_out'), (c + 1.0, 'f_w + f_out')]
        labels = self.mesh_labels or tuple(f'mesh {j + 1}'
                                           for j in range(len(self.mesh_orders_out)))
        cand += list(zip(self.mesh_orders_out, labels, strict=True))
        out: list[tuple[float, str]] = []
        for order, label in cand:
            if order <= 0.0 or any(abs(order - o) <= _DUPLICATE_TOL * max(1.0, o) for o, _ in out):
                continue
            out.append((float(order), label))
        return tuple(out)
