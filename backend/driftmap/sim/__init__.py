"""The synthetic mine: layout, survey DXF, renderer, vehicle motion and the site writer.

:func:`simulate_site` writes a complete site (survey.dxf, site.json, drive folders with ground truth)
for a seed and a size ("tiny", "small", "medium", "large"); the same seed gives the same bytes.
"""

from driftmap.sim.params import SIZES
from driftmap.sim.site import DriveSummary, SimulationSummary, SitePlan, plan_site, simulate_site

__all__ = ["SIZES", "DriveSummary", "SimulationSummary", "SitePlan", "plan_site", "simulate_site"]
