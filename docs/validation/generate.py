"""Write the validation pages from the studies' published JSON summaries.

Each page section reads ``docs/validation/data/<key>.json``, written by
``python studies/publish.py KEY --command "..."`` from a study's own summary, and turns
it into tables and a figure. Where a summary has not been published, the section says so
and gives the command that would produce it; the build does not fail.

Run by ``docs/conf.py`` before Sphinx reads the sources; writes
``docs/validation/generated/<page>.rst`` and its figures.
"""

import json
from pathlib import Path

from .render import (
    missing,
    render_batch,
    render_coverage,
    render_forward_accuracy,
    render_generic,
    render_real_products,
    render_speed,
)
from .render_inversion import render_real_inversion
from .render_reference import (
    render_continuity,
    render_coordinates_vs_reference,
    render_preparation_spread,
    render_time_vs_error,
)

#: Page → (title, intro, sections); a section is (key, heading, renderer, how to run it).
PAGES = {
    "accuracy": (
        "Accuracy",
        "How close the fast models come to slow references, and what it costs. How "
        "closely the inversion recovers known truths is on :doc:`calibration`.",
        [
            (
                "forward-accuracy",
                "Explicit engine against a converged run and a brute-force grid",
                render_forward_accuracy,
                "python studies/forward_runtime_vs_error.py --quick",
            ),
            (
                "expected-model-accuracy",
                "Expected-waveform model against its exact integral",
                render_generic,
                "python studies/stand_model_runtime_vs_error.py --quick",
            ),
            (
                "continuity",
                "Steps in the log-likelihood of real shots",
                render_continuity,
                "python studies/continuity.py --data DATA --shots lvis:ID:2 gedi:ID:1 ... "
                "--tag _TAG",
            ),
        ],
    ),
    "speed": (
        "Speed",
        "Wall time of an inversion and of a batch, one core each.",
        [
            (
                "inversion-speed",
                "One GEDI footprint to 50 τ",
                render_speed,
                "python studies/inversion_speed.py --n 6 --repeats 3 --config 10-free",
            ),
            (
                "inversion-speed-real",
                "Real shots against long reference runs: time against error",
                render_time_vs_error,
                "python studies/reference_posteriors.py --data DATA --gedi-shots ID ... "
                "--lvis-shots ID ... --steps 25000 --restarts 4; python "
                "studies/inversion_speed.py --data DATA --gedi-shots ID ... --lvis-shots ID ... "
                "--min-taus 10 20 --tag _real",
            ),
            (
                "preparation-spread",
                "Real shots prepared with other seeds: the spread, and what the runs stated",
                render_preparation_spread,
                "python studies/preparation_spread.py --data DATA --gedi-shots ID ... "
                "--lvis-shots ID ... --counts 256 --seeds 6 --tag _TAG",
            ),
            (
                "sampling-coordinates-real",
                "Sampling coordinates on the same real posteriors, against the long reference runs",
                render_coordinates_vs_reference,
                "python studies/sampling_coordinates.py --data DATA --lvis-shots ID ... "
                "--reference-file tests/data/reference_posteriors.json --coordinates LABEL "
                "... --tag _TAG; python studies/sampling_coordinates.py --combine _TAG ... "
                "--tag _real",
            ),
            (
                "batch-throughput",
                "Batch overhead and the coordinator's ceiling",
                render_batch,
                "python studies/batch_throughput.py --fake --shots 200 --workers 1 2",
            ),
            (
                "scaling",
                "Cost against the scene",
                render_generic,
                "python studies/scaling.py",
            ),
        ],
    ),
    "calibration": (
        "Calibration",
        "Truths drawn from the prior the inversion uses: Bayesian intervals must then "
        "cover at their nominal rate, whatever the prior's width. Truths from outside the "
        "model family (``studies/out_of_family_stands.py``: skewed heights, two storeys, "
        "an emergent tree, clumped, sparse and dense stands) show what the model's "
        "simplifications cost; they are compared on what the footprint holds (its crown "
        "cover and gap cover, its tallest stem within 2 σf, the RH98 of its noise-free "
        "waveform, the ground), and the target is 90 % intervals holding at least 85 % of "
        "those truths of cover, tallest stem and ground.",
        [
            (
                "calibration",
                "Explicit stands, truths from the prior",
                render_coverage,
                "python studies/recovery.py --n 200 --max-steps 20000 --workers 2 --truth prior "
                "--priors studies/calibration_priors.toml --tag _calibration",
            ),
            (
                "calibration-out-of-family",
                "Explicit stands from outside the model family",
                render_coverage,
                "python studies/recovery.py --truth out-of-family --n 42 --max-steps 20000 "
                "--workers 2 --tag _out_of_family",
            ),
        ],
    ),
    "real-products": (
        "Real products",
        "lidarinv against the GEDI L2A/L2B and LVIS L2 products on the shots of spatial "
        "subsets of public NASA products (other shots of the same acquisitions are kept "
        "aside to check the work). GEDI: orbit O01964 of 2019-04-18 over cerrado savanna "
        "in Brazil, granules ``GEDI01_B_2019108080338_O01964_T05337_02_003_01``, "
        "``GEDI02_A_…_02_001_01`` and ``GEDI02_B_…_02_001_01`` (Dubayah et al., GEDI L1B, "
        "L2A and L2B version 1, NASA LP DAAC; subsets as distributed with the rGEDI "
        "package's examples). LVIS: the AfriSAR 2016 campaign over the Mondah forest, "
        "Gabon, granule ``ILVIS1B_GA2016_0308_R1701_045736`` and its L2 (Blair and Hofton, "
        "AfriSAR LVIS L1B and L2 version 1, NASA NSIDC DAAC; clipped as distributed with "
        "the rLVIS package's examples). Both archives serve the granules free after an "
        "Earthdata login; a few shots of each ship with lidarinv "
        "(:func:`lidarinv.io.example_file`).",
        [
            (
                "real-products",
                "Direct metrics against the products",
                render_real_products,
                "python studies/real_products.py",
            ),
            (
                "real-inversion",
                "Posteriors against the products: the shipped examples",
                render_real_inversion,
                "python studies/real_inversion.py --data examples --workers 2",
            ),
            (
                "real-inversion-shared",
                "Posteriors against the products: the development files (every GEDI "
                "quality shot; the first 12 LVIS ones)",
                render_real_inversion,
                "python studies/real_inversion.py --instrument gedi --tag _shared_gedi; "
                "python studies/real_inversion.py --instrument lvis --max-shots 12 "
                "--tag _shared_lvis; python studies/real_inversion.py --combine _shared_gedi "
                "_shared_lvis --tag _shared",
            ),
            (
                "real-inversion-tall",
                "Posteriors against the products: the tall LVIS flight line (LFID "
                "1657455164, L2 RH98 27–50 m, weak grounds under closed canopies)",
                render_real_inversion,
                "python studies/real_inversion.py --data DATA --instrument "
                "lvis --skip-shots 155 --workers 2 --tag _tall",
            ),
        ],
    ),
}


def page_text(page: str, data: Path, figures: Path) -> str:
    title, intro, sections = PAGES[page]
    text = f"{title}\n{'=' * len(title)}\n\n{intro}\n\n"
    for key, heading, render, how in sections:
        text += f"{heading}\n{'-' * len(heading)}\n\n"
        path = data / f"{key}.json"
        if path.exists():
            text += render(json.loads(path.read_text()), figures, key) + "\n"
        else:
            text += missing(key, how) + "\n"
    return text


def write_validation_pages(folder) -> list:
    """Write ``generated/<page>.rst`` for every page of :data:`PAGES`; returns the paths."""
    folder = Path(folder)
    out = folder / "generated"
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for page in PAGES:
        path = out / f"{page}.rst"
        text = page_text(page, folder / "data", out)
        if not path.exists() or path.read_text() != text:
            path.write_text(text)
        paths.append(path)
    return paths
