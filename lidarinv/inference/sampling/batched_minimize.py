"""Several scipy optimisations in lockstep, their evaluations shared in batched calls.

The log-posterior costs about as much for one row as for dozens (per-call overhead, not
arithmetic), but :func:`scipy.optimize.minimize` asks for one point at a time. Here each
optimisation runs in its own thread, which only waits at its objective; once every live
optimisation has asked for a point, the points are evaluated together in one call and the
values handed back. The threads give each optimiser its own control flow, not
parallelism: one runs at a time. Rounds are evaluated in a fixed order, so the results
do not depend on thread timing.
"""

import threading

import numpy as np
from scipy.optimize import minimize


class _Stopped(Exception):
    """Ends an optimisation whose round could not be evaluated."""


class _Rendezvous:
    """Collects one pending point per live optimisation; the caller evaluates a round."""

    def __init__(self, count):
        self.lock = threading.Lock()
        self.ready = threading.Event()  # set when every live optimisation waits
        self.live = count
        self.pending = {}  # index → point
        self.answers = [None] * count
        self.events = [threading.Event() for _ in range(count)]
        self.failed = False  # set when an evaluation raised: every optimisation stops

    def _check(self):
        if len(self.pending) >= self.live:
            self.ready.set()

    def ask(self, index, x):
        with self.lock:
            self.pending[index] = np.array(x, float)
            self._check()
        self.events[index].wait()
        self.events[index].clear()
        if self.failed:
            raise _Stopped
        return self.answers[index]

    def leave(self):
        with self.lock:
            self.live -= 1
            self._check()

    def take_round(self):
        """The pending (index, point) pairs, sorted, once every live optimisation waits."""
        self.ready.wait()
        with self.lock:
            self.ready.clear()
            batch = sorted(self.pending.items())
            self.pending.clear()
        return batch

    def answer(self, index, value):
        self.answers[index] = value
        self.events[index].set()


def minimize_in_lockstep(batch_objective, starts, **minimize_options) -> list:
    """:func:`scipy.optimize.minimize` from each of ``starts`` (m, ndim), evaluating the
    points of all live optimisations in one call of ``batch_objective``.

    Parameters
    ----------
    batch_objective : callable
        (k, ndim) → (values (k,), gradients (k, ndim)), as ``jac=True`` expects per row.
    starts : array (m, ndim)
    **minimize_options
        Passed to :func:`scipy.optimize.minimize` (``method``, ``options``, ...).

    Returns
    -------
    list of scipy.optimize.OptimizeResult, in the order of ``starts``.
    """
    starts = np.atleast_2d(np.asarray(starts, float))
    count = starts.shape[0]
    meeting = _Rendezvous(count)
    results, errors = [None] * count, []

    def run(index):
        try:
            results[index] = minimize(
                lambda x: meeting.ask(index, x), starts[index], jac=True, **minimize_options
            )
        except _Stopped:
            pass
        except Exception as error:  # re-raised in the caller
            errors.append(error)
        finally:
            meeting.leave()

    threads = [threading.Thread(target=run, args=(i,), daemon=True) for i in range(count)]
    for thread in threads:
        thread.start()
    while True:
        batch = meeting.take_round()
        if not batch:
            break
        try:
            values, gradients = batch_objective(np.array([x for _, x in batch]))
        except Exception as error:
            errors.append(error)
            meeting.failed = True
            values, gradients = np.full(len(batch), np.nan), None
        for k, (index, _) in enumerate(batch):
            gradient = None if gradients is None else np.array(gradients[k], float)
            meeting.answer(index, (float(values[k]), gradient))
    for thread in threads:
        thread.join()
    if errors:
        raise errors[0]
    return results
