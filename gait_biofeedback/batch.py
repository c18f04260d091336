"""The public batch API: every pipeline step on whole recordings, in one import.

``from gait_biofeedback.batch import estimate_orientation, detect_gait_events, classify_activity``.
Scripts outside the package (your analyses, ``benchmarks/``) import from here only, so the
package's internal layout can change without breaking them; these names are kept stable and
documented in ``docs/api/index.md`` (the Batch API). Units SI, quaternions (w, x, y, z) Hamilton
sensor → world ENU, times in s from the first sample unless a stamp (int ns) is asked for
(``docs/conventions.md``).

Each step's streaming form (one sample at a time, as the nodes run it) is exported beside its
batch function; a batch function gives exactly what its stream gives when fed the same samples.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from gait_biofeedback.analyze import AnalysisResult, analyze_recording, parse_calibrate_at
from gait_biofeedback.core import quaternion
from gait_biofeedback.core.activity.monitor import (
    ActivityMonitor,
    ActivityState,
    UnitMismatchWarning,
    classify_activity,
)
from gait_biofeedback.core.body import BodyDimensions
from gait_biofeedback.core.calibration.foot import foot_calibration
from gait_biofeedback.core.calibration.sensor_to_segment import (
    PROTOCOLS,
    SegmentCalibrationResult,
    SessionCalibration,
    calibrate_segment,
    calibrate_session,
    helical_angle,
    mean_orientation,
    vertical_calibration,
)
from gait_biofeedback.core.calibration.windows import find_standing_then_motion
from gait_biofeedback.core.driver.clock import DeviceClock, map_device_time
from gait_biofeedback.core.driver.protocol import DeviceSample, FrameReader, decode_frame, encode_frame
from gait_biofeedback.core.driver.stream import DriverCore, DriverParams
from gait_biofeedback.core.gait.comparator import angular_velocity_events, sagittal_rate
from gait_biofeedback.core.gait.cycles import GaitCycle, GaitCycleTracker, cycles_from_event_times
from gait_biofeedback.core.gait.detect import detect_gait_events
from gait_biofeedback.core.gait.events import (
    INITIAL_CONTACT,
    TERMINAL_CONTACT,
    GaitEvent,
    GaitEventDetector,
    events_from_signal,
    foot_pitch_sine,
)
from gait_biofeedback.core.gait.matching import MATCH_TOLERANCE_S, EventScore, match_events
from gait_biofeedback.core.joints.angles import (
    JOINT_NAMES,
    JointAngleCalculator,
    align_headings,
    compute_joint_angles,
    joint_angles_from_segments,
    segment_orientations,
)
from gait_biofeedback.core.joints.relative_heading import (
    RelativeHeadingEstimator,
    estimate_joint_position,
    estimate_relative_heading,
    estimate_relative_orientation,
)
from gait_biofeedback.core.orientation.filters import ALGORITHMS, DEFAULT_ALGORITHM, estimate_orientation
from gait_biofeedback.core.orientation.filters.config import TUNED_PATH, filter_params, load_tuned
from gait_biofeedback.core.orientation.stream import SegmentOrientationTracker, track_orientation
from gait_biofeedback.core.segments import SEGMENTS, SIDES, ImuSeries
from gait_biofeedback.core.spatial.stream import (
    FootTrajectoryParams,
    FootTrajectoryStream,
    estimate_foot_trajectory,
)
from gait_biofeedback.core.spatial.strides import SpatialStride
from gait_biofeedback.core.stamps import ns_to_seconds, seconds_to_ns
from gait_biofeedback.io.bag import BagReader, BagWriter, read_imu_bag, write_imu_bag
from gait_biofeedback.io.importers import (
    QMT_FULLBODY_RATE_HZ,
    Recording,
    import_gaitmap,
    import_qmt_fullbody,
    import_recording,
)
from gait_biofeedback.report.analysis import (
    SessionAnalysis,
    analyse_session,
    gait_profile_score,
    gait_variable_score,
)
from gait_biofeedback.report.extract import NotASessionError, SessionData, read_session
from gait_biofeedback.report.session import SessionReport, format_report, session_report
from gait_biofeedback.sim.faults import (
    ClockStep,
    Dropout,
    Reorder,
    Spike,
    StampJump,
    inject,
    write_faulty_bag,
)
from gait_biofeedback.sim.recording import write_simulated_bag
from gait_biofeedback.sim.simulator import SCENARIOS, Phase, SimulatedSession, SimulationConfig, simulate
from gait_biofeedback.tuning.data import ReferenceRecording, broad_recordings, simulated_recordings
from gait_biofeedback.tuning.pso import PsoSettings, particle_swarm
from gait_biofeedback.tuning.run import tune as tune_gains

__all__ = [
    "ALGORITHMS",
    "DEFAULT_ALGORITHM",
    "INITIAL_CONTACT",
    "JOINT_NAMES",
    "MATCH_TOLERANCE_S",
    "PROTOCOLS",
    "QMT_FULLBODY_RATE_HZ",
    "SCENARIOS",
    "SEGMENTS",
    "SIDES",
    "TERMINAL_CONTACT",
    "TUNED_PATH",
    "ActivityMonitor",
    "ActivityState",
    "AnalysisResult",
    "BagReader",
    "BagWriter",
    "BatchOptions",
    "BatchResult",
    "BodyDimensions",
    "ClockStep",
    "DeviceClock",
    "DeviceSample",
    "DriverCore",
    "DriverParams",
    "Dropout",
    "EventScore",
    "FootTrajectoryParams",
    "FootTrajectoryStream",
    "FrameReader",
    "GaitCycle",
    "GaitCycleTracker",
    "GaitEvent",
    "GaitEventDetector",
    "ImuSeries",
    "JointAngleCalculator",
    "NotASessionError",
    "Patient",
    "Phase",
    "PsoSettings",
    "Recording",
    "ReferenceRecording",
    "RelativeHeadingEstimator",
    "Reorder",
    "SegmentCalibrationResult",
    "SegmentOrientationTracker",
    "SessionAnalysis",
    "SessionCalibration",
    "SessionData",
    "SessionReport",
    "SimulatedSession",
    "SimulationConfig",
    "SpatialStride",
    "Spike",
    "StampJump",
    "UnitMismatchWarning",
    "align_headings",
    "analyse_session",
    "analyze_recording",
    "angular_velocity_events",
    "broad_recordings",
    "calibrate_segment",
    "calibrate_session",
    "classify_activity",
    "compute_joint_angles",
    "cycles_from_event_times",
    "decode_frame",
    "detect_gait_events",
    "encode_frame",
    "estimate_foot_trajectory",
    "estimate_joint_position",
    "estimate_orientation",
    "estimate_relative_heading",
    "estimate_relative_orientation",
    "events_from_signal",
    "filter_params",
    "find_recordings",
    "find_standing_then_motion",
    "foot_calibration",
    "foot_pitch_sine",
    "format_report",
    "gait_profile_score",
    "gait_variable_score",
    "helical_angle",
    "import_gaitmap",
    "import_qmt_fullbody",
    "import_recording",
    "inject",
    "joint_angles_from_segments",
    "load_tuned",
    "map_device_time",
    "match_events",
    "mean_orientation",
    "ns_to_seconds",
    "parse_calibrate_at",
    "particle_swarm",
    "quaternion",
    "read_imu_bag",
    "read_session",
    "run_batch",
    "sagittal_rate",
    "seconds_to_ns",
    "segment_orientations",
    "session_report",
    "simulate",
    "simulated_recordings",
    "track_orientation",
    "tune_gains",
    "vertical_calibration",
    "write_faulty_bag",
    "write_imu_bag",
    "write_report",
    "write_simulated_bag",
]

# The report writer pulls in matplotlib and fpdf2 (0.7 s), the cohort runner Dask: imported on first use.
if TYPE_CHECKING:
    from gait_biofeedback.cohort.run import BatchResult, run_batch
    from gait_biofeedback.cohort.sessions import find_recordings
    from gait_biofeedback.cohort.task import BatchOptions
    from gait_biofeedback.report.build import Patient, write_report

_LAZY = {"Patient": "gait_biofeedback.report.build", "write_report": "gait_biofeedback.report.build",
         "run_batch": "gait_biofeedback.cohort.run", "BatchResult": "gait_biofeedback.cohort.run",
         "BatchOptions": "gait_biofeedback.cohort.task",
         "find_recordings": "gait_biofeedback.cohort.sessions"}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
