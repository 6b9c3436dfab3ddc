"""What the inversion asks of a likelihood.

A likelihood owns its noise model: it is built from the shot's window and measured noise
(:meth:`Likelihood.for_shot`), and the results stage (predictive bands and check, the
footprint's own waveform), the model error and the posterior call the methods below,
never its internals. A new likelihood is one module with a class of this shape and one
entry in :data:`lidarinv.inference.likelihood.LIKELIHOODS`.
"""

from typing import Protocol

import numpy as np


class Likelihood(Protocol):
    """The likelihood of one shot's window, for rows of model waveforms W.

    ``values`` below is a dict of arrays (n,) with ``gain`` (unless integrated out),
    ``baseline`` and ``noise_sigma`` (DN).
    """

    #: The window's bins, samples and which are censored or saturated (:class:`..shot.WindowData`).
    data: object
    #: Shot-noise variance per unit signal, g (DN).
    shot_factor: float

    @classmethod
    def for_shot(cls, window, noise, settings, fixed_discrepancy=None) -> "Likelihood":
        """The likelihood of a window, its noise model fitted to the measured ``noise``."""

    def log_likelihood(self, signal, values) -> tuple[np.ndarray, np.ndarray | None]:
        """log p(y | row) (n,), and each row's gain fit where the gain is integrated out."""

    def predictive_moments(self, signal, values) -> tuple[np.ndarray, np.ndarray]:
        """The samples' predictive mean (DN) and per-bin variance (DN²), (n, bins) each."""

    def replicate(self, signal, values, rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One replicated observation per row, with the moments it was drawn from."""

    def discrepancy_given_data(self, signal, values, rng) -> np.ndarray:
        """Draws of the footprint's model discrepancy given the samples (n, bins) (DN)."""

    def draw_gain(self, fit, rng) -> np.ndarray:
        """Gains drawn from p(a | θ, y) where the gain is integrated out."""

    def with_fixed_discrepancy(self, fixed_discrepancy) -> "Likelihood":
        """The same likelihood with a discrepancy variance (bins,) or covariance fixed."""

    def with_gain_prior(self, gain_prior) -> "Likelihood":
        """The same likelihood with the gain integrated out against ``gain_prior``."""

    @property
    def holds_noise(self) -> bool:
        """The noise mean and σ are held at the shot's estimates, not sampled."""

    @property
    def marginalises_gain(self) -> bool:
        """The gain is integrated out."""

    @property
    def gain_obstacle(self) -> str | None:
        """Why the gain cannot be integrated out, or None if it can."""

    @property
    def conditioning_obstacle(self) -> str | None:
        """Why the discrepancy cannot be drawn given the data, or None if it can."""

    @property
    def notes(self) -> list:
        """Flags for the result: what the likelihood simplified."""
