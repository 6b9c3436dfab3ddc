"""The continuity study's scan (``studies/continuity.py``): it finds a step where there is
one, and nothing on a smooth function."""

import numpy as np


def test_a_scan_measures_a_jump_and_ignores_smooth_curvature():
    import continuity  # studies/continuity.py (pyproject's pythonpath)

    def log_likelihood(u):
        smooth = -0.5 * np.sum(u**2, axis=1) * 1e3  # sharply curved, but smooth
        jump = np.where(u[:, 1] > 0.3, -2.5, 0.0)  # a cliff across u₁ = 0.3
        outside = np.where(u[:, 0] > 0.9, np.nan, 0.0)  # the support ends at u₀ = 0.9
        return smooth + jump + outside

    points = np.array([[0.0, 0.3], [0.0, 0.0], [0.95, 0.0]])
    steps = continuity.scan_steps(log_likelihood, points, 1, 2e-3, 201)
    assert steps[0] > 1.0  # the jump (half of it lands on each neighbouring difference)
    assert steps[1] < 1e-6
    assert np.isnan(steps[2])
    along = continuity.scan_steps(log_likelihood, points[:2], 0, 2e-3, 201)
    assert np.all(along < 1e-6)
