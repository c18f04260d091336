"""Optional numba compilation of per-sample kernels, one source for both runtimes; the project's one
loader of numba functions.

A kernel module is written in the subset of Python that numba compiles (loops, ``math``, small numpy
arrays), so it runs unchanged as plain Python. :func:`compiled` compiles the named functions of such
a module (lazily, on first use, ``cache=True``: numba's disk cache, ``NUMBA_CACHE_DIR`` if set) and
returns the compiled entry point, or None when numba is missing, ``GAIT_BIOFEEDBACK_NO_NUMBA`` is set,
or compiling the warm-up call fails; :func:`fast` returns the plain Python function instead of None.
The compiled functions replace the Python ones in their module (numba resolves a kernel's calls of its
helpers through the module's globals); :func:`plain` gives the Python one back. Each function is
compiled once per process. Importing this module never imports numba.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from types import ModuleType
from typing import Any

_DONE: dict[tuple[str, str], Callable[..., Any] | None] = {}
_PLAIN: dict[tuple[str, str], Callable[..., Any]] = {}


def plain(module: ModuleType, name: str) -> Callable[..., Any]:
    """The plain Python ``module.name``, also once :func:`compiled` has replaced it in the module."""
    return _PLAIN.get((module.__name__, name)) or getattr(module, name)


def compiled(
    module: ModuleType, entry: str, warmup: Sequence[Any], helpers: Sequence[str] = ()
) -> Callable[..., Any] | None:
    """``module.entry`` compiled with numba (its ``helpers`` too: the functions it calls), checked by one
    call on ``warmup``; None when that is not possible (the module keeps its Python functions)."""
    key = (module.__name__, entry)
    if key not in _DONE:
        out = None
        if not os.environ.get("GAIT_BIOFEEDBACK_NO_NUMBA"):
            original = {name: getattr(module, name) for name in (*helpers, entry)}
            try:
                import numba

                for name, fn in original.items():
                    if not hasattr(fn, "py_func"):  # not compiled yet (by another entry point)
                        _PLAIN[(module.__name__, name)] = fn
                        setattr(module, name, numba.njit(cache=True, nogil=True)(fn))
                getattr(module, entry)(*warmup)
                out = getattr(module, entry)
            except Exception:  # any failure → the pure-Python functions
                for name, fn in original.items():
                    setattr(module, name, fn)
        _DONE[key] = out
    return _DONE[key]


def fast(
    module: ModuleType, entry: str, warmup: Sequence[Any], helpers: Sequence[str] = ()
) -> Callable[..., Any]:
    """:func:`compiled`, or the plain Python ``module.entry`` when it gives None."""
    return compiled(module, entry, warmup, helpers) or plain(module, entry)
