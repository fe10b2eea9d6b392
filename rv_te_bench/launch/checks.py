"""What ``rv-te launch --check`` runs: every check the nodes run at start, and ROS's own name rules.

A session that passes these starts: the nodes' own configuration code runs here on the
merged parameters (:func:`check_node_config`: the bench builds its simulator, the TE node its
orders, the compensation node loads its preset, the recorder parses its types, metadata and
bag folder), and every name a node will create is checked with rclpy's validators and rcl's
argument parser (:func:`check_ros_names`): the namespace, each topic after remapping, and the
parameter services, whose full names ROS caps at 247 characters (a 209-character namespace
fails at start for the compensation node, not here).
"""

from __future__ import annotations

import contextlib
import os
import sys
from typing import TYPE_CHECKING, Any

from rv_te_bench.errors import ParameterFileError, RvTeError
from rv_te_bench.launch.node_specs import node_record, ros_arguments
from rv_te_bench.safe_yaml import brief
from sim.errors import SimError

if TYPE_CHECKING:
    from collections.abc import Iterator, Sequence

__all__ = ['NODE_TOPICS', 'check_namespace', 'check_node_config', 'check_ros_names',
           'check_topic_name']

#: Topics each node creates (relative names resolve under the session namespace).
NODE_TOPICS: dict[str, tuple[str, ...]] = {
    'bench': ('bench/encoders', 'bench/info', 'joint_states', '/diagnostics', '/clock'),
    'joint_state_adapter': ('joint_states', 'bench/encoders', 'bench/info', '/diagnostics'),
    'te_node': ('bench/encoders', 'bench/info', 'te/samples', 'te/plot', 'te/statistics',
                'te/spectrum', 'te/encoder_heads', '/diagnostics'),
    'compensation': ('bench/info', 'te/statistics', 'te/samples', 'te/encoder_heads',
                     'compensation/advice', '/diagnostics'),
    'recorder': ('/diagnostics', '/clock'),
}
#: Longest fully qualified topic or service name (rmw: 255 - 8 for the DDS prefixes).
MAX_NAME_LENGTH = 247
#: Services every rclpy node creates under its own name (Jazzy).
_NODE_SERVICES = ('describe_parameters', 'get_parameter_types', 'get_parameters',
                  'get_type_description', 'list_parameters', 'set_parameters',
                  'set_parameters_atomically')


def _first_line(exc: Exception) -> str:
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    for prefix in ('Invalid namespace: ', 'Invalid topic name: ', 'Invalid node name: '):
        text = text.removeprefix(prefix)
    text = text.split(', at /')[0]   # rcl's source location
    if ' is invalid: ' in text:   # "topic name 'x' is invalid: <rule>": the rule
        text = text.split(' is invalid: ', 1)[1]
    return text.rstrip(':')


def check_namespace(ns: str) -> str:
    """'' (root) or the absolute namespace ('/a/b'), as ROS validates it.

    Raises:
        ParameterFileError: Not a valid ROS namespace (the rule named).
    """
    ns = ns.strip()
    if ns in {'', '/'}:
        return ''
    absolute = ns if ns.startswith('/') else '/' + ns
    if not absolute.isascii() or not absolute.isprintable():
        msg = (f'namespace {brief(ns)} is not a valid ROS namespace (letters, digits, _ and '
               '/ only)')
        raise ParameterFileError(msg)
    from rclpy.validate_namespace import validate_namespace

    try:
        validate_namespace(absolute)
    except Exception as exc:  # noqa: BLE001 - rclpy's InvalidNamespaceException
        msg = f'namespace {brief(ns)} is not a valid ROS namespace: {_first_line(exc)}'
        raise ParameterFileError(msg) from None
    return absolute


def check_topic_name(topic: str, *, node: str, namespace: str, what: str = 'topic') -> str:
    """The fully qualified name of ``topic`` for ``node`` in ``namespace``, as rcl forms it.

    Raises:
        ParameterFileError: Not a valid ROS topic name, or too long once expanded.
    """
    from rclpy.expand_topic_name import expand_topic_name
    from rclpy.validate_full_topic_name import validate_full_topic_name

    if not topic.isascii() or not topic.isprintable():
        msg = f'{what} {brief(topic)} is not a valid ROS topic name (ASCII letters, digits, _, /)'
        raise ParameterFileError(msg)
    try:
        full = expand_topic_name(topic, node, namespace or '/')
        validate_full_topic_name(full)
    except Exception as exc:  # noqa: BLE001 - rclpy's name exceptions and RCLError
        msg = f'{what} {brief(topic)} is not a valid ROS topic name: {_first_line(exc)}'
        raise ParameterFileError(msg) from None
    return full


@contextlib.contextmanager
def _quiet_stderr() -> Iterator[None]:
    """rcl logs its own parse errors to fd 2; the launcher reports them in one line."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


def check_ros_arguments(args: Sequence[str], *, node: str) -> None:
    """Parse a node's ``--ros-args`` with rcl itself (remap rules as the node will see them).

    Raises:
        ParameterFileError: rcl refuses an argument (the rule named).
    """
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    ctx = Context()
    try:
        with _quiet_stderr():
            rclpy.init(args=['rv-te', *args], context=ctx,
                       signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # noqa: BLE001 - _rclpy.RCLError
        text = str(exc).replace('failed to initialize rcl: ', '').split(', at ')[0]
        text = text.split('. Error:')[0]
        msg = f'node {node!r}: ROS refuses its arguments: {brief(text)[1:-1]}'
        raise ParameterFileError(msg) from None
    finally:
        rclpy.try_shutdown(context=ctx)


def check_ros_names(node: str, namespace: str, remappings: Sequence[tuple[str, str]],
                    topics: Sequence[str] = ()) -> None:
    """Every name ``node`` creates under ``namespace`` after ``remappings`` is valid.

    Raises:
        ParameterFileError: A remap rule rcl refuses, or a name ROS rejects (too long...).
    """
    for a, b in remappings:
        for side in (a, b):
            if not side.isascii() or not side.isprintable():
                msg = f'remapping {brief(f"{a}:={b}")} holds characters ROS names cannot have'
                raise ParameterFileError(msg)
    check_ros_arguments(ros_arguments(node=node, namespace=namespace, remappings=remappings),
                        node=node)
    remapped: dict[str, str] = {}
    for a, b in remappings:
        src = a.split('://', 1)[-1]
        if ':' in src:   # node-specific rule 'name:from:=to'
            only, src = src.split(':', 1)
            if only != node:
                continue
        if src.startswith('__'):
            continue   # __ns / __node / __name: rcl checked them above
        full = check_topic_name(src, node=node, namespace=namespace, what='remapping source')
        remapped[full] = check_topic_name(b, node=node, namespace=namespace,
                                          what='remapping target')
    names = [check_topic_name(t, node=node, namespace=namespace)
             for t in (*NODE_TOPICS.get(node, ()), *topics)]
    names = [remapped.get(n, n) for n in names]
    names += [f'{namespace}/{node}/{s}' for s in _NODE_SERVICES]
    longest = max(names, key=len)
    if len(longest) > MAX_NAME_LENGTH:
        room = MAX_NAME_LENGTH - (len(longest) - len(namespace))
        msg = (f'node {node!r}: name {brief(longest)} would be {len(longest)} characters, '
               f'ROS allows {MAX_NAME_LENGTH}: this node needs a namespace of at most '
               f'{max(room, 0)} characters (got {len(namespace)})')
        raise ParameterFileError(msg)
    for full in names:
        check_topic_name(full, node=node, namespace=namespace, what=f'node {node!r}: name')


def check_node_config(node: str, values: dict[str, Any], *, namespace: str) -> None:
    """Run the start-up configuration code of ``node`` on its merged parameters.

    The same functions the node calls in its constructor, without creating the node.

    Raises:
        ParameterFileError: The node would refuse these parameters at start (names the
            node and the rule).
    """
    p = node_record(node, values)
    try:
        if node == 'bench':
            from rv_te_bench.nodes.bench_node import build_simulator

            build_simulator(p)
        elif node == 'te_node':
            from rv_te_bench.nodes.te_node import initial_orders, load_calibrations

            initial_orders(p)
            load_calibrations(p)
        elif node == 'compensation':
            from rv_te_bench.nodes.compensation_node import check_config

            check_config(p)
        elif node == 'recorder':
            from rv_te_bench.nodes.recorder import check_config as check_rec

            check_rec(p)
        elif node == 'joint_state_adapter':
            from rv_te_bench.nodes.joint_state_adapter import (
                check_config as check_adapter,
            )

            check_adapter(p)
    except ParameterFileError as exc:
        msg = f'node {node!r}: {exc}' if not str(exc).startswith('node ') else str(exc)
        raise ParameterFileError(msg) from None
    except (RvTeError, SimError, ValueError) as exc:
        msg = f'node {node!r}: {exc}'
        raise ParameterFileError(msg) from None
