"""File formats: lidarinv HDF5 layouts and mission readers."""
