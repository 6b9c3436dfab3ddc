"""Sphinx configuration of the lidarinv documentation.

Build: ``python -m sphinx -W --keep-going -b html docs docs/_build/html`` (warnings are
errors; ``tests/test_docs.py`` runs the same build in the test suite). The tutorials in
``docs/tutorials/`` are Python scripts that sphinx-gallery runs during the build; the
validation pages are generated from the studies' JSON summaries
(``docs/validation/generate.py``); the API pages from the packages' ``__all__``.
"""

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from api.generate import write_api_pages  # noqa: E402
from validation.generate import write_validation_pages  # noqa: E402

import lidarinv  # noqa: E402

project = "lidarinv"
author = "The lidarinv developers"
copyright = "2024–2025, the lidarinv developers"
release = version = lidarinv.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
]

exclude_patterns = ["_build", "**/README.rst", "tutorials/*.py", "auto_tutorials/*.ipynb"]
templates_path = ["_templates"]
html_static_path = []
html_theme = "alabaster"
html_theme_options = {"description": "Bayesian retrieval of forest structure from lidar waveforms"}
html_title = "lidarinv"
default_role = "code"

autosummary_generate = True
autodoc_typehints = "none"
autodoc_default_options = {"members": False}
numpydoc_show_class_members = False
numpydoc_validation_checks = set()

sphinx_gallery_conf = {
    "examples_dirs": ["tutorials"],
    "gallery_dirs": ["auto_tutorials"],
    # the plot_*.py tutorials run when the docs build; others are shown, not run
    "filename_pattern": r"/plot_",
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "remove_config_comments": True,
    "show_memory": False,
    "abort_on_example_error": True,
    # the test suite sets this, so that every build runs the tutorials again
    "run_stale_examples": os.environ.get("LIDARINV_DOCS_RERUN") == "1",
    "reset_modules": ("matplotlib",),
    "matplotlib_animations": False,
    "image_scrapers": ("matplotlib",),
}

# the pages generated before reading: API tables from __all__, validation from the JSON
write_api_pages(HERE / "api")
write_validation_pages(HERE / "validation")
