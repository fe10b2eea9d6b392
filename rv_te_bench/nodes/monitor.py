"""SessionMonitor: a small node that watches a session for live terminal progress.

Subscribes te/samples, te/spectrum and compensation/advice (relative names, so it follows
the session's namespace) and keeps the latest values; the demo prints them.
"""

from __future__ import annotations

import math
from typing import Any

from rclpy.node import Node
from rv_te_msgs.msg import CompensationAdvice, TeSpectrum, TransmissionError

from rv_te_bench.nodes import qos


class SessionMonitor(Node):
    """Latest TE statistics, spectrum lines and advice of a running session."""

    def __init__(self, **kwargs: Any) -> None:
        """Create the subscriptions; ``kwargs`` go to ``Node``."""
        super().__init__('session_monitor', **kwargs)
        self.cumulative_pp_rad = math.nan
        self.cumulative_revs = 0.0
        self.theta_out_rad = math.nan
        self.theta_out_start_rad = math.nan
        self.samples_msgs = 0
        self.gaps = 0
        self.windows: list[TransmissionError] = []
        self.spectrum: TeSpectrum | None = None
        self.advice: dict[str, CompensationAdvice] = {}
        self.create_subscription(TransmissionError, 'te/samples', self._on_samples,
                                 qos.PREVIEW_QOS)
        self.create_subscription(TransmissionError, 'te/statistics', self._on_stats,
                                 qos.LATCHED_QOS)
        self.create_subscription(TeSpectrum, 'te/spectrum', self._on_spectrum, qos.LATCHED_QOS)
        self.create_subscription(CompensationAdvice, 'compensation/advice', self._on_advice,
                                 qos.LATCHED_QOS)

    def _on_samples(self, msg: TransmissionError) -> None:
        self.samples_msgs += 1
        self.cumulative_pp_rad = msg.cumulative.pp_rad
        self.gaps = msg.gaps
        if len(msg.theta_out_rad):
            if math.isnan(self.theta_out_start_rad):
                self.theta_out_start_rad = float(msg.theta_out_rad[0])
            self.theta_out_rad = float(msg.theta_out_rad[-1])

    def _on_stats(self, msg: TransmissionError) -> None:
        self.windows.append(msg)
        self.cumulative_pp_rad = msg.cumulative.pp_rad

    def _on_spectrum(self, msg: TeSpectrum) -> None:
        self.spectrum = msg

    def _on_advice(self, msg: CompensationAdvice) -> None:
        self.advice[msg.method] = msg

    @property
    def revolutions(self) -> float:
        """Output revolutions seen so far."""
        if math.isnan(self.theta_out_rad):
            return 0.0
        return abs(self.theta_out_rad - self.theta_out_start_rad) / (2 * math.pi)

    def top_lines(self, n: int = 3) -> list[tuple[str, float]]:
        """(label, amplitude [rad]) of the n largest lines of the latest spectrum."""
        if self.spectrum is None:
            return []
        lines = sorted(self.spectrum.lines, key=lambda ln: -ln.amplitude_rad)[:n]
        return [(ln.label, ln.amplitude_rad) for ln in lines]
