"""The sampling stage: the MAP search and the walkers' start (:mod:`.start`), the emcee
run to convergence (:mod:`.sampler`, :mod:`.ensemble`), its moves (:mod:`.moves`) and the
importance draws that may end it early (:mod:`.importance`).
It takes a vectorised log-density of unbounded coordinates and a parameter space; it
knows nothing of lidar."""

from .importance import ImportanceSettings
from .sampler import SamplerRun, SamplerSettings, burn_in, run_sampler
from .start import MapEstimate, Mode, find_map, initial_ball, laplace_covariance

__all__ = [
    "ImportanceSettings",
    "MapEstimate",
    "Mode",
    "SamplerRun",
    "SamplerSettings",
    "burn_in",
    "find_map",
    "initial_ball",
    "laplace_covariance",
    "run_sampler",
]
