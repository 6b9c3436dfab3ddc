"""``lidarinv metrics``: ground, RH, cover, PAVD and quality for every shot of a file."""

import csv
import json
import sys
from pathlib import Path

import numpy as np

from lidarinv.io.formats import FORMATS, inspect_file, iter_observations
from lidarinv.observe.analyse import analyse, json_value
from lidarinv.observe.observation import ShotError
from lidarinv.observe.processing import NOISE_SOURCES, processing_settings

from .options import add_instrument_options, check_instrument
from .outputs import check_new_files, check_plot_folder, written_whole

HELP = "ground, RH0–RH100, cover, PAVD and quality flags for each shot of a waveform file"

_HEADER = ("shot", "latitude", "longitude", "ground", "±", "RH50", "RH98", "RH100",
           "cover", "sens.", "status")  # fmt: skip


def add_arguments(parser) -> None:
    parser.add_argument("file", type=Path, help="HDF5 waveform file (GEDI L1B, LVIS L1B, lidarinv)")
    parser.add_argument(
        "--format", default="auto", choices=["auto", *FORMATS], help="file layout (default auto)"
    )
    parser.add_argument("--beam", action="append", help="beam to read (GEDI; repeatable)")
    parser.add_argument("--shots", type=int, help="at most this many shots per beam")
    add_instrument_options(parser)
    parser.add_argument("--json", type=Path, help="write every shot's record to this JSON file")
    parser.add_argument("--csv", type=Path, help="write every shot's record to this CSV file")
    parser.add_argument("--plot", type=Path, help="write one PNG per shot to this folder")
    parser.add_argument(
        "--noise",
        choices=NOISE_SOURCES,
        help="measure the noise on the samples (default) or take the file's noise fields",
    )
    parser.add_argument("--rho-ratio", type=float, help="assumed ρv/ρg for cover (default 1.5)")
    parser.add_argument("--quiet", action="store_true", help="no table on the terminal")
    parser.add_argument(
        "--overwrite", action="store_true", help="replace existing --json/--csv files and figures"
    )


def _beam_cell(item, has_beams) -> str:
    return f" {item.metadata.get('beam', '-')!s:>8}" if has_beams else ""


def _row(result, beam="") -> str:
    rh = result.rh if result.rh is not None else np.full(101, np.nan)
    values = (result.latitude, result.longitude, result.ground, result.ground_uncertainty,
              rh[50], rh[98], rh[100], result.cover, result.sensitivity)  # fmt: skip
    formats = ("9.5f", "10.5f", "9.2f", "5.2f", "6.2f", "6.2f", "6.2f", "6.3f", "5.2f")
    cells = [
        format(v, f) if np.isfinite(v) else "-".rjust(int(f.split(".")[0]))
        for v, f in zip(values, formats)
    ]
    status = result.status + (f" ({', '.join(result.flags)})" if result.flags else "")
    if result.reason and not result.ok:
        status += f": {result.reason}"
    return f"{result.shot_id!s:>20}{beam} " + " ".join(cells) + f"  {status}"


def _header(has_beams=False) -> str:
    names, widths = list(_HEADER), [20, 9, 10, 9, 5, 6, 6, 6, 6, 5]
    if has_beams:
        names.insert(1, "beam")
        widths.insert(1, 8)
    cells = [name.rjust(width) for name, width in zip(names, widths)]
    return " ".join(cells) + "  " + names[-1]


def _with_beam(record, item, has_beams) -> dict:
    """``record`` with the shot's beam as its second key (formats with beams)."""
    if not has_beams:
        return record
    first, *rest = record.items()
    return dict([first, ("beam", json_value(item.metadata.get("beam"))), *rest])


def _error_record(item, reason) -> dict:
    meta = {key: json_value(value) for key, value in item.metadata.items()}
    return {"shot_id": json_value(item.shot_id), "status": "error", "reason": reason,
            "metadata": meta}  # fmt: skip


def _write_csv(path: Path, records) -> None:
    """One row per shot; flags joined by ';', metadata columns prefixed ``meta_`` (the
    beam, a plain column near the front, is not repeated)."""
    rows = []
    for record in records:
        row = {k: v for k, v in record.items() if k not in ("metadata", "flags")}
        row["flags"] = ";".join(record.get("flags", []))
        meta = record.get("metadata", {})
        row.update({f"meta_{k}": v for k, v in meta.items() if k not in record})
        rows.append(row)
    columns = list(dict.fromkeys(key for row in rows for key in row))
    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)


def _check_outputs(args) -> None:
    """Refuse, before any shot is read, outputs that cannot be written or would replace
    a file: the JSON and CSV files, and earlier figures in the --plot folder."""
    files = [(args.json, "JSON file"), (args.csv, "CSV file")]
    check_new_files([(path, what) for path, what in files if path is not None], args.overwrite)
    if args.plot:
        check_plot_folder(args.plot, overwrite=args.overwrite, pattern="shot_*.png")


def _terrain(path, analysed, records, echo, has_beams) -> int:
    """Flag grounds that leave their track neighbours (:mod:`lidarinv.observe.terrain`);
    the records, (index, analysis, observation) in ``analysed``, are rewritten with the
    check; returns the number of quality shots."""
    from lidarinv.observe.terrain import TERRAIN_FLAG, file_dem, flag_terrain

    results = [result for _, result, _ in analysed]
    if results:
        flag_terrain(results, file_dem(path, results))
    for index, result, item in analysed:
        records[index] = _with_beam(result.to_dict(), item, has_beams)
    outliers = [str(r.shot_id) for r in results if TERRAIN_FLAG in r.flags]
    if outliers:
        echo(f"# {TERRAIN_FLAG}: {len(outliers)} shot(s): {', '.join(outliers)}")
    return sum(r.quality for r in results)


def run(args) -> int:
    summary = inspect_file(args.file, args.format, args.beam)
    override = check_instrument(args, summary)
    _check_outputs(args)
    shots = None if args.shots is None else slice(0, args.shots)
    echo = print if not args.quiet else (lambda *a, **k: None)
    if override:
        print(f"lidarinv metrics: warning: {override}", file=sys.stderr)
    echo(_header(summary.has_beams))
    records, n_ok, analysed = [], 0, []
    for item in iter_observations(args.file, summary.format, beams=args.beam, shots=shots):
        beam = _beam_cell(item, summary.has_beams)
        if isinstance(item, ShotError):
            echo(f"{item.shot_id!s:>20}{beam} skipped: {item.reason}")
            records.append(_with_beam(_error_record(item, item.reason), item, summary.has_beams))
            continue
        try:
            instrument = args.instrument or item.instrument
            settings = processing_settings(instrument, noise=args.noise, rho_ratio=args.rho_ratio)
            result = analyse(item, settings, instrument=args.instrument)
        except ValueError as error:
            echo(f"{item.shot_id!s:>20}{beam} skipped: {error}")
            records.append(_with_beam(_error_record(item, str(error)), item, summary.has_beams))
            continue
        if override:
            result.flags.append(override)
        n_ok += result.ok
        echo(_row(result, beam))
        analysed.append((len(records), result, item))
        records.append(_with_beam(result.to_dict(), item, summary.has_beams))
        if args.plot:
            from lidarinv.observe.figures import save_analysis_figure

            save_analysis_figure(item, result, args.plot / f"shot_{item.shot_id}.png")
    n_quality = _terrain(args.file, analysed, records, echo, summary.has_beams)
    print(f"# {len(records)} shot(s): {n_ok} with metrics, {n_quality} quality")
    if args.json:
        with written_whole(args.json) as partial:
            partial.write_text(json.dumps(records, indent=1))
        print(f"# wrote {args.json}")
    if args.csv:
        with written_whole(args.csv) as partial:
            _write_csv(partial, records)
        print(f"# wrote {args.csv}")
    return 0 if n_ok or not records else 1
