"""An acceptance test as a session bag holds it: the final ``test/report``, the ``test/step``
records (EncoderBlock seq range and blocks per segment of each step), ``bench/info`` and the
encoder blocks of the steps. Read with rosbags from the bag's own message definitions (no
rclpy), so that the unit's metrics can be computed again from the raw data.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rv_te_bench.errors import BagError
from sim.bench_info import BenchInfoData

__all__ = ['Block', 'RecordedTest', 'read_recorded_test']

#: One block's arrays: theta_in_rad, theta_out_rad, torque_out_nm, torque_in_nm (None: no
#: BenchChannels for it), temp_case_degc (likewise).
Block = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]

_FIELDS_REPORT = ('serial', 'operator_name', 'plan_name', 'verdict', 'reason', 'plan_yaml',
                  'tolerance_yaml', 'report_json')
_FIELDS_STEP = ('serial', 'step_index', 'step_count', 'step_name', 'step_kind', 'state',
                'first_seq', 'last_seq', 'parameters_yaml', 'result_yaml')


@dataclass(frozen=True)
class RecordedTest:
    """One test read from a bag (SI values as recorded).

    Attributes:
        report: The final TestReport's fields (``report_json`` as text).
        steps: The finished or ended TestStep records of that test, in order (dicts, with
            ``segment_blocks`` as a list).
        bench_info: The bench's record (its first ``bench/info``).
        blocks: EncoderBlock seq -> (theta_in_rad, theta_out_rad, torque_out_nm,
            torque_in_nm, temp_case_degc) of the steps; the last two from the BenchChannels
            of the same seq (issue 38), None without.
        block_times: EncoderBlock seq -> its sample times [s] (header stamp + offsets), for
            steps whose segments were recorded as time ranges (a ros2_control bench).
    """

    report: dict[str, Any]
    steps: list[dict[str, Any]]
    bench_info: BenchInfoData
    blocks: dict[int, Block] = field(repr=False)
    block_times: dict[int, np.ndarray] = field(repr=False, default_factory=dict)


def read_recorded_test(bag: str | Path, *, serial: str | None = None) -> RecordedTest:
    """The last finished (or cancelled) test in ``bag`` (of ``serial`` when given).

    Raises:
        BagError: Not a readable bag, or no ended test (of that serial) in it.
    """
    from rosbags.highlevel import AnyReader

    path = Path(bag)
    reports: list[dict[str, Any]] = []
    steps: list[dict[str, Any]] = []
    info: BenchInfoData | None = None
    try:
        with AnyReader([path]) as reader:
            wanted = [c for c in reader.connections
                      if c.topic.endswith(('test/report', 'test/step', 'bench/info'))]
            for conn, _, raw in reader.messages(connections=wanted):
                msg = reader.deserialize(raw, conn.msgtype)
                if conn.topic.endswith('test/report'):
                    reports.append({k: getattr(msg, k) for k in _FIELDS_REPORT})
                elif conn.topic.endswith('test/step'):
                    d = {k: getattr(msg, k) for k in _FIELDS_STEP}
                    d['segment_blocks'] = [int(n) for n in getattr(msg, 'segment_blocks', [])]
                    steps.append(d)
                elif info is None:
                    info = BenchInfoData.from_message(msg)
            ended = [r for r in reports if r['verdict'] != 'running'
                     and (serial is None or r['serial'] == serial)]
            if not ended:
                who = f' of unit {serial!r}' if serial else ''
                msg = (f'{path}: no ended acceptance test{who} in the bag (topic '
                       'test/report); a record measured elsewhere is judged with rv-te test '
                       'PLAN --from BAG|FILE, whose output folder rv-te unit-report reads')
                raise BagError(msg)
            report = ended[-1]
            mine = [s for s in steps if s['serial'] == report['serial']
                    and s['state'] != 'started']
            # the steps of the last run of this unit: from the last step 0 on
            starts = [i for i, s in enumerate(mine) if s['step_index'] == 0]
            mine = mine[starts[-1]:] if starts else mine
            ranges = [(s['first_seq'], s['last_seq']) for s in mine]
            blocks: dict[int, Block] = {}
            times: dict[int, np.ndarray] = {}
            enc = [c for c in reader.connections if c.topic.endswith('bench/encoders')]
            for conn, _, raw in reader.messages(connections=enc):
                m: Any = reader.deserialize(raw, conn.msgtype)   # a generated class
                seq = int(m.seq)
                if any(a <= seq <= b for a, b in ranges):
                    blocks[seq] = (np.asarray(m.theta_in_rad, dtype=np.float64),
                                   np.asarray(m.theta_out_rad, dtype=np.float64),
                                   np.asarray(m.torque_out_nm, dtype=np.float64), None, None)
                    times[seq] = m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 + \
                        np.asarray(m.time_offset_s, dtype=np.float64)
            chans = [c for c in reader.connections if c.topic.endswith('bench/channels')]
            for conn, _, raw in reader.messages(connections=chans) if chans else ():
                m = reader.deserialize(raw, conn.msgtype)
                seq = int(m.seq)
                if seq in blocks:
                    blocks[seq] = (*blocks[seq][:3],
                                   np.asarray(m.torque_in_nm, dtype=np.float64),
                                   np.asarray(m.temp_case_degc, dtype=np.float64))
    except BagError:
        raise
    except Exception as exc:  # noqa: BLE001 - rosbags raises several types for a bad bag
        msg = f'{path}: cannot read the bag ({type(exc).__name__}: {exc})'
        raise BagError(msg) from None
    if info is None:
        msg = f'{path}: no bench/info in the bag'
        raise BagError(msg)
    return RecordedTest(report=report, steps=mine, bench_info=info, blocks=blocks,
                        block_times=times)
