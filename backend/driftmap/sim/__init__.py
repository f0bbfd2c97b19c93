"""The synthetic mine: layout, survey DXF, renderer, vehicle motion and the site writer.

:func:`simulate_site` writes a complete site (survey.dxf, site.json, drive folders with ground truth
and obscured copies) for a seed and a size ("tiny", "small", "medium", "large", "mine"); the same seed gives
the same bytes. :func:`plan_site` returns the layout and every drive's frame poses without rendering.

Modules: ``params`` (sizes, camera, vehicle), ``layout`` (tunnel network), ``survey`` (DXF),
``routes`` and ``motion`` (where the vehicle drives), ``trajectory`` (how: timing, wander, frame
poses), ``rig`` (the camera, pinhole or fisheye, and its drive.json block), ``boards`` (chessboard images
to calibrate a camera with a lens), ``textures``, ``strip``, ``patches``, ``decor`` and ``world`` (what the
tunnel looks like), ``shading`` and ``render`` (the ray caster), ``frames`` (rendering work units), ``site``
(the writer) and ``site_files`` (drive folders and site.json).
"""

from driftmap.sim.params import SIZES
from driftmap.sim.site import DriveSummary, SimulationSummary, SitePlan, plan_site, simulate_site

__all__ = ["SIZES", "DriveSummary", "SimulationSummary", "SitePlan", "plan_site", "simulate_site"]
