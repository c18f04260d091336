"""Node ``imu_driver``: live sensors → ``<segment>/imu/data_raw`` and ``<segment>/imu/mag``.

A receiving thread reads frames from the link (``backend``: udp, serial, simulated;
:mod:`gait_biofeedback.io.sensor_links`; or decoded samples from a vendor's devices: ximu3, ngimu,
shimmer, dot; :mod:`gait_biofeedback.io.vendors`), hands them to the core
(:class:`~gait_biofeedback.core.driver.stream.DriverCore`: sequence order, loss, device time → ROS
time) and publishes each sample as the replayer would, stamped in ROS time, frame ``<segment>_imu``.
The executor thread only publishes ``/diagnostics``: one status per mapped sensor (rate, loss,
duplicates, clock offset and drift, last seen, samples claiming its id from another source; ERROR
when silent), one per unmapped sensor id that sends, and one for the link (corrupt frames, frames
refused for their signature, the receiving thread's CPU).

Stamps are the system clock (ROS time), whatever ``use_sim_time`` says: sensors live in real time.
Parameters: :class:`~gait_biofeedback.core.driver.stream.DriverParams`.
"""

from __future__ import annotations

import threading
import time

from rclpy.context import Context

from gait_biofeedback.core.driver.stream import DriverCore, DriverParams
from gait_biofeedback.core.segments import sensor_frame
from gait_biofeedback.nodes.common import GuardedNode, log_notices
from gait_biofeedback.nodes.parameters import declare_parameters, node_overrides
from gait_biofeedback.wire import diagnostics, topics
from gait_biofeedback.wire.cdr import IMU_DOUBLES, MAG_DOUBLES, StampedPacker
from gait_biofeedback.wire.imu import raw_imu_values

_NINE_ZEROS = (0.0,) * 9
POLL_S = 0.005
"""s: the receiving thread's longest wait, i.e. how late a held sample can be released."""


def open_link(p: DriverParams, key: bytes | None = None):
    """The link of the ``backend`` parameter; the simulator signs its frames with ``key`` (the
    session key the core read, as sensors do)."""
    from gait_biofeedback.io import sensor_links

    if p.backend == "udp":
        return sensor_links.UdpLink(p.address, p.port)
    if p.backend == "serial":
        return sensor_links.SerialLink(p.device, p.baud)
    if p.backend == "shimmer":
        from gait_biofeedback.io.vendors.shimmer import ShimmerLink

        return ShimmerLink(p.device_ids(), p.device_rate_hz, p.shimmer_accelerometer)
    if p.backend == "dot":
        from gait_biofeedback.io.vendors.dot import DotLink

        return DotLink(p.device_ids(), p.device_rate_hz)
    if p.backend == "ximu3":
        from gait_biofeedback.io.vendors.ximu3 import XImu3Link

        return XImu3Link(p.device_ids())
    if p.backend == "ngimu":
        from gait_biofeedback.io.vendors.ngimu import NgimuLink

        return NgimuLink(p.address, p.port, p.device_ids())
    from gait_biofeedback.sim.sensor_link import simulated_schedules

    ids = {segment: sid for sid, segment in p.mapping().items()}
    return sensor_links.PacedLink(simulated_schedules(p.scenario, p.sim_rate_hz, ids, p.sim_loop, key=key),
                                  f"simulated sensors ({p.scenario} at {p.sim_rate_hz:g} Hz)")


class ImuDriverNode(GuardedNode):
    """Sensors → raw IMU topics (module docstring). ``start=False``: receive only after
    :meth:`start` (the in-process graph starts it once the recorder listens)."""

    NODE_NAME = "imu_driver"

    def __init__(self, context: Context | None = None, params: DriverParams | None = None,
                 start: bool = True, **overrides: object) -> None:
        super().__init__(self.NODE_NAME, context=context, parameter_overrides=node_overrides(overrides))
        p: DriverParams = declare_parameters(self, DriverParams, params)
        self.params = p
        self.core = DriverCore(p)
        segments = [s.segment for s in self.core.sensors.values()]
        self._imu = {seg: self.create_publisher(topics.raw_imu(seg).msg_type, topics.raw_imu(seg).name,
                                                topics.SENSOR_QOS) for seg in segments}
        self._mag = {seg: self.create_publisher(topics.magnetometer(seg).msg_type,
                                                topics.magnetometer(seg).name, topics.SENSOR_QOS)
                     for seg in segments}
        self._packers = {seg: (StampedPacker(sensor_frame(seg), IMU_DOUBLES),
                               StampedPacker(sensor_frame(seg), MAG_DOUBLES)) for seg in segments}
        self.link = open_link(p, self.core.frame_key)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._thread_cpu_s = 0.0
        self._started_at = time.monotonic()
        self.create_timer(p.diagnostics_period_s, self._publish_diagnostics)
        self.get_logger().info(f"imu_driver: receiving on {self.link.description}, "
                               f"{len(segments)} sensors mapped")
        if start:
            self.start()

    def start(self) -> None:
        """Start receiving (once)."""
        if self._thread is None:
            self._started_at = time.monotonic()
            self._thread = threading.Thread(target=self._receive, name="imu_driver", daemon=True)
            self._thread.start()

    def _receive(self) -> None:
        receive, core = self.link.receive, self.core
        link_notices = getattr(self.link, "notices", None)
        next_cpu = 0.0
        while not self._stop.is_set():
            try:
                received = receive(POLL_S)
                with self._lock:
                    out = []
                    for frame, arrival, source in received:
                        feed = core.feed if isinstance(frame, bytes) else core.feed_samples
                        out.extend(feed(frame, arrival, source))
                    out.extend(core.expire(time.time_ns()))
                    notices = core.notices.pop()
                    if link_notices is not None:
                        notices += link_notices.pop()
                for sample in out:
                    imu, mag = self._packers[sample.segment]
                    self._imu[sample.segment].publish(
                        imu.pack(sample.stamp_ns, raw_imu_values(sample.gyr, sample.acc)))
                    if sample.mag is not None:
                        values = (*sample.mag, *_NINE_ZEROS)
                        self._mag[sample.segment].publish(mag.pack(sample.stamp_ns, values))
                log_notices(self.get_logger(), notices)
            except Exception as exc:  # a link error must not end the session silently
                self._failed("receiving thread", exc)
                if self._stop.wait(0.5):
                    break
            if time.monotonic() > next_cpu:
                self._thread_cpu_s = time.thread_time()
                next_cpu = time.monotonic() + 0.5

    def _publish_diagnostics(self) -> None:
        now = time.time_ns()
        with self._lock:
            reports = self.core.reports(now)
            link_reports = self.link.reports() if hasattr(self.link, "reports") else []
        statuses = [diagnostics.status(r.name, r.level, r.message, hardware_id=self.link.description,
                                       values=r.values) for r in reports]
        statuses += [diagnostics.status(name, level, message, hardware_id=self.link.description,
                                        values=values) for name, level, message, values in link_reports]
        elapsed = time.monotonic() - self._started_at
        cpu = self._thread_cpu_s / elapsed if elapsed > 0 and self._thread is not None else 0.0
        bad = getattr(self.link, "bad_frames", 0)
        problem = getattr(self.link, "problem", None)
        level = diagnostics.ERROR if problem else diagnostics.WARN if bad else diagnostics.OK
        read_stamps = getattr(self.link, "arrival_clock", None) == "read"
        text = problem or (f"{self.link.description}, {100 * cpu:.1f} % of a core"
                           + (f", {bad} corrupt frame(s) skipped on the line" if bad else "")
                           + (", this kernel gives no receive timestamps: arrivals stamped when read "
                              "(more jitter in the clock fit)" if read_stamps else ""))
        statuses.append(diagnostics.status(
            "imu_driver: receiving", level, text, hardware_id=self.link.description,
            values={"cpu_fraction": cpu, "line_bad_frames": bad,
                    "reconnects": getattr(self.link, "reconnects", 0),
                    "arrival_clock": getattr(self.link, "arrival_clock", None) or "unknown"}))
        self.publish_diagnostics(statuses)

    def destroy_node(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self.link.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Console script ``imu_driver``: receive until Ctrl-C / SIGTERM."""
    from gait_biofeedback.nodes.common import run_nodes

    return run_nodes([ImuDriverNode], args)


if __name__ == "__main__":
    import sys

    sys.exit(main())
