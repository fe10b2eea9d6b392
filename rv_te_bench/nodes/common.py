"""Helpers every node shares: parameters from specs, diagnostics, throttled drop logging, main()."""

from __future__ import annotations

import ctypes
import gc
import os
import signal
import sys
import threading
import time
from typing import TYPE_CHECKING, Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.executors import ExternalShutdownException
from rclpy.parameter import Parameter

if TYPE_CHECKING:
    from collections.abc import Callable, Sequence

    from rclpy.context import Context
    from rclpy.executors import Executor
    from rclpy.node import Node

    from rv_te_bench.params import ParamSpec


#: rclpy parameter types by ParamSpec.type (for typed overrides).
PARAMETER_TYPES = {
    'bool': Parameter.Type.BOOL,
    'int': Parameter.Type.INTEGER,
    'double': Parameter.Type.DOUBLE,
    'string': Parameter.Type.STRING,
    'string_array': Parameter.Type.STRING_ARRAY,
    'double_array': Parameter.Type.DOUBLE_ARRAY,
}


def _descriptor(spec: ParamSpec) -> ParameterDescriptor:
    d = ParameterDescriptor(
        name=spec.name, type=PARAMETER_TYPES[spec.type].value, read_only=spec.read_only,
        description=spec.description,
        additional_constraints=(f'one of {list(spec.choices)}' if spec.choices else ''),
        dynamic_typing=False)
    lo, hi = spec.min_value, spec.max_value
    if spec.type == 'double' and (lo is not None or hi is not None):
        d.floating_point_range = [FloatingPointRange(
            from_value=float(lo if lo is not None else -1e300),
            to_value=float(hi if hi is not None else 1e300), step=0.0)]
    if spec.type == 'int' and (lo is not None or hi is not None):
        d.integer_range = [IntegerRange(
            from_value=int(lo if lo is not None else -(2**62)),
            to_value=int(hi if hi is not None else 2**62), step=1)]
    return d


def declare_from_specs(node: Node, specs: Sequence[ParamSpec]) -> dict[str, Any]:
    """Declare every parameter with its descriptor; return the effective values.

    rclpy rejects an out-of-range override while declaring (a bad launch fails at start-up);
    string choices and array contents are checked here with the same rule text as the launcher.

    Raises:
        rclpy.exceptions.InvalidParameterValueException: A value breaks its rule.
    """
    from rclpy.exceptions import InvalidParameterValueException

    values: dict[str, Any] = {}
    for spec in specs:
        default = list(spec.default) if isinstance(spec.default, tuple) else spec.default
        if spec.type in {'string_array', 'double_array'} and not default:
            p = node.declare_parameter(
                spec.name, Parameter.Type.STRING_ARRAY if spec.type == 'string_array'
                else Parameter.Type.DOUBLE_ARRAY, _descriptor(spec))
            value = p.value if p.value is not None else []
        else:
            value = node.declare_parameter(spec.name, default, _descriptor(spec)).value
        if spec.type == 'double' and isinstance(value, int):
            value = float(value)
        problem = spec.check(list(value) if isinstance(value, tuple) else value)
        if problem:
            raise InvalidParameterValueException(spec.name, value, problem)
        values[spec.name] = list(value) if isinstance(value, tuple) else value
    return values


def reject_invalid_changes(node: Node, specs: Sequence[ParamSpec],
                           extra_check: Callable[[str, Any], str | None] | None = None) -> None:
    """Install an on-set callback that rejects values breaking their spec (not applied)."""
    by_name = {s.name: s for s in specs}

    def on_set(params: list[Parameter]) -> SetParametersResult:
        for p in params:
            spec = by_name.get(p.name)
            if spec is None:
                continue
            problem = spec.check(p.value)
            if problem is None and extra_check is not None:
                problem = extra_check(p.name, p.value)
            if problem:
                return SetParametersResult(
                    successful=False, reason=f"Parameter '{p.name}' {problem}")
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(on_set)


def diagnostic_array(node: Node, name: str, level: int, message: str,
                     values: dict[str, Any]) -> DiagnosticArray:
    """One DiagnosticStatus named ``<node fqn>: name`` with key/values."""
    arr = DiagnosticArray()
    arr.header.stamp = node.get_clock().now().to_msg()
    st = DiagnosticStatus()
    st.level = bytes([level]) if isinstance(DiagnosticStatus().level, bytes) else level
    st.name = f'{node.get_fully_qualified_name()}: {name}'
    st.message = message
    st.hardware_id = node.get_name()
    st.values = [KeyValue(key=str(k), value=_fmt(v)) for k, v in values.items()]
    arr.status = [st]
    return arr


def _fmt(v: object) -> str:
    if isinstance(v, float):
        return f'{v:.6g}'
    return str(v)


#: A stopping node takes the messages queued for it until none came for
#: :data:`_DRAIN_QUIET_S` (and :data:`_DRAIN_QUIET_PASSES` executor passes in a row), at
#: most its ``drain_max_s`` (default :data:`_DRAIN_S`). Its upstream nodes stopped before it
#: (the launcher's data-flow order) and waited until their readers had their last messages
#: (:func:`wait_for_readers`): what is left for it is in its own process already, so a
#: quiet pass means drained. A fixed 0.5 s drain per node, and the launcher's fixed waits
#: between nodes (2 s after the bench, 1 s before the recorder), cost every session stop
#: ~4 s of waiting whatever there was to take (and the 0.5 s cut off a single-threaded
#: executor's node with more work queued; the EventsExecutor takes a subscription's whole
#: queue in one pass).
_DRAIN_S = 0.5
_DRAIN_QUIET_S = 0.1
_DRAIN_QUIET_PASSES = 3
#: ``drain_max_s`` of the readers that must not lose what was published (the TE node, the
#: recorder): a backlog of blocks (a fast bench runs up to ACK_WINDOW_BLOCKS ahead) is taken
#: before they go [s].
DRAIN_MAX_S = 3.0
#: Longest a stopping node waits until the readers of its publishers have its last
#: messages (reliable acknowledgements; a reader that died is given up on) [s].
READERS_ACK_MAX_S = 2.0

OK = 0
WARN = 1
ERROR = 2


class DropCounter:
    """Counts dropped / malformed messages by reason and logs them throttled."""

    def __init__(self, node: Node, throttle_s: float = 5.0) -> None:
        """Create a counter logging through ``node``'s logger at most every ``throttle_s``."""
        self._node = node
        self._throttle_s = throttle_s
        self.counts: dict[str, int] = {}
        self._last_log = 0.0

    def drop(self, reason: str, detail: str) -> None:
        """Count one drop and log it (throttled, with the running totals)."""
        self.counts[reason] = self.counts.get(reason, 0) + 1
        now = time.monotonic()
        if now - self._last_log >= self._throttle_s:
            self._last_log = now
            self._node.get_logger().warning(
                f'dropped message ({reason}): {detail}; totals {self.counts}')

    @property
    def total(self) -> int:
        """All drops so far."""
        return sum(self.counts.values())


#: Set by the launcher in its node processes' environment: a token of the session.
SESSION_ENV = 'RV_TE_SESSION'
#: Hidden topic on which every node of a launched session holds a publisher: the graph then
#: tells which nodes belong to this session (a bench waits for its own session's nodes only,
#: not for stale ones of the same names).
SESSION_TOPIC_PREFIX = '/_rv_te_session/'


def session_topic() -> str | None:
    """The hidden marker topic of the session this process belongs to (None: no launcher)."""
    token = os.environ.get(SESSION_ENV, '')
    return SESSION_TOPIC_PREFIX + token if token.isidentifier() else None


def mark_session(node: Node) -> None:
    """Give ``node`` a publisher on its session's marker topic (nothing is ever sent)."""
    topic = session_topic()
    if topic is not None:
        from std_msgs.msg import Empty

        node.create_publisher(Empty, topic, 1)


#: Longest a stopping node may take to finish work under way (``busy``) [s]; the launcher's
#: grace before it escalates is this plus 10 s (launch.session.stop_grace_s).
FINISH_MAX_S = 8.0

#: Longest a node whose launcher died keeps going once it stops: a drain of what is queued
#: for it, no waiting for work under way (the recorder of the session stops at the same
#: moment, so a result would reach no bag; issue #16 item 3: nodes gone within 2 s) [s].
LAUNCHER_GONE_FINISH_S = 0.5

#: Set by the launcher in its node processes' environment: its pid (see die_with_launcher).
LAUNCHER_PID_ENV = 'RV_TE_LAUNCHER_PID'
_PR_SET_PDEATHSIG = 1
_launcher = {'pid': 0}   # the launcher's pid once die_with_launcher ran (0: no launcher)


def launcher_gone() -> bool:
    """True when this process was started by a launcher that has died since (re-parented)."""
    return _launcher['pid'] > 0 and os.getppid() != _launcher['pid']


def die_with_launcher() -> bool:
    """Ask Linux to send this process SIGTERM when the launcher that started it dies.

    A node of a session stops as on Ctrl-C (the recorder closes its bag) instead of running
    on as an orphan when its launcher is SIGKILLed or given Ctrl-C twice (issue #16 item 3).
    Only for processes started by a launcher (``RV_TE_LAUNCHER_PID`` in the environment).

    Returns:
        False when the launcher died before the request took effect (this process should
        not start); True otherwise (also where prctl is not available).
    """
    want = os.environ.pop(LAUNCHER_PID_ENV, '')   # (not inherited further)
    if not want.isdigit() or not sys.platform.startswith('linux'):
        return True
    _launcher['pid'] = int(want)
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
    except (OSError, AttributeError):
        return True
    # the launcher may have died between our fork and the prctl: then we were re-parented
    return os.getppid() == int(want)


def run_node(factory: Callable[[Context], Node], args: Sequence[str] | None = None, *,
             linger_s: float = 0.0, executor_kind: str = 'events') -> int:
    """Run one node in its own Context until it is ``finished`` or SIGINT/SIGTERM arrives.

    Our own signal handling: rclpy's handler would shut the context down before the node
    could publish its last results (the TE node's final window, the recorder's last flush),
    so SIGINT/SIGTERM only request a stop and ``destroy_node`` runs with a live context.

    Args:
        factory: Builds the node in the given context (may raise on bad parameters).
        args: Command line (ROS arguments after ``--ros-args`` apply to the node).
        linger_s: Keep spinning this long after ``finished`` (reliable delivery) [s].
        executor_kind: ``'events'`` (data paths), ``'single'`` or ``'multi'``.

    Returns:
        0 ok, 1 error (printed as one ``ERROR: ...`` line on stderr), or the node's
        ``exit_code``.
    """
    from rclpy.context import Context
    from rclpy.exceptions import ParameterException
    from rclpy.signals import SignalHandlerOptions
    from rclpy.task import Future

    from rv_te_bench.errors import RvTeError
    from rv_te_bench.safe_yaml import one_line

    if not die_with_launcher():
        print('ERROR: the launcher that started this node is gone; not starting',
              file=sys.stderr)
        return 1
    from rv_te_bench.nodes.middleware import use_quick_acknowledgements

    use_quick_acknowledgements(os.environ)   # (before this process's first participant)
    context = Context()
    rclpy.init(args=list(args) if args is not None else None, context=context,
               signal_handler_options=SignalHandlerOptions.NO)
    stop = {'requested': False, 'starting': True}

    def request_stop(*_: object) -> None:
        stop['requested'] = True
        if stop['starting']:   # building the node (reading a bag...): stop right there
            raise KeyboardInterrupt

    main_thread = threading.current_thread() is threading.main_thread()
    if main_thread:
        old_int = signal.signal(signal.SIGINT, request_stop)
        old_term = signal.signal(signal.SIGTERM, request_stop)
        dump_stacks_on_request()
    node: Any = None
    code = 0
    try:
        try:
            node = factory(context)
        except (RvTeError, ParameterException, ValueError) as exc:
            if stop['requested']:   # what failed after a Ctrl-C is not what the user asked
                print('interrupted while starting', file=sys.stderr)
                return 130
            print(f'ERROR: {one_line(exc)}', file=sys.stderr)
            return 1
        except KeyboardInterrupt:
            print('interrupted while starting', file=sys.stderr)
            return 130
        stop['starting'] = False
        if stop['requested']:
            # The KeyboardInterrupt raised for a Ctrl-C during start-up is lost when the signal
            # lands in a finaliser (a ``__del__`` ignores it: seen in rclpy's logger under load);
            # the request is remembered, so the node still stops before it runs.
            print('interrupted while starting', file=sys.stderr)
            return 130
        mark_session(node)
        # what start-up made (imports, the node) stays: out of the collector's full passes
        # (~35 ms each over ~60,000 objects on the 2-core VM; issue 41 item 4)
        gc.freeze()
        executor = make_executor(executor_kind, context=context)
        executor.add_node(node)
        # up to 0.1 s of events per pass (a future that is never completed; a new one each
        # pass, as the executors add a done callback to it): one Python pass per event cost
        # ~4-8 us each, at hundreds of messages per second (issue 41 item 4)
        while context.ok() and not stop['requested'] and not getattr(node, 'finished', False):
            executor.spin_until_future_complete(Future(), timeout_sec=0.1)
        # Linger (reliable delivery of our last messages), and on a stop request drain what
        # is already queued for us so that it is analysed / recorded, not dropped.
        note_stop_phase('draining what is queued for it')
        taken = count_messages_taken(node)
        start = time.monotonic()
        linger_end = start + linger_s
        drain_max_s = float(getattr(node, 'drain_max_s', _DRAIN_S))
        end = start + max(linger_s, drain_max_s if stop['requested'] else 0.0)
        # a node with work under way (the compensation node's search) finishes it and
        # publishes the result before it goes, within FINISH_MAX_S (issue #15 item 4)
        finish_by = start + FINISH_MAX_S
        cut_off = False
        finishing = False
        last_count, last_taken, quiet_passes = taken[0], start, 0
        while context.ok():
            now = time.monotonic()
            if not cut_off and launcher_gone():
                # the launcher died (parent-death signal): the session's recorder stops now
                # too, so nothing waits for results; drain briefly and go
                cut_off = True
                finish_by = now
                end = min(end, now + LAUNCHER_GONE_FINISH_S)
                if getattr(node, 'busy', False):
                    node.stop_reason = 'the launcher died'
                    node.get_logger().error('the launcher died: work under way is cut off, '
                                            'not finished')
            if getattr(node, 'busy', False) and now < finish_by:
                if not finishing:
                    finishing = True
                    note_stop_phase('finishing work under way')
                end = max(end, now + drain_max_s)   # and a drain after the last result
                last_taken, quiet_passes = now, 0
            elif now >= end or (stop['requested'] and now >= linger_end
                                and quiet_passes >= _DRAIN_QUIET_PASSES
                                and now - last_taken >= _DRAIN_QUIET_S):
                break   # (the longest drain, or nothing came for a while: drained)
            executor.spin_once(timeout_sec=0.05)
            if taken[0] != last_count:
                last_count, last_taken, quiet_passes = taken[0], time.monotonic(), 0
            else:
                quiet_passes += 1
        note_stop_phase('shutting down its executor')
        executor.shutdown()
        if not launcher_gone():   # (its recorder stops at the same moment: nobody to wait for)
            note_stop_phase('publishing its final status')
            publish_final_status(node)
            note_stop_phase("waiting for its readers' acknowledgements")
            wait_for_readers(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            note_stop_phase('destroying the node')
            node.destroy_node()   # (a recorder sets its exit code when it closes the bag)
            code = int(getattr(node, 'exit_code', 0) or 0)
            if code:
                report_failure(str(getattr(node, 'failure', '') or ''))
        if main_thread:
            signal.signal(signal.SIGINT, old_int)
            signal.signal(signal.SIGTERM, old_term)
        note_stop_phase('shutting down its ROS context')
        rclpy.try_shutdown(context=context)
        note_stop_phase('exiting its process')
    if launcher_gone():
        _exit_without_waiting_for_workers(code)
    return code


def count_messages_taken(node: Node, taken: list[int] | None = None) -> list[int]:
    """Count the messages ``node``'s subscriptions take from now on: ``[count]`` (``taken``
    if given, shared between nodes), updated in place. Each subscription's callback is
    wrapped (both executors look it up per message); one counted already is left as it is."""
    taken = [0] if taken is None else taken

    def counted(callback: Callable[..., Any]) -> Callable[..., Any]:
        def call(*args: Any) -> Any:
            taken[0] += 1
            return callback(*args)
        call.rv_te_counted = True   # type: ignore[attr-defined]
        return call

    for sub in list(node.subscriptions):
        if not getattr(sub.callback, 'rv_te_counted', False):
            sub.callback = counted(sub.callback)
    return taken


def publish_final_status(node: Node) -> None:
    """Publish the node's diagnostics once more as it stops (its counters as they end: the
    periodic status may be up to a period old, and nothing waits for the next one)."""
    publish = getattr(node, '_publish_diagnostics', None)
    if publish is None:
        return
    try:
        publish()
    except Exception as exc:  # noqa: BLE001 - stopping: report, do not raise
        node.get_logger().debug(f'final status not published: {exc}')


def wait_for_readers(node: Node, timeout_s: float = READERS_ACK_MAX_S) -> bool:
    """Wait until every reader of ``node``'s publishers has acknowledged what it published
    (reliable readers; at most ``timeout_s`` in all): a node about to exit then leaves its
    last messages in its readers' queues, where their drain takes them (the TE node's final
    window in the recorder). True when all were acknowledged in time."""
    from rclpy.duration import Duration

    deadline = time.monotonic() + timeout_s
    ok = True
    for pub in list(node.publishers):
        left = deadline - time.monotonic()
        try:
            ok = pub.wait_for_all_acked(Duration(seconds=max(left, 0.0))) and ok
        except Exception:  # noqa: BLE001 - a publisher destroyed or a context shut down
            ok = False
    return ok


#: The signal on which a node process of a session prints its threads' Python stacks to
#: its output (the launcher sends it to a node that does not stop, before it kills it).
STACKS_SIGNAL = signal.SIGUSR1


def dump_stacks_on_request() -> bool:
    """In a node process of a session (a launcher reads its stop steps): print every
    thread's stack on :data:`STACKS_SIGNAL`. True when set up."""
    import faulthandler

    from rv_te_bench.nodes.params import STOP_PHASE_FILE_ENV

    if not os.environ.get(STOP_PHASE_FILE_ENV):
        return False
    try:
        faulthandler.register(STACKS_SIGNAL, file=sys.stderr, all_threads=True)
    except (OSError, ValueError, AttributeError, RuntimeError):
        return False   # (no real stderr file, or not on this platform)
    return True


_stop_clock = {'t0': 0.0}


def note_stop_phase(phase: str) -> None:
    """Note the step of its stop this node process is at (one line, with the seconds since
    the stop began) where its launcher reads it when the node is slow to end."""
    from rv_te_bench.nodes.params import STOP_PHASE_FILE_ENV

    path = os.environ.get(STOP_PHASE_FILE_ENV)
    if not path:
        return
    now = time.monotonic()
    if not _stop_clock['t0']:
        _stop_clock['t0'] = now
    try:
        with open(path, 'w', encoding='utf-8') as f:
            f.write(f'{phase} ({now - _stop_clock["t0"]:.1f} s into its stop)\n')
    except OSError:
        pass   # the launcher then names the exit code only


def report_failure(reason: str) -> None:
    """Leave a failing node's reason (one line) where its launcher reads it, if any."""
    from pathlib import Path

    from rv_te_bench.nodes.params import FAILURE_FILE_ENV
    from rv_te_bench.safe_yaml import one_line

    path = os.environ.get(FAILURE_FILE_ENV)
    if reason and path:
        try:
            Path(path).write_text(one_line(reason) + '\n', encoding='utf-8')
        except OSError:
            pass   # the launcher then names the exit code only


def _exit_without_waiting_for_workers(code: int) -> None:
    """End the process now if a worker thread still runs (a search cut off because the
    launcher died): the interpreter would otherwise wait for it at exit, for minutes."""
    deadline = time.monotonic() + 0.2
    for t in threading.enumerate():
        if t is not threading.current_thread() and not t.daemon:
            t.join(timeout=max(0.0, deadline - time.monotonic()))
    if any(t.is_alive() and not t.daemon and t is not threading.current_thread()
           for t in threading.enumerate()):
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)


def make_executor(kind: str = 'events', context: Context | None = None) -> Executor:
    """EventsExecutor on data paths (fastest measured here); single-threaded otherwise."""
    if kind == 'events':
        import io

        from rclpy.experimental import EventsExecutor

        try:
            return EventsExecutor(context=context)
        except io.UnsupportedOperation:
            # it enables faulthandler, which needs a real stderr file (not so under a
            # captured stderr, e.g. in tests): the single-threaded executor is the fallback
            kind = 'single'
    if kind == 'multi':
        from rclpy.executors import MultiThreadedExecutor

        return MultiThreadedExecutor(context=context)
    from rclpy.executors import SingleThreadedExecutor

    return SingleThreadedExecutor(context=context)
