"""``lidarinv invert``: posterior of the stand parameters for shots of a waveform file."""

import sys
from pathlib import Path

import numpy as np

from lidarinv.io.formats import FORMATS, inspect_file, iter_observations
from lidarinv.observe.observation import ShotError
from lidarinv.observe.quality import clipped_plateau

from .kernels import announce_compilation
from .options import add_inversion_options, check_instrument, inversion_settings
from .outputs import check_hdf5_groups, check_plot_folder, save_group

HELP = "sample the posterior of canopy height, volume, cover and LAI for waveform shots"

#: What a user compares with a product's RH98 and canopy cover, printed first:
#: (quantity, name printed, what it is).
HEADLINE = (
    (
        "footprint_top_height",
        "canopy height",
        "tallest stem within the footprint's 1/e² radius (compare with RH98)",
    ),
    (
        "rh98_footprint",
        "RH98 of the footprint",
        "of its own waveform, the fitted one and the discrepancy the data show (compare "
        "with a product's RH98)",
    ),
    ("rh98", "RH98 of the fitted waveform", "height above the ground of 98 % of its energy"),
    (
        "gap_cover",
        "canopy cover",
        "gap-based, 1 − P(0) through the tree crowns (compare with GEDI L2B cover)",
    ),
    (
        "footprint_cover",
        "crown cover of the footprint",
        "footprint-weighted, of a realisation of the stand (--footprint-cover)",
    ),
    ("cover", "crown cover", "fraction of the ground under at least one crown"),
)


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
    add_inversion_options(parser)
    parser.add_argument("--seed", type=int, default=0, help="random seed")
    parser.add_argument("-o", "--output", type=Path, required=True, help="posterior HDF5 file")
    parser.add_argument("--plots", type=Path, help="write corner/predictive/profile PNGs here")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def group_of(shot_id) -> str:
    """The posterior file's group of a shot."""
    return f"shot_{shot_id}"


def _selected(args, rng):
    if args.example is not None:
        from lidarinv.examples import SYNTHETIC_SHOTS, synthetic_shot

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


def headline(result) -> str:
    """The footprint's canopy height and cover, then what ``top_height`` is and the
    result's warnings (:attr:`InversionResult.warnings`): the lines ``lidarinv invert``
    prints before the full table."""
    summary = result.summary()
    canopy = result.footprint_canopy()
    lines = [f"shot {result.shot_id}: the footprint (median, 90 % interval)"]
    lines += _seen_canopy_lines(canopy)
    for name, label, meaning in HEADLINE:
        if name not in summary or not np.isfinite(summary[name]["median"]):
            continue  # e.g. no footprint RH where the likelihood cannot condition on y
        if name == "footprint_top_height" and canopy is not None:
            continue  # its canopy height as the waveform supports it, above
        row = summary[name]
        units = "" if row["units"] in ("", "1") else f" {row['units']}"
        lines.append(
            f"  {label:<28}{row['median']:8.3g}{units}  [{row['p05']:.3g}, {row['p95']:.3g}]"
            f"  {meaning}"
        )
    lines += _canopy_lines(result, canopy)
    if "top_height" in summary:
        row = summary["top_height"]
        lines.append(
            f"  {'stand top_height':<28}{row['median']:8.3g} m  [{row['p05']:.3g}, "
            f"{row['p95']:.3g}]  upper limit of the stand's height distribution "
            "(mean + 2 sd), which one footprint rarely reaches"
        )
    # a wrong answer must not read as clean: the warnings follow, in full
    lines += [f"  warning: {flag}" for flag in result.warnings]
    return "\n".join(lines)


def _seen_canopy_lines(canopy) -> list:
    """The headline's canopy height: the footprint's tallest stem where its waveform shows
    a canopy, 0 where it shows none, with the probability that it shows none."""
    if canopy is None:
        return []
    height, p_none = canopy["height"], canopy["none_probability"]
    lines = [
        f"  {'canopy height':<28}{height['median']:8.3g} m  [{height['p05']:.3g}, "
        f"{height['p95']:.3g}]  tallest stem within the footprint's 1/e² radius where its "
        "waveform shows a canopy, 0 where it shows none (compare with RH98)",
        f"  {'P(no canopy in footprint)':<28}{p_none:8.2f}    no stem, or none whose return "
        "the waveform can tell from a bare ground's",
    ]
    if p_none >= 0.5:
        lines[-1] += ": the footprint more likely holds no canopy"
    return lines


def _canopy_lines(result, canopy) -> list:
    """Whether the footprint holds a tree at all, whether its waveform sees one, and the
    height of the canopy it sees if it sees one: a bare footprint's canopy height is the
    zero of most draws, not the top of a stand."""
    if canopy is None:
        return []
    p_none, given = canopy["no_tree_probability"], canopy["height_given_canopy"]
    lines = [
        f"  {'P(no tree in footprint)':<28}{p_none:8.2f}    no stem within the footprint's "
        "1/e² radius (Poisson stand: exp(−density × disc area))"
    ]
    if p_none >= 0.5:
        lines[0] += ": the footprint more likely holds no tree"
    p_bare = canopy["bare_probability"]
    if np.isfinite(p_bare):
        lines.append(
            f"  {'P(no canopy return)':<28}{p_bare:8.2f}    the footprint's waveform shows "
            "no return above a bare ground's (the pulse under the fitted broadening) that "
            "stands out of the noise"
        )
        if p_bare >= 0.5:
            lines[-1] += (
                ": the footprint more likely holds no canopy the waveform sees; its stems "
                "are ones it cannot see"
            )
    if np.isfinite(given["median"]):
        lines.append(
            f"  {'canopy height if any':<28}{given['median']:8.3g} m  [{given['p05']:.3g}, "
            f"{given['p95']:.3g}]  the tallest stem, given the footprint holds one its "
            "waveform sees"
        )
    summary = result.summary()
    if "footprint_top_height" in summary:  # every stem, seen or not
        row = summary["footprint_top_height"]
        lines.append(
            f"  {'tallest stem':<28}{row['median']:8.3g} m  [{row['p05']:.3g}, "
            f"{row['p95']:.3g}]  within the footprint's 1/e² radius, whether or not the "
            "waveform sees it"
        )
    return lines


def figure_names(shot_id) -> list:
    """The files ``--plots`` writes for a shot
    (:func:`lidarinv.inference.results.plots.save_plots`)."""
    from lidarinv.inference.results.plots import PLOTS

    return [f"shot_{shot_id}_{name}.png" for name in PLOTS]


def _check_outputs(args, shot_ids) -> None:
    """Refuse, before any sampling, outputs that cannot be written or would replace a
    result: the posterior file and the shots' groups, and the shots' figures."""
    check_hdf5_groups(args.output, [group_of(s) for s in shot_ids], args.overwrite)
    if args.plots is not None:
        names = [name for shot_id in shot_ids for name in figure_names(shot_id)]
        check_plot_folder(args.plots, names, args.overwrite)


def _sample_notes(item) -> list:
    """What the samples hold that the likelihood treats specially, said before sampling."""
    notes = []
    saturated = int(np.count_nonzero(item.saturated_mask))
    if saturated:
        notes.append(f"{saturated} saturated sample(s) enter the likelihood as censored")
    elif clipped_plateau(item.samples):
        notes.append(
            "clipped return (a plateau at the maximum, no saturation level in the file): its "
            "samples enter the likelihood as censored"
        )
    return notes


def run(args) -> int:
    from lidarinv.inference import invert_shot
    from lidarinv.inference.results.plots import save_plots

    if (args.file is None) == (args.example is None):
        raise ValueError("give a waveform file or --example NAME (one of them)")
    if args.example is not None:
        from lidarinv.examples import SYNTHETIC_SHOTS

        if args.example not in SYNTHETIC_SHOTS:
            raise ValueError(f"unknown example {args.example!r}; known: {list(SYNTHETIC_SHOTS)}")
    override = None
    if args.file is not None:
        override = check_instrument(args, inspect_file(args.file, args.format, args.beam))
    # the built-in examples carry no transmitted waveform: no broadening to sample
    settings = inversion_settings(args, measured_pulse=args.example is None)
    _check_outputs(args, [args.example] if args.example is not None else args.shot or [])
    if override:
        print(f"lidarinv invert: warning: {override}", file=sys.stderr)
    rng = np.random.default_rng(args.seed)
    failures, announced = 0, False
    for item in _selected(args, rng):
        if isinstance(item, ShotError):
            print(f"shot {item.shot_id}: skipped: {item.reason}")
            failures += 1
            continue
        group = group_of(item.shot_id)
        _check_outputs(args, [item.shot_id])  # the first shot's id, known now
        for note in _sample_notes(item):
            print(f"lidarinv invert: shot {item.shot_id}: {note}", file=sys.stderr)
        if not announced:
            announced = announce_compilation("lidarinv invert")
        try:
            result = invert_shot(item, settings, rng=rng, progress=not args.quiet)
        except ValueError as error:
            print(f"shot {item.shot_id}: skipped: {error}")
            failures += 1
            continue
        if override:
            result.flags.append(override)
        save_group(args.output, group, result.write)
        print(headline(result))
        print()
        print(result.summary_table())
        if args.plots:
            for path in save_plots(result, args.plots):
                print(f"wrote {path}")
        print(f"wrote {args.output} (group {group})")
    return 1 if failures else 0
