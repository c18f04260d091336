"""What every node shares: executors, logging the core's notices, diagnostics, `main`.

Topics, QoS and message conversion are :mod:`gait_biofeedback.wire`; parameters
:mod:`gait_biofeedback.nodes.parameters`.

Nodes stay thin: they convert messages, hold parameters and call the core. Executor choice is
measured (ROS_FROM_PYPI.md): an ``EventsExecutor`` driven by ``spin_once`` in a loop is about 3×
cheaper than the ``SingleThreadedExecutor``; its ``spin()`` is broken in rclpy 7.1.6, so it is never
called. ``GAIT_EXECUTOR=single`` selects the fallback.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.context import Context
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.subscription import Subscription

from gait_biofeedback.core.notices import Notice
from gait_biofeedback.core.params import ParameterError
from gait_biofeedback.parameters import load_params_file
from gait_biofeedback.wire import diagnostics
from gait_biofeedback.wire.topics import Topic


def log_notices(logger: Any, notices: Iterable[Notice]) -> None:
    """Log what a core stream said (:mod:`gait_biofeedback.core.notices`), one call site per severity
    (rclpy refuses to log from one call site at two severities)."""
    for notice in notices:
        if notice.level == "error":
            logger.error(notice.text)
        elif notice.level == "warn":
            logger.warning(notice.text)
        else:
            logger.info(notice.text)


def publisher(node: Node, topic: Topic) -> Publisher:
    """A publisher of ``topic`` with its message type and QoS (:mod:`gait_biofeedback.wire.topics`)."""
    return node.create_publisher(topic.msg_type, topic.name, topic.qos)


def subscribe(node: Node, topic: Topic, callback: Callable[[Any], None], raw: bool = False) -> Subscription:
    """A subscription to ``topic`` with its message type and QoS; ``raw``: the callback gets CDR bytes."""
    return node.create_subscription(topic.msg_type, topic.name, callback, topic.qos, raw=raw)


def diagnostic_array(node: Node, statuses: Iterable[DiagnosticStatus]) -> DiagnosticArray:
    """DiagnosticArray of ``statuses`` stamped with the node clock."""
    return diagnostics.array(node.get_clock().now().to_msg(), statuses)


def make_executor(context: Context | None = None) -> Executor:
    """The project's executor: EventsExecutor (driven by spin_once) unless GAIT_EXECUTOR=single."""
    if os.environ.get("GAIT_EXECUTOR", "events") == "single":
        return SingleThreadedExecutor(context=context)
    from rclpy.experimental import EventsExecutor

    return EventsExecutor(context=context)


def spin_until(
    executor: Executor,
    done: Callable[[], bool],
    timeout: float | None = None,
    period: float = 0.05,
    check_every: float = 0.005,
) -> bool:
    """Drive ``executor`` with ``spin_once`` until ``done()`` or ``timeout`` s; True if done.

    ``spin_once`` handles one callback, i.e. runs thousands of times a second in a busy graph; the
    context, ``done()`` and the deadline are checked at most every ``check_every`` s, not after each
    callback (an idle ``spin_once`` waits ``period`` s, so an idle graph checks after each)."""
    deadline = None if timeout is None else time.monotonic() + timeout
    context = executor.context
    spin_once = executor.spin_once
    monotonic = time.monotonic
    next_check = 0.0
    while True:
        now = monotonic()
        if now >= next_check:
            if not context.ok() or done():
                break
            if deadline is not None and now > deadline:
                return False
            next_check = now + check_every
        spin_once(timeout_sec=period)
    return done()


def params_files(args: Sequence[str]) -> list[str]:
    """The ``--params-file`` arguments of a ROS command line."""
    return [args[i + 1] for i, a in enumerate(args[:-1]) if a == "--params-file"]


def run_nodes(node_factories: Sequence[Callable[[Context], Node]], args: list[str] | None = None) -> int:
    """Console-script body: check the ``--params-file`` files, init rclpy with ``args`` (``--ros-args``
    work), spin the nodes until Ctrl-C / SIGTERM, destroy them (each node's ``destroy_node`` closes its
    files) and shut down. A refused parameter prints one line and returns 2."""
    args = sys.argv if args is None else args
    try:
        for path in params_files(args):
            load_params_file(path)
    except ParameterError as exc:
        print(f"{os.path.basename(args[0]) if args else 'node'}: {exc}", file=sys.stderr)
        return 2
    context = Context()
    rclpy.init(args=args, context=context)
    nodes: list[Node] = []
    executor = make_executor(context)
    code = 0
    try:
        for factory in node_factories:
            nodes.append(factory(context))
            executor.add_node(nodes[-1])
        spin_until(executor, lambda: False)
    except KeyboardInterrupt:
        pass
    except ParameterError as exc:
        print(f"{os.path.basename(args[0]) if args else 'node'}: {exc}", file=sys.stderr)
        code = 2
    finally:
        for node in nodes:
            node.destroy_node()
        executor.shutdown()
        if context.ok():
            rclpy.shutdown(context=context)
    return code
