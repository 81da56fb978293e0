"""Plotting: the only part of heliostep that imports matplotlib.

Simulation, geometry and comparison code hand their results to a module here; the
backend is forced to Agg so plots render without a screen (CI, workers).
"""

import matplotlib

matplotlib.use("Agg")
