"""The ``meshcat`` package (0.3.2, pinned in ``pyproject.toml``), imported in one place.

Importing meshcat pulls in zmq, tornado, PIL and IPython (≈ 0.3 s) and its server module
triggers a DeprecationWarning from pyzmq; this module imports it once, with that warning
silenced. ``granular_mpc.viz`` loads :mod:`granular_mpc.viz.meshcat` lazily (its
``__getattr__``), so only code that draws pays for the import.
"""

from __future__ import annotations

import warnings
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

with warnings.catch_warnings():
    warnings.simplefilter("ignore", DeprecationWarning)
    import meshcat
    import meshcat.animation as animation
    import meshcat.commands as commands
    import meshcat.geometry as geometry

Visualizer = meshcat.Visualizer
"""meshcat's scene-tree handle; created here with our own window (recorder or socket)."""


def package_dir() -> Path:
    """Folder of the installed ``meshcat`` package."""
    return Path(meshcat.__file__).resolve().parent


def viewer_script_path() -> Path:
    """meshcat's browser viewer script, ``meshcat/viewer/dist/main.min.js``."""
    return package_dir() / "viewer" / "dist" / "main.min.js"


def meshcat_version() -> str:
    """Installed meshcat version (``"unknown"`` for a copy without package metadata)."""
    try:
        return version("meshcat")
    except PackageNotFoundError:  # pragma: no cover - vendored copies
        return "unknown"


__all__ = ["meshcat", "animation", "commands", "geometry", "Visualizer", "package_dir",
           "viewer_script_path", "meshcat_version"]
