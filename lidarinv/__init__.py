"""lidarinv: observation, Bayesian inversion, I/O and the command line, built on ``forward``."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("lidarinv")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+unknown"
