#!/usr/bin/env bash
# Create or refresh .venv: pinned ROS 2 Jazzy wheels + numerics, this package (editable), and
# gait_biofeedback_msgs built from source into the venv. Needs only python3.11 (Debian 12's
# python3), gcc and cmake. Re-running is cheap: each step is skipped while its inputs are unchanged.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
VENV="$ROOT/.venv"
cd "$ROOT"

say() { printf '[setup] %s\n' "$*" >&2; }
die() { printf '[setup] ERROR: %s\n' "$*" >&2; exit 1; }

find_python() {
    for cand in "${PYTHON:-}" python3.11 python3; do
        [ -n "$cand" ] || continue
        command -v "$cand" >/dev/null 2>&1 || continue
        if "$cand" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' 2>/dev/null; then
            echo "$cand"; return 0
        fi
    done
    return 1
}

for tool in cmake gcc g++; do
    command -v "$tool" >/dev/null 2>&1 || die "$tool not found: apt-get install cmake gcc g++"
done

if [ ! -x "$VENV/bin/python" ]; then
    PY=$(find_python) || die "Python 3.11 not found (the ROS 2 Jazzy wheels are cp311): apt-get install python3 python3-venv python3-dev, or set PYTHON=/path/to/python3.11"
    say "creating $VENV with $PY"
    "$PY" -m venv "$VENV" || die "venv creation failed: apt-get install python3-venv"
fi
VPY="$VENV/bin/python"

stamp_of() { cat "$@" 2>/dev/null | sha256sum | cut -c1-16; }

# 1. Python packages (pinned)
req_stamp=$(stamp_of requirements.txt constraints.txt setup.py)
if [ "$(cat "$VENV/.stamp-pip" 2>/dev/null)" != "$req_stamp" ]; then
    say "installing pinned packages (about 30 s on a fresh venv)"
    "$VPY" -m pip install -q --disable-pip-version-check -r requirements.txt -c constraints.txt
    "$VPY" -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation -e .
    echo "$req_stamp" > "$VENV/.stamp-pip"
    rm -f "$VENV/.stamp-msgs"
fi

# 2. Interface package, built into the venv so nothing needs sourcing
msgs_stamp=$(stamp_of gait_biofeedback_msgs/CMakeLists.txt gait_biofeedback_msgs/package.xml \
    gait_biofeedback_msgs/msg/*.msg gait_biofeedback_msgs/srv/*.srv)
if [ "$(cat "$VENV/.stamp-msgs" 2>/dev/null)" != "$msgs_stamp" ]; then
    say "building gait_biofeedback_msgs into the venv (about 40 s)"
    "$VPY" scripts/repair_cmake_exports.py "$VENV"
    rm -rf build/gait_biofeedback_msgs
    log="$ROOT/build/gait_biofeedback_msgs.log"
    mkdir -p build
    if ! (export CMAKE_PREFIX_PATH="$VENV" AMENT_PREFIX_PATH="$VENV"
          cmake -S gait_biofeedback_msgs -B build/gait_biofeedback_msgs \
              -DCMAKE_INSTALL_PREFIX="$VENV" -DPython3_EXECUTABLE="$VPY" -DBUILD_TESTING=OFF \
          && cmake --build build/gait_biofeedback_msgs -j2 \
          && cmake --install build/gait_biofeedback_msgs) >"$log" 2>&1; then
        tail -30 "$log" >&2
        die "building gait_biofeedback_msgs failed; full log in $log"
    fi
    "$VPY" -c 'from gait_biofeedback_msgs.msg import GaitEvent; from gait_biofeedback_msgs.srv import Calibrate' \
        || die "gait_biofeedback_msgs was built but does not import from the venv"
    echo "$msgs_stamp" > "$VENV/.stamp-msgs"
fi
say "environment ready: $VENV"
