"""The quantities a result reports, as the sampler's stopping rule monitors them.

The stopping rule (:mod:`lidarinv.inference.sampling.stopping`) judges these, not every
sampled coordinate: a coordinate the waveform cannot constrain (the cone fraction, the
understory's LAI) may mix slowly without moving what the result reports.
"""

import numpy as np

#: Reported quantities the rule monitors: canopy top height, the model waveform's RH98,
#: crown cover and the gap-probability cover, PAI, crown volume and ground elevation.
#: Each is a sampled parameter (mapped from the sampler's coordinates to physical units:
#: the joint coordinates of cover and PAI, of the ground and the understory, of the top
#: height and the tallest stem are not monotone in one parameter alone) or a blob of the
#: log-posterior, whichever the posterior has.
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
        (chain (steps, walkers, ndim) in the sampler's unbounded coordinates, blobs
        (steps, walkers, n_blobs)) → dict of name → array (steps, walkers) in physical
        units, in the order of ``names``.
    """
    sampled = {name: i for i, name in enumerate(space.names)}
    blobbed = {name: i for i, name in enumerate(blob_names)}
    picked = [name for name in names if name in sampled or name in blobbed]

    def monitor(chain, blobs):
        chain = np.asarray(chain, float)
        physical = None
        if any(name in sampled for name in picked):
            x, _ = space.from_unbounded(chain.reshape(-1, chain.shape[-1]))
            physical = x.reshape(chain.shape)
        out = {}
        for name in picked:
            if name in sampled:
                out[name] = physical[..., sampled[name]]
            else:
                out[name] = np.asarray(blobs)[..., blobbed[name]]
        return out

    return monitor
