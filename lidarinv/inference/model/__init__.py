"""The model stage: inversion parameters (:mod:`.parameters`, :mod:`.space`, their priors
:mod:`.priors` and sampling coordinates :mod:`.coordinates`) → stand (:mod:`.stand`, with
the tallest-stem latent :mod:`.tallest_stem`) → expected waveform (:mod:`.waveform`)."""
