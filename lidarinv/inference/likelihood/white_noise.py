"""A Gaussian likelihood that takes the read noise as white, whatever the shot measured
(the likelihood of earlier releases, to compare against the correlated one)."""

from .gaussian import ShotLikelihood


class WhiteNoiseLikelihood(ShotLikelihood):
    """:class:`.gaussian.ShotLikelihood` with the read noise taken as white."""

    @classmethod
    def for_shot(cls, window, noise, settings, fixed_discrepancy=None) -> "WhiteNoiseLikelihood":
        return cls(window, settings.shot_factor, settings.discrepancy, fixed_discrepancy)
