"""Meshcat views of a biped on granular or rigid terrain: live view and standalone HTML.

Two ways to look at a run, one scene:

* :class:`LiveViewer` starts a Meshcat server bound to 127.0.0.1 (no browser is opened),
  prints its URL and is fed one log row at a time (``viewer.update(row)``) while a run
  goes on, never making the caller wait.
* :func:`export_html` writes ONE self-contained HTML file (viewer JavaScript, geometry and
  animation inlined, no network needed) that plays the run in a loop.
* :func:`replay` does either for a saved run folder (``granular-mpc view RUN_DIR``).

One job per module (user guide: ``docs/viewing.md``):

==================  ====================================================================
``backend``         the ``meshcat`` package, imported once
``log_rows``        run-log rows → the numbers the scene draws (columns, touchdowns)
``scene``           :class:`TerrainView`, :class:`SceneStyle`, :class:`BipedScene`: robot,
                    terrain, footprints, force arrows; node poses per frame
``recording``       animation of a whole log (:func:`sample_frames`), for page and server
``html_page``       :func:`export_html`, :func:`read_html_commands`
``server``          the meshcat server subprocess and its command socket (time-outs)
``live``            :class:`LiveViewer`: rows streamed by a background thread
``run_folder``      :func:`replay` of a saved run folder
==================  ====================================================================

Errors: :class:`~granular_mpc.exceptions.ViewerError` (server), ``DataFormatError`` (log
columns), ``ConfigError`` (options), ``OutputError`` (files).
"""

from ...exceptions import ViewerError
from .html_page import export_html, read_html_commands
from .live import LiveViewer
from .recording import sample_frames
from .run_folder import replay
from .scene import ROOT, BipedScene, SceneData, SceneStyle, TerrainView

__all__ = ["LiveViewer", "export_html", "replay", "read_html_commands", "BipedScene",
           "SceneData", "SceneStyle", "TerrainView", "ViewerError", "sample_frames", "ROOT"]
