"""Trend detection on run-in / life-test checkpoints: a one-sided CUSUM on relative growth.

A life test measures the unit at checkpoints (every N output revolutions or minutes): TE
p-p, the crank-order lines, lost motion, no-load torque, case temperature. A worn or
damaged part shows as a *growth* of a quantity, typically of one crank-order line, well
before the TE p-p limit is reached. The detector:

* the **baseline** is the mean of the first ``baseline_checkpoints`` values (after
  run-in);
* each later checkpoint gives ``z_k = (x_k / baseline - 1) / s`` with
  ``s = noise_rel sqrt(1 + 1 / n0)`` (the checkpoint's relative repeatability, stated, and
  the baseline's own uncertainty);
* Page's one-sided CUSUM ``S_k = max(0, S_{k-1} + z_k - kappa)`` with the reference
  ``kappa = growth / (2 s)`` (half the growth to detect, the classical choice for a step
  of that size) alarms when ``S_k > h``.

``h`` trades false alarms on stable units against the delay: :func:`detector_rates`
simulates both with a seeded generator (stable units: checkpoint values with relative
Gaussian scatter ``noise_rel``; degraded units: a step of ``+growth`` at a checkpoint), and
docs/LOSSES_TESTS.md states the rates for the shipped settings. What the data cannot tell
apart: a growth smaller than about 2 s per checkpoint is not found within 2 checkpoints,
and a drift of the bench (a warmer lab, a remounted encoder) grows the line the same way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rv_te_bench.errors import TeConfigError, TeInputError

__all__ = ['DetectorRates', 'TrendConfig', 'TrendResult', 'cusum_growth', 'detector_rates']


@dataclass(frozen=True)
class TrendConfig:
    """Settings of the growth detector.

    Attributes:
        growth_fraction: Relative growth to detect (0.10: +10 %), > 0.
        noise_rel: Relative standard deviation of one checkpoint of a stable unit
            (repeatability of the quantity), > 0.
        baseline_checkpoints: n0, checkpoints averaged into the baseline, >= 1.
        threshold: h, in units of s, > 0.
    """

    growth_fraction: float = 0.10
    noise_rel: float = 0.02
    baseline_checkpoints: int = 3
    threshold: float = 1.5

    def __post_init__(self) -> None:
        """Validate (TeConfigError names the field)."""
        for name in ('growth_fraction', 'noise_rel', 'threshold'):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) \
                    or v <= 0:
                msg = f'TrendConfig.{name} must be finite and > 0, got {v!r}'
                raise TeConfigError(msg)
        n0 = self.baseline_checkpoints
        if isinstance(n0, bool) or not isinstance(n0, int) or not 1 <= n0 <= 100:
            msg = f'TrendConfig.baseline_checkpoints must be an integer in 1..100, got {n0!r}'
            raise TeConfigError(msg)

    @property
    def scale(self) -> float:
        """s = noise_rel sqrt(1 + 1/n0)."""
        return self.noise_rel * math.sqrt(1.0 + 1.0 / self.baseline_checkpoints)

    @property
    def reference(self) -> float:
        """kappa = growth / (2 s)."""
        return self.growth_fraction / (2.0 * self.scale)


@dataclass(frozen=True)
class TrendResult:
    """The detector run over one quantity's checkpoints.

    Attributes:
        baseline: Mean of the baseline checkpoints (NaN: not enough checkpoints).
        growth: x_k / baseline - 1 per checkpoint (NaN for the baseline ones).
        statistic: S_k per checkpoint (0 for the baseline ones).
        alarm_index: First checkpoint (0-based) with S_k > h, or -1.
    """

    baseline: float
    growth: tuple[float, ...]
    statistic: tuple[float, ...]
    alarm_index: int

    @property
    def alarm(self) -> bool:
        """Whether the detector flagged a growth."""
        return self.alarm_index >= 0


def _cusum(values: np.ndarray, cfg: TrendConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vectorised over units (rows): baseline, growth, statistic (columns: checkpoints)."""
    n0 = cfg.baseline_checkpoints
    base = values[:, :n0].mean(axis=1)
    growth = values / base[:, None] - 1.0
    growth[:, :n0] = np.nan
    z = growth / cfg.scale - cfg.reference
    stat = np.zeros_like(values)
    s = np.zeros(values.shape[0])
    for k in range(n0, values.shape[1]):      # checkpoints, not samples
        s = np.maximum(0.0, s + z[:, k])
        stat[:, k] = s
    return base, growth, stat


def cusum_growth(values: npt.ArrayLike, config: TrendConfig | None = None) -> TrendResult:
    """Run the detector on one quantity's checkpoint values (in time order).

    Raises:
        TeInputError: Values not 1-D, not finite or not > 0 (a growth needs a positive
            baseline).
    """
    cfg = config or TrendConfig()
    x = np.asarray(values, dtype=np.float64)
    if x.ndim != 1 or not np.all(np.isfinite(x)) or np.any(x <= 0):
        msg = 'checkpoint values must be a 1-D list of finite numbers > 0'
        raise TeInputError(msg)
    if x.size <= cfg.baseline_checkpoints:
        return TrendResult(math.nan, (math.nan,) * x.size, (0.0,) * x.size, -1)
    base, growth, stat = _cusum(x[None, :], cfg)
    over = np.flatnonzero(stat[0] > cfg.threshold)
    return TrendResult(float(base[0]), tuple(float(g) for g in growth[0]),
                       tuple(float(s) for s in stat[0]), int(over[0]) if over.size else -1)


@dataclass(frozen=True)
class DetectorRates:
    """Rates of the detector from a seeded simulation.

    Attributes:
        false_alarm_rate: Share of stable units flagged anywhere in ``checkpoints``.
        detection_rate: Share of degraded units flagged at the step's checkpoint or the
            next one (within 2 checkpoints of the growth).
        units: Units simulated of each kind.
        checkpoints: Checkpoints per unit (baseline included).
        step_at: Checkpoint of the step (0-based) in the degraded units.
        seed: The generator's seed.
    """

    false_alarm_rate: float
    detection_rate: float
    units: int
    checkpoints: int
    step_at: int
    seed: int


def detector_rates(config: TrendConfig, *, units: int = 20000, checkpoints: int = 20,
                   step_at: int = 10, seed: int = 38) -> DetectorRates:
    """Simulate stable and degraded units (relative Gaussian scatter ``noise_rel``; the
    degraded ones grow by ``growth_fraction`` from checkpoint ``step_at`` on)."""
    if not config.baseline_checkpoints <= step_at < checkpoints - 1:
        msg = (f'step_at must lie after the baseline and leave 2 checkpoints, got {step_at} '
               f'of {checkpoints}')
        raise TeConfigError(msg)
    rng = np.random.default_rng(seed)
    stable = 1.0 + config.noise_rel * rng.standard_normal((units, checkpoints))
    grown = 1.0 + config.noise_rel * rng.standard_normal((units, checkpoints))
    grown[:, step_at:] *= 1.0 + config.growth_fraction
    _, _, s_stable = _cusum(stable, config)
    _, _, s_grown = _cusum(grown, config)
    fa = float(np.mean(np.any(s_stable > config.threshold, axis=1)))
    early = np.any(s_grown[:, :step_at] > config.threshold, axis=1)
    hit = np.any(s_grown[:, step_at:step_at + 2] > config.threshold, axis=1) & ~early
    return DetectorRates(fa, float(np.mean(hit)), units, checkpoints, step_at, seed)
