"""``lidarinv batch``: invert every shot of a waveform file into one resumable HDF5 file."""

import importlib
import sys
from pathlib import Path

import h5py

from lidarinv.io.formats import FORMATS, inspect_file, iter_observations

from . import Interrupted, interrupted
from .kernels import announce_compilation
from .options import add_inversion_options, check_instrument, inversion_settings, positive_int
from .outputs import check_folder_writable, check_new_files

HELP = "invert many shots in parallel (local processes or a Dask cluster) into one HDF5 file"


def add_arguments(parser) -> None:
    parser.add_argument("file", type=Path, help="HDF5 waveform file")
    parser.add_argument(
        "--format", default="auto", choices=["auto", *FORMATS], help="file layout (default auto)"
    )
    parser.add_argument("--beam", action="append", help="beam to read (GEDI; repeatable)")
    parser.add_argument(
        "--shot", action="append", metavar="ID", help="invert only this shot id (repeatable)"
    )
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--workers", type=positive_int, help="local worker processes (default: all cores)"
    )
    where.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler, e.g. tcp://h:8786")
    add_inversion_options(parser)
    parser.add_argument(
        "-o", "--output", type=Path, required=True, help="results file (HDF5; resumed if present)"
    )
    parser.add_argument("--max-shots", type=positive_int, help="stop after this many new shots")
    parser.add_argument("--seed", type=int, help="root seed of the per-shot random generators")
    parser.add_argument(
        "--retries",
        type=int,
        default=1,
        help="retries of a shot whose worker died or met an error of its environment "
        "(errors of the shot's data repeat and are not retried)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    terrain = parser.add_mutually_exclusive_group()
    terrain.add_argument(
        "--no-terrain",
        action="store_true",
        help="do not check each shot's ground against its track neighbours' (by default a "
        "ground that leaves them is flagged 'terrain outlier', as lidarinv metrics does)",
    )
    terrain.add_argument(
        "--terrain-prior",
        action="store_true",
        help="take each shot's ground prior from its track neighbours' robust fit instead "
        "of its own ground peak (shots are then no longer independent)",
    )
    parser.add_argument(
        "--invert",
        metavar="MODULE:FUNCTION",
        help="inversion function to use instead of lidarinv.inference.invert_shot",
    )


def batch_settings(args):
    """Inversion settings from the options; None (the inversion's defaults) when none of
    them is given, so that a results file written without options resumes as before."""
    given = (args.priors, args.instrument, args.max_steps, args.walkers, args.cohorts,
             args.footprint_cover)  # fmt: skip
    if all(value is None for value in given):
        return None
    try:
        return inversion_settings(args)
    except ImportError as error:
        raise ValueError(f"inversion options need lidarinv.inference ({error})") from error


def _invert_function(spec):
    if spec is None:
        from lidarinv.batch.runner import default_invert

        try:
            return default_invert()
        except ImportError as error:
            raise ValueError(str(error)) from error
    module_name, _, name = spec.partition(":")
    try:
        return getattr(importlib.import_module(module_name), name)
    except (ImportError, AttributeError) as error:
        raise ValueError(f"--invert {spec}: {error}") from error


def _with_terrain(args, described, settings, invert):
    """The inversion with the file's terrain context (:mod:`lidarinv.batch.terrain`): each
    result carries its shot's terrain flag, and with ``--terrain-prior`` its ground prior
    is the terrain fit's."""
    from lidarinv.batch.terrain import WithTerrain, terrain_context

    observations = iter_observations(args.file, described.format, beams=args.beam)
    instrument = None if settings is None else settings.instrument
    processing = None if settings is None else settings.processing
    context = terrain_context(args.file, observations, instrument, processing)
    if context.flags:
        print(f"# terrain outlier: {len(context.flags)} shot(s): {', '.join(context.flags)}")
    return WithTerrain(invert, context, ground_prior=args.terrain_prior)


def _check_outputs(args) -> None:
    """Refuse, before any work, outputs that cannot be written or would be replaced: a
    results file that is the input or not a batch results file (a batch file is resumed),
    and a CSV beside it that is not that file's summary, unless ``--overwrite``."""
    from lidarinv.batch.store import csv_path_for, is_results_file, is_summary_csv

    results, summary = args.output, csv_path_for(args.output)
    if results.exists() and results.resolve() == args.file.resolve():
        raise ValueError(f"-o {results} is the input file; write the results to another file")
    if results.exists() and not results.is_dir() and not is_results_file(results):
        check_new_files([(results, "file")], args.overwrite)  # not ours: never resumed
    resumed = results.exists() and not args.overwrite and is_results_file(results)
    ours = resumed and is_summary_csv(summary)
    where = f"file {summary}, where the summary CSV of {results.name} goes,"
    check_new_files([(summary, where)], args.overwrite or ours or not summary.exists())
    check_folder_writable(results, "results file")


class _Selected:
    """The shots whose ids were asked for; remembers those it met."""

    def __init__(self, items, shot_ids):
        from lidarinv.batch import group_name

        self._items, self._name = items, group_name
        self.wanted = {group_name(s): str(s) for s in shot_ids}
        self.found = set()

    def __iter__(self):
        for item in self._items:
            name = self._name(item.shot_id)
            if name in self.wanted:
                self.found.add(name)
                yield item

    @property
    def missing(self) -> list:
        return sorted(text for name, text in self.wanted.items() if name not in self.found)


def _start_afresh(args) -> bool:
    """With ``--overwrite``, remove an existing results file and its CSV (just before
    the run starts). Returns whether a results file is there to resume."""
    from lidarinv.batch import csv_path_for

    if args.output.exists() and args.overwrite:
        args.output.unlink()
        csv_path_for(args.output).unlink(missing_ok=True)
    return args.output.exists()


def _stored_shots(path) -> int:
    try:
        with h5py.File(path, "r") as handle:
            return len(handle.get("shots", {}))
    except OSError:
        return 0


def run(args) -> int:
    from lidarinv.batch import connect_dask, csv_path_for, invert_many
    from lidarinv.batch.executors import WithFlag

    described = inspect_file(args.file, args.format, args.beam)
    override = check_instrument(args, described)
    settings = batch_settings(args)
    invert = _invert_function(args.invert)
    _check_outputs(args)
    if override:
        print(f"lidarinv batch: warning: {override}", file=sys.stderr)
        invert = WithFlag(invert, override)
    if not args.no_terrain:
        invert = _with_terrain(args, described, settings, invert)
    items = iter_observations(args.file, described.format, beams=args.beam)
    selected = None
    if args.shot:
        items = selected = _Selected(items, args.shot)
    client = None
    if args.scheduler:
        try:
            client = connect_dask(args.scheduler)
        except ImportError as error:
            raise ValueError(str(error)) from error
    existed = True  # until known: an interruption then removes nothing
    try:
        existed = _start_afresh(args)
        if args.invert is None:  # the default inversion: its kernels compile in each worker
            announce_compilation("lidarinv batch")
        summary = invert_many(
            items,
            settings,
            output=args.output,
            executor=client,
            workers=args.workers,
            invert=invert,
            rng=args.seed,
            progress=not args.no_progress,
            retries=args.retries,
            max_shots=args.max_shots,
            total=len(args.shot) if args.shot else described.n_shots,
        )
    except BaseException as error:
        if not interrupted(error):
            raise
        kept = _stored_shots(args.output)
        if not existed and kept == 0:  # nothing finished: leave no file behind
            args.output.unlink(missing_ok=True)
            csv_path_for(args.output).unlink(missing_ok=True)
            raise Interrupted("interrupted; no shot finished, no file written") from None
        raise Interrupted(
            f"interrupted; {kept} finished shot(s) kept in {args.output}, rerun the "
            "command to continue"
        ) from None
    finally:
        if client is not None:
            client.close()
    print(f"# {summary}")
    print(f"# results: {summary.output}  summary: {summary.csv}")
    for shot_id, reason in list(summary.failed.items())[:10]:
        beam = f" ({summary.beams[shot_id]})" if shot_id in summary.beams else ""
        print(f"# failed {shot_id}{beam}: {reason}")
    if len(summary.failed) > 10:
        print(f"# ... and {len(summary.failed) - 10} more failed shots (see the CSV)")
    missing = [] if selected is None or summary.stopped_early else selected.missing
    if missing:
        print(f"# shot(s) not found in {args.file}: {', '.join(missing)}")
    return 1 if summary.n_failed or missing else 0
