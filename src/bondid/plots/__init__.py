"""Plots of bondid, written as PNG files (matplotlib, imported lazily; no pyplot state).

Every ``plot_*`` function writes its PNG atomically and returns the output path; the matching
``build_*`` returns the :class:`matplotlib.figure.Figure` without saving it.
"""

from .bode import Curve, build_bode, noise_curve, plot_bode
from .convergence import build_convergence, plot_convergence
from .heatmap import build_heatmap, plot_heatmap
from .residual_map import build_residual_map, plot_residual_map
from .sweep import build_sweep, plot_sweep, rank_parameters

__all__ = [
    "Curve",
    "build_bode",
    "build_convergence",
    "build_heatmap",
    "build_residual_map",
    "build_sweep",
    "noise_curve",
    "plot_bode",
    "plot_convergence",
    "plot_heatmap",
    "plot_residual_map",
    "plot_sweep",
    "rank_parameters",
]
