"""Visualisation: paper-style figures and Meshcat views.

* :mod:`.plots` — figures of a run and of a sweep (``make_run_plots``, Fig. 4 and 6);
  :mod:`.validation_plots` — workbench figures (model vs measurement, RMSE, residuals),
  re-exported by :mod:`.plots`; :mod:`.figures` — the shared figure plumbing.
* :mod:`.meshcat` — live viewer, standalone HTML page and run-folder replay (a package,
  one job per module).

Names are imported lazily so that ``import granular_mpc.viz`` pulls in neither matplotlib
nor meshcat until a function that needs it is used.
"""
from importlib import import_module

_PLOTS = (
    "PlotOutput", "plot_joint_bands", "plot_grf_bands", "plot_intrusion_bands",
    "plot_rolling_cot", "trunk_rpy", "plot_trajectories", "plot_cot_vs_speed",
    "plot_model_vs_measurement", "plot_rmse_vs_speed", "plot_residual_heatmap",
    "make_run_plots",
)
_MESHCAT = ("LiveViewer", "export_html", "replay", "read_html_commands", "SceneStyle",
            "TerrainView", "ViewerError")


def __getattr__(name):
    if name in _PLOTS:
        return getattr(import_module(".plots", __name__), name)
    if name in _MESHCAT:
        return getattr(import_module(".meshcat", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = list(_PLOTS) + list(_MESHCAT)
