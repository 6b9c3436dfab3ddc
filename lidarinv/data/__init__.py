"""Example data shipped with the package.

``stems.csv``: a stem map (x, y, height, crown_length, crown_radius, shape, favd) of the
trees of the paper's jack pine stand (``forward.examples.example("jack-pine")``, Sun &
Ranson 2000) standing in the square [30, 70] m × [30, 70] m; open it with
``importlib.resources.files("lidarinv.data") / "stems.csv"``.
"""
