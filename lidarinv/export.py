"""Export a shot's posterior to other tools: ArviZ (optional: ``pip install "lidarinv[arviz]"``).

>>> from lidarinv.export import to_inference_data          # doctest: +SKIP
>>> idata = to_inference_data(InversionResult.load("post.h5", "shot_0"))
>>> arviz.summary(idata, var_names=["cover", "top_height"])

The stored posterior samples are the chain after burn-in, thinned by τ/2 and pooled over
the walkers, so they are nearly independent draws: they become one chain of
``draw`` samples (ArviZ's between-chain diagnostics such as R-hat need several chains and
do not apply; the sampler's own diagnostics are kept as attributes).
"""

import json

import numpy as np

__all__ = ["read_inference_data", "to_inference_data"]


def _arviz():
    try:
        import arviz
    except ImportError as error:
        raise ImportError(
            "exporting to ArviZ needs arviz: pip install 'lidarinv[arviz]'"
        ) from error
    return arviz


def to_inference_data(result):
    """An ``arviz.InferenceData`` of one shot's posterior.

    Parameters
    ----------
    result : lidarinv.inference.InversionResult
        E.g. ``InversionResult.load(path, "shot_<id>")``, or a batch file's shot through
        :func:`lidarinv.batch.read_result`.

    Returns
    -------
    arviz.InferenceData
        ``posterior``: every free parameter and derived quantity, dims ``(chain, draw)``
        with one chain; ``sample_stats``: ``lp`` (the log-posterior density of each
        draw); ``observed_data``: ``waveform`` (DN) on the ``height`` coordinate (m, the
        window's axis); ``constant_data``: the fixed parameters. Attributes: the shot id,
        the units of each quantity (JSON), whether the chain converged, its τ and
        ``lidarinv_version``.

    Raises
    ------
    ImportError
        If arviz is not installed.
    """
    arviz = _arviz()
    posterior = {
        name: result.column(name)[np.newaxis, :].astype(float) for name in result.quantity_names
    }
    attrs = {
        "shot_id": str(result.shot_id),
        "units": json.dumps({k: result.units.get(k, "") for k in result.quantity_names}),
        "converged": int(result.converged),
        "max_tau_steps": float(np.max(result.diagnostics.get("tau", [np.nan]))),
        "lidarinv_version": str(result.version),
    }
    return arviz.from_dict(
        posterior=posterior,
        sample_stats={"lp": np.asarray(result.log_prob, float)[np.newaxis, :]},
        observed_data={"waveform": np.asarray(result.observed, float)},
        constant_data={  # held parameters (a marginalised gain has no value: it is drawn)
            name: np.asarray(float(value))
            for name, value in result.fixed.items()
            if value is not None
        },
        coords={"height": np.asarray(result.axis, float)},
        dims={"waveform": ["height"]},
        attrs=attrs,
    )


def read_inference_data(path, name):
    """:func:`to_inference_data` of the posterior stored in group ``name`` of ``path``
    (a ``lidarinv invert`` file: ``shot_<id>``)."""
    from lidarinv.inference import InversionResult

    return to_inference_data(InversionResult.load(path, name))
