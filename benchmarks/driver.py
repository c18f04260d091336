"""imu_driver over UDP loopback (or a vendor backend): exact sample accounting, stamp accuracy, CPU.

Run: ``.venv/bin/python benchmarks/driver.py`` (about 22 min: 10 min of sending per rate, plus setup;
``--minutes 1`` for a quick look). For each rate (100 and 200 Hz):

1. the simulator makes a straight walk of 8 sensors (``walk``) of that length;
2. ``gait-biofeedback run --driver udp:PORT --nodes '' --record OUT`` runs in a process of its own
   (the driver and the recorder, no processing: what is measured is the driver);
3. this process sends the walk as the sensors would (:func:`gait_biofeedback.sim.sensor_link.send_udp`,
   the ``stream-sim`` command's sender): device clocks offset by 0.1 s per sensor and drifting
   ±100 ppm, each datagram delayed uniformly in [0, 5 ms], 1 % of the datagrams dropped, 1 %
   reordered;
4. the recording is read back and each sensor's recorded samples are matched in order with the ones
   sent (their values must be equal: a shifted match would show).

``--backend ximu3|ngimu`` measures a vendor backend the same way: step 2 runs ``--driver ximu3:...``
(fake x-IMU3s on TCP, the driver connecting through x-io's SDK) or ``--driver ngimu:...`` (fake NGIMUs
sending OSC bundles), and step 3 sends the same walk, clocks and link through those fake devices
(:mod:`gait_biofeedback.sim.xio_devices`); the values are compared to float32 rounding of their units
(°/s, g). ``--duration S`` sends S seconds per rate instead of ``--minutes``.

Printed per rate: samples sent (all the sensors took), dropped by the link, recorded, whether
recorded = sent - dropped exactly and each recorded sample's values are the ones sent, the driver's
own loss count (= dropped?); the stamp error against the sender's true sample
times after removing one constant offset (the link's least latency): p50 / p99 / max, over every
sample from the first; the spread of the per-sensor median offsets (alignment of the sensors); the
drift estimate error; the receiving thread's CPU (from the driver's /diagnostics) and the whole
process' CPU (driver + recorder + DDS) as fractions of one core.

``--backend shimmer``: the same, through the shimmer backend (``run --driver shimmer:...``, the real
``pyshimmer``) reading 8 fake Shimmer3 devices on pseudo-terminals
(:mod:`gait_biofeedback.io.vendors.shimmer_fake`, in this process): each device's own 32768 Hz clock
offset and drifting as above, packets delayed 0-5 ms (in order: a serial line does not reorder) and
1 % lost; the rates are the device's (32768 Hz over a whole number: 99.90 and 199.80 Hz). The truth
is each device's sample times; values match to half a count of its ranges. CPU per sample is the
whole driver process' (pyshimmer decodes in a thread per device, not in the receiving thread).

``--backend dot``: no radio here, so the Movella DOT decoder alone: CPU per notification decoded into
a sample and queued for the driver (:class:`gait_biofeedback.io.vendors.dot.DotLink`).

``--duration S`` sends S seconds per rate instead of ``--minutes``.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from gait_biofeedback.io.bag import BagReader
from gait_biofeedback.io.imu_bag import read_imu_bag
from gait_biofeedback.sim.sensor_link import FrameSchedule, LinkModel, send_udp
from gait_biofeedback.sim.simulator import simulate, walk

CLI = [sys.executable, "-m", "gait_biofeedback.cli"]
LINK = {"offset_s": 5.0, "drift_ppm": 100.0, "jitter_ms": 5.0, "loss": 0.01, "reorder": 0.01}


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def driver_diagnostics(bag: Path) -> dict[str, dict[str, str]]:
    """The last imu_driver status of each name, as key → value."""
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.serialization import deserialize_message

    last: dict[str, dict[str, str]] = {}
    with BagReader(bag) as reader:
        for _topic, _type, data, _ns in reader.raw_messages(["/diagnostics"]):
            for s in deserialize_message(data, DiagnosticArray).status:
                if s.name.startswith("imu_driver"):
                    last[s.name] = {kv.key: kv.value for kv in s.values}
    return last


def _start_driver(backend: str, schedule: FrameSchedule, out: Path, seconds: float):
    """The driver process of ``backend`` and how to send one sample through its devices (None: our UDP
    frames), and what to close at the end."""
    from gait_biofeedback.sim import xio_devices

    args = ["--nodes", "", "--record", str(out), "--duration", f"{seconds:.1f}"]
    sensor_ids = [t.sensor_id for t in schedule.truth.values()]
    ids = {seg: t.sensor_id for seg, t in schedule.truth.items()}
    if backend == "udp":
        port = free_port()
        return [*CLI, "run", "--driver", f"udp:{port}", *args], port, None, []
    if backend == "ximu3":
        fakes = xio_devices.ximu3_devices(sensor_ids)
        devices = xio_devices.device_entries({sid: f.spec for sid, f in fakes.items()}, ids)
        return ([*CLI, "run", "--driver", "ximu3:" + ",".join(devices), *args], None,
                lambda s: fakes[s.sensor_id].send_sample(s), list(fakes.values()))
    port = free_port()
    fakes = xio_devices.FakeNgimus(sensor_ids, "127.0.0.1", port)
    devices = xio_devices.device_entries({sid: f"127.0.0.1:{p}" for sid, p in fakes.ports.items()}, ids)
    return ([*CLI, "run", "--driver", f"ngimu:{port}," + ",".join(devices), *args], None, fakes.send_sample,
            [fakes])


def run_one(rate_hz: float, minutes: float, workdir: Path, backend: str = "udp") -> dict[str, object]:
    config = walk(duration=minutes * 60.0)
    config.rate_hz = rate_hz
    session = simulate(config)
    ids = {segment: k for k, segment in enumerate(session.imu)}
    schedule = FrameSchedule(session.imu, ids, LinkModel(**LINK, seed=int(rate_hz)))
    out = workdir / f"driver_{backend}_{rate_hz:g}hz"
    duration = schedule.send_ns[-1] * 1e-9
    command, port, send, fakes = _start_driver(backend, schedule, out, duration + 8)
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    for line in proc.stdout:  # wait until the driver listens
        if "Ctrl-C stops" in line:
            break
    if send is None:
        report = send_udp(schedule, "127.0.0.1", port)
    else:
        from gait_biofeedback.sim.xio_devices import play

        report = play(schedule, send)
    for _ in proc.stdout:
        pass
    for fake in fakes:
        fake.close()
    _, status, usage = os.wait4(proc.pid, 0)
    if status != 0:
        raise RuntimeError(f"the driver process ended with status {status}")
    process_cpu = (usage.ru_utime + usage.ru_stime) / (duration + 8)

    recorded = read_imu_bag(out)
    errors, offsets, counts_ok, values_ok = [], [], True, True
    for segment, truth in schedule.truth.items():
        kept = ~truth.dropped
        rec = recorded[segment]
        if len(rec) != int(kept.sum()):
            counts_ok = False
            continue
        tolerance = {"atol": 1e-5} if backend == "udp" else {"rtol": 2e-7, "atol": 2e-6}  # float32 of g
        sent_acc = session.imu[segment].acc[kept].astype(np.float32)
        values_ok &= bool(np.allclose(rec.acc, sent_acc, **tolerance))
        true_ns = report.t0_ns + np.round(truth.t[kept] * 1e9)
        err = (rec.t - true_ns * 1e-9) * 1e3  # ms (float s of the stamps: 0.2 µs resolution)
        offsets.append(float(np.median(err)))
        errors.append(err)
    diag = driver_diagnostics(out)
    lost = sum(int(v.get("lost", 0)) for k, v in diag.items() if "sensor_id" in v and "lost" in v)
    late = sum(int(v.get("late", 0)) for k, v in diag.items() if "sensor_id" in v and "late" in v)
    drift_error = []
    for k, segment in enumerate(schedule.truth):
        _, drift = LinkModel(**LINK).clock(k)
        values = diag.get(f"imu_driver: {segment}", {})
        if "clock_drift_ppm" in values:
            drift_error.append(abs(float(values["clock_drift_ppm"]) - drift * 1e6))
    e = np.concatenate(errors) - np.median(np.concatenate(errors)) if errors else np.array([np.nan])
    return {
        "rate": rate_hz, "sent": schedule.samples, "dropped": report.samples_dropped,
        "recorded": sum(len(s) for s in recorded.values()), "exact": counts_ok and values_ok,
        "lost": lost, "late": late,
        "p50": float(np.percentile(np.abs(e), 50)), "p99": float(np.percentile(np.abs(e), 99)),
        "max": float(np.abs(e).max()), "spread": max(offsets) - min(offsets) if offsets else float("nan"),
        "drift": max(drift_error) if drift_error else float("nan"),
        "thread_cpu": float(diag.get("imu_driver: receiving", {}).get("cpu_fraction", "nan")),
        "process_cpu": process_cpu, "late_s": report.worst_lateness_s,
        "cpu_us": 1e6 * (usage.ru_utime + usage.ru_stime) / max(1, sum(len(s) for s in recorded.values())),
    }


def run_shimmer(rate_hz: float, minutes: float, workdir: Path) -> dict[str, object]:
    """One rate through the shimmer backend and 8 fake devices (module docstring)."""
    from gait_biofeedback.io.vendors.shimmer_fake import FakeShimmers, fakes_for_recording

    config = walk(duration=minutes * 60.0)
    config.rate_hz = rate_hz
    session = simulate(config)
    fakes = fakes_for_recording(session.imu, offset_s=LINK["offset_s"], drift_ppm=LINK["drift_ppm"],
                                jitter_s=LINK["jitter_ms"] * 1e-3, loss=LINK["loss"], seed=int(rate_hz))
    server = FakeShimmers(list(fakes.values())).start()
    params = workdir / f"shimmer_{rate_hz:g}.yaml"
    params.write_text(f"/**/imu_driver:\n  ros__parameters:\n    device_rate_hz: {rate_hz:g}\n")
    out = workdir / f"shimmer_{rate_hz:g}hz"
    spec = "shimmer:" + ",".join(f"{f.path}={segment}" for segment, f in fakes.items())
    log = workdir / f"shimmer_{rate_hz:g}.log"
    with log.open("w") as log_file:
        proc = subprocess.Popen([*CLI, "run", "--driver", spec, "--params", str(params), "--nodes", "",
                                 "--record", str(out), "--duration", f"{minutes * 60 + 3600:.0f}"],
                                stdout=log_file, stderr=subprocess.STDOUT)
    started = time.monotonic()
    while not (server.finished and all(f.started for f in fakes.values())):
        time.sleep(0.2)
        if proc.poll() is not None or time.monotonic() - started > minutes * 60 + 120:
            server.close()
            raise RuntimeError(f"the driver process ended or the devices did not finish: {log.read_text()}")
    time.sleep(1.0)  # the last samples reach the recorder
    proc.send_signal(signal.SIGINT)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.monotonic() - started
    server.close()
    if status != 0:
        raise RuntimeError(f"the driver process ended with status {status}: {log.read_text()[-3000:]}")
    cpu_s = usage.ru_utime + usage.ru_stime
    recorded = read_imu_bag(out)
    errors, offsets, counts_ok, values_ok = [], [], True, True
    for segment, fake in fakes.items():
        kept = np.asarray(fake.kept)
        rec = recorded[segment]
        if len(rec) != int(kept.sum()) or len(rec) != fake.sent:
            counts_ok = False
            continue
        truth = session.imu[segment]
        values_ok &= bool(np.abs(rec.acc - truth.acc[: len(kept)][kept]).max() < 0.55 / 408 + 1e-6)
        err = (rec.t - np.asarray(fake.due_ns)[kept] * 1e-9) * 1e3
        offsets.append(float(np.median(err)))
        errors.append(err)
    diag = driver_diagnostics(out)
    lost = sum(int(v.get("lost", 0)) for k, v in diag.items() if "sensor_id" in v and "lost" in v)
    drift_error = []
    for k, segment in enumerate(fakes):
        values = diag.get(f"imu_driver: {segment}", {})
        if "clock_drift_ppm" in values:
            truth = LINK["drift_ppm"] if k % 2 == 0 else -LINK["drift_ppm"]
            drift_error.append(abs(float(values["clock_drift_ppm"]) - truth))
    e = np.concatenate(errors) - np.median(np.concatenate(errors)) if errors else np.array([np.nan])
    samples = sum(len(s) for s in recorded.values())
    return {
        "rate": 32768 / fakes[next(iter(fakes))].divider, "sent": sum(len(f.kept) for f in fakes.values()),
        "dropped": sum(f.dropped for f in fakes.values()), "recorded": samples,
        "exact": counts_ok and values_ok, "lost": lost,
        "p50": float(np.percentile(np.abs(e), 50)), "p99": float(np.percentile(np.abs(e), 99)),
        "max": float(np.abs(e).max()), "spread": max(offsets) - min(offsets) if offsets else float("nan"),
        "drift": max(drift_error) if drift_error else float("nan"),
        "thread_cpu": float(diag.get("imu_driver: receiving", {}).get("cpu_fraction", "nan")),
        "process_cpu": cpu_s / wall, "cpu_us": 1e6 * cpu_s / max(1, samples), "late_s": 0.0,
    }


def dot_decoder_cpu(n: int = 200_000) -> float:
    """µs of CPU per DOT notification decoded into a sample and queued (no radio: module docstring)."""
    from gait_biofeedback.io.vendors import dot_payload as dp
    from gait_biofeedback.io.vendors.dot import DotLink

    class Silent:  # a client that never connects: the link's loop idles
        def __init__(self, *_):
            pass

        async def connect(self):
            await asyncio.sleep(3600)

        async def disconnect(self):
            pass

    link = DotLink({"D4:22:CD:00:00:01": 0}, 60, Silent)
    sensor = link.sensors[0]
    payloads = [dp.encode_rate_quantities(k * 16667, (0.1, 0.2, 9.8), (10.0, -5.0, 1.0), (0.3, 0.1, 0.9))
                for k in range(1000)]
    t0 = time.thread_time()
    for k in range(n):
        link._on_payload(sensor, bytearray(payloads[k % 1000]))
        if k % 4096 == 4095:
            link.receive(0.0)
    cpu = time.thread_time() - t0
    link.close()
    return 1e6 * cpu / n


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--minutes", type=float, default=10.0, help="sending time per rate [%(default)s]")
    parser.add_argument("--duration", type=float, default=None, help="sending time per rate, s (instead of "
                        "--minutes)")
    parser.add_argument("--rates", default="100,200", help="comma-separated rates, Hz [%(default)s]")
    parser.add_argument("--backend", choices=("udp", "ximu3", "ngimu", "shimmer", "dot"), default="udp",
                        help="udp: our frames; ximu3: fake x-IMU3s through x-io's SDK; ngimu: fake NGIMUs "
                        "over OSC; shimmer: fake Shimmer3 devices through pyshimmer; dot: the DOT decoder's "
                        "CPU only [udp]")
    args = parser.parse_args()
    if args.duration is not None:
        args.minutes = args.duration / 60.0
    if args.backend == "dot":
        print(f"dot backend (no radio): {dot_decoder_cpu():.1f} µs of CPU per notification decoded into a "
              "sample and queued for the driver")
        return 0
    t0 = time.monotonic()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for rate in (float(r) for r in args.rates.split(",")):
            rows.append(run_shimmer(rate, args.minutes, Path(tmp)) if args.backend == "shimmer"
                        else run_one(rate, args.minutes, Path(tmp), args.backend))
    if args.backend == "shimmer":
        print(f"imu_driver, shimmer backend (pyshimmer) reading 8 fake Shimmer3 on pseudo-terminals, "
              f"{args.minutes * 60:g} s per rate; devices: clock offset 5 s + 0.1 s per device, drift "
              "±100 ppm, packets delayed 0-5 ms in order, 1 % lost")
    else:
        print(f"imu_driver, backend {args.backend}, loopback, 8 sensors, {60 * args.minutes:g} s per rate; "
              "link: offset 5 s + 0.1 s per sensor, drift ±100 ppm, jitter 0-5 ms, 1 % datagrams lost, "
              "1 % reordered")
    print("| rate | sent | dropped | recorded | = sent - dropped, same values | driver's lost count | "
          "stamp error p50 / p99 / max (ms) | sensor offsets spread (ms) | drift error (ppm) | "
          "receiving thread CPU | process CPU | process CPU per sample (µs) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['rate']:g} Hz | {r['sent']} | {r['dropped']} | {r['recorded']} | "
              f"{'yes' if r['exact'] else 'NO'} | {r['lost']} ({r.get('late', 0)} late) | "
              f"{r['p50']:.3f} / {r['p99']:.3f} / {r['max']:.2f} | "
              f"{r['spread']:.3f} | {r['drift']:.1f} | {100 * r['thread_cpu']:.1f} % | "
              f"{100 * r['process_cpu']:.1f} % | {r['cpu_us']:.0f} |")
    late = (f"the sender was at worst {max(r['late_s'] for r in rows) * 1e3:.1f} ms late; "
            if args.backend in ("udp", "ximu3", "ngimu") else "")
    print(f"({late}{time.monotonic() - t0:.0f} s in all)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
