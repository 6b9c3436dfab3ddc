"""A tqdm progress bar that counts finished, failed and skipped shots."""

from tqdm.auto import tqdm


class ProgressBar:
    """Shots per second, ETA and done/failed/skipped counts.

    Parameters
    ----------
    total : int, optional
        Number of shots expected (for the ETA); unknown if None.
    enabled : bool
        False: count only, draw nothing.
    """

    def __init__(self, total=None, enabled=True):
        self.counts = {"done": 0, "failed": 0, "skipped": 0}
        self._bar = tqdm(total=total, unit="shot", desc="inverting", disable=not enabled,
                         dynamic_ncols=True, smoothing=0.1)  # fmt: skip

    def advance(self, kind: str) -> None:
        """Count one shot of ``kind`` (``done``, ``failed`` or ``skipped``)."""
        self.counts[kind] += 1
        self._bar.set_postfix(self.counts, refresh=False)
        self._bar.update(1)

    def close(self) -> None:
        self._bar.close()
