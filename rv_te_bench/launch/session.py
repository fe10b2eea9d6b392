"""rclpy launch scripts: a TE test session (bench + TE node + compensation node + recorder).

There is no ``launch`` / ``ros2 launch`` on PyPI, so this module does what a launch file does:

* reads ROS-style parameter files (``node_name: ros__parameters: {...}``; node keys may carry
  a namespace, ``/**`` applies to every node), merges ``--param node.key=value`` overrides,
  and checks everything against each node's :class:`~rv_te_bench.params.ParamSpec` list
  **before any node starts** (unknown node or key, wrong type, out of range: one error naming
  file, key and rule);
* starts the nodes either one process per node (default; a crash stays contained and is
  reported with its exit code) or all in one process on one executor;
* applies a namespace and topic remappings to every node, so two benches run side by side;
* on Ctrl-C / SIGTERM stops the nodes in data-flow order (bench, TE, compensation, recorder
  last, so the bag gets the final windows) and finalises the bag;
* a session with a finite bench duration ends by itself once the bench is done.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rv_te_bench.errors import ParameterFileError, YamlInputError, YamlLimitError
from rv_te_bench.launch.checks import check_namespace, check_node_config, check_ros_names
from rv_te_bench.launch.node_specs import NODE_TYPES, node_specs, ros_arguments
from rv_te_bench.launch.pacing import PacedNode
from rv_te_bench.nodes.params import FAILURE_FILE_ENV, STOP_PHASE_FILE_ENV
from rv_te_bench.params import (
    ParamSpec,
    check_parameters,
    coerce_parameters,
    coerce_value,
    load_parameter_file,
)
from rv_te_bench.safe_yaml import (
    BAG_METADATA_LIMITS,
    SMALL_TEXT_LIMITS,
    brief,
    dump_ros_yaml,
    load_yaml,
    read_yaml_file,
)

if TYPE_CHECKING:
    from collections.abc import Callable, Sequence
    from typing import IO

#: Nodes the raw data depends on: the session ends when one of them fails.
RAW_DATA_NODES = ('bench', 'joint_state_adapter', 'recorder')
STOP_ORDER = ('test_sequencer', 'bench', 'joint_state_adapter', 'te_node', 'compensation',
              'recorder')


def normalise_namespace(ns: str) -> str:
    """'' or '/a/b' (leading slash, no trailing slash), valid as ROS validates it.

    Raises:
        ParameterFileError: Not a valid ROS namespace (rmw's rule named).
    """
    return check_namespace(ns)


@dataclass
class SessionSpec:
    """What to launch: nodes, their parameters, namespace, remappings, process layout."""

    nodes: tuple[str, ...] = ('bench', 'te_node', 'compensation', 'recorder')
    namespace: str = ''
    parameters: dict[str, dict[str, Any]] = field(default_factory=dict)
    remappings: tuple[tuple[str, str], ...] = ()
    single_process: bool = False
    use_sim_time: bool = False
    launch_file: str = ''   # the ROS 2 launch file the session came from, if any
    launch_arguments: dict[str, str] = field(default_factory=dict)


def parse_param_override(item: str) -> tuple[str, str, Any]:
    """``node.key=value`` -> (node, key, value typed as ROS types ``-p key:=value``).

    The value is read like rcl reads a ``-p`` value (``1e5`` a double, ``yes`` a bool,
    quoted text a string), bounded (:data:`~rv_te_bench.safe_yaml.SMALL_TEXT_LIMITS`, no
    aliases); text that is not YAML at all is taken as a string.

    Raises:
        ParameterFileError: Not of the form node.key=value, or a value over a limit.
    """
    if '=' not in item or '.' not in item.split('=', 1)[0]:
        msg = f'--param {brief(item)} is not of the form node.key=value'
        raise ParameterFileError(msg)
    lhs, text = item.split('=', 1)
    node, key = lhs.split('.', 1)
    where = f'--param {brief(item)}'
    try:
        value = load_yaml(text, origin=where, limits=SMALL_TEXT_LIMITS,
                          scalars='ros') if text.strip() else ''
    except YamlLimitError:
        raise
    except YamlInputError:
        value = text
    return node.strip(), key.strip(), value


def build_session(param_files: Sequence[str | Path] = (), *, namespace: str = '',
                  overrides: Sequence[str] = (), nodes: Sequence[str] | None = None,
                  remappings: Sequence[str] = (), single_process: bool = False) -> SessionSpec:
    """Read and validate everything a session needs; start nothing.

    Raises:
        ParameterFileError: Any invalid file, node, key, value, namespace or remapping.
    """
    ns = normalise_namespace(namespace)
    wanted = tuple(nodes) if nodes else ('bench', 'te_node', 'compensation', 'recorder')
    for n in wanted:
        if n not in NODE_TYPES:
            msg = f'unknown node {brief(n)}; known nodes: {", ".join(STOP_ORDER)}'
            raise ParameterFileError(msg)
    params: dict[str, dict[str, Any]] = {n: {} for n in wanted}
    use_sim_time = False
    for f in param_files:
        for node_key, values in load_parameter_file(f).items():
            targets = _match_node_key(node_key, ns, f)
            for t in targets:
                if t in params:
                    where = f'parameter file {f}: node {brief(node_key)}'
                    if node_key != '/**':
                        check_parameters(node_specs(t), values, where=where)
                    params[t].update(coerce_parameters(node_specs(t), values))
            if node_key == '/**':
                use_sim_time = bool(values.get('use_sim_time', use_sim_time))
                _check_wildcard(values, f, wanted, params)
    for item in overrides:
        node, key, value = parse_param_override(item)
        if node not in NODE_TYPES:
            msg = (f'--param {brief(item)}: unknown node {brief(node)}; known nodes: '
                   f'{", ".join(STOP_ORDER)}')
            raise ParameterFileError(msg)
        if node in params:
            check_parameters(node_specs(node), {key: value}, where=f'--param {brief(item)}')
            params[node].update(coerce_parameters(node_specs(node), {key: value}))
    remaps = []
    for r in remappings:
        if ':=' not in r or not all(r.split(':=', 1)):
            msg = f'remapping {brief(r)} is not of the form from:=to'
            raise ParameterFileError(msg)
        a, b = r.split(':=', 1)
        remaps.append((a.strip(), b.strip()))
    spec = SessionSpec(nodes=wanted, namespace=ns, parameters=params,
                       remappings=tuple(remaps), single_process=single_process,
                       use_sim_time=use_sim_time)
    check_session(spec)
    return spec


def check_session(spec: SessionSpec) -> None:
    """What each node checks at start, run now (so that ``--check`` means it will start).

    Every name a node creates (ROS's rules, rcl's remap parser) and each node's own start-up
    configuration code (:mod:`rv_te_bench.launch.checks`).

    Raises:
        ParameterFileError: A node would refuse to start; names the node and the rule.
    """
    for node in spec.nodes:
        values = node_parameters(spec, node)
        topics = values.get('topics', next(
            (s.default for s in node_specs(node) if s.name == 'topics'), ()))
        check_ros_names(node, spec.namespace, spec.remappings, topics=list(topics))
        check_node_config(node, values, namespace=spec.namespace)


def _match_node_key(node_key: str, ns: str, f: str | Path) -> list[str]:
    """The nodes of this session a parameter-file node key applies to.

    ``/**`` is every node; a relative key is relative to the session namespace; an absolute
    key for another (valid) namespace is meant for another session from the same file.
    Namespaces and node names follow ROS's rules (rcl refuses a file that breaks them), so
    a key that can never match a node (``/1x/bench``, ``a//bench``) is an error.
    """
    if node_key == '/**':
        return list(NODE_TYPES)
    key = node_key if node_key.startswith('/') else f'{ns}/{node_key}' if ns else node_key
    name = key.rsplit('/', 1)[-1]
    key_ns = key.rsplit('/', 1)[0] if '/' in key.lstrip('/') or key.startswith('/') else ''
    if name not in NODE_TYPES:
        msg = (f'parameter file {f}: unknown node {brief(node_key)}; known nodes: '
               f'{", ".join(STOP_ORDER)} (optionally /namespace/node or /**)')
        raise ParameterFileError(msg)
    if key_ns not in {'', '/**'}:
        try:
            key_ns = check_namespace(key_ns)
        except ParameterFileError as exc:
            msg = (f'parameter file {f}: node {brief(node_key)} can never match a node: '
                   f'{exc}')
            raise ParameterFileError(msg) from None
    if node_key.startswith('/') and key_ns not in {'', ns, '/**'}:
        return []  # meant for another namespace (two benches in one file)
    return [name]


def _check_wildcard(values: dict[str, Any], f: str | Path, wanted: Sequence[str],
                    params: dict[str, dict[str, Any]]) -> None:
    """``/**`` parameters apply to every node that declares them; others must be common."""
    for key, value in values.items():
        if key == 'use_sim_time':
            if not isinstance(value, bool):
                msg = f'parameter file {f}: node "/**": parameter {brief(key)} must be a bool'
                raise ParameterFileError(msg)
            continue
        owners = [n for n in wanted if any(s.name == key for s in node_specs(n))]
        if not owners:
            msg = f'parameter file {f}: node "/**": no node declares parameter {brief(key)}'
            raise ParameterFileError(msg)
        for n in owners:
            check_parameters(node_specs(n), {key: value}, where=f'parameter file {f}: "/**"')
            params[n].setdefault(key, coerce_parameters(node_specs(n), {key: value})[key])


def bench_is_paced(spec: SessionSpec) -> bool:
    """True when the session's bench paces to the wall clock on real-time scheduling
    (``realtime_priority`` > 0, real time mode): its node process then talks over UDP only
    (:func:`rv_te_bench.nodes.middleware.use_paced_transport`)."""
    values = spec.parameters.get('bench', {})
    return 'bench' in spec.nodes and int(values.get('realtime_priority', 0) or 0) > 0 \
        and values.get('time_mode', 'realtime') == 'realtime'


def node_parameters(spec: SessionSpec, node: str) -> dict[str, Any]:
    """A node's parameters in a session: the validated ones plus the session's defaults."""
    values = dict(spec.parameters.get(node, {}))
    if node == 'bench':
        # the bench's clock starts once the session's encoder subscribers are up
        # (and, fast, holds while they are behind: the sequencer pairs blocks and channels)
        waits = [n for n in ('te_node', 'recorder', 'test_sequencer') if n in spec.nodes]
        if values.get('output') == 'joint_state' or values.get('ros2_control'):
            # its subscriber is the adapter
            waits = [n for n in ('joint_state_adapter',) if n in spec.nodes]
        if waits:
            values.setdefault('wait_for_nodes', waits)
    if node == 'joint_state_adapter':
        # the adapter holds its first blocks until the session's encoder subscribers are up
        waits = [n for n in ('te_node', 'recorder') if n in spec.nodes]
        if waits:
            values.setdefault('wait_for_nodes', waits)
    if node == 'recorder':
        values.setdefault('session_metadata_yaml', session_metadata_yaml(spec))
    if spec.use_sim_time and node != 'bench':   # the bench is the /clock source
        values['use_sim_time'] = True
    if node == 'recorder' and recorder_uses_sim_time(spec):
        # log time = the session's clock (ros2 bag record --use-sim-time): a viewer's
        # timeline then shows a fast session at its simulated duration
        values.setdefault('use_sim_time', True)
    return values


def recorder_uses_sim_time(spec: SessionSpec) -> bool:
    """True when the session's bench runs in fast (sim-time) mode and publishes /clock."""
    bench = spec.parameters.get('bench', {})
    return 'bench' in spec.nodes and bench.get('time_mode', 'realtime') == 'fast'


def typed_parameter(name: str, value: Any, specs: tuple[ParamSpec, ...]) -> Any:
    """An rclpy Parameter with the declared type (an empty list would infer BYTE_ARRAY)."""
    from rclpy.parameter import Parameter

    from rv_te_bench.nodes.common import PARAMETER_TYPES

    spec = next((s for s in specs if s.name == name), None)
    if spec is None:
        return Parameter(name, value=value)
    return Parameter(name, PARAMETER_TYPES[spec.type], coerce_value(spec, value))


def session_metadata_yaml(spec: SessionSpec) -> str:
    """What the recorder stores in the bag's metadata record: every node's parameters, and
    the unit under test of the adapter's bench description (:func:`unit_metadata`)."""
    meta: dict[str, Any] = {**unit_metadata(spec),
                            'namespace': spec.namespace or '/', 'nodes': list(spec.nodes),
                            'parameters': spec.parameters,
                            'remappings': [f'{a}:={b}' for a, b in spec.remappings]}
    if spec.launch_file:
        meta['launch_file'] = spec.launch_file
        meta['launch_arguments'] = dict(spec.launch_arguments)
    if 'te_node' in spec.nodes and (cal := encoder_calibrations_metadata(
            spec.parameters.get('te_node', {}))):
        meta['encoder_calibration'] = cal
    return dump_ros_yaml(meta)


def unit_metadata(spec: SessionSpec) -> dict[str, Any]:
    """The bench and unit under test of a session's JointState bench, for the bag's metadata.

    A session with the ``joint_state_adapter`` and a bench description records what
    ``rv-te import`` records from one (``unit_serial``, ``operator``, ``temperature_c``,
    ``unit_notes``, ``bench_id``, ``preset``, the description): the report and the results
    store read the unit from there (issue 33: this route dropped it). Empty otherwise.

    Raises:
        BenchDescriptionError: The description file is invalid (checked at build already).
    """
    path = spec.parameters.get('joint_state_adapter', {}).get('bench_description') \
        if 'joint_state_adapter' in spec.nodes else None
    if not path:
        return {}
    from rv_te_bench.io.bench_description import load_bench_description

    return load_bench_description(path).to_metadata()


def encoder_calibrations_metadata(te_params: dict[str, Any]) -> dict[str, Any]:
    """The calibrations a session's TE node applies, for the bag's metadata: per scale the
    file, serial, date, method and validity (or why the file cannot be read)."""
    from rv_te_bench.errors import EncoderCalibrationError
    from rv_te_bench.io.calibration_file import load_encoder_calibration

    out: dict[str, Any] = {}
    for side, key in (('output', 'out'), ('input', 'in')):
        path = te_params.get(f'encoder_{key}_calibration')
        if not path:
            continue
        try:
            cal = load_encoder_calibration(path)
        except EncoderCalibrationError as exc:
            out[side] = {'file': str(path), 'error': str(exc)}
            continue
        out[side] = {'file': str(path), 'scale_serial': cal.scale_serial, 'date': cal.date,
                     'method': cal.method, 'valid_until': cal.valid_until,
                     'orders': list(cal.orders),
                     'undetermined_orders': list(cal.undetermined_orders)}
    return out


def clock_remapping(spec: SessionSpec) -> tuple[str, str] | None:
    """``/clock -> <ns>/clock`` for a namespaced sim-time session, so that its clock is its
    own (issue #22: two fast sessions in two namespaces shared /clock, and each recorder
    logged at the other's clock); None when not namespaced, not on sim time, or /clock is
    remapped by the user already."""
    if not spec.namespace or any(a in {'/clock', 'clock'} for a, _ in spec.remappings):
        return None
    if not (spec.use_sim_time or recorder_uses_sim_time(spec)
            or any(v.get('use_sim_time') for v in spec.parameters.values())):
        return None
    return '/clock', f'{spec.namespace}/clock'


def ros_args(spec: SessionSpec, node: str | None, params_file: Path | None) -> list[str]:
    """The ``--ros-args`` for one node process (``node`` None: all nodes in one process)."""
    return ros_arguments(node=node, namespace=spec.namespace,
                         remappings=session_remappings(spec), params_file=params_file)


def session_remappings(spec: SessionSpec) -> list[tuple[str, str]]:
    """The session's remappings, then its own /clock (:func:`clock_remapping`)."""
    clock = clock_remapping(spec)
    return [*spec.remappings, *([] if clock is None else [clock])]


#: BLAS / OpenMP thread pools of a node process: one thread each unless the user set them.
#: A session runs four node processes (a multi-bench set-up 16) on a few cores; numpy's
#: OpenBLAS otherwise starts a spinning thread per core in every process, and the
#: compensation node's searches then cost twice the CPU for no gain in time (issue #23
#: item 1: 1.37 CPU s vs 0.72 CPU s per Wang 2020 Eq. 21 grid on 2 cores) and starve the
#: benches.
NODE_THREAD_ENV = ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS')


def child_env() -> dict[str, str]:
    """Environment for node processes (the ROS wheel bootstrap marker must not leak; one
    BLAS thread per process unless set, see :data:`NODE_THREAD_ENV`)."""
    env = dict(os.environ)
    for var in NODE_THREAD_ENV:
        env.setdefault(var, '1')
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    env.pop('RV_TE_LAUNCHER_PID', None)   # set by Session.start for its own children only
    env.pop('RV_TE_SESSION', None)
    env.pop(FAILURE_FILE_ENV, None)
    env.pop(STOP_PHASE_FILE_ENV, None)
    env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    env.setdefault('PYTHONUNBUFFERED', '1')
    return env


@dataclass
class NodeProcess:
    """One running node process."""

    name: str
    proc: subprocess.Popen[bytes]
    expected_exit: bool = False


class Session:
    """A running session (process per node). Use as a context manager or call stop()."""

    def __init__(self, spec: SessionSpec, *, log: Callable[[str], None] | None = None,
                 stdout: IO[Any] | int | None = None, log_dir: Path | None = None) -> None:
        """Prepare; nothing starts until :meth:`start`. ``log_dir``: each node's output
        goes to ``<log_dir>/<node>.log`` (instead of ``stdout``), kept after the stop."""
        self.spec = spec
        self.log = log or (lambda s: print(s, file=sys.stderr))
        self._stdout = stdout
        self.log_dir = log_dir
        self._logs: list[IO[Any]] = []
        #: Seconds each node took to end after its SIGTERM in :meth:`stop` (None: it had
        #: ended before).
        self.stop_s: dict[str, float | None] = {}
        self._tmp = tempfile.TemporaryDirectory(prefix='rv-te-session-')
        self.procs: dict[str, NodeProcess] = {}
        self.failures: list[str] = []
        #: This session's token: its nodes mark themselves with it (see nodes.common), so
        #: that its bench waits for them and not for stale nodes of the same names.
        self.token = f's{os.getpid()}_{time.time_ns()}'
        #: Nodes that ended on their own with an error (or any node but a finished bench).
        self.crashed: list[str] = []
        self._summary_path = Path(self._tmp.name) / 'recorder_summary.yaml'
        #: The recorder's closing summary (``bag``, ``messages_on_disk``, ``lost_messages``,
        #: ``lost``, ``write_gaps``), once it has stopped; None without one.
        self.recorder_summary: dict[str, Any] | None = None
        #: True once stop() has begun (a Ctrl-C then hurries the stop, see hurry()).
        self.stopping = False
        self._hurried_at: float | None = None

    def _params_file(self, node: str) -> Path:
        values = node_parameters(self.spec, node)
        if node == 'recorder':   # its closing summary (bag, on disk, lost), read in stop()
            values.setdefault('summary_file', str(self._summary_path))
        fq = f'{self.spec.namespace}/{node}' if self.spec.namespace else f'/{node}'
        path = Path(self._tmp.name) / f'{node}.yaml'
        # strings quoted: rcl reads a plain 'y' or '1e5' as a bool or a number
        path.write_text(dump_ros_yaml({fq: {'ros__parameters': values}}), encoding='utf-8')
        return path

    def start(self) -> None:
        """Start every node process, the recorder first and 0.5 s ahead of the others.

        The bench starts its clock once the session's readers (the recorder, the TE node)
        subscribe (``wait_for_nodes``), but the recorder subscribes to each topic as it
        finds it: without its head start it could still be busy doing so (up to ~0.3 s)
        when a fast bench's first blocks came, and they were logged at a later session
        clock (a fast session's bag of one output revolution spanned 15.5 s of its 15.8 s:
        1 full suite in 3 without the head start).

        A Ctrl-C or SIGTERM while the nodes start is held until the process just started
        is in :attr:`procs` (then raised again, and no further node starts): one that came
        between a process's start and its registration left it out of the stop, and the
        session's parameter files went from under it (a traceback: "Couldn't parse params
        file")."""
        held: list[int] = []
        main = threading.current_thread() is threading.main_thread()
        old = {s: signal.signal(s, lambda sig, _frame: held.append(sig))
               for s in (signal.SIGINT, signal.SIGTERM)
               if main and signal.getsignal(s) is not signal.SIG_IGN}   # ignored stays so
        try:
            self._start_nodes(held)
        finally:
            for sig, handler in old.items():
                signal.signal(sig, signal.SIG_DFL if handler is None else handler)
            if held:
                signal.raise_signal(held[0])

    def _start_nodes(self, held: list[int]) -> None:
        for node in [n for n in NODE_TYPES if n in self.spec.nodes]:
            if held:
                return
            module, _ = NODE_TYPES[node]
            # (through _entry: a stop while the node still imports ends it quietly)
            cmd = [sys.executable, '-m', 'rv_te_bench.nodes._entry', module,
                   *ros_args(self.spec, node, self._params_file(node))]
            # own process group: a terminal Ctrl-C reaches the launcher only, which then
            # stops the nodes in data-flow order (recorder last)
            env = child_env()
            if node == 'bench' and bench_is_paced(self.spec):
                # its SCHED_FIFO thread must not wait for shared-memory ports' locks held
                # by time-shared processes (issue 41 item 4: publish() held 10-650 ms)
                from rv_te_bench.nodes.middleware import use_paced_transport

                use_paced_transport(env)
            env['RV_TE_SESSION'] = self.token
            env[FAILURE_FILE_ENV] = str(self._failure_path(node))
            env[STOP_PHASE_FILE_ENV] = str(self._phase_path(node))
            if threading.current_thread() is threading.main_thread():
                # the nodes die with this process (Linux parent-death signal, set by the
                # node itself: rv_te_bench.nodes.common.die_with_launcher). The signal
                # follows the thread that started the child, so only from the main thread.
                env['RV_TE_LAUNCHER_PID'] = str(os.getpid())
            out = self._stdout
            if self.log_dir is not None:
                self.log_dir.mkdir(parents=True, exist_ok=True)
                out = open(self.log_dir / f'{node}.log', 'wb')   # noqa: SIM115 - closed in stop
                self._logs.append(out)
            proc = subprocess.Popen(cmd, env=env, stdout=out, stderr=out,
                                    start_new_session=True)
            self.procs[node] = NodeProcess(node, proc)
            if node == 'recorder':
                time.sleep(0.5)   # (a Ctrl-C meanwhile is held: no further node starts)

    def _failure_path(self, node: str) -> Path:
        return Path(self._tmp.name) / f'{node}.failure'

    def _phase_path(self, node: str) -> Path:
        return Path(self._tmp.name) / f'{node}.stopping'

    def stop_phase(self, node: str) -> str:
        """The step of its stop a node last noted (one line; '' if none)."""
        try:
            return self._phase_path(node).read_text(encoding='utf-8').strip()
        except OSError:
            return ''

    def failure_reason(self, node: str) -> str:
        """The reason a node that ended with an error left (one line; '' if none)."""
        try:
            return self._failure_path(node).read_text(encoding='utf-8').strip()
        except OSError:
            return ''

    def poll(self) -> dict[str, int | None]:
        """Exit codes so far (None: running). Records unexpected exits as failures."""
        codes: dict[str, int | None] = {}
        for name, np_ in self.procs.items():
            code = np_.proc.poll()
            codes[name] = code
            if code is not None and not np_.expected_exit:
                np_.expected_exit = True
                if code != 0 or name != 'bench':
                    self.crashed.append(name)
                    reason = self.failure_reason(name)
                    self.failures.append(f'node {name!r} exited with code {code}'
                                         + (f': {reason}' if reason else ''))
                    self.log(f'[launch] node {name!r} exited unexpectedly with code {code}')
        return codes

    def must_end(self) -> bool:
        """True when the session cannot go on: the raw data path (bench, recorder) broke, or
        no node is left running. A crashed TE or compensation node is contained: the bench
        and the recorder go on, so the bag stays complete (issue #16 item 4)."""
        if any(name in RAW_DATA_NODES for name in self.crashed):
            return True
        return all(np_.proc.poll() is not None for np_ in self.procs.values())

    def bench_done(self) -> bool:
        """True once the bench process has ended with exit code 0 (finite duration)."""
        b = self.procs.get('bench')
        return b is not None and b.proc.poll() == 0

    #: After a second Ctrl-C: longest wait for a node other than the recorder [s].
    HURRY_S = 2.0

    def hurry(self) -> None:
        """A Ctrl-C (or SIGTERM) while stopping: the nodes other than the recorder are told to
        stop now and waited for at most :data:`HURRY_S` (the compensation node's search is
        cut short); the recorder still gets its full time to close the bag and write its
        summary, which the launcher reads before it removes the session's folder."""
        if self._hurried_at is not None:
            return
        self._hurried_at = time.monotonic()
        self.log('[launch] Ctrl-C again: stopping the other nodes now; waiting for the '
                 'recorder to close the bag')
        for name, np_ in self.procs.items():
            if name != 'recorder' and np_.proc.poll() is None:
                np_.expected_exit = True
                np_.proc.send_signal(signal.SIGTERM)

    def _wait(self, np_: NodeProcess, timeout_s: float) -> bool:
        """Wait for a node to end within ``timeout_s`` (shortened by hurry() except for the
        recorder); True when it ended."""
        deadline = time.monotonic() + timeout_s
        while np_.proc.poll() is None:
            now = time.monotonic()
            if self._hurried_at is not None and np_.name != 'recorder':
                deadline = min(deadline, self._hurried_at + self.HURRY_S)
            if now >= deadline:
                return False
            time.sleep(min(0.05, deadline - now))
        return True

    def stop(self, grace_s: float | None = None, settle_s: float = 0.0) -> dict[str, int | None]:
        """Stop nodes in data-flow order with SIGTERM (then SIGKILL); returns codes.

        A running node takes SIGTERM as Ctrl-C (:func:`rv_te_bench.nodes.common.run_node`:
        it stops, the recorder closes its bag); a node process still starting up ends
        silently on it, where a SIGINT in Python's own start-up printed a traceback.

        A Ctrl-C or SIGTERM during the stop does not abort it (issue #16: a second Ctrl-C
        made the launcher exit while the nodes still stopped, the session folder went, and
        the recorder's summary with it): it hurries the stop (:meth:`hurry`)."""
        self.stopping = True
        main = threading.current_thread() is threading.main_thread()
        if main:
            old = {s: signal.signal(s, lambda *_: self.hurry())
                   for s in (signal.SIGINT, signal.SIGTERM)}
        try:
            codes = self._stop_nodes(stop_grace_s() if grace_s is None else grace_s, settle_s)
            self.recorder_summary = read_recorder_summary(self._summary_path)
        finally:
            if main:
                for sig, handler in old.items():
                    signal.signal(sig, handler)
        for f in self._logs:
            f.close()
        self._tmp.cleanup()
        return codes

    def _stop_nodes(self, grace_s: float, settle_s: float) -> dict[str, int | None]:
        codes: dict[str, int | None] = {}
        for name in STOP_ORDER:
            np_ = self.procs.get(name)
            if np_ is None:
                continue
            np_.expected_exit = True
            if np_.proc.poll() is None:
                # (the nodes before the recorder waited until it had their last messages,
                # nodes.common.wait_for_readers, and it drains them: no wait needed here)
                if name == 'recorder':
                    end = time.monotonic() + settle_s
                    while time.monotonic() < end and self._hurried_at is None:
                        time.sleep(0.05)
                np_.proc.send_signal(signal.SIGTERM)
                t0 = time.monotonic()
                if not self._wait(np_, grace_s):
                    waited = time.monotonic() - t0
                    phase = self.stop_phase(name)
                    if phase:   # (it runs run_node's stop: its stacks go to its output)
                        self._dump_stacks(np_)
                    phase = phase or 'no step of its stop noted'
                    np_.proc.terminate()
                    if not self._wait(np_, 3.0):
                        np_.proc.kill()
                        np_.proc.wait()
                        end = 'killed (SIGKILL)'
                    else:
                        end = f'ended {exit_text(np_.proc.returncode)} after a second SIGTERM'
                    if self._hurried_at is None or name == 'recorder':
                        self.failures.append(
                            f'node {name!r} did not stop on SIGTERM within {waited:.1f} s '
                            f'(at: {phase}); {end}')
                self.stop_s[name] = time.monotonic() - t0
            else:
                self.stop_s.setdefault(name, None)
            codes[name] = np_.proc.returncode
        return codes

    def _dump_stacks(self, np_: NodeProcess) -> None:
        """Ask a node that does not stop to print its threads' stacks to its output."""
        from rv_te_bench.nodes.common import STACKS_SIGNAL

        with contextlib.suppress(OSError):
            np_.proc.send_signal(STACKS_SIGNAL)
            self.log(f'[launch] node {np_.name!r} does not stop: its threads\' stacks '
                     'follow in its output')
            self._wait(np_, 0.5)

    def __enter__(self) -> Session:
        """Start the session."""
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        """Stop the session."""
        self.stop()


def exit_text(code: int | None) -> str:
    """A process's end in words: 'with code 1', 'by SIGKILL', 'still running'."""
    if code is None:
        return 'still running'
    if code < 0:
        try:
            return f'by {signal.Signals(-code).name}'
        except ValueError:
            return f'by signal {-code}'
    return f'with code {code}'


def stop_grace_s() -> float:
    """How long the launcher waits for a node to end after its SIGTERM before it escalates
    (and says the node did not stop) [s]: the FINISH_MAX_S a busy node may take to finish
    work under way, then 10 s for its drain, ``destroy_node`` and exit. With 2 s left after
    the 8 s (a grace of 10 s), a session on a machine at load 13 said "node 'compensation'
    did not stop on SIGTERM" and exited 1 although the node stopped as designed. A node
    that stops at once is not waited for longer."""
    from rv_te_bench.nodes.common import FINISH_MAX_S

    return FINISH_MAX_S + 10.0


def run_single_process(spec: SessionSpec, *, until: Callable[[], bool] | None = None) -> int:
    """All nodes in one process on one executor; returns an exit code.

    The EventsExecutor (single-threaded; the fastest receiver measured here, DESIGN s.3):
    the compensation node's searches run on its own worker thread. A real-time bench beside
    other nodes runs on a thread and executor of its own (:mod:`rv_te_bench.launch.pacing`:
    its blocks wait for no other node's callback, and only that thread gets the SCHED_FIFO
    of its ``realtime_priority``; the other nodes' thread the middleware's nice -10).
    SIGINT/SIGTERM request a stop; the nodes are then destroyed in data-flow order with the
    executor spinning in between, so the TE node's final window reaches the recorder before
    the bag closes.
    """
    import rclpy
    from rclpy.exceptions import InvalidHandle, ParameterException
    from rclpy.signals import SignalHandlerOptions

    from rv_te_bench.nodes.common import DRAIN_MAX_S as READER_DRAIN_MAX_S
    from rv_te_bench.nodes.common import (
        count_messages_taken,
        make_executor,
        publish_final_status,
        wait_for_readers,
    )
    from rv_te_bench.nodes.middleware import use_quick_acknowledgements

    args = ros_args(spec, None, None)
    use_quick_acknowledgements(os.environ)   # as in a node process (nodes.common.run_node)
    ctx = rclpy.context.Context()
    rclpy.init(args=args, context=ctx, signal_handler_options=SignalHandlerOptions.NO)
    stop = {'requested': False}

    def request_stop(*_: object) -> None:
        stop['requested'] = True

    old_int = signal.signal(signal.SIGINT, request_stop)
    old_term = signal.signal(signal.SIGTERM, request_stop)
    nodes: list[Any] = []
    recorder: Any = None
    executor = make_executor('events', context=ctx)
    failed: list[str] = []   # nodes that ended with an error (the adapter's joints)
    pacer: PacedNode | None = None
    tearing_down = False

    def spin_once() -> None:
        try:
            executor.spin_once(timeout_sec=0.05)
        except InvalidHandle:
            if not tearing_down:
                raise
            # a message queued for a node destroyed already (a stop mid-stream): the
            # node is gone, its callback has nothing to publish to

    def settle(seconds: float) -> None:
        end = time.monotonic() + seconds
        while ctx.ok() and time.monotonic() < end:
            spin_once()

    def settle_quiet(max_s: float) -> None:
        """Spin until the nodes took no message for QUIET_S (and QUIET_PASSES passes in a
        row), at most ``max_s``: what was published is taken (a fixed settle waited its
        whole time whatever there was; nodes.common.run_node drains the same way)."""
        taken = [0]
        for n in nodes:
            count_messages_taken(n, taken)   # (the recorder subscribes as it discovers)
        start = last_taken = time.monotonic()
        seen, passes = taken[0], 0
        while ctx.ok():
            now = time.monotonic()
            if now - start >= max_s or (passes >= QUIET_PASSES and now - last_taken >= QUIET_S):
                return
            spin_once()
            if taken[0] != seen:
                seen, last_taken, passes = taken[0], time.monotonic(), 0
            else:
                passes += 1

    def drain(bench: Any) -> None:
        """Spin until the readers that acknowledge blocks (the TE node, the recorder) have
        taken the bench's last one, at most DRAIN_MAX_S, then until the TE node's last
        results are taken (at most 2 s). A fixed 2 s lost blocks: eight sessions on a loaded
        2-core machine were 300-1,000 blocks behind when their bench finished (issue 41
        item 4)."""
        end = time.monotonic() + DRAIN_MAX_S
        behind = readers_behind(bench, nodes)
        while ctx.ok() and behind and time.monotonic() < end:
            settle(0.05)
            behind = readers_behind(bench, nodes)
        if behind:
            print(f'[launch] {", ".join(behind)} still behind the bench after '
                  f'{DRAIN_MAX_S:g} s: stopping anyway', file=sys.stderr)
        settle_quiet(2.0)

    try:
        for name in [n for n in NODE_TYPES if n in spec.nodes]:
            module, cls_name = NODE_TYPES[name]
            cls = getattr(importlib.import_module(module), cls_name)
            values = node_parameters(spec, name)
            overrides = [typed_parameter(k, v, node_specs(name)) for k, v in values.items()]
            paced = name == 'bench' and len(spec.nodes) > 1 \
                and values.get('time_mode', 'realtime') == 'realtime'
            try:
                if paced:
                    pacer = PacedNode(lambda c=cls, o=overrides: c(
                        context=ctx, parameter_overrides=o), ctx)
                    nodes.append(pacer.start())
                else:
                    nodes.append(cls(context=ctx, parameter_overrides=overrides))
            except ParameterException as exc:
                msg = f'node {name!r}: {exc}'
                raise ParameterFileError(msg) from None
            if not paced:
                executor.add_node(nodes[-1])
        bench = next((n for n in nodes if n.get_name() == 'bench'), None)
        while ctx.ok() and not stop['requested']:
            executor.spin_once(timeout_sec=0.1)
            if pacer is not None:
                pacer.check()   # (an error in the bench's callbacks ends the session)
            if bench is not None and getattr(bench, 'finished', False):
                drain(bench)   # the TE node and the recorder take the last blocks
                break
            if until is not None and until():
                break
            if any(getattr(n, 'failure', '') for n in nodes):   # (the adapter's joints)
                settle(1.0)   # its ERROR diagnostics go out
                break
    finally:
        tearing_down = True
        failed += [f'node {n.get_name()!r}: {n.failure}' for n in nodes
                   if getattr(n, 'failure', '')]
        for n in sorted(nodes, key=lambda n: STOP_ORDER.index(n.get_name())
                        if n.get_name() in STOP_ORDER else 99):
            if getattr(n, 'busy', False):   # the compensation node's search: let it end
                from rv_te_bench.nodes.common import FINISH_MAX_S

                end = time.monotonic() + FINISH_MAX_S
                while getattr(n, 'busy', False) and time.monotonic() < end:
                    settle(0.1)
            if n.get_name() == 'recorder':
                # the final windows and advice reach the bag: the nodes destroyed before
                # waited until it had them (wait_for_readers); it takes them now
                settle_quiet(READER_DRAIN_MAX_S)
                recorder = n
            else:
                settle_quiet(0.5)   # (what is queued for it)
                publish_final_status(n)   # (its counters as they end)
                wait_for_readers(n)   # its last messages reach their readers' queues
            if pacer is not None and n is pacer.node:
                pacer.stop()
            else:
                executor.remove_node(n)
            n.destroy_node()
        if pacer is not None:
            pacer.stop()   # (stopped already unless the bench was never built)
        signal.signal(signal.SIGINT, old_int)
        signal.signal(signal.SIGTERM, old_term)
        rclpy.try_shutdown(context=ctx)
    lines, lost = recording_report(recorder.summary()) if recorder is not None else ([], False)
    for line in [*lines, *failed]:
        print(f'[launch] {line}', file=sys.stderr)
    return 1 if lost or failed or (recorder is not None and recorder.exit_code) else 0


#: Longest a one-process session waits at its end for the readers to take the bench's
#: last block [s].
DRAIN_MAX_S = 30.0
#: A one-process session's nodes have taken what was queued when none took a message for
#: this long and this many executor passes in a row [s] (as nodes.common.run_node).
QUIET_S = 0.1
QUIET_PASSES = 3


def readers_behind(bench: Any, nodes: Sequence[Any]) -> list[str]:
    """Names of the nodes that acknowledge blocks (``block_acks``: the TE node, the
    recorder) and have not taken the bench's last published block yet."""
    last = int(getattr(bench, 'blocks_published', 0)) - 1
    behind = []
    for n in nodes:
        acks = getattr(n, 'block_acks', None)
        if acks is None:
            continue
        seq = acks.last()
        if (-1 if seq is None else seq) < last:
            behind.append(n.get_name())
    return behind


def read_recorder_summary(path: Path) -> dict[str, Any] | None:
    """The summary file a recorder wrote when it closed its bag (None if there is none)."""
    if not path.exists():
        return None
    try:
        doc = read_yaml_file(path, what='recorder summary', limits=BAG_METADATA_LIMITS)
    except YamlInputError:
        return None
    return doc if isinstance(doc, dict) else None


def recording_report(summary: dict[str, Any] | None) -> tuple[list[str], bool]:
    """Lines on the recorded bag (what is on disk, what a full disk cost, a foreign
    publisher) and whether the data was lost or mixed with another source's."""
    if not summary:
        return [], False
    on_disk = summary.get('messages_on_disk') or {}
    lines = [f'bag {summary.get("bag")}: {sum(on_disk.values())} messages on disk']
    lost = int(summary.get('lost_messages') or 0)
    if lost:
        per_topic = ', '.join(f'{t}: {n}' for t, n in sorted((summary.get('lost') or {}).items()))
        lines.append(f'ERROR: recording lost {lost} messages ({per_topic}): the disk was full')
        lines += [f'  {g}' for g in summary.get('write_gaps') or []]
    foreign = summary.get('foreign_publishers') or {}
    if foreign:
        lines.append(f'ERROR: more than one publisher on {", ".join(sorted(foreign))} '
                     '(a second bench, or a replay into this namespace): the recorded data '
                     'mixes sources')
    return lines, bool(lost or foreign)


def run_session(spec: SessionSpec, *, log: Callable[[str], None] | None = None,
                on_tick: Callable[[Session], None] | None = None) -> int:
    """Run a process-per-node session until Ctrl-C, a crash, or the bench's end.

    Returns:
        0 when every node ended cleanly, 1 when a node crashed or had to be killed.
    """
    session = Session(spec, log=log)
    interrupted = False

    def on_signal(*_: object) -> None:
        # the first Ctrl-C / SIGTERM stops the session; one during the stop hurries it
        if session.stopping:
            session.hurry()
            return
        session.stopping = True
        raise KeyboardInterrupt

    old_int = signal.signal(signal.SIGINT, on_signal)
    old_term = signal.signal(signal.SIGTERM, on_signal)
    try:
        session.start()   # (a Ctrl-C while the nodes start stops those already started)
        while True:
            session.poll()
            if session.must_end() or session.bench_done():
                break
            if on_tick is not None:
                on_tick(session)
            time.sleep(0.2)
        # (the bench ended once its readers had its last blocks: the TE node, stopped
        # next, takes what is queued for it before it goes; no fixed wait here)
    except KeyboardInterrupt:
        interrupted = True
        session.log('[launch] Ctrl-C: stopping the session')
    finally:
        codes = session.stop()
        signal.signal(signal.SIGINT, old_int)
        signal.signal(signal.SIGTERM, old_term)
    for name, c in codes.items():
        # (a node that exited by itself is named once, by poll(), with its reason)
        told = any(f.startswith(f'node {name!r} exited with code') for f in session.failures)
        if c not in (0, None) and not told and not (
                interrupted and c in (-signal.SIGINT, -signal.SIGTERM, -signal.SIGKILL, 130)):
            session.failures.append(f'node {name!r} ended with code {c}')
    lines, lost = recording_report(session.recorder_summary)
    for line in lines:
        session.log(f'[launch] {line}')
    for f in session.failures:
        session.log(f'[launch] {f}')
    return 1 if session.failures or lost else 0
