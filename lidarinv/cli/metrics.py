"""``lidarinv metrics``: direct waveform metrics for every shot of a waveform file."""

import json
from pathlib import Path

import numpy as np

from lidarinv.io.formats import FORMATS, iter_observations
from lidarinv.observe.analyse import analyse, json_value
from lidarinv.observe.observation import ShotError

HELP = "noise, signal extent, ground, RH metrics and cover for each shot of a waveform file"

_COLUMNS = ("shot", "noise_mean", "noise_sd", "start", "end", "ground", "RH50", "RH95",
            "RH98", "RH100", "cover", "status")  # fmt: skip


def add_arguments(parser) -> None:
    parser.add_argument("file", type=Path, help="HDF5 waveform file")
    parser.add_argument(
        "--format", default="auto", choices=["auto", *FORMATS], help="file layout (default auto)"
    )
    parser.add_argument("--beam", action="append", help="beam to read (GEDI; repeatable)")
    parser.add_argument("--shots", type=int, help="at most this many shots per beam")
    parser.add_argument("--json", type=Path, help="write all results (RH0–RH100) to this file")
    parser.add_argument("--plot", type=Path, help="write one PNG per shot to this folder")
    parser.add_argument("--n-sigma", type=float, default=4.0, help="floor = mean + n·σ")
    parser.add_argument("--smooth", type=float, default=1.0, help="smoothing σ in bins")
    parser.add_argument(
        "--noise",
        default="auto",
        choices=["auto", "ends", "histogram", "product"],
        help="noise estimate: from the window ends, the histogram, or the file's values",
    )
    parser.add_argument("--rho-ratio", type=float, default=1.5, help="assumed ρv/ρg for cover")


def _row(result) -> str:
    rh = result.rh if result.rh is not None else np.full(101, np.nan)
    values = [result.noise_mean, result.noise_sigma, result.signal_start, result.signal_end,
              result.ground, rh[50], rh[95], rh[98], rh[100], result.cover]  # fmt: skip
    cells = [f"{v:10.3f}" if np.isfinite(v) else f"{'-':>10}" for v in values]
    status = result.status + (f" ({', '.join(result.flags)})" if result.flags else "")
    if result.reason and not result.ok:
        status += f": {result.reason}"
    return f"{result.shot_id!s:>20} " + " ".join(cells) + f"  {status}"


def _plot(obs, result, folder: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(4, 6))
    ax.plot(obs.samples, obs.axis, lw=0.8, color="k")
    ax.axvline(result.floor, color="tab:gray", ls="--", lw=0.8, label="noise floor")
    for value, label, colour in ((result.signal_start, "signal start", "tab:green"),
                                 (result.signal_end, "signal end", "tab:red"),
                                 (result.ground, "ground", "tab:brown")):  # fmt: skip
        if np.isfinite(value):
            ax.axhline(value, color=colour, lw=0.8, label=label)
    ax.set_xlabel("digitiser units")
    ax.set_ylabel(f"{obs.axis_kind} (m)")
    ax.set_title(f"shot {obs.shot_id}: {result.status}", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(folder / f"shot_{obs.shot_id}.png", dpi=80)
    plt.close(fig)


def run(args) -> int:
    if not args.file.exists():
        raise ValueError(f"no such file: {args.file}")
    shots = None if args.shots is None else slice(0, args.shots)
    print(" ".join(f"{c:>20}" if i == 0 else f"{c:>10}" for i, c in enumerate(_COLUMNS)))
    results, n_ok = [], 0
    for item in iter_observations(args.file, args.format, beams=args.beam, shots=shots):
        if isinstance(item, ShotError):
            print(f"{item.shot_id!s:>20} skipped: {item.reason}")
            results.append({"shot_id": item.shot_id, "status": "error", "reason": item.reason,
                            "metadata": _clean(item.metadata)})  # fmt: skip
            continue
        try:
            result = analyse(item, noise=args.noise, n_sigma=args.n_sigma,
                             smooth_bins=args.smooth, rho_ratio=args.rho_ratio)  # fmt: skip
        except ValueError as error:
            print(f"{item.shot_id!s:>20} skipped: {error}")
            results.append({"shot_id": item.shot_id, "status": "error", "reason": str(error),
                            "metadata": _clean(item.metadata)})  # fmt: skip
            continue
        n_ok += result.ok
        print(_row(result))
        results.append(result.to_dict())
        if args.plot:
            _plot(item, result, args.plot)
    print(f"# {len(results)} shot(s), {n_ok} with metrics")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1, default=_json_default))
    return 0 if n_ok or not results else 1


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"cannot write {type(value).__name__} to JSON")


def _clean(metadata: dict) -> dict:
    return {key: json_value(value) for key, value in metadata.items()}
