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
