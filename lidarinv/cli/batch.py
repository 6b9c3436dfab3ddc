"""``lidarinv batch``: invert every shot of a waveform file into one resumable HDF5 file."""

import importlib
from pathlib import Path

import h5py

from lidarinv.io.formats import FORMATS, detect_format, iter_observations

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
    where.add_argument("--workers", type=int, help="local worker processes (default: all cores)")
    where.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler, e.g. tcp://h:8786")
    parser.add_argument("--priors", type=Path, help="priors file (InversionSettings)")
    parser.add_argument(
        "-o", "--output", type=Path, required=True, help="results file (HDF5; resumed if present)"
    )
    parser.add_argument("--max-shots", type=int, help="stop after this many new shots")
    parser.add_argument("--seed", type=int, help="root seed of the per-shot random generators")
    parser.add_argument("--retries", type=int, default=1, help="retries of a failed shot")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument(
        "--invert",
        metavar="MODULE:FUNCTION",
        help="inversion function to use instead of lidarinv.inference.invert_shot",
    )


def _settings(priors):
    if priors is None:
        return None
    try:
        from lidarinv.inference import InversionSettings
    except ImportError as error:
        raise ValueError(f"--priors needs lidarinv.inference (not available: {error})") from error
    if not hasattr(InversionSettings, "from_priors_file"):
        raise ValueError("--priors: InversionSettings.from_priors_file is not available")
    if not priors.exists():
        raise ValueError(f"no such priors file: {priors}")
    return InversionSettings.from_priors_file(priors)


def _invert_function(spec):
    if spec is None:
        from lidarinv.batch.runner import _default_invert

        try:
            return _default_invert()
        except ImportError as error:
            raise ValueError(str(error)) from error
    module_name, _, name = spec.partition(":")
    try:
        return getattr(importlib.import_module(module_name), name)
    except (ImportError, AttributeError) as error:
        raise ValueError(f"--invert {spec}: {error}") from error


def _count(path, format, beams, shot_ids):
    """Number of shots to expect (for the ETA), None if unknown."""
    if shot_ids:
        return len(shot_ids)
    try:
        with h5py.File(path, "r") as handle:
            module = FORMATS[detect_format(handle) if format == "auto" else format]
            chosen = module.beams(handle) if beams is None else beams
            return sum(module.count_shots(handle, beam) for beam in chosen)
    except (KeyError, ValueError, OSError):
        return None


def _selected(items, shot_ids):
    from lidarinv.batch import group_name

    wanted = {group_name(s) for s in shot_ids}
    for item in items:
        if group_name(item.shot_id) in wanted:
            yield item


def run(args) -> int:
    from lidarinv.batch import connect_dask, invert_many

    if not args.file.exists():
        raise ValueError(f"no such file: {args.file}")
    settings = _settings(args.priors)
    invert = _invert_function(args.invert)
    items = iter_observations(args.file, args.format, beams=args.beam)
    if args.shot:
        items = _selected(items, args.shot)
    client = None
    if args.scheduler:
        try:
            client = connect_dask(args.scheduler)
        except ImportError as error:
            raise ValueError(str(error)) from error
    try:
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
            total=_count(args.file, args.format, args.beam, args.shot),
        )
    finally:
        if client is not None:
            client.close()
    print(f"# {summary}")
    print(f"# results: {summary.output}  summary: {summary.csv}")
    for shot_id, reason in list(summary.failed.items())[:10]:
        print(f"# failed {shot_id}: {reason}")
    if len(summary.failed) > 10:
        print(f"# ... and {len(summary.failed) - 10} more failed shots (see the CSV)")
    return 1 if summary.n_failed and not summary.n_done and not summary.n_skipped else 0
