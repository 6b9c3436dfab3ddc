"""Say so when the numerical kernels are about to be compiled (a cold numba cache).

Numba compiles each kernel on its first call and keeps it in its on-disk cache (the
kernels are marked ``cache=True`` by :func:`forward.backends.jit`), so the first run after
an installation spends most of a minute compiling without a word; later runs load the
cache. :func:`announce_compilation` prints one line to stderr before that minute.
"""

import os
import sys

#: Share of the registered kernels that must be uncached for the notice.
COLD_SHARE = 0.5

#: The line printed before a cold compilation.
NOTICE = "compiling numerical kernels (first run only; numba keeps them in its cache)…"


def _is_cold(dispatcher) -> bool:
    """A dispatcher neither compiled in this process nor cached on disk."""
    if getattr(dispatcher, "signatures", None):
        return False
    try:
        index = dispatcher._cache._cache_file._index_path  # numba's cache index file
    except AttributeError:
        return False  # not a caching dispatcher, or another numba: say nothing
    return not os.path.exists(index)


def cold_kernels() -> list:
    """Names of the registered kernels (:func:`forward.backends.jit`) that the next call
    would compile: neither compiled in this process nor found in numba's cache."""
    from forward import backends

    if not backends.AVAILABLE:
        return []
    dispatchers = backends._DISPATCHERS.values()
    return [getattr(d, "__name__", repr(d)) for d in dispatchers if _is_cold(d)]


def announce_compilation(prefix="lidarinv", stream=None) -> bool:
    """Print :data:`NOTICE` to ``stream`` (stderr) when most kernels will be compiled
    (at least :data:`COLD_SHARE` of them uncached); returns whether it did."""
    from forward import backends

    cold = cold_kernels()
    if not cold or len(cold) < COLD_SHARE * len(backends._DISPATCHERS):
        return False
    print(f"{prefix}: {NOTICE}", file=stream or sys.stderr, flush=True)
    return True
