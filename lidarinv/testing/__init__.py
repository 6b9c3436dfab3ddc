"""Slow, obviously correct references, and the one check of a fast path against them.

For lidarinv's tests and studies alike (as celerite2 ships ``testing.py``): nothing else
in the package imports it. Every fast path is checked against a reference that is slow
and plain:

- each compiled kernel against its numpy twin, through the one ``backend=`` switch of
  :mod:`forward.backends` (:func:`assert_backends_agree`);
- the compiled likelihood against :func:`row_log_likelihood_reference`, the Gaussian
  density written out (:func:`log_likelihood`, scipy's ``log_ndtr`` for censored and
  saturated bins);
- the compiled relative heights against :func:`relative_heights_reference`, the RH of
  record (:func:`lidarinv.observe.metrics.rh_metrics`) row by row;
- the waveform engines against :func:`.reference_model.reference_waveform`, the
  brute-force column model (re-exported here).

:mod:`.fake_inversion` is a stand-in inversion for the batch machinery (picklable, with
scripted failures and delays).

:func:`assert_fast_path` is the single check: it runs both on copies of the arguments and
compares what they return and what they change in place (accumulators).
"""

import copy
import dataclasses
from functools import partial

import numpy as np
from scipy.special import log_ndtr

from lidarinv.observe.metrics import rh_metrics

from .reference_model import reference_waveform

__all__ = [
    "assert_backends_agree",
    "assert_fast_path",
    "dense_log_likelihood",
    "log_likelihood",
    "reference_waveform",
    "relative_heights_reference",
    "row_log_likelihood_reference",
]

LOG_2PI = np.log(2.0 * np.pi)


def _compare(fast, reference, rtol, atol, where):
    """Assert that two results (arrays, scalars, tuples, lists, dicts) agree."""
    if isinstance(reference, dict):
        assert fast.keys() == reference.keys(), f"{where}: keys differ"
        for key in reference:
            _compare(fast[key], reference[key], rtol, atol, f"{where}[{key!r}]")
    elif isinstance(reference, (tuple, list)):
        assert len(fast) == len(reference), f"{where}: lengths differ"
        for i, (a, b) in enumerate(zip(fast, reference)):
            _compare(a, b, rtol, atol, f"{where}[{i}]")
    elif reference is None or isinstance(reference, (str, bool)):
        assert fast == reference, f"{where}: {fast!r} != {reference!r}"
    elif dataclasses.is_dataclass(reference):
        for item in dataclasses.fields(reference):
            name = item.name
            _compare(getattr(fast, name), getattr(reference, name), rtol, atol, f"{where}.{name}")
    elif not isinstance(reference, (int, float, complex, np.ndarray, np.generic)):
        return  # an object passed through (a pulse, a settings record): nothing to compare
    else:
        a, b = np.asarray(fast), np.asarray(reference)
        if b.dtype == bool or a.dtype == bool:
            np.testing.assert_array_equal(a, b, err_msg=where)
        else:
            np.testing.assert_allclose(a, b, rtol=rtol, atol=atol, err_msg=where)


def assert_fast_path(fast, reference, *args, rtol=1e-12, atol=0.0, **kwargs):
    """Check a fast path against its reference.

    Parameters
    ----------
    fast, reference : callable
        The fast path and the slow reference, called with the same arguments.
    *args, **kwargs
        The arguments; each call gets its own deep copy, so that arrays a function
        updates in place are compared too.
    rtol, atol : float
        Tolerances of the comparison (:func:`numpy.testing.assert_allclose`).

    Returns
    -------
    The reference's result (for further assertions).
    """
    fast_args, fast_kwargs = copy.deepcopy((args, kwargs))
    ref_args, ref_kwargs = copy.deepcopy((args, kwargs))
    got = fast(*fast_args, **fast_kwargs)
    expected = reference(*ref_args, **ref_kwargs)
    _compare(got, expected, rtol, atol, "result")
    _compare(fast_args, ref_args, rtol, atol, "arguments changed in place")
    _compare(fast_kwargs, ref_kwargs, rtol, atol, "arguments changed in place")
    return expected


def assert_backends_agree(function, *args, rtol=1e-12, atol=0.0, **kwargs):
    """:func:`assert_fast_path` of ``function(..., backend="numba")`` against
    ``function(..., backend="numpy")``: a compiled kernel against its numpy twin."""
    return assert_fast_path(
        partial(function, backend="numba"),
        partial(function, backend="numpy"),
        *args,
        rtol=rtol,
        atol=atol,
        **kwargs,
    )


def log_likelihood(data, mean, variance) -> np.ndarray:
    """Reference log-likelihood of each row of model ``mean`` and ``variance`` (n, n_bins)
    (DN, DN²) for a window ``data``: Gaussian densities for the exact bins, log Φ((floor −
    μ)/s) for censored and log Φ((μ − max)/s) for saturated ones."""
    sd = np.sqrt(variance)
    total = np.zeros(mean.shape[0])
    exact = data.exact
    if exact.any():
        r = (data.samples[exact] - mean[:, exact]) / sd[:, exact]
        total -= 0.5 * np.sum(r * r + LOG_2PI, axis=1) + np.sum(np.log(sd[:, exact]), axis=1)
    if data.censored.any():
        c = data.censored
        total += np.sum(log_ndtr((data.floor - mean[:, c]) / sd[:, c]), axis=1)
    if data.saturated.any():
        s = data.saturated
        total += np.sum(log_ndtr((mean[:, s] - data.saturation) / sd[:, s]), axis=1)
    return total


def row_log_likelihood_reference(
    data, signal, gain, baseline, noise_sigma, shot_factor=0.0, discrepancy_scale=0.0,
    fixed_variance=None, unit=None,
) -> np.ndarray:  # fmt: skip
    """Reference of :func:`lidarinv.inference.likelihood.gaussian.row_log_likelihood`, with
    its arguments: the mean b·unit + a·W and the variance σn² + g·a·W + (η·a·W)² + v
    written out, then :func:`log_likelihood`."""
    unit = np.ones(data.samples.size) if unit is None else np.asarray(unit)
    fixed = 0.0 if fixed_variance is None else np.asarray(fixed_variance)
    scaled = np.asarray(gain)[:, None] * signal
    mean = np.asarray(baseline)[:, None] * unit + scaled
    variance = np.asarray(noise_sigma)[:, None] ** 2 + shot_factor * scaled
    variance = variance + (discrepancy_scale * scaled) ** 2 + fixed
    return log_likelihood(data, mean, variance)


def relative_heights_reference(signal, axis, ground, levels=(0.5, 0.98)) -> np.ndarray:
    """RH of each row by :func:`lidarinv.observe.metrics.rh_metrics` over the whole window
    (heights above ``ground``, m, at energy fractions ``levels``); NaN for rows without
    positive energy."""
    signal = np.atleast_2d(signal)
    out = np.full((signal.shape[0], len(levels)), np.nan)
    percentiles = 100.0 * np.asarray(levels, float)
    for r, row in enumerate(signal):
        if np.clip(row, 0.0, None).sum() > 0:
            out[r] = rh_metrics(row, axis, float(ground[r]), percentiles=percentiles)
    return out


def dense_log_likelihood(
    samples, signal, gain, baseline, noise_sigma, correlation, covariance=None
):
    """Reference log-likelihood of rows of model waveforms under correlated noise: the
    multivariate normal N(b + a·W, σn²·Σ + C) with Σ the noise's dense Toeplitz
    correlation matrix (bins × bins) and C a discrepancy covariance (DN²), by scipy."""
    from scipy.stats import multivariate_normal

    bins = samples.size
    out = np.empty(signal.shape[0])
    for r in range(signal.shape[0]):
        cov = noise_sigma[r] ** 2 * correlation
        if covariance is not None:
            cov = cov + covariance
        mean = baseline[r] + gain[r] * signal[r]
        out[r] = multivariate_normal(mean, cov).logpdf(samples)
    assert correlation.shape == (bins, bins)
    return out
