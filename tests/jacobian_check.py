"""A slow, obviously correct check of a parameter space's log-Jacobian."""

import numpy as np
import pytest


def assert_exact_jacobian(space, u, log_jac, step=1e-6):
    """log|det ∂x/∂u| of rows u against central finite differences."""
    for row, expected in zip(u, log_jac):
        jacobian = np.empty((space.ndim, space.ndim))
        for j in range(space.ndim):
            du = np.zeros(space.ndim)
            du[j] = step
            up, down = space.from_unbounded(row + du)[0], space.from_unbounded(row - du)[0]
            jacobian[:, j] = (up[0] - down[0]) / (2 * step)
        assert np.linalg.slogdet(jacobian)[1] == pytest.approx(expected, abs=1e-5)


def assert_log_derivative(function, at, log_jac, step=1e-6, atol=1e-6):
    """log|f′| of an elementwise map ``function`` at points ``at`` against central
    differences."""
    slope = (function(at + step) - function(at - step)) / (2 * step)
    np.testing.assert_allclose(log_jac, np.log(np.abs(slope)), atol=atol)


def assert_same_posterior(problems, x, least_finite=16):
    """Two problems that differ only in their sampling coordinates: at the same physical
    rows ``x`` their log-posteriors differ by the log-Jacobians alone, finite on the same
    rows, and their blobs (the expected waveform's quantities) are the same."""
    rows = []
    for problem in problems:
        u = problem.space.to_unbounded(x)
        _, log_jac = problem.space.from_unbounded(u)
        out = problem.log_posterior(u)
        rows.append((out[:, 0] - log_jac, out[:, 1:]))
    finite = np.isfinite(rows[0][0])
    assert finite.sum() >= least_finite
    np.testing.assert_array_equal(finite, np.isfinite(rows[1][0]))
    np.testing.assert_allclose(rows[0][0][finite], rows[1][0][finite], rtol=1e-10, atol=1e-8)
    np.testing.assert_allclose(rows[0][1][finite], rows[1][1][finite], rtol=1e-10, atol=1e-10)
