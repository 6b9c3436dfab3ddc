"""Write the API reference's package pages from each public package's ``__all__``.

The pages name every object through its package (``forward.Stand``,
``lidarinv.inference.invert_shot``), never through the private module that defines it,
so moving code between modules inside a package changes nothing here.
"""

import importlib
from pathlib import Path

#: Public packages, in the order of the reference, with one line on each.
PACKAGES = {
    "forward": "The physics: explicit stands, the 3-D waveform engine, the expected "
    "waveform of a parameterised stand, instruments and pulses.",
    "lidarinv.observe": "Observations: the observation model, noise, signal extent, "
    "ground peak, alignment and direct metrics (RH, cover).",
    "lidarinv.io": "Files: the lidarinv waveform layout, mission readers, simulation output.",
    "lidarinv.inference": "Bayesian inversion of one shot: parameters, priors, likelihood, "
    "posterior, sampling and results.",
    "lidarinv.batch": "Many shots at once, on local processes or a Dask cluster, into one "
    "resumable file.",
    "lidarinv.export": "The posterior in other tools (ArviZ).",
    "lidarinv.plotting": "Figure helpers shared by the command line.",
}


def public_names(package: str) -> list:
    module = importlib.import_module(package)
    names = getattr(module, "__all__", None)
    if names is None:  # a module without __all__: its public functions
        names = [
            name
            for name, value in vars(module).items()
            if not name.startswith("_")
            and callable(value)
            and getattr(value, "__module__", "") == package
        ]
    return sorted(names, key=lambda n: (not n[0].isupper() or n.isupper(), n.lower()))


def package_page(package: str, blurb: str) -> str:
    title = f"``{package}``"
    lines = [title, "=" * len(title), "", blurb, "", f".. automodule:: {package}", ""]
    lines += [
        ".. autosummary::",
        "   :toctree: ../generated",
        "   :nosignatures:",
        "",
    ]
    module = importlib.import_module(package)
    names = public_names(package)
    documented = [n for n in names if callable(getattr(module, n, None))]
    constants = [n for n in names if n not in documented]
    lines += [f"   {name}" for name in documented]
    if constants:  # tables and defaults: their docs live in the module that defines them
        listed = ", ".join(f"``{name}``" for name in constants)
        lines += ["", f"Constants: {listed}."]
    return "\n".join(lines) + "\n"


def write_api_pages(folder) -> None:
    """Write ``_packages/<package>.rst`` for every package of :data:`PACKAGES` (only
    where the text changed, so that Sphinx rebuilds no more than it must)."""
    out = Path(folder) / "_packages"
    out.mkdir(parents=True, exist_ok=True)
    documented = set()
    for package in PACKAGES:
        module = importlib.import_module(package)
        names = [n for n in public_names(package) if callable(getattr(module, n, None))]
        documented.update(f"{package}.{name}.rst" for name in names)
    for stale in (Path(folder) / "generated").glob("*.rst"):  # objects no longer exported
        if stale.name not in documented:
            stale.unlink()
    for package, blurb in PACKAGES.items():
        path = out / f"{package}.rst"
        text = package_page(package, blurb)
        if not path.exists() or path.read_text() != text:
            path.write_text(text)
