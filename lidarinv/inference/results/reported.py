"""The quantities a result reports, as the sampler's stopping rule monitors them.

The stopping rule (:mod:`lidarinv.inference.sampling.stopping`) judges these, not every
sampled coordinate: a coordinate the waveform cannot constrain (the cone fraction, the
understory's LAI) may mix slowly without moving what the result reports.
"""

import numpy as np

#: Reported quantities the rule monitors: canopy top height, the model waveform's RH98,
#: crown cover and the gap-probability cover, PAI, crown volume and ground elevation.
#: Each is a sampled coordinate or a blob of the log-posterior, whichever the posterior
#: has (rank-normalised ESS and R̂ do not change under the monotone map between a
#: coordinate and its unbounded value).
REPORTED = (
    "top_height",
    "rh98",
    "cover",
    "gap_cover",
    "pai",
    "crown_volume",
    "ground_elevation",
)


def reported_monitor(space, blob_names, names=REPORTED):
    """The monitor of :func:`lidarinv.inference.sampling.run_sampler` for the reported
    quantities.

    Parameters
    ----------
    space : ParameterSpace
    blob_names : sequence of str
        The log-posterior's blob columns (e.g. :data:`.posterior.BLOB_NAMES`).
    names : sequence of str
        Quantities to monitor; those neither sampled nor a blob (held fixed) are skipped.

    Returns
    -------
    callable
        (chain (steps, walkers, ndim), blobs (steps, walkers, n_blobs)) → dict of name →
        array (steps, walkers), in the order of ``names``.
    """
    sampled = {name: i for i, name in enumerate(space.names)}
    blobbed = {name: i for i, name in enumerate(blob_names)}
    picked = [name for name in names if name in sampled or name in blobbed]

    def monitor(chain, blobs):
        out = {}
        for name in picked:
            if name in sampled:
                out[name] = chain[..., sampled[name]]
            else:
                out[name] = np.asarray(blobs)[..., blobbed[name]]
        return out

    return monitor
