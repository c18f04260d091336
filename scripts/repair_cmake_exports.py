"""Repair the CMake exports of the ROS 2 wheels so CMake can build interfaces in this venv.

The PyPI wheels' ``share/*/cmake/*.cmake`` files name include directories of the machine that
built them (``/opt/python/cp3X-cp3X/include/python3.X`` and that machine's numpy include dir).
Replace them with this interpreter's. Idempotent; exits non-zero with a message when the layout is
not what this script knows (so the set-up fails loudly instead of building against wrong paths).
"""

from __future__ import annotations

import re
import sys
import sysconfig
from pathlib import Path

import numpy

PYTHON_INCLUDE = re.compile(r"/opt/python/cp3\d+-cp3\d+/include/python3\.\d+")
NUMPY_INCLUDE = re.compile(r"/opt/python/cp3\d+-cp3\d+/lib/python3\.\d+/site-packages/numpy/_core/include")


def main(prefix: str) -> int:
    share = Path(prefix) / "share"
    python_include = sysconfig.get_paths()["include"]
    numpy_include = numpy.get_include()
    for needed in (python_include, numpy_include):
        if not Path(needed, "Python.h" if needed == python_include else "numpy").exists():
            print(f"repair_cmake_exports: {needed} lacks its headers; install python3-dev", file=sys.stderr)
            return 2
    files = sorted(share.glob("*/cmake/*.cmake"))
    if not files:
        print(f"repair_cmake_exports: no CMake exports under {share}: is this a ROS venv?", file=sys.stderr)
        return 2
    changed = 0
    for path in files:
        text = path.read_text()
        if "/opt/python/" not in text:
            continue
        new = NUMPY_INCLUDE.sub(numpy_include, PYTHON_INCLUDE.sub(python_include, text))
        if "/opt/python/" in new:
            line = next(x for x in new.splitlines() if "/opt/python/" in x)
            print(f"repair_cmake_exports: unknown build path left in {path}:\n  {line.strip()}\n"
                  "the wheel layout changed; update scripts/repair_cmake_exports.py", file=sys.stderr)
            return 2
        path.write_text(new)
        changed += 1
    print(f"repair_cmake_exports: {changed} file(s) repaired, {len(files)} checked")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else sys.prefix))
