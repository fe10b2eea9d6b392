"""rosbag2 bags of ``sensor_msgs/JointState`` (MCAP or sqlite3), read through ``rosbags``.

What a ros2_control bench records (``joint_state_broadcaster``): the input and output joints
(names from ``--theta-in/--theta-out`` or the bench description's ``joints``) in one message
or in separate messages. A sample is the pair of positions with the same header stamp (the
stamps, not the log times, give the sample times); a position without its partner at that
stamp is left out and counted (``unpaired``; the CLI says how many). ``--torque JOINT``
takes that joint's effort as the output torque. Positions are in rad (REP-103) unless a
unit option says otherwise; counts need the bench's counts per revolution. Stamps are kept
as int64 nanoseconds; one more than 1.5 sample periods after the last, or not after it, is a
drop-out (as in the live ``joint_state_adapter``).

Each JointState is one CDR message, so messages are deserialised one by one (a Python loop
over messages: a JointState per sample is the expensive case); the samples of
``chunk_samples`` messages are then paired, converted and checked as arrays.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.errors import DataImportError
from rv_te_bench.io.importers._common import RawChunk

if TYPE_CHECKING:
    from collections.abc import Iterator

    from rv_te_bench.io.importers._common import ImportOptions

__all__ = ['JOINT_STATE', 'JointStateBagReader']

JOINT_STATE = 'sensor_msgs/msg/JointState'


def _short(exc: BaseException) -> str:
    return ' '.join(str(exc).split())[:200] or type(exc).__name__


class JointStateBagReader:
    """A JointState bag opened for import (see the module docstring).

    Args:
        path: Bag folder (metadata.yaml + .mcap or .db3) or a lone ``.mcap`` file.
        options: ``theta_in``/``theta_out`` (joint names), ``torque`` (joint whose effort
            is the torque), ``time`` (the JointState topic, when the bag has several).
        joints: Default joint names (input, output) from the bench description.

    Raises:
        DataImportError: Not a readable bag, no JointState topic (or several), joint
            names missing.
    """

    has_time = True
    time_unit: str | None = 'ns'
    declared_rate_hz: float | None = None

    def __init__(self, path: Path, options: ImportOptions,
                 joints: tuple[str | None, str | None] = (None, None),
                 head_joints: tuple[str, ...] = ()) -> None:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        self.path = Path(path)
        self.origin = str(path)
        self.options = options
        self.joint_in = options.theta_in or joints[0]
        self.joint_out = options.theta_out or joints[1]
        if not self.joint_in or not self.joint_out:
            msg = (f'{path}: name the input and output joints (--theta-in/--theta-out, or '
                   'joints: {input, output} in the bench description)')
            raise DataImportError(msg)
        self.joint_torque = options.torque
        # the output scale's further heads (1..N-1): --theta-out-heads, else the bench
        # description's joints.output_heads (head 0 is the output joint)
        heads = options.theta_out_heads or head_joints
        if heads and heads[0] != self.joint_out:
            msg = (f'{path}: the first head joint {heads[0]!r} must be the output joint '
                   f'{self.joint_out!r} (head 0)')
            raise DataImportError(msg)
        self.head_joints = tuple(heads[1:])
        try:
            self._reader = AnyReader([self.path],
                                     default_typestore=get_typestore(Stores.ROS2_JAZZY))
            self._reader.open()
        except Exception as exc:  # noqa: BLE001 - rosbags raises several types
            msg = f'{path}: not a readable rosbag2 bag ({_short(exc)})'
            raise DataImportError(msg) from None
        conns = [c for c in self._reader.connections if c.msgtype == JOINT_STATE]
        topics = sorted({c.topic for c in conns})
        if options.time is not None:   # --time names the topic for a JointState bag
            topics = [t for t in topics if t == options.time]
        if len(topics) != 1:
            what = 'no topic' if not topics else f'several topics {topics}'
            msg = (f'{path}: {what} of type {JOINT_STATE} '
                   f'{"(choose one with --time TOPIC)" if len(topics) > 1 else ""}'.rstrip())
            raise DataImportError(msg)
        self.topic = topics[0]
        self._conns = [c for c in conns if c.topic == self.topic]
        self.labels = {'in': f'{self.topic}:{self.joint_in}',
                       'out': f'{self.topic}:{self.joint_out}',
                       'time': f'{self.topic}:header.stamp'}
        if self.joint_torque:
            self.labels['torque'] = f'{self.topic}:{self.joint_torque}.effort'
        for j, name in enumerate(self.head_joints, start=1):
            self.labels[f'out_h{j}'] = f'{self.topic}:{name}'
        self.declared_units: dict[str, str | None] = {}
        self.start_ns: int | None = None
        self.unpaired = 0
        self.messages = 0

    def locate(self, index: int) -> str:
        """Sample index -> ``'sample N'`` (0-based pair of positions)."""
        return f'sample {index}'

    def _collect(self, batch: list[Any]) -> dict[str, np.ndarray]:
        """Stamps and values per joint of a batch of messages (loop over messages)."""
        want = {self.joint_in: 'in', self.joint_out: 'out'}
        want.update({name: f'h{j}' for j, name in enumerate(self.head_joints, start=1)})
        cols: dict[str, list[float]] = {'in_t': [], 'in': [], 'out_t': [], 'out': [],
                                        'tq_t': [], 'tq': []}
        for j in range(1, len(self.head_joints) + 1):
            cols[f'h{j}_t'], cols[f'h{j}'] = [], []
        for k, msg in batch:
            stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            names = list(msg.name)
            pos = msg.position
            for j, name in enumerate(names):
                role = want.get(name)
                if role is not None:
                    if j >= len(pos):
                        msg_ = (f'{self.origin}: message {k} of {self.topic}: joint {name!r} '
                                f'has no position ({len(pos)} positions for {len(names)} '
                                'names)')
                        raise DataImportError(msg_)
                    cols[f'{role}_t'].append(stamp)
                    cols[role].append(float(pos[j]))
                if self.joint_torque and name == self.joint_torque and j < len(msg.effort):
                    cols['tq_t'].append(stamp)
                    cols['tq'].append(float(msg.effort[j]))
        out = {k: np.asarray(v, dtype=np.int64 if k.endswith('_t') else np.float64)
               for k, v in cols.items()}
        return out

    def chunks(self) -> Iterator[RawChunk]:
        """Yield paired samples, ``chunk_samples`` messages at a time.

        Raises:
            DataImportError: A message does not deserialise or the bag is damaged, naming
                the message; no sample pairs at all.
        """
        size = self.options.chunk_samples
        first = 0
        carry: dict[str, np.ndarray] | None = None
        batch: list[Any] = []
        try:
            for conn, _t, raw in self._reader.messages(connections=self._conns):
                try:
                    batch.append((self.messages, self._reader.deserialize(raw, conn.msgtype)))
                except Exception as exc:  # noqa: BLE001
                    msg = (f'{self.origin}: message {self.messages} of {self.topic} does not '
                           f'deserialise ({_short(exc)})')
                    raise DataImportError(msg) from None
                self.messages += 1
                if len(batch) >= size:
                    chunk, carry = self._pair(self._collect(batch), carry, first, last=False)
                    batch = []
                    if chunk is not None:
                        yield chunk
                        first += chunk.theta_in.size
        except DataImportError:
            raise
        except Exception as exc:  # noqa: BLE001 - a damaged bag
            msg = (f'{self.origin}: {self.topic} unreadable after message {self.messages} '
                   f'({_short(exc)})')
            raise DataImportError(msg) from None
        chunk, _ = self._pair(self._collect(batch), carry, first, last=True)
        if chunk is not None:
            yield chunk
            first += chunk.theta_in.size
        if first == 0:
            msg = (f'{self.origin}: no sample has both joints {self.joint_in!r} and '
                   f'{self.joint_out!r} at one stamp ({self.messages} messages on '
                   f'{self.topic})')
            raise DataImportError(msg)

    def _pair(self, cols: dict[str, np.ndarray], carry: dict[str, np.ndarray] | None,
              first: int, *, last: bool) -> tuple[RawChunk | None, dict[str, np.ndarray]]:
        """Pair input and output positions by equal stamp (sorted, vectorised)."""
        if carry is not None:
            cols = {k: np.concatenate([carry[k], cols[k]]) for k in cols}
        t_in, t_out = cols['in_t'], cols['out_t']
        # samples at or after the last stamp both joints reached may still get a partner
        limit = None if last or not (t_in.size and t_out.size) else min(t_in[-1], t_out[-1])
        keep_in = np.ones(t_in.size, dtype=bool) if limit is None else t_in <= limit
        keep_out = np.ones(t_out.size, dtype=bool) if limit is None else t_out <= limit
        keep_tq = np.ones(cols['tq_t'].size, dtype=bool) if limit is None \
            else cols['tq_t'] <= limit
        rest = {'in_t': t_in[~keep_in], 'in': cols['in'][~keep_in],
                'out_t': t_out[~keep_out], 'out': cols['out'][~keep_out],
                'tq_t': cols['tq_t'][~keep_tq], 'tq': cols['tq'][~keep_tq]}
        keep_h = {}
        for j in range(1, len(self.head_joints) + 1):
            th = cols[f'h{j}_t']
            keep_h[j] = np.ones(th.size, dtype=bool) if limit is None else th <= limit
            rest[f'h{j}_t'], rest[f'h{j}'] = th[~keep_h[j]], cols[f'h{j}'][~keep_h[j]]
        ti, vi = t_in[keep_in], cols['in'][keep_in]
        to, vo = t_out[keep_out], cols['out'][keep_out]
        common, ii, io_ = np.intersect1d(ti, to, assume_unique=False, return_indices=True)
        self.unpaired += (ti.size - common.size) + (to.size - common.size)
        if common.size == 0:
            return None, rest
        # the pairs in message order (a stamp going backwards stays where it was recorded:
        # the converter reports it as a drop-out, as the live adapter does)
        order = np.argsort(ii, kind='stable')
        common, ii, io_ = common[order], ii[order], io_[order]
        torque = None
        if self.joint_torque:
            tq_t, tq = cols['tq_t'][keep_tq], cols['tq'][keep_tq]
            _, a, b = np.intersect1d(common, tq_t, return_indices=True)
            torque = np.full(common.size, np.nan)
            torque[a] = tq[b]
        heads = None
        if self.head_joints:    # a head without a reading at a stamp: NaN (left out later)
            heads = np.full((len(self.head_joints), common.size), np.nan)
            for j in range(1, len(self.head_joints) + 1):
                th, vh = cols[f'h{j}_t'][keep_h[j]], cols[f'h{j}'][keep_h[j]]
                _, a, b = np.intersect1d(common, th, return_indices=True)
                heads[j - 1, a] = vh[b]
        if self.start_ns is None:
            self.start_ns = int(common[0])
        return RawChunk(first=first, time=common - np.int64(self.start_ns),
                        theta_in=vi[ii], theta_out=vo[io_], torque=torque,
                        out_heads=heads), rest

    def close(self) -> None:
        """Close the bag."""
        self._reader.close()
