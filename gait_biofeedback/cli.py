"""``gait-biofeedback``: the project's command line (see ``gait-biofeedback --help``)."""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from pathlib import Path
from typing import Any

from gait_biofeedback.core.words import plural

DEMO_BAG = Path("bags/demo_walk")
DEMO_OUTPUT = Path("output/demo_session")
FOXGLOVE_PORT = 8765  # Foxglove's default WebSocket port

DESCRIPTION = """\
Wearable-IMU gait biofeedback (ROS 2 Jazzy). Typical use:

  gait-biofeedback demo                        simulate a session, replay it through the graph, summarise
  gait-biofeedback simulate -o bags/walk       make a synthetic recording with ground truth
  gait-biofeedback import csv my.csv --mapping map.yaml -o bags/mine
                                               convert your own IMU data to the project's MCAP layout
  gait-biofeedback replay bags/mine --record output/mine
                                               run a recording through the node graph, record outputs
  gait-biofeedback analyze bags/mine -o output/mine_offline --calibrate-at 36:hip_flexion
                                               the same processing offline, straight from the file
                                               (and its tables: output/mine_offline/tables/*.parquet)
  gait-biofeedback run --driver udp:5600 --record output/today
                                               live sensors (docs/guide/live_sensors.md) through the graph
  gait-biofeedback stream-sim bags/demo_walk --to udp:127.0.0.1:5600
                                               send a recording as live sensors would (demos, tests)
  gait-biofeedback info output/mine            what is in a recording
  gait-biofeedback params --check my.yaml      check a parameter file (a typo is refused, naming it)
  gait-biofeedback repair output/mine          make a recording cut off by a crash readable again

Run `gait-biofeedback COMMAND --help` for the options of one command.
"""


def _progress(total: int, desc: str):
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="msg", unit_scale=True, leave=False,
                disable=not sys.stderr.isatty())


DURATION_SCENARIOS = ("training", "walk", "hemiparetic")


def cmd_simulate(args: argparse.Namespace) -> int:
    from gait_biofeedback.io.bag_writer import check_output
    from gait_biofeedback.sim.recording import write_simulated_bag
    from gait_biofeedback.sim.simulator import SCENARIOS, simulate

    if args.duration is not None and args.scenario == "demo":
        args.scenario = "training"  # the demo has its own length; a duration asks for a longer session
    if args.scenario not in SCENARIOS:
        print(f"unknown scenario {args.scenario!r}; choose one of {sorted(SCENARIOS)}", file=sys.stderr)
        return 2
    if args.duration is not None and args.scenario not in DURATION_SCENARIOS:
        raise ValueError(f"--duration sets the length of the scenarios {', '.join(DURATION_SCENARIOS)}, "
                         f"not of {args.scenario!r}; e.g. --scenario training --duration 600")
    check_output(args.output, args.overwrite)
    config = SCENARIOS[args.scenario](**({} if args.duration is None else {"duration": args.duration}))
    config.rate_hz = args.rate
    config.seed = args.seed
    if args.no_mag:
        config.with_magnetometer = False
    session = simulate(config)
    path = write_simulated_bag(args.output, session, overwrite=args.overwrite)
    n = len(next(iter(session.imu.values())))
    print(f"wrote {path}: scenario {args.scenario}, {plural(len(session.imu), 'sensor')} x {n} samples "
          f"at {config.rate_hz:g} Hz ({n / config.rate_hz:.1f} s), seed {config.seed}")
    return 0


def cmd_import(args: argparse.Namespace) -> int:
    from gait_biofeedback.core.safe_yaml import clip
    from gait_biofeedback.io.bag_writer import check_output
    from gait_biofeedback.io.importers import import_to_bag

    check_output(args.output)
    options = {}
    if args.mapping:
        options["mapping"] = args.mapping
    if args.units:
        bad = [u for u in args.units if "=" not in u]
        if bad:
            raise ValueError(f"--units {' '.join(bad)}: expected QUANTITY=UNIT pairs, e.g. --units acc=g "
                             "gyr=deg/s mag=uT time=ms")
        options["units"] = dict(u.split("=", 1) for u in args.units)
    if args.rate:
        options["rate_hz"] = args.rate
    if args.trust_units:
        options["trust_units"] = True
    try:  # a CSV is streamed (bounded memory); whatever fails ends in one line (main)
        path, segments = import_to_bag(args.kind, args.path, args.output, **options,
                                       warn=lambda text: print(f"warning: {text}", file=sys.stderr),
                                       note=print)
    except MemoryError:
        raise ValueError(f"{args.path}: not enough memory to import it (a {args.kind} file is read whole; "
                         "a CSV is streamed)") from None
    except (ValueError, OSError):
        raise
    except Exception as exc:  # e.g. a damaged MAT file: what failed, not a traceback
        raise ValueError(f"{args.path}: cannot import it ({type(exc).__name__}: "
                         f"{clip(' '.join(str(exc).split()), 200)})") from None
    print(f"wrote {path}: {plural(len(segments), 'sensor')} ({', '.join(segments)}) from {args.path}")
    return 0


def _session_parameters(path: str | None) -> dict[str, dict]:
    from gait_biofeedback.parameters import load_params_file

    return {} if path is None else load_params_file(path)


def _node_list(text: str | None) -> list[str] | None:
    return None if text is None else [n for n in text.split(",") if n]


DRIVER_SPECS = ("udp:PORT, udp:ADDRESS:PORT, serial:DEVICE[:BAUD], simulated[:SCENARIO], "
                "ximu3[:DEVICE=SEGMENT,...] (DEVICE: tcp:HOST:PORT, udp:HOST:SEND:RECEIVE or serial:PATH), "
                "ngimu:[ADDRESS:]PORT[,IP[:PORT]=SEGMENT,...], "
                "shimmer[:PORT=SEGMENT,...] (e.g. shimmer:/dev/rfcomm0=left_shank,/dev/rfcomm1=right_shank) "
                "or dot[:ADDRESS=SEGMENT,...] (e.g. dot:D4:22:CD:00:12:34=left_foot); without devices, the "
                "--params file's imu_driver 'devices'")


def parse_driver(spec: str) -> dict[str, object]:
    """``--driver`` → imu_driver parameters: ``udp:PORT``, ``udp:ADDRESS:PORT``,
    ``serial:DEVICE[:BAUD]``, ``simulated[:SCENARIO]``, ``ximu3[:DEVICE=SEGMENT,...]``,
    ``ngimu:[ADDRESS:]PORT[,DEVICE=SEGMENT,...]``, ``shimmer[:PORT=SEGMENT,...]``,
    ``dot[:ADDRESS=SEGMENT,...]`` (no devices: the parameter file's ``devices``;
    docs/connecting_sensors.md)."""
    kind, _, rest = spec.partition(":")
    if kind in ("shimmer", "dot"):
        return _vendor_driver(spec, kind, rest)
    if kind == "ximu3":
        devices = [d for d in rest.split(",") if d]
        if all("=" in d for d in devices):
            return {"backend": "ximu3", **({"devices": devices} if devices else {})}
    if kind == "ngimu":
        listen, *devices = rest.split(",")
        where = listen.split(":")
        if len(where) in (1, 2) and where[-1].isdigit() and all("=" in d for d in devices):
            address = {"address": where[0]} if len(where) == 2 else {}
            return {"backend": "ngimu", "port": int(where[-1]), **address,
                    **({"devices": devices} if devices else {})}
    parts = rest.split(":") if rest else []
    try:
        if kind == "udp" and len(parts) in (1, 2):
            address = {"address": parts[0]} if len(parts) == 2 else {}
            return {"backend": "udp", "port": int(parts[-1]), **address}
        if kind == "serial" and len(parts) in (1, 2):
            baud = {"baud": int(parts[1])} if len(parts) == 2 else {}
            return {"backend": "serial", "device": parts[0], **baud}
    except ValueError:
        pass
    if kind == "simulated" and len(parts) <= 1:
        return {"backend": "simulated", **({"scenario": parts[0]} if parts else {})}
    raise ValueError(f"--driver {spec!r}: expected {DRIVER_SPECS}")


def _vendor_driver(spec: str, kind: str, rest: str) -> dict[str, object]:
    """``shimmer:PORT=SEGMENT,...`` / ``dot:ADDRESS=SEGMENT,...`` → backend and devices."""
    devices = [d.strip() for d in rest.split(",") if d.strip()]
    if any("=" not in d for d in devices):
        raise ValueError(f"--driver {spec!r}: each device is DEVICE_ID=SEGMENT; expected {DRIVER_SPECS}")
    return {"backend": kind, **({"devices": devices} if devices else {})}


def cmd_run(args: argparse.Namespace) -> int:
    import time

    from gait_biofeedback.graph import run_live

    params = _session_parameters(args.params)
    if args.driver:
        params["imu_driver"] = {**params.get("imu_driver", {}), **parse_driver(args.driver)}
        if args.frame_key_file:
            params["imu_driver"]["frame_key_file"] = args.frame_key_file
    elif args.frame_key_file:
        raise ValueError("--frame-key-file is the driver's: give --driver too")
    end = time.monotonic() + args.duration if args.duration > 0 else None
    return run_live(_node_list(args.nodes), args.record, params, driver=bool(args.driver),
                    until=None if end is None else (lambda: time.monotonic() > end), foxglove=args.foxglove)


def cmd_stream_sim(args: argparse.Namespace) -> int:
    from gait_biofeedback.core.driver.protocol import load_frame_key
    from gait_biofeedback.io.imu_bag import read_imu_bag
    from gait_biofeedback.parameters import stage_parameters
    from gait_biofeedback.sim.sensor_link import FrameSchedule, LinkModel, send_udp

    if args.as_ == "shimmer":
        return _stream_sim_shimmer(args)
    if not args.to and args.as_ != "x-imu3":
        raise ValueError(f"stream-sim --as {args.as_}: give --to udp:HOST:PORT (where the driver listens)")
    kind, _, rest = (args.to or "").partition(":")
    host, _, port = rest.rpartition(":")
    if args.as_ != "x-imu3" and (kind != "udp" or not host or not port.isdigit()):
        raise ValueError(f"--to {args.to!r}: expected udp:HOST:PORT, e.g. udp:127.0.0.1:5600")
    driver = stage_parameters("imu_driver", _session_parameters(args.params).get("imu_driver", {}))
    ids = {segment: sid for sid, segment in driver.mapping().items()}
    link = LinkModel(args.offset_s, args.drift_ppm, args.jitter_ms, args.loss, args.reorder,
                     args.samples_per_frame, args.seed)
    key = load_frame_key(args.frame_key_file) if args.frame_key_file else None
    schedule = FrameSchedule(read_imu_bag(args.bag), ids, link, key)
    if schedule.missing:
        print(f"note: the mapping's {', '.join(schedule.missing)} are not in {args.bag}")
    if args.as_ != "ours":
        return _stream_as_xio(args, schedule, ids, host, int(port) if port.isdigit() else 0)
    duration = schedule.send_ns[-1] * 1e-9
    signed = f", signed with the key of {args.frame_key_file}" if key is not None else ""
    print(f"sending {schedule.samples} samples of {len(schedule.series)} sensors ({duration:.1f} s) to "
          f"{host}:{port}{signed}; Ctrl-C stops")
    from gait_biofeedback.nodes.common import STOP, stop_on_signals

    with stop_on_signals():
        report = send_udp(schedule, host, int(port), stop=STOP.is_set)
    print(f"sent {report.samples_sent} samples in {report.frames_sent} datagrams, dropped "
          f"{report.samples_dropped} (--loss {args.loss:g}); the sender was at worst "
          f"{1e3 * report.worst_lateness_s:.1f} ms late")
    return 0


def _stream_sim_shimmer(args: argparse.Namespace) -> int:
    """``stream-sim --as shimmer``: one fake Shimmer3 per segment on a pseudo-terminal, each streaming
    the recording once a client connects and starts it (``run --driver shimmer:...``)."""
    import time

    from gait_biofeedback.io.imu_bag import read_imu_bag
    from gait_biofeedback.io.vendors.shimmer_fake import FakeShimmers, fakes_for_recording
    from gait_biofeedback.nodes.common import stop_on_signals

    series = read_imu_bag(args.bag)
    fakes = fakes_for_recording(series, offset_s=args.offset_s, drift_ppm=args.drift_ppm,
                                jitter_s=args.jitter_ms * 1e-3, loss=args.loss, seed=args.seed)
    spec = ",".join(f"{f.path}={segment}" for segment, f in fakes.items())
    server = FakeShimmers(list(fakes.values())).start()
    print(f"{len(fakes)} fake Shimmer3 devices wait for a client; connect them with\n"
          f"  gait-biofeedback run --driver shimmer:{spec}\nCtrl-C stops", flush=True)
    try:
        with stop_on_signals() as stop:
            while not stop.is_set() and not (server.finished and all(f.started for f in fakes.values())):
                time.sleep(0.1)
    finally:
        server.close()
    sent = sum(f.sent for f in fakes.values())
    dropped = sum(f.dropped for f in fakes.values())
    print(f"sent {sent} samples as data packets, dropped {dropped} (--loss {args.loss:g})")
def _stream_as_xio(args: argparse.Namespace, schedule, ids: dict[str, int], host: str, port: int) -> int:
    """``stream-sim --as x-imu3|ngimu``: the recording through fake x-io devices
    (:mod:`gait_biofeedback.sim.xio_devices`), each sensor one device."""
    import time

    from gait_biofeedback.nodes.common import STOP, stop_on_signals
    from gait_biofeedback.sim import xio_devices

    sensor_ids = [t.sensor_id for t in schedule.truth.values()]
    used = {seg: sid for seg, sid in ids.items() if sid in sensor_ids}
    if args.as_ == "x-imu3":
        fakes = xio_devices.ximu3_devices(sensor_ids, ascii_mode=args.ascii)
        devices = xio_devices.device_entries({sid: f.spec for sid, f in fakes.items()}, used)

        def send(sample) -> bool:
            return fakes[sample.sensor_id].send_sample(sample)

        print(f"{len(fakes)} x-IMU3s listening; connect with: gait-biofeedback run --driver "
              f"'ximu3:{','.join(devices)}'", flush=True)
        with stop_on_signals():
            for fake in fakes.values():
                while not fake.wait_connected(0.5) and not STOP.is_set():
                    pass
    else:
        fakes = xio_devices.FakeNgimus(sensor_ids, host, port, args.source_port)
        devices = xio_devices.device_entries({sid: f"127.0.0.1:{p}" for sid, p in fakes.ports.items()}, used)
        send = fakes.send_sample
        print(f"{len(sensor_ids)} NGIMUs sending to {host}:{port}; their devices: '{','.join(devices)}'",
              flush=True)
    print(f"sending {schedule.samples} samples of {len(schedule.series)} sensors "
          f"({schedule.send_ns[-1] * 1e-9:.1f} s) as {args.as_}; Ctrl-C stops", flush=True)
    try:
        with stop_on_signals():
            report = xio_devices.play(schedule, send, stop=STOP.is_set)
        time.sleep(0.5)  # let the last messages leave before the devices close
    finally:
        for fake in (fakes.values() if isinstance(fakes, dict) else [fakes]):
            fake.close()
    print(f"sent {report.samples_sent} samples, dropped {report.samples_dropped} (--loss {args.loss:g}); the "
          f"sender was at worst {1e3 * report.worst_lateness_s:.1f} ms late")
    return 0


def _print_calibrations(attempts: list, start_ns: int) -> None:
    """Each calibration request: its outcome and the standing and motion windows it used (s into
    the recording)."""
    for attempt in attempts:
        until = ("" if attempt.until_ns is None
                 else f", data up to {(attempt.until_ns - start_ns) / 1e9:.2f} s")
        print(f"calibrate ({attempt.protocol}{until}): " + ("" if attempt.success else "REFUSED: ")
              + attempt.message)
        cal = attempt.calibration
        if cal is not None and cal.standing is not None and cal.motion is not None:
            (s0, s1), (m0, m1) = ((t - start_ns / 1e9 for t in w) for w in (cal.standing, cal.motion))
            print(f"  quiet standing {s0:.2f}-{s1:.2f} s, motion {m0:.2f}-{m1:.2f} s into the recording")


def _calibration_options(args: argparse.Namespace, params: dict[str, dict]) -> list[tuple[float | None, str]]:
    """--calibrate-at requests (an ``auto`` time is None); --calibration goes into the calibration
    stage's parameters."""
    from gait_biofeedback.analyze import parse_calibrate_at

    if args.calibration is not None:
        params.setdefault("calibration", {})["calibration_file"] = args.calibration
    return [parse_calibrate_at(text) for text in args.calibrate_at or []]


def _walk_calibration(bag: str, request: tuple[float, str], params: dict[str, dict], folder: Path,
                      why: str) -> bool:
    """An ``auto`` calibration made of the recording's walk: a recording that starts walking (no
    standing: the feet's calibration from the walk's stance phases), or the walking protocol after a
    standing (the calibration walk is the walk to analyse). Pressed at the end of that walk, as live,
    the replay would have no events before it; so the calibration is saved in ``folder`` and in force
    from the start of the replay, as ``analyze`` does (``why`` says which case). The calibration node
    handles the segments it has entries for. False when it is refused (then Calibrate is pressed as
    usual, and says why) or when a calibration file was given (``--calibration`` stays in force, and
    Calibrate is pressed)."""
    from datetime import UTC, datetime

    from gait_biofeedback.analyze import calibration_ahead
    from gait_biofeedback.core.calibration.stream import write_calibration_file
    from gait_biofeedback.core.segments import SEGMENTS

    stage = params.setdefault("calibration", {})
    if stage.get("calibration_file"):
        return False
    attempt = calibration_ahead(bag, request, params)
    if not attempt.success or attempt.calibration is None:
        return False
    path = folder / "calibration_from_the_walk.yaml"
    write_calibration_file(path, attempt.calibration, datetime.now(UTC).isoformat())
    stage["calibration_file"] = str(path)
    stage["segments"] = [s for s in stage.get("segments", SEGMENTS) if s in attempt.calibration.segments]
    print(f"--calibrate-at auto: {why}: {attempt.message}; in force from the start of the replay (as analyze "
          "does)")
    return True


def cmd_replay(args: argparse.Namespace) -> int:
    import shutil
    import tempfile

    from gait_biofeedback.analyze import (
        AUTO_OPTIONS,
        NO_STANDING,
        drop_needless_auto,
        recording_rates,
        resolve_calibrate_at,
        with_recording_rate,
    )
    from gait_biofeedback.graph import replay_through_graph
    from gait_biofeedback.io.bag import BagReader
    from gait_biofeedback.parameters import stage_parameters

    params = _session_parameters(args.params)  # a parameter file's typo is refused before the bag is read
    rates = recording_rates(args.bag)
    params, notes = with_recording_rate(rates, params)
    calibration = stage_parameters("calibration", params.get("calibration", {}))
    asked, dropped = drop_needless_auto(list(rates), _calibration_options(args, params))
    notes += dropped
    requests, found = resolve_calibrate_at(args.bag, asked, calibration.default_standing_duration_s)
    notes += found
    for note in notes:
        print(note)
    no_standing = any(NO_STANDING in n for n in notes)
    with tempfile.TemporaryDirectory() as folder:
        pressed = []
        for (t, protocol), (when, _) in zip(requests, asked, strict=True):
            why = ("no standing to press Calibrate after" if no_standing else
                   f"the walking calibration is the recording's walk (pressed at its end, {t:.2f} s, the "
                   "replay would have no events before it)")
            if when is None and (no_standing or protocol == "walking") and _walk_calibration(
                    args.bag, (t, protocol), params, Path(folder), why):
                continue
            pressed.append((t, protocol, AUTO_OPTIONS) if when is None else (t, protocol))
        with BagReader(args.bag) as reader:
            total = reader.message_count
        with _progress(total, "replay") as bar:
            result = replay_through_graph(args.bag, args.record, speed=args.speed, start_offset_s=args.start,
                                          stop_offset_s=args.stop, progress=bar.update,
                                          nodes=_node_list(args.nodes), node_parameters=params,
                                          calibrate_at=pressed, foxglove=args.foxglove)
        walk_file = Path(folder) / "calibration_from_the_walk.yaml"
        if walk_file.exists() and args.record and result.calibration_file is None:
            result.calibration_file = Path(args.record) / "calibration.yaml"  # kept with the recording
            shutil.copyfile(walk_file, result.calibration_file)
    _print_calibrations(result.calibrations, result.start_ns)
    where = ", ".join(str(p) for p in result.outputs)
    print(f"replayed {result.published} messages in {result.wall_time:.1f} s"
          + (f"; recorded {result.recorded} to {where}" if result.outputs else ""))
    if result.calibration_file is not None:
        print(f"calibration saved as {result.calibration_file}")
    if result.interrupted:
        print("stopped by a signal before the end of the recording", file=sys.stderr)
    if result.write_error:
        print(f"warning: {result.write_error}", file=sys.stderr)
        return 1
    note = result.loss_note(args.speed, args.bag)
    if note:
        print(f"replay: {note}", file=sys.stderr)
        return 1
    return 0


def cmd_analyze(args: argparse.Namespace) -> int:
    from gait_biofeedback.analyze import analyze_recording
    from gait_biofeedback.report.recording import read_recording_file
    from gait_biofeedback.report.session import format_report, summarise
    from gait_biofeedback.report.tables import write_tables

    params = _session_parameters(args.params)
    requests = _calibration_options(args, params)
    result = analyze_recording(args.bag, args.output, calibrate_at=requests, params=params,
                               overwrite=args.overwrite)
    for note in result.notes:
        print(note)
    _print_calibrations(result.calibrations, result.start_ns)
    if not requests and args.calibration is None:
        print("no calibration given (--calibrate-at or --calibration): orientations and activity only")
    for warning in result.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    outputs = ", ".join(f"{t} {n}" for t, n in sorted(result.counts.items()) if "/imu/" not in t)
    oriented = any("/imu/" in t for t in result.counts)
    print(f"wrote {result.output}: {outputs or ('orientations only' if oriented else 'no output')}")
    recording = read_recording_file(result.output)  # once, for the tables and the summary
    if not args.no_tables:
        files = write_tables(result.output, recording=recording)
        print(f"wrote {files.folder}: {files.summary()} (Parquet; docs/guide/report.md, Tables for analysis)")
    if result.calibration_file is not None:
        print(f"calibration in force saved as {result.calibration_file}")
    print("\n".join(format_report(summarise(recording))))
    if result.requested and not any(a.success for a in result.calibrations):
        print("analyze: no calibration took effect (see the REFUSED or 'never ran' lines above), so there "
              "are no joint angles and no calibrated gait outputs; change the --calibrate-at request, or "
              "pass --calibration FILE", file=sys.stderr)
        return 1
    return 0


def cmd_tables(args: argparse.Namespace) -> int:
    from gait_biofeedback.report.tables import write_tables

    files = write_tables(args.bag, args.output)
    for text in files.damage:
        print(f"warning: DAMAGED RECORDING: {text}; the tables hold only what could be read", file=sys.stderr)
    print(f"wrote {files.folder}: {files.summary()}")
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    from gait_biofeedback.report.build import Patient, patient_from_params, write_report

    patient = patient_from_params(args.params) if args.params else Patient()
    patient = Patient(args.patient_id or patient.id, args.session_label or patient.session)
    files = write_report(args.sessions, args.output, patient, labels=args.labels, norms_file=args.norms,
                         targets_file=args.targets, overwrite=args.overwrite, date=args.date,
                         paretic_side=args.paretic_side)
    for note in files.analyses[-1].notes:
        print(note)
    for text in files.damage:
        print(f"warning: DAMAGED RECORDING: {text}; the report covers only what could be read",
              file=sys.stderr)
    for path in (files.html, files.pdf, files.strides_csv, files.joints_csv):
        print(f"wrote {path}")
    return 0


def cmd_batch(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from gait_biofeedback.analyze import parse_calibrate_at
    from gait_biofeedback.cohort.run import run_batch
    from gait_biofeedback.cohort.task import BatchOptions

    requests = tuple(args.calibrate_at or ["auto"])
    for text in requests:
        parse_calibrate_at(text)  # a bad request is refused before any worker starts
    options = BatchOptions(requests, _session_parameters(args.params), report=not args.no_report)
    with tqdm(desc="batch", unit="session", disable=not sys.stderr.isatty()) as bar:
        def done(row: dict) -> None:
            bar.update()
            if row["status"] != "done":
                bar.write(f"{row['session']}: failed: {row['error']}", file=sys.stderr)

        result = run_batch(args.inputs, args.output, options, args.workers, args.scheduler, on_done=done)
    print(f"batch: {len(result.analysed)} analysed, {len(result.skipped)} skipped (done before, same "
          f"recording), {len(result.failed)} failed")
    for name, error in sorted(result.failed.items()):
        print(f"failed: {name}: {error}  (details: {Path(args.output) / name / 'session.json'}; "
              "run the batch again to retry)", file=sys.stderr)
    print(f"wrote {result.csv} and {result.parquet} ({len(result.rows)} sessions)")
    return 1 if result.failed else 0


def cmd_tune(args: argparse.Namespace) -> int:
    from gait_biofeedback.tuning.data import broad_recordings, simulated_recordings
    from gait_biofeedback.tuning.pso import PsoSettings
    from gait_biofeedback.tuning.run import table, tune, write
    from gait_biofeedback.tuning.space import SearchSpace

    SearchSpace(args.algorithm, args.scheme)  # a bad name is refused before any data is read
    if not args.broad and not args.simulated:
        raise ValueError("tune needs recordings with reference orientations: --broad DIR (BROAD trials) "
                         "and/or --simulated N (simulated subjects)")
    locations = args.locations.split(",") if args.locations else None
    recs = []
    if args.broad:
        recs += broad_recordings(args.broad, args.trials.split(",") if args.trials else None)
    if args.simulated:
        recs += simulated_recordings(args.simulated, args.sim_seconds, locations)
    if locations:
        recs = [r for r in recs if r.location in locations]
    if not recs:
        raise ValueError(f"no recording of the locations {locations}")
    recs = [r.cut(args.seconds) for r in recs]
    settings = PsoSettings(args.particles, args.iterations, seed=args.seed)
    verbose = sys.stderr.isatty() or args.verbose
    results = tune(args.algorithm, args.scheme, recs, settings, args.folds,
                   log=(lambda m: print(m, file=sys.stderr, flush=True)) if verbose else (lambda _: None))
    print(table(args.algorithm, args.scheme, results))
    if args.write is not None:
        command = "gait-biofeedback tune " + " ".join(sys.argv[2:] if sys.argv[1:2] == ["tune"] else [])
        path = write(args.algorithm, results, command.strip(), args.write or None,
                     shared_location="board")
        print(f"wrote {path}")
    return 0


def cmd_params(args: argparse.Namespace) -> int:
    from gait_biofeedback.parameters import NODE_PARAMETERS, load_params_file, parameter_table

    if args.check:
        for node, values in load_params_file(args.check).items():
            print(f"{node}: " + ", ".join(f"{k}={v!r}" for k, v in values.items()))
        print(f"{args.check}: ok")
        return 0
    unknown = [n for n in args.nodes if n not in NODE_PARAMETERS]
    if unknown:
        raise ValueError(f"unknown node(s) {unknown}; nodes: {', '.join(NODE_PARAMETERS)}")
    for node in args.nodes or NODE_PARAMETERS:
        print(f"\n{node}\n" + "\n".join(parameter_table(node)))
    return 0


def cmd_record(args: argparse.Namespace) -> int:
    from gait_biofeedback.nodes.recorder import main

    ros_args = ["--ros-args", "-p", f"output:={args.output}"]
    if args.topics:
        ros_args += ["-p", "topics:=[" + ",".join(args.topics) + "]"]
    return main(["gait-biofeedback-record", *ros_args])


def cmd_info(args: argparse.Namespace) -> int:
    from gait_biofeedback.io.bag import BagReader, BagRecoveryWarning
    from gait_biofeedback.io.bag_info import bag_info

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BagRecoveryWarning)  # printed below as DAMAGED lines
        with BagReader(args.bag) as reader:
            per_topic, bad = bag_info(reader)
            duration = reader.duration_ns * 1e-9
            damaged = [w for w in reader.warnings if w not in bad]
    total = sum(t.count for t in per_topic)
    print(f"{args.bag}: {total} messages, {duration:.2f} s, {len(per_topic)} topics")
    for t in per_topic:
        note = "" if t.from_stamps else " (log time)"
        if t.stamps_back:
            note += f"; {t.stamps_back} stamps not after the one before"
        print(f"  {t.topic:42s} {t.type_name:42s} {t.count:8d}  {t.rate_hz:7.1f} Hz{note}")
    for text in [*damaged, *bad]:
        print(f"DAMAGED: {text}")
    if damaged or bad:
        print(f"`gait-biofeedback repair {args.bag}` writes a whole copy of what is readable")
    return 1 if damaged or bad else 0


def cmd_repair(args: argparse.Namespace) -> int:
    from gait_biofeedback.io.bag import repair

    report = repair(args.bag)
    for entry in report["files"]:
        line = f"{entry['file']}: {entry['status']}, {plural(entry['messages'], 'message')}"
        if entry.get("damage"):
            line += f"; lost: {entry['damage']}"
        if entry.get("original"):
            line += f"; the original is kept as {entry['original']}"
        print(line)
    total = plural(report["message_count"], "message")
    metadata = ("(a single .mcap file: no metadata.yaml)" if report["metadata"] == "not a folder"
                else f"metadata.yaml {report['metadata']}")
    print(f"{report['path']}: {total}, {metadata}")
    if not report["message_count"]:
        print(f"repair: {report['path']} holds no message that can be read: nothing to analyse or report; "
              "record or import the session again", file=sys.stderr)
        return 1
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from gait_biofeedback.demo import run_demo

    return run_demo(bag=Path(args.bag), output=Path(args.output), speed=args.speed,
                    dashboard_port=args.dashboard_port)


def _calibration_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--calibrate-at", action="append", metavar="T:PROTOCOL",
                   help="press Calibrate T seconds into the recording with PROTOCOL (hip_flexion, walking "
                   "or auto = the one the movement shows; a time alone: auto), e.g. 36:hip_flexion = 1 s "
                   "after the demo's hip moves; 'auto' finds the first calibration (quiet standing, then a "
                   "protocol) and prints the windows it used; repeat to recalibrate")
    p.add_argument("--calibration", metavar="FILE",
                   help="calibration.yaml (as the calibration node saves it) in force from the start")


def _foxglove_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("--foxglove", type=int, nargs="?", const=FOXGLOVE_PORT, default=None, metavar="PORT",
                   help=f"serve the Foxglove live view (body in 3D, joint angles, events, cues, diagnostics) "
                   f"on 127.0.0.1:PORT [{FOXGLOVE_PORT}; 0 = any free port]; docs/foxglove.md")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="gait-biofeedback", description=DESCRIPTION,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("demo", help="simulate (or reuse) the demo recording, replay it through the "
                       "whole graph, record the outputs and print a summary")
    p.add_argument("--bag", default=str(DEMO_BAG), help="demo recording (made if missing) [%(default)s]")
    p.add_argument("--output", default=str(DEMO_OUTPUT), help="where the outputs are recorded [%(default)s]")
    p.add_argument("--speed", type=float, default=1.5,
                   help="replay speed factor [%(default)s; at 2 the whole graph needs 85-90 %% of a core and "
                        "this 2-core machine loses samples in some runs]")
    p.add_argument("--dashboard-port", type=int, default=0,
                   help="port of the live dashboard on 127.0.0.1 (0 = any free port; the log says which)")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("simulate", help="synthetic session with ground truth → MCAP recording")
    p.add_argument("-o", "--output", required=True, help="output bag folder (rosbag2: metadata.yaml + .mcap)")
    p.add_argument("--scenario", default="demo", help="what the subject does [%(default)s]")
    p.add_argument("--duration", type=float, default=None,
                   help="length, s, of a training session (the demo's calibration, then 50 s walking laps; "
                   "the default scenario becomes 'training') or of the walking of the walk and"
                   " hemiparetic scenarios")
    p.add_argument("--rate", type=float, default=100.0, help="IMU sampling rate, Hz [%(default)s]")
    p.add_argument("--seed", type=int, default=0, help="random seed (same seed, same file) [%(default)s]")
    p.add_argument("--no-mag", action="store_true", help="sensors without magnetometer")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output")
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("import", help="real recording (CSV/MAT) → the project's MCAP layout")
    p.add_argument("kind", help="qmt_fullbody, gaitmap, broad, ipol_gait, pyshoe, hapt, csv (with --mapping; "
                                ".csv or gzip-compressed .csv.gz), or auto (from the file name)")
    p.add_argument("path", help="the file to import")
    p.add_argument("-o", "--output", required=True, help="output bag folder (rosbag2: metadata.yaml + .mcap)")
    p.add_argument("--mapping", help="csv: YAML file mapping segments to columns")
    p.add_argument("--units", nargs="*", help="csv: e.g. acc=g gyr=deg/s mag=uT time=ms")
    p.add_argument("--rate", type=float, help="csv without a time column: sampling rate, Hz")
    p.add_argument("--trust-units", action="store_true", help="csv: import data that contradict their "
                   "units (resting acceleration, gyro range, Earth's field) with a warning instead of "
                   "refusing them")
    p.set_defaults(func=cmd_import)

    p = sub.add_parser("replay", help="run a recording through the node graph in this process")
    p.add_argument("bag", help="recording: rosbag2 folder or .mcap file")
    p.add_argument("--record", help="record every topic of the graph to this folder")
    p.add_argument("--speed", type=float, default=1.0, help="speed factor, 0 = as fast as possible")
    p.add_argument("--start", type=float, default=0.0, help="start at this many s into the recording")
    p.add_argument("--stop", type=float, default=0.0, help="stop at this many s (0 = the end)")
    p.add_argument("--params", default=None, help="ROS 2 parameter file, e.g. config/session.yaml")
    p.add_argument("--nodes", help="comma-separated processing nodes (default: all)")
    _foxglove_argument(p)
    _calibration_arguments(p)
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser(
        "analyze", help="process a recording offline (no ROS graph), same numbers as `replay`; report",
        description="Run a recording's raw IMU data through the same processing as the live node graph "
        "(orientation, calibration, joint angles, gait events, activity), straight from the file and "
        "without DDS, write the outputs as a bag with the graph's topics and print the session report. "
        "Joint angles and gait events need a calibration: say when the subject finished the calibration "
        "moves (--calibrate-at) or give a calibration.yaml from an earlier session (--calibration).")
    p.add_argument("bag", help="recording with /<segment>/imu/data_raw topics: rosbag2 folder or .mcap file")
    p.add_argument("-o", "--output", required=True, help="bag folder to write the outputs to")
    _calibration_arguments(p)
    p.add_argument("--params", default=None, help="ROS 2 parameter file, e.g. config/session.yaml")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output")
    p.add_argument("--no-tables", action="store_true", help="do not write the Parquet tables (strides, "
                   "joint angles, events, activity) into OUTPUT/tables")
    p.set_defaults(func=cmd_analyze)

    p = sub.add_parser(
        "tables", help="a session's strides, joint angles, events and activity as Parquet tables",
        description="Write strides.parquet, joint_angles.parquet, events.parquet and activity.parquet "
        "(docs/guide/report.md, Tables for analysis) of a recording of the graph or an analyze output "
        "(analyze writes them itself unless --no-tables).")
    p.add_argument("bag", help="recording of the graph or analyze output")
    p.add_argument("-o", "--output", default=None, help="folder for the tables [BAG/tables]")
    p.set_defaults(func=cmd_tables)

    p = sub.add_parser(
        "report", help="clinician's report of one or more sessions: report.html, report.pdf, strides.csv, "
        "joints.csv", description="Write the session report of the last SESSION (a recording of the graph "
        "or an analyze output) with a progress page over all of them (one patient's, first = baseline). "
        "The patient is named only by a pseudonymous code.")
    p.add_argument("sessions", nargs="+", metavar="SESSION", help="recording of the graph or analyze output")
    p.add_argument("-o", "--output", required=True, help="folder to write the report files to")
    p.add_argument("--patient-id", default="", help="pseudonymous patient code (overrides the patient block)")
    p.add_argument("--session-label", default="", help="label of the last session (overrides the block's)")
    p.add_argument("--labels", nargs="+", metavar="LABEL", help="a label per SESSION (default: folder names)")
    p.add_argument("--params", default=None, help="parameter file whose patient: block gives the header")
    p.add_argument("--norms", default=None, help="YAML of normative bands replacing the built-in ones")
    p.add_argument("--targets", default=None, help="targets of the offline cues [config/targets.yaml]")
    p.add_argument("--paretic-side", default="none", choices=("none", "left", "right"),
                   help="the patient's paretic side: the targets' 'paretic' bands and the paretic "
                   "asymmetry ratios refer to it [%(default)s]")
    p.add_argument("--overwrite", action="store_true", help="replace a report already in the output folder")
    p.add_argument("--date", default=None, metavar="'YYYY-MM-DD[ HH:MM]'",
                   help="the last session's date, for a recording whose clock holds none (imported, "
                   "simulated)")
    p.set_defaults(func=cmd_report)

    p = sub.add_parser(
        "batch", help="analyse many recordings in parallel on Dask (a local cluster or a scheduler): one "
        "analysis and report per session, a cohort table", description="Analyse every recording of "
        "INPUTS (a folder, searched recursively, or a glob; quote it) as `analyze` and `report` would, "
        "on Dask distributed workers: OUT/<session>/analysis (the output bag), OUT/<session>/report, "
        "OUT/<session>/session.json, and OUT/cohort.csv and OUT/cohort.parquet with one row per session. "
        "Sessions already done for the same recording are skipped; a failing one is reported and the "
        "others go on (exit 1 if any failed).")
    p.add_argument("inputs", metavar="GLOB_OR_DIR", help="folder of recordings, one recording, or a glob")
    p.add_argument("-o", "--output", required=True, help="folder for the sessions' outputs and the table")
    p.add_argument("--workers", type=int, default=None,
                   help="worker processes of the local cluster [one per core]")
    p.add_argument("--scheduler", metavar="ADDRESS", default=None,
                   help="run on the Dask scheduler at ADDRESS (e.g. tcp://10.0.0.5:8786) instead of a local "
                   "cluster; its workers need this package and the same paths")
    p.add_argument("--calibrate-at", action="append", metavar="T:PROTOCOL",
                   help="as for analyze, the same for every session [auto]")
    p.add_argument("--params", default=None, help="ROS 2 parameter file, the same for every session")
    p.add_argument("--no-report", action="store_true", help="no report files (the cohort row still)")
    p.set_defaults(func=cmd_batch)

    p = sub.add_parser(
        "tune", help="optimise an orientation filter's gains by particle swarm (thesis ch. 4) per sensor "
        "location, cross-validated by group", description="Particle swarm optimisation with the thesis' "
        "settings (50 particles, 50 iterations, inertia 0.73 damped by 0.99, learning coefficients 1.5) of "
        "the decision variables of thesis Table 5, on recordings with reference orientations, per location; "
        "prints the held-out RMSE per location and writes config/orientation_filters.yaml with --write.")
    p.add_argument("algorithm", choices=("madgwick", "mahony", "guo_fkf", "roetenberg_ikf"))
    p.add_argument("--scheme", default="two_level",
                   help="fixed (FOG), two_level (VST1), three_level (VST2), fuzzy (VST3), iae [two_level]")
    p.add_argument("--broad", metavar="DIR", help="BROAD trials (location 'board', written as the "
                   "algorithm's parameters for every sensor)")
    p.add_argument("--trials", help="comma-separated BROAD trial numbers (default: all in DIR)")
    p.add_argument("--simulated", type=int, default=0, metavar="N", help="N simulated subjects (groups)")
    p.add_argument("--sim-seconds", type=float, default=30.0, help="walking time per simulated subject [30]")
    p.add_argument("--locations", help="comma-separated locations to tune (default: all present)")
    p.add_argument("--seconds", type=float, default=None, help="score only this long after the motion "
                   "starts (faster tuning)")
    p.add_argument("--folds", type=int, default=3, help="cross-validation folds by group; 1 = none [3]")
    p.add_argument("--particles", type=int, default=50)
    p.add_argument("--iterations", type=int, default=50)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--write", nargs="?", const="", default=None, metavar="YAML",
                   help="store the result [config/orientation_filters.yaml]")
    p.add_argument("--verbose", action="store_true", help="progress on stderr even when not a terminal")
    p.set_defaults(func=cmd_tune)

    p = sub.add_parser("run", help="run the processing graph on live sensors (--driver) or live topics "
                       "until Ctrl-C")
    p.add_argument("--driver", metavar="SPEC", help=f"also run imu_driver: {DRIVER_SPECS} (its other "
                   "parameters, e.g. device_rate_hz: --params; docs/connecting_sensors.md)")
    p.add_argument("--frame-key-file", metavar="PATH", help="with --driver: take only frames signed with "
                   "the session key in PATH (imu_driver's 'frame_key_file'; docs/guide/live_sensors.md)")
    p.add_argument("--record", help="also record every topic to this bag folder")
    p.add_argument("--params", default=None, help="ROS 2 parameter file, e.g. config/session.yaml")
    p.add_argument("--nodes", help="comma-separated processing nodes (default: all; '' = none)")
    p.add_argument("--duration", type=float, default=0.0, help="stop after this many s (0 = at Ctrl-C)")
    _foxglove_argument(p)
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("stream-sim", help="send a recording as live sensors would, over UDP",
                       description="Send a recording's raw IMU samples in the imu_driver's wire format "
                       "(docs/guide/live_sensors.md) in real time, each sensor with its own device clock "
                       "(offset, drift), over a link with jitter, loss and reordering.")
    p.add_argument("bag", help="recording with /<segment>/imu/data_raw topics")
    p.add_argument("--to", metavar="udp:HOST:PORT", help="where the driver listens (--as ours and ngimu)")
    p.add_argument("--as", dest="as_", choices=("ours", "x-imu3", "ngimu", "shimmer"), default="ours",
                   help="the devices' protocol: ours (docs/guide/live_sensors.md), x-imu3 (fake x-IMU3s on "
                   "TCP that the driver connects to; the command to run is printed), ngimu (fake NGIMUs "
                   "sending OSC to --to) or shimmer (one fake Shimmer3 per segment on a pseudo-terminal, its "
                   "path printed, for `run --driver shimmer:...`); docs/connecting_sensors.md [ours]")
    p.add_argument("--ascii", action="store_true", help="--as x-imu3: ASCII data messages, not binary")
    p.add_argument("--source-port", type=int, default=0, help="--as ngimu: the first NGIMU sends from this "
                   "port of 127.0.0.1, the next from the port after, ... (0 = any free ports) [0]")
    p.add_argument("--offset-s", type=float, default=0.0,
                   help="device clock offset of the first sensor, s (sensor k: +0.1 k s)")
    p.add_argument("--drift-ppm", type=float, default=0.0,
                   help="device clock drift, ppm (+ for even sensors, - for odd ones)")
    p.add_argument("--jitter-ms", type=float, default=0.0,
                   help="delay of each datagram, uniform in [0, J] ms")
    p.add_argument("--loss", type=float, default=0.0, help="fraction of datagrams not sent")
    p.add_argument("--reorder", type=float, default=0.0,
                   help="fraction of datagrams held back two datagram periods (they arrive after later ones)")
    p.add_argument("--samples-per-frame", type=int, default=1, help="samples of one sensor per datagram")
    p.add_argument("--seed", type=int, default=0, help="random seed of jitter, loss and reordering")
    p.add_argument("--params", default=None, help="parameter file whose imu_driver 'sensors' gives the ids")
    p.add_argument("--frame-key-file", metavar="PATH", help="sign the frames (GBI2) with the session key "
                   "in PATH, as the driver's 'frame_key_file' expects")
    p.set_defaults(func=cmd_stream_sim)

    p = sub.add_parser("record", help="record live topics to a crash-safe MCAP bag until Ctrl-C")
    p.add_argument("-o", "--output", required=True, help="bag folder to create")
    p.add_argument("topics", nargs="*", help="topics to record (default: all)")
    p.set_defaults(func=cmd_record)

    p = sub.add_parser("params", help="every node's parameters (default, unit, range); check a params file")
    p.add_argument("nodes", nargs="*", help="nodes to list (default: all)")
    p.add_argument("--check", metavar="FILE", help="check a ROS 2 params file and print what it sets")
    p.set_defaults(func=cmd_params)

    p = sub.add_parser("info", help="topics, types, counts and rates (from the stamps) of a recording; "
                       "checks every chunk (exit 1 if any is damaged)")
    p.add_argument("bag")
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("repair", help="rebuild the index and metadata.yaml of a recording cut off by a crash")
    p.add_argument("bag")
    p.set_defaults(func=cmd_repair)
    return parser


def _show_warning(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                  file: Any = None, line: str | None = None) -> None:
    """A Python warning as one line for the user, without the source line it came from."""
    print(f"warning: {message}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``gait-biofeedback`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 1
    try:
        with warnings.catch_warnings():  # restores the default display when main returns (tests call it)
            warnings.showwarning = _show_warning
            return int(args.func(args) or 0)
    except FileExistsError as err:
        replaceable = hasattr(args, "overwrite") and "not empty" in str(err)
        hint = " (or pass --overwrite to replace it)" if replaceable else ""
        print(f"gait-biofeedback {args.command}: {err}{hint}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the output was piped into e.g. `head`, which has closed it
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115 (stays open until exit)
        return 0
    except (ValueError, OSError) as err:  # bad input, missing or unwritable files, a full disk: one line
        print(f"gait-biofeedback {args.command}: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
