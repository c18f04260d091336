"""What every node shares: executors, logging the core's notices, diagnostics, `main`.

Topics, QoS and message conversion are :mod:`gait_biofeedback.wire`; parameters
:mod:`gait_biofeedback.nodes.parameters`.

Nodes stay thin: they convert messages, hold parameters and call the core. Executor choice is
measured: an ``EventsExecutor`` driven by ``spin_once`` in a loop is about 3× cheaper than the
``SingleThreadedExecutor``; its ``spin()`` is broken in rclpy 7.1.6, so it is never
called. ``GAIT_EXECUTOR=single`` selects the fallback.
"""

from __future__ import annotations

import contextlib
import fcntl
import functools
import os
import re
import signal
import sys
import tempfile
import threading
import time
import traceback
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.clock import Clock, ClockType
from rclpy.context import Context
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.signals import SignalHandlerOptions
from rclpy.subscription import Subscription

from gait_biofeedback.core.notices import Notice
from gait_biofeedback.core.params import ParameterError
from gait_biofeedback.parameters import load_params_file
from gait_biofeedback.wire import diagnostics, topics
from gait_biofeedback.wire.topics import Topic


class GuardedNode(Node):
    """A node whose callbacks never end the process, and whose timers run on the steady clock.

    An exception in a subscription, timer, service or future callback (:meth:`guarded`) is logged
    once per callback with its traceback, naming the node and the callback, counted in
    :attr:`callback_errors` and reported on ``/diagnostics`` (``<node>: callbacks``, ERROR, every
    second while there are errors); the node goes on with the next message. A failed service callback
    answers with the default response (``success`` false where the service has it).

    Timers count wall seconds also under ``use_sim_time`` (a replay at 10x must not run the
    dashboard or the diagnostics 10x as often); only stamps follow ``/clock``.

    A node whose constructor raises (a refused parameter, an output that exists) is destroyed before
    the error propagates: left to the garbage collector, its name stays on the ROS graph and the next
    graph in the process is refused as a second one (:func:`refuse_other_graph`)."""

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        init = cls.__dict__.get("__init__")
        if init is None:
            return

        @functools.wraps(init)
        def init_or_destroy(self: GuardedNode, *args: Any, **kw: Any) -> None:
            try:
                init(self, *args, **kw)
            except BaseException:
                with contextlib.suppress(Exception):
                    Node.destroy_node(self)  # rclpy's own: an override may expect a whole node
                raise

        cls.__init__ = init_or_destroy

    def __init__(self, node_name: str, **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self.callback_errors: dict[str, int] = {}
        self._steady_clock = Clock(clock_type=ClockType.STEADY_TIME)
        self._diagnostics_publisher = publisher(self, topics.DIAGNOSTICS)
        super().create_timer(1.0, self._report_errors, clock=self._steady_clock)

    def publish_diagnostics(self, statuses: Iterable[DiagnosticStatus]) -> None:
        """Publish ``statuses`` on ``/diagnostics``, stamped with the node's clock. Under
        ``use_sim_time`` nothing is published until the first ``/clock`` (a stamp of 0 would put the
        status in another time base than the data)."""
        now = self.get_clock().now()
        if now.nanoseconds == 0 and self.get_parameter("use_sim_time").value:
            return
        self._diagnostics_publisher.publish(diagnostics.array(now.to_msg(), statuses))

    def guarded(self, what: str, callback: Callable[..., Any]) -> Callable[..., Any]:
        """``callback`` that logs, counts and swallows its exceptions (see class docstring)."""

        def call(*args: Any, **kwargs: Any) -> Any:
            try:
                return callback(*args, **kwargs)
            except Exception as exc:  # the process must not end on one bad message
                self._failed(what, exc)
                return None

        return call

    def _failed(self, what: str, exc: Exception) -> None:
        count = self.callback_errors.get(what, 0) + 1
        self.callback_errors[what] = count
        if count == 1:
            trace = "".join(traceback.format_exception(exc)).rstrip()
            self.get_logger().error(f"{what} failed and was skipped ({type(exc).__name__}: {exc}); the node "
                                    f"goes on; further failures are counted on /diagnostics\n{trace}")

    def _report_errors(self) -> None:
        if not self.callback_errors:
            return
        total = sum(self.callback_errors.values())
        worst = max(self.callback_errors, key=self.callback_errors.get)
        status = diagnostics.status(f"{self.get_name()}: callbacks", diagnostics.ERROR,
                                    f"{total} callback failure(s), skipped (most: {worst}); see the log",
                                    values={k: v for k, v in self.callback_errors.items()})
        self.publish_diagnostics([status])

    def create_subscription(self, msg_type: Any, topic: str, callback: Callable[..., Any],
                            qos_profile: Any, **kwargs: Any) -> Subscription:
        wrapped = self.guarded(f"callback of {topic}", callback)
        return super().create_subscription(msg_type, topic, wrapped, qos_profile, **kwargs)

    def create_timer(self, timer_period_sec: float, callback: Callable[..., Any], *args: Any,
                     **kwargs: Any) -> Any:
        name = getattr(callback, "__name__", "timer").lstrip("_").replace("_", " ")
        wrapped = self.guarded(f"timer {name}", callback)
        kwargs.setdefault("clock", self._steady_clock)
        return super().create_timer(timer_period_sec, wrapped, *args, **kwargs)

    def create_service(self, srv_type: Any, srv_name: str, callback: Callable[..., Any],
                       **kwargs: Any) -> Any:
        guarded = self.guarded(f"service {srv_name}", callback)

        def serve(request: Any, response: Any) -> Any:
            answer = guarded(request, response)
            if answer is None:  # the callback failed: answer anyway
                if hasattr(response, "success"):
                    response.success = False
                if hasattr(response, "message"):
                    response.message = f"{srv_name} failed inside the node; see its log"
                return response
            return answer

        return super().create_service(srv_type, srv_name, serve, **kwargs)


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


STOP = threading.Event()
"""Set by SIGINT or SIGTERM while :func:`stop_on_signals` is active: every :func:`spin_until` ends."""


def init_ros(args: list[str] | None, context: Context) -> None:
    """``rclpy.init`` without rclpy's own signal handlers: :func:`stop_on_signals` handles SIGINT and
    SIGTERM alike, so neither raises inside a callback (rclpy's handler makes Ctrl-C a KeyboardInterrupt
    in whatever callback runs, and leaves SIGTERM to kill the process with its files open)."""
    rclpy.init(args=args, context=context, signal_handler_options=SignalHandlerOptions.NO)


@contextlib.contextmanager
def stop_on_signals() -> Iterator[threading.Event]:
    """While active (main thread only), SIGINT and SIGTERM set :data:`STOP`: the spin loops return and
    the caller destroys its nodes, which closes their files; a second signal interrupts at once."""
    if threading.current_thread() is not threading.main_thread():
        yield STOP
        return

    def handler(signum: int, _frame: Any) -> None:
        if STOP.is_set():
            raise KeyboardInterrupt
        STOP.set()

    STOP.clear()
    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield STOP
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
        STOP.clear()


def make_executor(context: Context | None = None) -> Executor:
    """The project's executor: EventsExecutor (driven by spin_once) unless GAIT_EXECUTOR=single."""
    if os.environ.get("GAIT_EXECUTOR", "events") == "single":
        return SingleThreadedExecutor(context=context)
    from rclpy.experimental import EventsExecutor

    try:
        sys.stderr.fileno()
    except (AttributeError, OSError):  # e.g. Jupyter, captured output: EventsExecutor's
        with contextlib.redirect_stderr(sys.__stderr__):  # faulthandler.enable() needs a real file
            return EventsExecutor(context=context)
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
            if not context.ok() or STOP.is_set() or done():
                break
            if deadline is not None and now > deadline:
                return False
            next_check = now + check_every
        spin_once(timeout_sec=period)
    return done()


def params_files(args: Sequence[str]) -> list[str]:
    """The ``--params-file`` arguments of a ROS command line."""
    return [args[i + 1] for i, a in enumerate(args[:-1]) if a == "--params-file"]


class DomainInUseError(ValueError):
    """Another process on this ROS domain runs a node this one is about to start (a ValueError: the
    CLI prints it in one line)."""


class GraphClaim:
    """The node names a graph holds on its ROS domain and namespace (see :func:`refuse_other_graph`):
    one exclusive ``flock`` per name, released by :meth:`release` or by the kernel when the process
    ends, however it ends."""

    def __init__(self, handles: list[int]) -> None:
        self._handles = handles

    def release(self) -> None:
        while self._handles:
            os.close(self._handles.pop())


def _lock_path(domain: int, namespace: str, name: str) -> str:
    slug = re.sub(r"[^A-Za-z0-9_]", "_", namespace.strip("/"))
    return os.path.join(tempfile.gettempdir(),
                        f"gait_biofeedback.ros_domain_{domain}{'.' + slug if slug else ''}.{name}.lock")


def _claim_names(domain: int, namespace: str, names: Iterable[str]) -> tuple[list[int], list[str]]:
    """Lock one file per node name, in name order (see :class:`GraphClaim`): (the held descriptors, the
    first name another process of this machine holds, if any). Taking them in one order and stopping at
    the first one taken means two graphs whose names overlap never both refuse. A lock file that cannot
    be opened (another user's, a symlink) is left to the discovery check."""
    held: list[int] = []
    taken: list[str] = []
    for name in sorted(set(names)):
        path = _lock_path(domain, namespace, name)
        try:
            fd = os.open(path, os.O_RDONLY | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            taken.append(name)
            break  # in name order, so of two graphs the one holding the first shared name wins
        held.append(fd)
    return held, taken


def refuse_other_graph(context: Context, names: Iterable[str], settle: float = 0.6) -> GraphClaim:
    """Claim the node ``names`` on this ROS domain and namespace for this process, or raise
    :class:`DomainInUseError` when another process already runs one of them: two graphs on one domain
    process each other's data (joint states of both patients in one bag). Checked before the nodes
    exist (no file is opened). Keep the returned claim until the nodes are destroyed.

    Two checks: on this machine, an exclusive lock per node name (:class:`GraphClaim`), taken at once,
    so two graphs started at any offset, even together, end with exactly one running; on other
    machines of the domain, ``settle`` s of DDS discovery, which cannot tell two graphs started within
    that time of each other apart."""
    probe = Node(f"_gait_biofeedback_probe_{os.getpid()}", context=context)
    domain = context.get_domain_id()
    namespace = probe.get_namespace()
    wanted = {n for n in names if n}
    handles: list[int] = []
    try:
        handles, taken = _claim_names(domain, namespace, wanted)
        deadline = time.monotonic() + settle
        while not taken:
            taken = sorted({n for n, ns in probe.get_node_names_and_namespaces()
                            if n in wanted and ns == namespace})
            if taken or time.monotonic() > deadline:
                break
            time.sleep(0.02)
    except BaseException:
        GraphClaim(handles).release()
        raise
    finally:
        probe.destroy_node()
    if taken:
        GraphClaim(handles).release()
        where = f"namespace {namespace} of " if namespace != "/" else ""
        raise DomainInUseError(
            f"another gait_biofeedback graph already runs {', '.join(sorted(taken))} on {where}ROS_DOMAIN_ID="
            f"{domain}; two graphs on one domain process each other's data. Stop it, or start this one on "
            f"a domain of its own (e.g. ROS_DOMAIN_ID={(domain + 1) % 101} gait-biofeedback ...) or in a "
            "namespace of its own (console scripts: --ros-args -r __ns:=/patient2). A graph killed with -9 "
            "stays visible for up to 20 s (the DDS lease).")
    return GraphClaim(handles)


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
    init_ros(args, context)
    nodes: list[Node] = []
    executor = make_executor(context)
    claim = GraphClaim([])
    code = 0
    try:
        with stop_on_signals():
            claim = refuse_other_graph(context, [getattr(f, "NODE_NAME", "") for f in node_factories])
            for factory in node_factories:
                nodes.append(factory(context))
                executor.add_node(nodes[-1])
            spin_until(executor, lambda: False)
    except KeyboardInterrupt:
        pass
    except (ParameterError, DomainInUseError) as exc:
        print(f"{os.path.basename(args[0]) if args else 'node'}: {exc}", file=sys.stderr)
        code = 2
    finally:
        for node in nodes:
            node.destroy_node()
        claim.release()
        executor.shutdown()
        if context.ok():
            rclpy.shutdown(context=context)
    return code
