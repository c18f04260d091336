"""Optional numba compilation of per-sample kernels, one source for both runtimes.

A kernel module is written in the subset of Python that numba compiles (loops, ``math``, small numpy
arrays), so it runs unchanged as plain Python. :func:`fast` compiles the named functions of such a
module (lazily, on first use, cached on disk) and returns the compiled entry point, or the Python one
when numba is missing, ``GAIT_BIOFEEDBACK_NO_NUMBA`` is set, or compiling the warm-up call fails.
Importing this module never imports numba.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from types import ModuleType
from typing import Any

_DONE: dict[tuple[str, str], Callable[..., Any]] = {}


def fast(
    module: ModuleType, entry: str, warmup: Sequence[Any], helpers: Sequence[str] = ()
) -> Callable[..., Any]:
    """``module.entry`` compiled with numba (its ``helpers`` too: the functions it calls), checked by one
    call on ``warmup``; the plain Python function when that is not possible."""
    key = (module.__name__, entry)
    if key not in _DONE:
        original = {name: getattr(module, name) for name in (*helpers, entry)}
        out = original[entry]
        if not os.environ.get("GAIT_BIOFEEDBACK_NO_NUMBA"):
            try:
                import numba

                for name, fn in original.items():  # numba resolves the helpers through the module globals
                    if not hasattr(fn, "py_func"):  # not compiled yet (by another entry point)
                        setattr(module, name, numba.njit(cache=True, nogil=True)(fn))
                getattr(module, entry)(*warmup)
                out = getattr(module, entry)
            except Exception:  # any failure → the pure-Python functions
                for name, fn in original.items():
                    setattr(module, name, fn)
        _DONE[key] = out
    return _DONE[key]
