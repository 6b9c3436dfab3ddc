"""The one switch between a numpy reference and its compiled (numba) twin.

A process computed two ways lives in one module under one public name: the numpy code
is the reference, obviously correct and vectorised over rows; the kernel computes the
same numbers row by row, compiled with numba, and saves numpy's per-call overhead where a
sampler asks for a few rows at a time. Every such function takes ``backend=`` and
:func:`resolve` turns the user's choice into ``"numpy"`` or ``"numba"``:

- ``"numba"``: the compiled kernel (an ImportError where numba is missing);
- ``"numpy"``: the reference;
- ``"auto"`` (the default everywhere): numba where it can be imported.

Kernels are marked with :func:`jit`, every compiled kernel of :mod:`forward` (the
expected model's, the ground pulse of :func:`forward.pulse.point_returns`, the explicit
engine's column kernel) and of ``lidarinv``. Numba compiles each on its first call and
caches it on disk (``cache=True``), so the first run of a program compiles it once and
later runs load it; a program that only uses the numpy paths never compiles one. One
large kernel may live in a module of its own beside its reference
(:mod:`forward.explicit.column_kernel_numba`), still chosen by :func:`resolve` in the
reference's module. Without
numba, :func:`jit` returns the plain Python function and ``"auto"`` resolves to numpy.
:mod:`lidarinv.testing` checks every compiled path against its reference.
"""

import importlib.util

import numpy as np

#: Whether numba is installed.
AVAILABLE = importlib.util.find_spec("numba") is not None

#: The backend names a ``backend=`` argument takes.
BACKENDS = ("auto", "numba", "numpy")


def resolve(backend) -> str:
    """``"numba"`` or ``"numpy"`` for a ``backend=`` argument.

    Parameters
    ----------
    backend : str
        One of :data:`BACKENDS`.

    Returns
    -------
    str
        ``"numba"`` for ``"numba"``, and for ``"auto"`` where numba is installed;
        ``"numpy"`` otherwise.

    Raises
    ------
    ValueError
        For a name not in :data:`BACKENDS`.
    ImportError
        For ``"numba"`` without numba installed.
    """
    if backend not in BACKENDS:
        raise ValueError(f"backend must be 'auto', 'numba' or 'numpy', got {backend!r}")
    if backend == "numba" and not AVAILABLE:
        raise ImportError("backend='numba' needs numba installed")
    return "numba" if backend != "numpy" and AVAILABLE else "numpy"


def as_float64(x):
    """``x`` as a C-contiguous float64 array (no copy if it already is one), as the
    compiled kernels take their arrays.

    Parameters
    ----------
    x : array_like

    Returns
    -------
    numpy.ndarray
    """
    return np.ascontiguousarray(x, dtype=np.float64)


def jit(function=None, **options):
    """``numba.njit(cache=True, **options)`` of ``function`` where numba is installed,
    else ``function`` itself; usable as ``@jit`` or ``@jit(error_model="numpy")``.

    Parameters
    ----------
    function : callable, optional
        The kernel's Python source: scalar loops over arrays, as numba compiles them.
    **options
        Passed to :func:`numba.njit`.

    Returns
    -------
    callable
        A numba dispatcher, compiled on its first call; the same one for every call with
        the same function and options, so that several kernels can call one function.
    """
    if function is None:
        return lambda f: jit(f, **options)
    if not AVAILABLE:
        return function
    key = (function, tuple(sorted(options.items())))
    if key not in _DISPATCHERS:  # one dispatcher per function: kernels share it
        from numba import njit

        _DISPATCHERS[key] = njit(cache=True, **options)(function)
    return _DISPATCHERS[key]


_DISPATCHERS = {}
