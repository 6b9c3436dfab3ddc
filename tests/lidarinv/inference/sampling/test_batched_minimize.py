"""Optimisations in lockstep (sampling.batched_minimize): the same answers as one at a time, in
fewer batched calls."""

import numpy as np
import pytest
from scipy.optimize import minimize, rosen, rosen_der

from lidarinv.inference.sampling.batched_minimize import minimize_in_lockstep


class Rosenbrock:
    """Batched Rosenbrock with a call counter."""

    def __init__(self):
        self.calls, self.rows = 0, 0

    def __call__(self, points):
        self.calls += 1
        self.rows += len(points)
        return np.array([rosen(x) for x in points]), np.array([rosen_der(x) for x in points])


STARTS = np.random.default_rng(0).uniform(-2.0, 2.0, (12, 4))


def test_each_run_matches_minimize_alone_in_far_fewer_calls():
    batched = Rosenbrock()
    together = minimize_in_lockstep(batched, STARTS, method="L-BFGS-B", options={"maxiter": 200})
    alone_calls = 0
    for start, result in zip(STARTS, together):
        alone = minimize(
            lambda x: (rosen(x), rosen_der(x)),
            start,
            jac=True,
            method="L-BFGS-B",
            options={"maxiter": 200},
        )
        alone_calls += alone.nfev
        np.testing.assert_array_equal(result.x, alone.x)
        assert result.nfev == alone.nfev and result.fun == alone.fun
    assert batched.rows == alone_calls  # the same evaluations...
    assert batched.calls <= max(r.nfev for r in together)  # ...in one call per round


def test_runs_of_different_lengths_do_not_stall_each_other():
    batched = Rosenbrock()
    starts = np.vstack([np.ones(4), STARTS[:3]])  # the first starts at the optimum
    results = minimize_in_lockstep(batched, starts, method="L-BFGS-B")
    assert results[0].nfev < results[1].nfev
    assert all(r.success for r in results)


def test_an_error_in_the_objective_ends_every_run_and_is_raised():
    def failing(points):
        if failing.calls == 3:
            raise FloatingPointError("model blew up")
        failing.calls += 1
        return Rosenbrock()(points)

    failing.calls = 0
    with pytest.raises(FloatingPointError, match="blew up"):
        minimize_in_lockstep(failing, STARTS[:5], method="L-BFGS-B")
