"""The likelihood stage: the Gaussian likelihood of a shot's window (:mod:`.gaussian`,
its row terms :mod:`.gaussian_rows`), with the gain integrated out (:mod:`.marginal`), a
discrepancy per bin (:mod:`.discrepancy`) or a covariance between bins
(:mod:`.covariance`), correlated read noise (:mod:`.ar_noise`), replicated observations
(:mod:`.predictive`) and the footprint's discrepancy given the data
(:mod:`.conditional`). Every likelihood has the shape of :class:`.protocol.Likelihood`;
:data:`LIKELIHOODS` names them (``InversionSettings.likelihood``)."""

from .gaussian import ShotLikelihood
from .protocol import Likelihood

#: The likelihoods an inversion can use, by name.
LIKELIHOODS = {"gaussian": ShotLikelihood}

__all__ = ["LIKELIHOODS", "Likelihood", "ShotLikelihood"]
