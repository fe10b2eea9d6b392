"""A measurement-system study on the simulated bench (``rv-te msa demo``; issue 35).

Runs the acceptance plan's TE and hysteresis steps offline (:func:`run_plan_offline`, no
ROS) on simulated units and writes one results-store record per run, as ``rv-te test``
does, so that ``rv-te msa type1`` and ``rv-te msa grr`` read them like records of a real
bench:

* **parts**: units of the preset with their own errors (the TE-causing errors of the
  preset and the free play drawn around the preset's values, +-50 %);
* **repeats with re-mounting**: before every run the output encoder's scale is mounted
  again: a new mounting eccentricity (amplitude drawn uniformly in [0, e_max] on a scale
  of diameter D: 2 e / D rad, phase uniform) and new phases of its graduation harmonics
  (:func:`sim.encoders.remounted`);
* **operators**: operator ``A`` runs the plan as shipped; operator ``B`` loads the torque
  steps with another timing (dwell ``b_dwell_s`` instead of the plan's).

The records of the R&R runs carry the lot ``msa-grr``, those of the type 1 study (the
reference part, part 1, by operator A) ``msa-type1``.

The simulated torsion has no creep: a different dwell changes only how much noise each
dwell mean averages, so the reproducibility the study finds is small, and the re-mounting
(repeatability) dominates the TE; that is what the simulator can say, not a property of
real benches.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import hashlib
import json
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.acceptance._store import record_of_report
from rv_te_bench.acceptance.plan import HysteresisStep, TeStep, load_plan
from rv_te_bench.acceptance.runner import run_plan_offline
from rv_te_bench.acceptance.tolerance import load_tolerance
from rv_te_bench.errors import MsaError

if TYPE_CHECKING:
    from collections.abc import Callable

    from rv_te_bench.store import UnitRecord

__all__ = ['MsaDemoConfig', 'MsaDemoResult', 'run_msa_demo']

#: The errors of each preset family varied between simulated parts (+-50 % of the value).
_PART_ERRORS = {
    'hu2020-rv': ('errors.cycloid_runout_m', 'errors.eccentricity_m',
                  'errors.cumulative_pitch_m', 'torsion.clearance_rad'),
    'li2023-rv': ('torsion.clearance_rad',),
    'wang2020-2kv': ('eccentricity.e_p1_m', 'eccentricity.e_ot_m', 'torsion.clearance_rad'),
}

#: The TE model of each preset family (the same as ``rv-te test``'s default).
_TE_MODE = {'wang2020-2kv': 'nlte', 'hu2020-rv': 'elastic', 'li2023-rv': 'dte'}


@dataclass(frozen=True)
class MsaDemoConfig:
    """What the demo runs.

    Attributes:
        preset: Reducer preset (its plan: ``rv-80e`` for the RV-80E presets, else the
            preset's name).
        parts, operators, repeats: The gauge R&R design (operators 1 or 2: A, B).
        type1_repeats: Repeats of the reference part (part 1) by operator A for the type 1
            study (0: none).
        mount_eccentricity_um: e_max of the re-mounting [um].
        scale_diameter_mm: D of the output scale [mm].
        b_dwell_s: Dwell of operator B's torque steps [s].
        encoder: Output (and input) encoder model.
        seed: Seed of every draw.
    """

    preset: str = 'rv-80e-101'
    parts: int = 10
    operators: int = 2
    repeats: int = 3
    type1_repeats: int = 25
    mount_eccentricity_um: float = 2.0
    scale_diameter_mm: float = 206.0
    b_dwell_s: float = 0.5
    encoder: str = 'renishaw-resm'
    seed: int = 35

    def __post_init__(self) -> None:
        """Validate (MsaError names the field)."""
        for name, lo in (('parts', 2), ('repeats', 2), ('operators', 1),
                         ('type1_repeats', 0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < lo:
                msg = f'{name} must be an integer >= {lo}, got {v!r}'
                raise MsaError(msg)
        if self.operators > 2:
            msg = f'operators must be 1 or 2 (A: as planned, B: other dwell), got {self.operators}'
            raise MsaError(msg)
        for name in ('mount_eccentricity_um', 'scale_diameter_mm', 'b_dwell_s'):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0) or (name != 'mount_eccentricity_um' and v == 0):
                msg = f'{name} must be finite and > 0, got {v!r}'
                raise MsaError(msg)


def _plan_name(preset: str) -> str:
    return 'rv-80e' if preset in ('rv-80e-101', 'hu2020-rv', 'hu2020-rv-modified') else preset


@dataclass(frozen=True)
class MsaDemoResult:
    """The records of the runs and the reference part's reference values.

    Attributes:
        records: One per run (the caller writes them to the store).
        reference: (metric name, direction) -> value [SI] of the reference part (part 1)
            measured with ideal encoders: what a calibrated reference measurement gives
            (the bias of the type 1 study is against it).
    """

    records: list[UnitRecord]
    reference: dict[tuple[str, str], float]


def run_msa_demo(cfg: MsaDemoConfig, *,
                 on_run: Callable[[int, int, str], None] | None = None) -> MsaDemoResult:
    """Run the study.

    Args:
        cfg: The design.
        on_run: Called before each run with (run index, total, description).

    Raises:
        MsaError, AcceptanceError, PresetError: Bad configuration or a refused program.
    """
    from sim.encoders import encoder_preset, remounted
    from sim.presets import load_preset
    from sim.program import ProgramSimulator

    plan, _ = load_plan(_plan_name(cfg.preset))
    steps = tuple(s for s in plan.steps if isinstance(s, TeStep | HysteresisStep))
    plan_a = dataclasses.replace(plan, steps=steps)
    plan_b = dataclasses.replace(plan, steps=tuple(
        dataclasses.replace(s, dwell_s=cfg.b_dwell_s) if isinstance(s, HysteresisStep) else s
        for s in steps))
    profile = load_tolerance(cfg.preset)[0]
    base = load_preset(cfg.preset)
    rng = np.random.default_rng(cfg.seed)
    keys = [k for k in _PART_ERRORS.get(base.model, ('torsion.clearance_rad',))
            if k in base.values]
    te_mode = _TE_MODE.get(base.model, 'nlte')
    parts = []
    for j in range(cfg.parts):
        over = () if j == 0 else tuple(
            f'{k}={float(base[k]) * rng.uniform(0.5, 1.5):.6g}' for k in keys)
        parts.append((f'MSA-P{j + 1:02d}', over))
    spec = encoder_preset(cfg.encoder)
    runs: list[tuple[str, tuple[str, ...], str, str]] = []
    for rep in range(cfg.repeats):
        for op in 'AB'[:cfg.operators]:
            runs += [(serial, over, op, f'grr repeat {rep + 1}') for serial, over in parts]
    runs += [(parts[0][0], parts[0][1], 'A', f'type 1 repeat {k + 1}')
             for k in range(cfg.type1_repeats)]
    records: list[UnitRecord] = []
    start = dt.datetime(2026, 11, 1, 8, 0, tzinfo=dt.UTC)
    runs.append((parts[0][0], parts[0][1], 'A', 'reference (ideal encoders)'))
    for n, (serial, over, op, what) in enumerate(runs):
        if on_run is not None:
            on_run(n, len(runs), f'{serial} operator {op} {what}')
        ecc = cfg.mount_eccentricity_um * 1e-6 * float(rng.uniform(0.0, 1.0))
        mount = remounted(spec, rng, eccentricity_rad=2.0 * ecc / (cfg.scale_diameter_mm * 1e-3))
        ideal = what.startswith('reference')
        sim = ProgramSimulator(preset=cfg.preset, overrides=over, te_mode=te_mode,
                               encoder_in='ideal' if ideal else spec,
                               encoder_out='ideal' if ideal else mount,
                               seed=int(rng.integers(2**31)))
        info = dataclasses.replace(sim.info, bench_id='simulated-msa')
        conditions = {'msa': what, 'mount_eccentricity_um': ecc * 1e6,
                      'dwell_s': cfg.b_dwell_s if op == 'B' else None, 'part_overrides': over}
        report = run_plan_offline(plan_b if op == 'B' else plan_a, profile, serial=serial,
                                  operator=op, sim=sim, info=info, conditions=conditions)
        report['unit']['date_utc'] = (start + dt.timedelta(minutes=10 * n)).isoformat()
        if ideal:
            ref = record_of_report(report, bag_path='simulated:reference', bag_sha256='0' * 64)
            return MsaDemoResult(records, {(m.name, m.direction): m.value for m in ref.metrics})
        key = hashlib.sha256(json.dumps([cfg.seed, n, serial, op, what, ecc],
                                        default=str).encode()).hexdigest()
        records.append(record_of_report(report, bag_path=f'simulated:msa-demo/{n:04d}',
                                        bag_sha256=key, details={'simulated': _plain(cfg)},
                                        lot='msa-type1' if what.startswith('type') else 'msa-grr'))
    msg = 'the reference run did not take place'
    raise AssertionError(msg)


def _plain(cfg: MsaDemoConfig) -> dict[str, Any]:
    return dataclasses.asdict(cfg)
