"""Direct metrics of real GEDI and LVIS shots against the NASA products of the same shots.

Runs ``lidarinv.observe.analyse`` with default options on every shot of the GEDI L1B and
LVIS L1B files and compares ground, RH50, RH98, RH100 and cover with GEDI L2A/L2B and
LVIS L2: median difference, median and 90th percentile of |difference|, fraction within
1 m. The GEDI statistics use the L2A quality shots (``quality_flag == 1``). The cover
comparison is repeated at ρv/ρg = 1 and 2 to show how much of it the assumed ratio
carries. Each file's shots are checked against their track neighbours
(:mod:`lidarinv.observe.terrain`), as ``lidarinv metrics`` does.

Where the RH offsets come from: ``rh_profile`` gives the median difference at each
percentile the product has (RH10 … RH100), and RH recomputed in the same convention with
the window's top moved to the product's own signal start (GEDI L2A
``elev_highestreturn``, LVIS L2 ZT), which shows how much of each offset the signal start
carries.

The LVIS shots are also reported per flight line (grouped by the ``LFID`` the file
gives each shot): the ground of every shot with one, against L2 ZG, counting the shots
more than 1 m and 3 m off and those more than 3 m off that carry no flag (status other
than ok, "ground ambiguous" or "terrain outlier"). The flight line with the tallest
canopy (largest median L2 RH98) gets a figure of its worst shots: the waveform, the
chosen ground and its alternative, and the L2 ZG.

    python studies/real_products.py [--data ../shared/data/real] [--tag _NAME]

``--data examples`` runs on the files shipped in ``lidarinv/data``. Writes
``studies/output/real_products{tag}/`` with ``summary.json``, ``scatter.png`` (metrics
against the products) and ``waveforms.png`` (example shots with floors, signal extent and
ground marked) and ``tall_line_worst.png``.
"""

import time
from pathlib import Path

import harness
import numpy as np
from real_products_figures import scatter_figure, tall_line_figure, waveform_figure

from lidarinv.io import (
    example_file,
    iter_observations,
    read_gedi_l2a,
    read_gedi_l2b,
    read_lvis_l2,
)
from lidarinv.observe import Observation, analyse, processing_settings, rh_metrics
from lidarinv.observe.signal import smooth
from lidarinv.observe.terrain import TERRAIN_FLAG, file_dem, flag_terrain

HERE = Path(__file__).resolve().parent
DEFAULT_DATA = HERE.parent.parent / "shared" / "data" / "real"
QUANTITIES = ("ground", "rh50", "rh98", "rh100", "cover")
#: Percentiles compared one by one (those LVIS L2 gives from RH10 up).
PROFILE_PERCENTILES = (10, 25, 50, 75, 90, 95, 96, 97, 98, 99, 100)
#: Flags that tell a user the ground may be wrong (besides a status other than ok).
GROUND_WARNINGS = ("ground ambiguous", TERRAIN_FLAG)


def data_files(data: str):
    if data == "examples":
        names = ("gedi-l1b", "gedi-l2a", "gedi-l2b", "lvis-l1b", "lvis-l2")
        return {name: example_file(name) for name in names}
    root = Path(data)

    def one(pattern):
        found = sorted(root.glob(pattern))
        if len(found) != 1:
            raise SystemExit(f"expected one {pattern} in {root}, found {len(found)}")
        return found[0]

    return {
        "gedi-l1b": one("GEDI01_B_*.h5"),
        "gedi-l2a": one("GEDI02_A_*.h5"),
        "gedi-l2b": one("GEDI02_B_*.h5"),
        "lvis-l1b": one("LVIS1B_*.h5"),
        "lvis-l2": one("LVIS2_*.txt"),
    }


def differences(pairs) -> dict:
    """Statistics of ours − product over the shots where both exist."""
    d = np.array([a - b for a, b in pairs if np.isfinite(a) and np.isfinite(b)])
    if d.size == 0:
        return {"n": 0}
    return {
        "n": int(d.size),
        "median": float(np.median(d)),
        "median_abs": float(np.median(np.abs(d))),
        "p90_abs": float(np.percentile(np.abs(d), 90)),
        "max_abs": float(np.max(np.abs(d))),
        "within_1m": float(np.mean(np.abs(d) <= 1.0)),
    }


def rh_profile(rows, product_rh, product_top) -> dict:
    """Median ours − product at each of :data:`PROFILE_PERCENTILES`, as analysed and with
    the RH window's top at the product's signal start (same energy, ground and bottom).

    ``product_rh(shot)`` gives the product's 101 RH (NaN where it has none) or None to
    skip the shot; ``product_top(shot)`` its signal start (m, on the shot's axis)."""
    levels = np.array(PROFILE_PERCENTILES)
    as_analysed, at_top, start = [], [], []
    for obs, result, _, shot in rows:
        theirs = product_rh(shot) if result is not None and result.ok else None
        if theirs is None:
            continue
        top = product_top(shot)
        settings = processing_settings(result.instrument)
        energy = smooth(obs.samples, result.smoothing_bins) if settings.rh_smoothed else obs.samples
        baseline = result.noise.mean if settings.rh_energy == "above-noise" else 0.0
        theirs = np.asarray(theirs, float)[levels]
        as_analysed.append(result.rh[levels] - theirs)
        if np.isfinite(top) and result.signal_end < top:
            moved = rh_metrics(
                energy, obs.axis, result.ground, noise_mean=baseline,
                start=top, end=result.signal_end, percentiles=levels,
            )  # fmt: skip
            at_top.append(moved - theirs)
            start.append(result.signal_start - top)

    def medians(diffs):
        if not diffs:
            return {}
        table = np.array(diffs)
        return {
            f"rh{p}": float(np.nanmedian(column)) if np.isfinite(column).any() else None
            for p, column in zip(levels, table.T)
        }

    return {
        "n": len(as_analysed),
        "signal_start_minus_product_median": float(np.median(start)) if start else None,
        "as_analysed": medians(as_analysed),
        "window_top_at_product_start": medians(at_top),
    }


def analyse_file(path):
    """Every shot of a file: (observation or None, analysis or None, error text)."""
    rows, seconds = [], []
    for item in iter_observations(path):
        if not isinstance(item, Observation):
            rows.append((None, None, f"unreadable: {item.reason}", item.shot_id))
            continue
        start = time.perf_counter()
        try:
            result = analyse(item)
            error = ""
        except Exception as exc:  # the study counts exceptions; none may occur
            result, error = None, f"exception: {type(exc).__name__}: {exc}"
        seconds.append(time.perf_counter() - start)
        rows.append((item, result, error, item.shot_id))
    results = [result for _, result, _, _ in rows if result is not None]
    if results:
        flag_terrain(results, file_dem(path, results))
    return rows, seconds


def _status_counts(rows) -> dict:
    statuses, flags, reasons = {}, {}, {}
    for _, result, error, _ in rows:
        status = result.status if result is not None else ("error" if error else "?")
        statuses[status] = statuses.get(status, 0) + 1
        if result is not None:
            for flag in result.flags:
                flags[flag] = flags.get(flag, 0) + 1
            if not result.ok:
                reasons[result.reason] = reasons.get(result.reason, 0) + 1
        elif error:
            reasons[error] = reasons.get(error, 0) + 1
    return {"statuses": statuses, "flags": flags, "reasons": reasons}


def gedi_study(files):
    rows, seconds = analyse_file(files["gedi-l1b"])
    l2a, l2b = read_gedi_l2a(files["gedi-l2a"]), read_gedi_l2b(files["gedi-l2b"])
    records = []
    for obs, result, _, shot in rows:
        product = l2a.get(shot)
        if product is None or result is None or not result.ok:
            continue
        cover = l2b.get(shot, {})
        ratio = cover.get("rhov", np.nan) / cover.get("rhog", np.nan)
        record = {
            "shot": shot,
            "quality": product["quality_flag"] == 1,
            "ours": _ours(result),
            "product": {
                "ground": float(product["elev_lowestmode"]),
                **{f"rh{p}": float(product["rh"][p]) for p in (50, 98, 100)},
                "cover": float(cover.get("cover", np.nan)),
            },
            "cover_at_ratio": {
                r: analyse(obs, processing_settings("gedi", rho_ratio=r)).cover for r in (1.0, 2.0)
            },
            "product_ratio": float(ratio),
        }
        records.append(record)
    quality = [r for r in records if r["quality"]]
    summary = {
        "shots": len(rows),
        "quality_shots": len(quality),
        **_status_counts(rows),
        "seconds_per_shot": float(np.median(seconds)),
        "differences": {
            q: differences((r["ours"][q], r["product"][q]) for r in quality) for q in QUANTITIES
        },
        "cover_ratio": _cover_ratio(quality),
        "rh_profile": rh_profile(
            rows,
            lambda s: l2a[s]["rh"] if s in l2a and l2a[s]["quality_flag"] == 1 else None,
            lambda s: float(l2a[s]["elev_highestreturn"]),
        ),
        "ground_all_shots": ground_check(
            rows,
            lambda s: (
                float(l2a[s]["elev_lowestmode"])
                if s in l2a and l2a[s]["quality_flag"] == 1
                else np.nan
            ),
        ),
    }
    return summary, rows, records


def _ours(result) -> dict:
    return {
        "ground": float(result.ground),
        **{f"rh{p}": float(result.rh[p]) for p in (50, 98, 100)},
        "cover": float(result.cover),
    }


def _cover_ratio(records) -> dict:
    """How cover moves with the assumed ρv/ρg (GEDI L2B's own ratio is in the file)."""
    if not records:
        return {}
    low = np.array([r["cover_at_ratio"][1.0] for r in records])
    high = np.array([r["cover_at_ratio"][2.0] for r in records])
    ours = np.array([r["ours"]["cover"] for r in records])
    return {
        "product_ratio_median": float(np.nanmedian([r["product_ratio"] for r in records])),
        "median_cover_at_1": float(np.median(low)),
        "median_cover_at_1_5": float(np.median(ours)),
        "median_cover_at_2": float(np.median(high)),
        "median_change_per_unit_ratio": float(np.median(high - low)),
    }


def flagged(result) -> bool:
    """The shot tells its user that its ground may be wrong."""
    return not result.ok or any(flag in result.flags for flag in GROUND_WARNINGS)


def ground_check(rows, product_ground) -> dict:
    """Every shot with a ground (whatever its status) against the product's ground."""
    d, warned = [], []
    for _, result, _, shot in rows:
        truth = product_ground(shot)
        if result is None or not np.isfinite(result.ground) or not np.isfinite(truth):
            continue
        d.append(result.ground - truth)
        warned.append(flagged(result))
    d, warned = np.abs(np.array(d)), np.array(warned, bool)
    if d.size == 0:
        return {"n": 0}
    return {
        "n": int(d.size),
        "within_1m": float(np.mean(d <= 1.0)),
        "over_1m": int(np.sum(d > 1.0)),
        "over_3m": int(np.sum(d > 3.0)),
        "over_3m_unflagged": int(np.sum((d > 3.0) & ~warned)),
        "flagged": int(warned.sum()),
        "median_abs": float(np.median(d)),
    }


def lvis_groups(rows, l2) -> dict:
    """Per flight line (the file's LFID): shots, statuses, flags, ground check and the
    ok shots' differences, with the median L2 RH98 that tells the tall line apart."""
    groups = {}
    for row in rows:
        obs = row[0]
        lfid = obs.metadata.get("lfid", "?") if obs is not None else "?"
        groups.setdefault(str(lfid), []).append(row)
    out = {}
    for lfid, members in groups.items():
        zg = {shot: l2[shot]["zg"] for *_, shot in members if shot in l2}
        rh98 = [l2[shot]["rh"][98] for shot in zg if np.isfinite(l2[shot]["rh"][98])]
        out[lfid] = {
            "shots": len(members),
            "product_rh98_median": float(np.median(rh98)) if rh98 else float("nan"),
            **_status_counts(members),
            "ground_all_shots": ground_check(members, lambda s, zg=zg: zg.get(s, np.nan)),
            "rh_profile": _lvis_rh_profile(members, l2),
            "differences": {
                q: differences(
                    (_ours(r)[q], _lvis_product(l2[s])[q])
                    for _, r, _, s in members
                    if r is not None and r.ok and s in l2
                )
                for q in QUANTITIES[:-1]
            },
        }
    return out


def _lvis_rh_profile(rows, l2) -> dict:
    return rh_profile(rows, lambda s: l2[s]["rh"] if s in l2 else None, lambda s: l2[s]["zt"])


def _lvis_product(product) -> dict:
    return {
        "ground": float(product["zg"]),
        **{f"rh{p}": float(product["rh"][p]) for p in (50, 98, 100)},
    }


def lvis_study(files):
    rows, seconds = analyse_file(files["lvis-l1b"])
    l2 = read_lvis_l2(files["lvis-l2"])
    records = []
    for _, result, _, shot in rows:
        product = l2.get(shot)
        if product is None or result is None or not result.ok:
            continue
        ours = _ours(result)
        ours.pop("cover")
        records.append({"shot": shot, "ours": ours, "product": _lvis_product(product)})
    summary = {
        "shots": len(rows),
        "shots_in_l2": len(records),
        **_status_counts(rows),
        "seconds_per_shot": float(np.median(seconds)),
        "differences": {
            q: differences((r["ours"][q], r["product"][q]) for r in records)
            for q in QUANTITIES[:-1]
        },
        "ground_all_shots": ground_check(rows, lambda s: l2[s]["zg"] if s in l2 else np.nan),
        "rh_profile": _lvis_rh_profile(rows, l2),
        "flight_lines": lvis_groups(rows, l2),
    }
    return summary, rows, records


def pick_examples(instrument, rows, records):
    """Typical (median |ground difference|), worst, and the shot with most modes."""
    by_shot = {shot: (obs, result) for obs, result, _, shot in rows if result is not None}
    scored = sorted(records, key=lambda r: abs(r["ours"]["ground"] - r["product"]["ground"]))
    if not scored:
        return []
    chosen = {"typical": scored[len(scored) // 2], "worst": scored[-1]}
    chosen["most modes"] = max(records, key=lambda r: by_shot[r["shot"]][1].n_modes)
    out = []
    for label, record in chosen.items():
        obs, result = by_shot[record["shot"]]
        out.append((f"{instrument} {label}", obs, result, record["product"]["ground"]))
    return out


def _print_profile(profile) -> None:
    start = profile["signal_start_minus_product_median"]
    print(f"  RH ours − product (median of {profile['n']} shots; signal start − product's "
          f"{start:+.3f} m):" if start is not None else "  RH ours − product:")  # fmt: skip
    for label, key in (
        ("as analysed", "as_analysed"),
        ("top at product's", "window_top_at_product_start"),
    ):
        cells = [f"{k}:{v:+.2f}" for k, v in profile[key].items() if v is not None]
        print(f"    {label:17s}" + " ".join(cells))


def main(argv=None):
    parser = harness.parser(__doc__)
    parser.add_argument("--data", default=str(DEFAULT_DATA), help="folder, or 'examples'")
    args = parser.parse_args(argv)
    files = data_files(args.data)
    out = harness.output_folder("real_products", args.tag)
    gedi, gedi_rows, gedi_records = gedi_study(files)
    lvis, lvis_rows, lvis_records = lvis_study(files)
    summary = {
        "data": {k: Path(v).name for k, v in files.items()},
        "settings": {"gedi": "processing_settings('gedi')", "lvis": "processing_settings('lvis')"},
        "gedi": gedi,
        "lvis": lvis,
    }
    harness.write_json(out / "summary.json", summary)
    quality = [r for r in gedi_records if r["quality"]]
    scatter_figure(quality, lvis_records, out / "scatter.png")
    examples = pick_examples("GEDI", gedi_rows, quality)
    examples += pick_examples("LVIS", lvis_rows, lvis_records)
    waveform_figure(examples, out / "waveforms.png")
    l2 = read_lvis_l2(files["lvis-l2"])
    tall = tall_line_figure(lvis_rows, l2, lvis["flight_lines"], out / "tall_line_worst.png")
    for name, part in (("GEDI", gedi), ("LVIS", lvis)):
        print(f"{name}: {part['shots']} shots, statuses {part['statuses']}, flags {part['flags']}")
        for q, d in part["differences"].items():
            if d["n"]:
                print(f"  {q:7s} n={d['n']:3d} median {d['median']:+.3f}  |d| median "
                      f"{d['median_abs']:.3f}  p90 {d['p90_abs']:.3f}  within 1 m "
                      f"{d['within_1m']:.3f}")  # fmt: skip
        print(f"  ground over every shot with one: {part['ground_all_shots']}")
        _print_profile(part["rh_profile"])
    for lfid, line in lvis["flight_lines"].items():
        label = " (tallest canopy)" if lfid == tall else ""
        print(f"LVIS flight line {lfid}{label}: {line['shots']} shots, L2 RH98 median "
              f"{line['product_rh98_median']:.1f} m, statuses {line['statuses']}, "
              f"flags {line['flags']}")  # fmt: skip
        print(f"  ground over every shot with one: {line['ground_all_shots']}")
        _print_profile(line["rh_profile"])
    print(f"cover against ρv/ρg: {gedi['cover_ratio']}")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
