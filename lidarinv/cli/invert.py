"""``lidarinv invert``: posterior of the stand parameters for shots of a waveform file."""

from pathlib import Path

import numpy as np

from lidarinv.io.formats import FORMATS, iter_observations
from lidarinv.observe.observation import ShotError

HELP = "sample the posterior of canopy height, volume, cover and LAI for waveform shots"


def add_arguments(parser) -> None:
    parser.add_argument("file", type=Path, nargs="?", help="HDF5 waveform file")
    parser.add_argument(
        "--example",
        help="invert a built-in synthetic shot instead of a file (e.g. gedi-mixed)",
    )
    parser.add_argument(
        "--format", default="auto", choices=["auto", *FORMATS], help="file layout (default auto)"
    )
    parser.add_argument("--beam", action="append", help="beam to read (GEDI; repeatable)")
    parser.add_argument(
        "--shot", action="append", help="shot id to invert (repeatable; default: the first)"
    )
    parser.add_argument("--priors", type=Path, help="TOML file of prior overrides")
    parser.add_argument("--instrument", default="gedi", help="instrument preset (pulse, optics)")
    parser.add_argument("--max-steps", type=int, help="cap on sampler steps")
    parser.add_argument("--walkers", type=int, help="number of walkers")
    parser.add_argument("--seed", type=int, default=0, help="random seed")
    parser.add_argument("-o", "--output", type=Path, required=True, help="posterior HDF5 file")
    parser.add_argument("--plots", type=Path, help="write corner/predictive/profile PNGs here")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def _settings(args):
    from dataclasses import replace

    from lidarinv.inference import InversionSettings

    if args.priors is not None:
        if not args.priors.exists():
            raise ValueError(f"no such priors file: {args.priors}")
        settings = InversionSettings.from_priors_file(args.priors, instrument=args.instrument)
    else:
        settings = InversionSettings(instrument=args.instrument)
    sampler = settings.sampler
    if args.max_steps is not None:
        sampler = replace(sampler, max_steps=args.max_steps)
    if args.walkers is not None:
        sampler = replace(sampler, n_walkers=args.walkers)
    return replace(settings, sampler=sampler)


def _selected(args, rng):
    if args.example is not None:
        from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot

        if args.example not in SYNTHETIC_SHOTS:
            raise ValueError(f"unknown example {args.example!r}; known: {list(SYNTHETIC_SHOTS)}")
        yield synthetic_shot(SYNTHETIC_SHOTS[args.example], rng, shot_id=args.example)
        return
    wanted = None if not args.shot else {str(s) for s in args.shot}
    for item in iter_observations(args.file, args.format, beams=args.beam):
        if wanted is None or str(item.shot_id) in wanted:
            yield item
            if wanted is None:
                return
            wanted.discard(str(item.shot_id))
            if not wanted:
                return
    if wanted:
        raise ValueError(f"shot(s) not found in {args.file}: {sorted(wanted)}")


def run(args) -> int:
    from lidarinv.inference import invert_shot
    from lidarinv.inference.plots import save_plots

    if (args.file is None) == (args.example is None):
        raise ValueError("give a waveform file or --example NAME (one of them)")
    if args.file is not None and not args.file.exists():
        raise ValueError(f"no such file: {args.file}")
    settings = _settings(args)
    rng = np.random.default_rng(args.seed)
    failures = 0
    for item in _selected(args, rng):
        if isinstance(item, ShotError):
            print(f"shot {item.shot_id}: skipped: {item.reason}")
            failures += 1
            continue
        try:
            result = invert_shot(item, settings, rng=rng, progress=not args.quiet)
        except ValueError as error:
            print(f"shot {item.shot_id}: skipped: {error}")
            failures += 1
            continue
        result.save(args.output, name=f"shot_{result.shot_id}")
        print(result.summary_table())
        if args.plots:
            for path in save_plots(result, args.plots):
                print(f"wrote {path}")
        print(f"wrote {args.output} (group shot_{result.shot_id})")
    return 1 if failures else 0
