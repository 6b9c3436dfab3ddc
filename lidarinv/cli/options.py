"""Options that ``lidarinv invert`` and ``lidarinv batch`` share, validated by the parser.

Values a run cannot use (no steps, fewer walkers than the ensemble needs, an unknown
instrument) are refused before any file is read or any sampling starts.
"""

import argparse
from dataclasses import replace
from pathlib import Path

from forward.instrument import INSTRUMENT_PRESETS


def positive_int(text: str) -> int:
    """An integer > 0 (argparse type)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {value}")
    return value


def walker_count(text: str) -> int:
    """An even integer ≥ 4 (argparse type); :func:`check_walkers` checks the minimum the
    settings need."""
    value = positive_int(text)
    if value < 4 or value % 2:
        raise argparse.ArgumentTypeError(f"must be an even integer ≥ 4, got {value}")
    return value


def add_instrument_options(parser, default_text="the one the file names") -> None:
    """``--instrument`` and ``--override-instrument``."""
    parser.add_argument(
        "--instrument",
        choices=sorted(INSTRUMENT_PRESETS),
        help=f"instrument preset for the pulse and footprint (default: {default_text}); "
        "one that contradicts the file is refused",
    )
    parser.add_argument(
        "--override-instrument",
        action="store_true",
        help="use --instrument even where the file says another instrument recorded it "
        "(a warning is recorded with every result)",
    )


def check_instrument(args, summary) -> str | None:
    """Refuse an ``--instrument`` that contradicts the instrument the file's layout names
    (``summary``: :class:`lidarinv.io.formats.FileSummary`), unless
    ``--override-instrument``; then return the warning to record with each result."""
    chosen, recorded = args.instrument, summary.instrument
    if chosen is None or recorded is None or chosen == recorded:
        return None
    if not getattr(args, "override_instrument", False):
        raise ValueError(
            f"--instrument {chosen} contradicts {summary.path}, a {summary.format} file of "
            f"{recorded} shots; leave --instrument out to use {recorded}, or pass "
            f"--override-instrument to process them as {chosen}"
        )
    return f"instrument {chosen} overrides the file's {recorded} (--override-instrument)"


def add_inversion_options(parser) -> None:
    """``--priors``, ``--instrument`` (and ``--override-instrument``), ``--max-steps``,
    ``--walkers``, ``--cohorts``, ``--footprint-cover`` and ``--overwrite``."""
    parser.add_argument("--priors", type=Path, help="TOML file of prior overrides")
    add_instrument_options(parser)
    parser.add_argument(
        "--max-steps", type=positive_int, metavar="N", help="cap on sampler steps (default 20000)"
    )
    parser.add_argument(
        "--walkers",
        type=walker_count,
        metavar="N",
        help="walkers of the ensemble (even; at least 2 × free parameters + 2; default 128)",
    )
    parser.add_argument(
        "--cohorts",
        choices=("1", "2", "auto"),
        help="height cohorts of the stand: 1, 2 (a lower storey), or auto (default): the "
        "one with the lower BIC at its MAP",
    )
    parser.add_argument(
        "--footprint-cover",
        type=positive_int,
        metavar="N",
        help="draw the footprint's own crown cover for N posterior samples (an explicit "
        "stand each; off by default)",
    )
    parser.add_argument(
        "--overwrite", action="store_true", help="replace results the output already holds"
    )


def inversion_settings(args, measured_pulse: bool = True):
    """``InversionSettings`` from ``--priors``, ``--instrument``, ``--max-steps`` and
    ``--walkers`` (checked against the free parameters before any sampling)."""
    from lidarinv.inference import InversionSettings

    changes = {} if args.instrument is None else {"instrument": args.instrument}
    if getattr(args, "cohorts", None) is not None:
        changes["cohorts"] = args.cohorts if args.cohorts == "auto" else int(args.cohorts)
    if getattr(args, "footprint_cover", None) is not None:
        changes["footprint_cover_draws"] = args.footprint_cover
    if args.priors is not None:
        if not args.priors.exists():
            raise ValueError(f"no such priors file: {args.priors}")
        settings = InversionSettings.from_priors_file(args.priors, **changes)
    else:
        settings = InversionSettings(**changes)
    sampler = settings.sampler
    if args.max_steps is not None:
        sampler = replace(sampler, max_steps=args.max_steps)
    if args.walkers is not None:
        sampler = replace(sampler, n_walkers=args.walkers)
        check_walkers(settings, args.walkers, measured_pulse)
    return replace(settings, sampler=sampler)


def check_walkers(settings, walkers: int, measured_pulse: bool = True) -> None:
    """``walkers`` is at least the ensemble's minimum, 2 × sampled coordinates + 2."""
    from lidarinv.inference.problem import sampled_dimensions

    ndim = sampled_dimensions(settings, measured_pulse)
    least = 2 * ndim + 2
    if walkers < least:
        raise ValueError(
            f"--walkers {walkers}: the ensemble needs at least {least} walkers for "
            f"{ndim} sampled parameters (2 × {ndim} + 2)"
        )
