"""driftmap: camera-only mapping and localisation for underground mines."""

__version__ = "0.1.0"
