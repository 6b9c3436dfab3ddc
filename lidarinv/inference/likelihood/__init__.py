"""The likelihood stage: the Gaussian likelihood of a shot's window (:mod:`.gaussian`),
with the gain integrated out (:mod:`.marginal`), a discrepancy per bin
(:mod:`.discrepancy`) or a covariance between bins (:mod:`.covariance`)."""
