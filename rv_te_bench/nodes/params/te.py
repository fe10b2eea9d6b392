"""The parameters of the TE node: one frozen record, declared from its fields.

The node is :mod:`rv_te_bench.nodes.te_node`.
No rclpy here: the launcher checks parameter files against :data:`PARAMS` before any node
starts (:mod:`rv_te_bench.launch.node_specs`).
"""

from __future__ import annotations

from dataclasses import dataclass

from rv_te_bench.core.orders import MAX_CRANK_HARMONICS
from rv_te_bench.core.stream_records import MAX_WINDOW_REVOLUTIONS
from rv_te_bench.params import param, param_specs

__all__ = ['PARAMS', 'TeParams']


@dataclass(frozen=True)
class TeParams:
    """The TE node's parameters (ratio and lines for a real bench, windows, display rates).

    Declared from these fields (:func:`~rv_te_bench.params.param_specs`), read through the
    record (:func:`~rv_te_bench.params.params_record`); units in the descriptions.
    """

    gear_ratio: float = param(
        0.0, 'Overall ratio i [input rev / output rev]; 0 = take it from bench/info', min_value=0.0,
        max_value=1e5)
    crank_per_output: float = param(
        0.0,
        '|Absolute crank revolutions per output revolution| f_w / f_out [1] (25 for '
        'the Wang 2020 2K-V; as rv-te analyze --crank-per-output); used when '
        'gear_ratio > 0',
        min_value=0.0, max_value=1e5)
    crank_per_input: float = param(
        0.0,
        'crank_per_output = |crank_per_input| x gear_ratio; absolute crank revolutions '
        'per input revolution [1]',
        min_value=-1e3, max_value=1e3, deprecated_by='crank_per_output')
    mesh_orders: tuple[float, ...] = param(
        (), 'Mesh frequencies as output orders [1/rev]; used when gear_ratio > 0')
    n_crank_harmonics: int = param(
        10, 'Crank harmonics k f_w reported [1]', min_value=1, max_value=MAX_CRANK_HARMONICS)
    window_revolutions: int = param(
        1, 'Analysis window length [whole output revolutions]', min_value=1,
        max_value=MAX_WINDOW_REVOLUTIONS)
    plot_rate_hz: float = param(
        20.0,
        'Rate of te/plot (flat scalars for plot panels) in session time, at most one '
        'per encoder block; 0 = off [Hz]',
        min_value=0.0, max_value=100000.0, read_only=False)
    decimated_rate_hz: float = param(
        50.0, 'Rate of TE samples published on te/samples [Hz]', min_value=0.1, max_value=100000.0,
        read_only=False)
    diagnostics_period_s: float = param(
        1.0, 'Diagnostics period [s]', min_value=0.05, max_value=60.0)
    heads_mode: str = param(
        'average',
        'How a scale with several read heads (bench/info) forms its angle: average '
        '(equal-division averaging) or head0 (head 0 alone) [-]',
        choices=('average', 'head0'))
    encoder_out_calibration: str = param(
        '',
        'Encoder calibration file of the output scale (rv-te selfcal), taken off its '
        'readings; its scale serial must be the one bench/info reports; empty: none [path]')
    encoder_in_calibration: str = param(
        '', 'Encoder calibration file of the input scale; empty: none [path]')
    te_zero: str = param(
        'auto',
        "The TE's zero: 'encoders' = the encoder zeros bench/info declares (a bench "
        "description's zero_offset_deg, a simulated bench), whole output turns removed; "
        "'first-sample' = the TE at the first clean sample removed; 'auto' = encoders "
        'when declared, else the first sample [-]',
        choices=('auto', 'encoders', 'first-sample'))


PARAMS = param_specs(TeParams)
