"""``lidarinv simulate``: waveforms of an explicit stand."""

import numpy as np

import forward as fw
from forward.examples import EXAMPLES, example

from .outputs import check_new_file, written_whole

HELP = "simulate waveforms of an explicit stand (stem-map CSV or a built-in example)"


def add_arguments(parser):
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument(
        "stemmap",
        nargs="?",
        help="stem-map CSV (x, y, height, crown_length, crown_radius, shape, favd[, dbh, species])",
    )
    source.add_argument("--example", choices=sorted(EXAMPLES), help="built-in example scene")
    parser.add_argument(
        "--instrument",
        choices=sorted(fw.INSTRUMENT_PRESETS),
        help="instrument preset (default: gedi, or the example's)",
    )
    parser.add_argument("--footprint-sigma", type=float, metavar="M", help="footprint σf (m)")
    parser.add_argument("--pulse-fwhm", type=float, metavar="NS", help="pulse FWHM (ns)")
    parser.add_argument("--bin-ns", type=float, metavar="NS", help="digitiser bin (ns)")
    parser.add_argument(
        "--center",
        type=float,
        nargs=2,
        action="append",
        metavar=("X", "Y"),
        help="footprint centre (m); repeat for several footprints",
    )
    parser.add_argument("--rho-v", type=float, help="canopy reflectance ρv (default 0.45)")
    parser.add_argument("--rho-g", type=float, help="ground reflectance ρg (default 0.3)")
    parser.add_argument("--hotspot-k", type=float, help="hot-spot exponent k in [1, 2]")
    parser.add_argument("--shape", choices=fw.SHAPE_NAMES, help="give every crown this shape")
    parser.add_argument("-o", "--output", required=True, help="output HDF5 file")
    parser.add_argument("--plot", help="PNG of waveforms beside crown-volume profiles")
    parser.add_argument(
        "--overwrite", action="store_true", help="replace the output file if it exists"
    )


def run(args) -> int:
    from lidarinv.io.simulation import write_simulation

    check_new_file(args.output, args.overwrite, "output")
    if args.plot:
        check_new_file(args.plot, args.overwrite, "figure")
    if args.example:
        scene = example(args.example)
        stand, instrument, centers = scene.stand, scene.instrument, scene.centers
        ground, rho_v = scene.ground, scene.canopy_reflectance
    else:
        stand = fw.Stand.from_csv(args.stemmap)
        instrument = fw.instrument_preset("gedi")
        centers = np.array([[stand.x.mean(), stand.y.mean()]]) if stand.n_trees else [[0, 0]]
        ground, rho_v = fw.Ground(), fw.explicit.DEFAULT_CANOPY_REFLECTANCE
    if args.instrument:
        instrument = fw.instrument_preset(args.instrument)
    instrument = instrument.with_overrides(
        footprint_sigma_m=args.footprint_sigma,
        pulse_fwhm_ns=args.pulse_fwhm,
        bin_ns=args.bin_ns,
        hotspot_k=args.hotspot_k,
    )
    if args.center:
        centers = np.array(args.center)
    if args.rho_g is not None:
        ground = fw.Ground(args.rho_g, ground.slope_deg, ground.aspect_deg)
    if args.rho_v is not None:
        rho_v = args.rho_v
    if args.shape:
        stand = stand.with_shape(args.shape)

    simulator = fw.WaveformSimulator(instrument)
    waveforms = simulator.simulate_many(stand, centers, ground=ground, canopy_reflectance=rho_v)
    with written_whole(args.output) as partial:
        source = {"source": args.example or str(args.stemmap)}
        write_simulation(partial, waveforms, stand, source)
    print(
        f"{'footprint':>9} {'x (m)':>8} {'y (m)':>8} {'top (m)':>8} {'P(0)':>6} "
        f"{'canopy':>7} {'ground':>7}"
    )
    for i, wf in enumerate(waveforms):
        signal = wf.canopy > 1e-3 * max(wf.canopy.max(), 1e-300)
        top = wf.heights[signal].max() if signal.any() else 0.0
        print(
            f"{i:>9} {wf.center[0]:>8.1f} {wf.center[1]:>8.1f} {top:>8.2f} "
            f"{wf.ground_gap:>6.3f} {wf.canopy_energy:>7.4f} {wf.ground_energy:>7.4f}"
        )
    print(f"wrote {len(waveforms)} waveform(s) to {args.output}")
    if args.plot:
        from lidarinv.plotting import plot_waveforms

        with written_whole(args.plot) as partial:
            title = f"{args.example or args.stemmap} ({instrument.name})"
            plot_waveforms(waveforms, partial, title=title)
        print(f"wrote {args.plot}")
    return 0
