"""Cost of one log-posterior call of the sampler, per stage (issue 46: the fixed cost of a call).

For each shot given (a waveform file, a shot number, a count of height cohorts), the
problem is built as the inversion builds it (:func:`lidarinv.inference.invert.
prepare_problem`, default settings: the realisations discrepancy, the MAP as the start;
or ``--problem build``: :func:`lidarinv.inference.build_problem` alone, its rows the best
of many prior draws), ``--rows`` rows are drawn about the start in the unbounded
coordinates (fixed seed), and ``problem.log_posterior(u)``, the call the sampler makes, is
timed ``--repeats`` times on one core, in wall time and in the thread's CPU time (the
fairer figure on a shared machine). A second pass times, in CPU time, each stage of the call by
wrapping the stage's function with a timer: the unbounded map, the prior and coordinate
values, the stand's validity, the stand mapping, the expected waveform, the pulse
broadening, the model waveform's relative heights, the likelihood; what is left is the
call's own overhead. The load average is recorded before and after.

    python studies/log_posterior_call.py --shot FILE SHOT COHORTS [--shot ...]
        [--rows 64] [--repeats 2000] [--problem prepare|build] [--seed 0] [--tag _NAME]
        [--cache FOLDER] [--snapshot PATH.npz | --compare PATH.npz]

Each shot's rows are also evaluated one at a time: the largest difference from the
batch's output (``batch_dependence``) says whether a row's log-posterior depends on the
rows beside it. ``--snapshot`` saves each shot's rows and the call's output; ``--compare`` checks a later
run against such a file, bit for bit (``numpy.array_equal``) and within 1e-12 relative.
Writes studies/output/log_posterior_call[_TAG]/summary.json.
"""

from harness import output_folder, parser, pin_threads, write_json

pin_threads()

import functools  # noqa: E402
import os  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402

import numpy as np  # noqa: E402

from lidarinv.inference import InversionSettings, build_problem  # noqa: E402
from lidarinv.inference.invert import prepare_problem  # noqa: E402
from lidarinv.inference.model import waveform  # noqa: E402
from lidarinv.io import iter_observations  # noqa: E402


def find_observation(path, shot):
    """The observation numbered ``shot`` in the waveform file ``path``."""
    for obs in iter_observations(path):
        if str(getattr(obs, "shot_id", None)) == str(shot):
            return obs
    raise SystemExit(f"{path}: no shot numbered {shot}")


def make_problem(obs, cohorts, how, rng, cache=None):
    """The sampler's posterior of ``obs`` and its start (unbounded, (ndim,)).

    With ``how="prepare"`` and a ``cache`` file, the prepared problem's fixed
    discrepancy and start are read from it where it exists (the problem is then
    :func:`build_problem`'s with that discrepancy, as :func:`prepare_problem` makes it)
    and written to it where it does not: the MAP search and the realisations run once.
    """
    settings = replace(InversionSettings(), cohorts=cohorts)
    problem = build_problem(obs, settings)
    if how == "prepare":
        if cache is not None and os.path.exists(cache):
            kept = np.load(cache)
            likelihood = problem.log_posterior.likelihood
            fixed = kept["fixed_discrepancy"]
            if fixed.ndim:
                problem = problem.with_likelihood(likelihood.with_fixed_discrepancy(fixed))
            return problem, kept["start"]
        prepared = prepare_problem(obs, settings, rng)
        start = np.atleast_2d(prepared.start)[0]
        fixed = prepared.problem.log_posterior.likelihood.fixed_discrepancy
        if cache is not None:
            np.savez(cache, start=start, fixed_discrepancy=np.asarray(fixed, float))
        return prepared.problem, start
    space = problem.space
    u = space.to_unbounded(space.sample_prior(rng, 2048))
    log_post = problem.log_posterior(u)[:, 0]
    return problem, u[np.argmax(log_post)]


def draw_rows(problem, start, n, rng, spread=0.02):
    """``n`` rows about ``start`` in the unbounded coordinates, all inside the support."""
    rows = []
    while sum(len(r) for r in rows) < n:
        u = start + spread * rng.standard_normal((4 * n, start.size))
        rows.append(u[np.isfinite(problem(u)[:, 0])])
    return np.concatenate(rows)[:n]


def time_calls(call, u, repeats):
    """Wall and CPU seconds (this thread's) of each of ``repeats`` calls."""
    call(u)  # compile and warm
    wall, cpu = np.empty(repeats), np.empty(repeats)
    for i in range(repeats):
        start, start_cpu = time.perf_counter(), time.thread_time()
        call(u)
        cpu[i] = time.thread_time() - start_cpu
        wall[i] = time.perf_counter() - start
    return wall, cpu


def milliseconds(seconds) -> dict:
    """Median, min and mean of per-call seconds, in ms."""
    return {"median": float(np.median(seconds) * 1e3), "min": float(np.min(seconds) * 1e3),
            "mean": float(np.mean(seconds) * 1e3)}  # fmt: skip


class StageTimers:
    """Timers wrapped around the stages of one posterior's call, by stage name."""

    def __init__(self, post):
        self.seconds = {}
        model = post.model
        targets = {
            "unbounded map": (post.space, "from_unbounded"),
            "prior and values": (post.space, ("log_prior", "values")),
            "stand validity": (model.mapping, "valid"),
            "stand mapping": (model.mapping, "model_vectors"),
            "expected waveform": (model.expected, "evaluate"),
            "pulse broadening": (model, "widen"),
            "relative heights": (waveform, "relative_heights"),
            "likelihood": (post.likelihood, "log_likelihood"),
        }
        self._undo = []
        for stage, (owner, names) in targets.items():
            for name in (names,) if isinstance(names, str) else names:
                self._wrap(stage, owner, name)

    def _wrap(self, stage, owner, name):
        self.seconds.setdefault(stage, 0.0)
        original = getattr(owner, name)
        had_own = name in getattr(owner, "__dict__", {})

        @functools.wraps(original)
        def timed(*args, **kwargs):
            start = time.thread_time()
            try:
                return original(*args, **kwargs)
            finally:
                self.seconds[stage] += time.thread_time() - start

        setattr(owner, name, timed)
        self._undo.append((owner, name, original if had_own else None))

    def remove(self):
        for owner, name, original in reversed(self._undo):
            if original is None:
                delattr(owner, name)
            else:
                setattr(owner, name, original)

    def reset(self):
        for stage in self.seconds:
            self.seconds[stage] = 0.0


def stage_breakdown(post, u, repeats):
    """Mean CPU ms per call of each stage, and of the call under the timers."""
    timers = StageTimers(post)
    try:
        post(u)
        timers.reset()
        start = time.thread_time()
        for _ in range(repeats):
            post(u)
        total = (time.thread_time() - start) / repeats * 1e3
        stages = {stage: s / repeats * 1e3 for stage, s in timers.seconds.items()}
    finally:
        timers.remove()
    stages["call overhead (rest)"] = total - sum(stages.values())
    return {"timed call": total, **stages}


def batch_dependence(post, u, out) -> dict:
    """How much a row's log-posterior and blobs change when it is evaluated alone rather
    than in its batch (the largest absolute difference over the rows; the sampler's
    target is one density only where this is at rounding level)."""
    alone = np.concatenate([post(u[i : i + 1]) for i in range(u.shape[0])])
    with np.errstate(invalid="ignore"):
        difference = np.abs(alone - out)
    finite = np.isfinite(difference)
    log_post = difference[:, 0][finite[:, 0]]
    blobs = difference[:, 1:][finite[:, 1:]]
    return {
        "log_posterior_nats": float(log_post.max()) if log_post.size else 0.0,
        "blobs": float(blobs.max()) if blobs.size else 0.0,
    }


def compare(saved, key, got):
    """Bit-equal, and largest relative difference, of one shot's output."""
    ref = saved[key]
    finite = np.isfinite(ref)
    same_pattern = np.array_equal(finite, np.isfinite(got)) and np.array_equal(
        np.isnan(ref), np.isnan(got)
    )
    scale = np.maximum(np.abs(ref[finite]), 1e-300)
    rel = float(np.max(np.abs(got[finite] - ref[finite]) / scale)) if finite.any() else 0.0
    return {
        "array_equal": bool(np.array_equal(ref, got, equal_nan=True)),
        "same_nonfinite": bool(same_pattern),
        "max_relative_difference": rel,
    }


def main(argv=None):
    p = parser(__doc__, seed=0)
    p.add_argument("--shot", nargs=3, action="append", required=True,
                   metavar=("FILE", "SHOT", "COHORTS"), help="a shot to time (repeatable)")  # fmt: skip
    p.add_argument("--rows", type=int, default=64, help="rows per call (walkers)")
    p.add_argument("--repeats", type=int, default=2000, help="timed calls per shot")
    p.add_argument("--stage-repeats", type=int, default=500, help="calls of the stage pass")
    p.add_argument("--problem", choices=("prepare", "build"), default="prepare")
    p.add_argument("--cache", help="folder of the prepared problems (made if missing)")
    p.add_argument("--snapshot", help="save rows and outputs to this .npz")
    p.add_argument("--compare", help="compare the outputs with this .npz")
    args = p.parse_args(argv)
    load = [os.getloadavg()]
    saved = dict(np.load(args.compare)) if args.compare else None
    snapshot, records = {}, []
    for index, (path, shot, cohorts) in enumerate(args.shot):
        rng = np.random.default_rng([args.seed, index])
        obs = find_observation(path, shot)
        cache = None
        if args.cache:
            os.makedirs(args.cache, exist_ok=True)
            cache = os.path.join(args.cache, f"{os.path.basename(path)}_{shot}_{cohorts}.npz")
        problem, start = make_problem(obs, int(cohorts), args.problem, rng, cache)
        post = problem.log_posterior
        key = f"shot{index}"
        u = saved[f"{key}_u"] if saved else draw_rows(post, start, args.rows, rng)
        out = post(u)
        snapshot[f"{key}_u"], snapshot[f"{key}_out"] = u, out
        wall, cpu = time_calls(post, u, args.repeats)
        record = {
            "file": os.path.basename(path), "shot": shot, "cohorts": int(cohorts),
            "ndim": post.ndim, "bins": int(post.data.axis.size), "rows": int(u.shape[0]),
            "ms_per_call": milliseconds(wall), "cpu_ms_per_call": milliseconds(cpu),
            "stages_ms": stage_breakdown(post, u, args.stage_repeats),
        }  # fmt: skip
        record["batch_dependence"] = batch_dependence(post, u, out)
        if saved is not None:
            record["equality"] = compare(saved, f"{key}_out", out)
        records.append(record)
        print(record, flush=True)
    load.append(os.getloadavg())
    if args.snapshot:
        np.savez(args.snapshot, **snapshot)
    summary = {"command": " ".join(sys.argv), "load_average": load, "shots": records}
    folder = output_folder("log_posterior_call", args.tag)
    write_json(folder / "summary.json", summary)
    print("load average before/after:", load)
    for r in records:
        stages = "  ".join(f"{k} {v:.3f}" for k, v in r["stages_ms"].items())
        wall, cpu = r["ms_per_call"], r["cpu_ms_per_call"]
        print(f"{r['shot']} ({r['cohorts']} cohorts): wall {wall['median']:.3f} ms median, "
              f"{wall['min']:.3f} min; CPU {cpu['median']:.3f} median, {cpu['min']:.3f} min "
              f"| CPU ms per stage: {stages}")  # fmt: skip
        print("   alone against in the batch:", r["batch_dependence"])
        if "equality" in r:
            print("   equality:", r["equality"])
    return summary


if __name__ == "__main__":
    main()
