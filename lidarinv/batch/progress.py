"""A tqdm progress bar that counts finished, failed and skipped shots."""

from tqdm.auto import tqdm


class ProgressBar:
    """Shots per second, ETA and done/failed/skipped counts, over the shots the run will
    actually process.

    The bar's total is the shots inverted or failed so far, those in flight, and those
    still to come: the input shots not yet met, at most ``cap`` minus the shots started.
    Shots skipped because the results file holds them take no place in it, so neither a
    resumed run nor ``max_shots`` shows a total (and an ETA) of the whole file.

    Parameters
    ----------
    total : int, optional
        Number of input shots (unknown if None).
    enabled : bool
        False: count only, draw nothing.
    cap : int, optional
        Most shots the run will start (``max_shots``).
    """

    def __init__(self, total=None, enabled=True, cap=None):
        self.counts = {"done": 0, "failed": 0, "skipped": 0}
        self._input, self._cap = total, cap
        self._seen = self._started = self._unreadable = 0
        self._bar = tqdm(total=self.expected, unit="shot", desc="inverting",
                         disable=not enabled, dynamic_ncols=True, smoothing=0.1)  # fmt: skip

    @property
    def expected(self) -> int | None:
        """Shots this run will process (finished, in flight and to come); None if unknown."""
        ahead = []
        if self._input is not None:
            ahead.append(self._input - self._seen)
        if self._cap is not None:
            ahead.append(self._cap - self._started)
        if not ahead:
            return None
        return self._started + self._unreadable + max(min(ahead), 0)

    def _retotal(self) -> None:
        expected = self.expected
        if expected != self._bar.total:
            self._bar.total = expected
            self._bar.refresh()

    def started(self) -> None:
        """An input shot handed to an inversion (it advances the bar when it finishes)."""
        self._seen += 1
        self._started += 1
        self._retotal()

    def unreadable(self) -> None:
        """An input shot that could not be read: failed at once."""
        self._seen += 1
        self._unreadable += 1
        self._retotal()
        self.advance("failed")

    def skipped(self) -> None:
        """An input shot the results file already holds: counted, not processed."""
        self._seen += 1
        self.counts["skipped"] += 1
        self._retotal()
        self._bar.set_postfix(self.counts)

    def advance(self, kind: str) -> None:
        """Count one finished shot of ``kind`` (``done`` or ``failed``)."""
        self.counts[kind] += 1
        self._bar.set_postfix(self.counts, refresh=False)
        self._bar.update(1)

    def close(self) -> None:
        self._bar.close()
