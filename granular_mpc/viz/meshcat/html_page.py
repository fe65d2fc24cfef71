"""Standalone HTML: one self-contained page that plays a run (autoplay, endless loop).

The page records transforms per frame (:mod:`.recording`) and sends each geometry once.
meshcat 0.3.2's own ``Visualizer.static_html()`` needs a running server, and although it
does embed the last ``set_animation`` command, it emits it before any geometry and loads
every command through an asynchronous ``fetch`` of a ``data:`` URL; :func:`export_html`
writes the page itself, with the same viewer script (``meshcat/viewer/dist/main.min.js``)
and the same msgpack commands, applied synchronously and in order, geometry first, the
animation last with ``play = true`` and endless repetitions.
"""

from __future__ import annotations

import base64
import html
import json
import math
from pathlib import Path
from typing import Any

import umsgpack

from ...exceptions import OutputError, ViewerError
from ...robot.model import Biped
from .backend import Visualizer, commands, meshcat_version, viewer_script_path
from .recording import record_animation
from .scene import ROOT, BipedScene, SceneStyle, set_states


class _RecordingWindow:
    """A stand-in for meshcat's server connection that keeps the lowered commands."""

    def __init__(self) -> None:
        self.commands: list[dict] = []

    def send(self, command) -> None:
        self.commands.append(command.lower())


def _viewer_js() -> str:
    path = viewer_script_path()
    try:
        js = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ViewerError("meshcat's viewer script is missing", detail=f"{path}: {exc}") from None
    return js.replace("</script", "<\\/script")


_PAGE = """<!DOCTYPE html>
<html>
<head>
<meta charset="utf-8">
<meta name="generator" content="granular_mpc.viz.meshcat (meshcat {meshcat_version})">
<title>{title}</title>
<style>
body {{ margin: 0; }}
#meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
#granular-mpc-overlay {{ position: absolute; left: 10px; bottom: 10px; font: 14px monospace;
  color: #fff; text-shadow: 0 0 3px #000; pointer-events: none; white-space: pre; }}
</style>
</head>
<body>
<div id="meshcat-pane"></div>
<div id="granular-mpc-overlay"></div>
<script>
{viewer_js}
</script>
<script type="application/octet-stream" id="granular-mpc-commands">
{commands}
</script>
<script>
(function () {{
  var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
  window.viewer = viewer;
  var lines = document.getElementById("granular-mpc-commands").textContent.split("\\n");
  var applied = 0;
  for (var i = 0; i < lines.length; i++) {{
    var line = lines[i].trim();
    if (!line) continue;
    var bin = atob(line), bytes = new Uint8Array(bin.length);
    for (var j = 0; j < bin.length; j++) bytes[j] = bin.charCodeAt(j);
    viewer.handle_command_bytearray(bytes);
    applied++;
  }}
  document.body.setAttribute("data-commands-applied", String(applied));
  var overlay = document.getElementById("granular-mpc-overlay");
  var t0 = {t0}, label = {label};
  function tick() {{
    overlay.textContent = label + "   t = " + (t0 + viewer.animator.time).toFixed(2) + " s";
    requestAnimationFrame(tick);
  }}
  tick();
}})();
</script>
</body>
</html>
"""


def _pack(command: dict) -> str:
    data = umsgpack.packb(command, force_float_precision="single")
    return base64.b64encode(data).decode("ascii")


def export_html(biped: Biped, log_df, terrain_cfg: Any, path: str | Path, fps: float = 30.0, *,
                style: SceneStyle | None = None, title: str | None = None) -> Path:
    """Write one self-contained HTML page that plays the run (autoplay, endless loop).

    The page holds meshcat's viewer script, each geometry once and one animation: per
    frame, only transforms (position, quaternion, scale) and visibility. The log is
    subsampled to ``fps``: frame k shows the row nearest ``t0 + k/fps``, so the page plays
    in real time. No network is needed to view it.

    Args:
        biped: the robot of the run.
        log_df: run log as a DataFrame (:func:`granular_mpc.runlog.read_log`); needs
            ``time``, ``base_x..z``, ``base_qw..qz``, ``q_<joint>`` and, for footprints and
            arrows, per foot ``contact``, ``grf_x..z`` [N, W], ``px, py, pz`` [m, W].
        terrain_cfg: terrain config, terrain model, ``terrain:`` mapping or ``None`` (flat
            granular terrain).
        path: output file.
        fps: animation frame rate [1/s].
        style: drawing options.
        title: page title (default: the file name).

    Returns:
        The path written.

    Raises:
        DataFormatError: missing columns, non-finite or decreasing time.
        OutputError: the file cannot be written.
    """
    path = Path(path)
    scene = BipedScene(biped, terrain_cfg, style)
    window = _RecordingWindow()
    vis = Visualizer(window=window)[ROOT]
    rec = record_animation(scene, vis, log_df, fps)
    scene.draw_static(vis, rec.extent)
    scene.draw_footprints(vis, rec.footprints, hidden=True)
    set_states(vis, rec.first_states)  # the first frame, also shown if paused at load
    window.send(commands.SetAnimation(rec.animation, play=True, repetitions=math.inf))
    label = f"granular_mpc · {scene.terrain.kind} terrain · {rec.n_frames} frames @ {fps:g} fps"
    page = _PAGE.format(
        meshcat_version=html.escape(meshcat_version()),
        title=html.escape(title or path.stem),
        viewer_js=_viewer_js(),
        commands="\n".join(_pack(c) for c in window.commands),
        t0=repr(float(rec.t0)),
        label=json.dumps(label),
    )
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(page, encoding="utf-8")
        tmp.replace(path)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror}") from None
    return path


def read_html_commands(path_or_text: str | Path) -> list[dict]:
    """Decode the Meshcat commands embedded in a page written by :func:`export_html`.

    Useful to inspect an export (tests, debugging): returns the command dictionaries in
    the order the page applies them.
    """
    text = str(path_or_text)
    if not text.lstrip().startswith("<"):
        text = Path(path_or_text).read_text(encoding="utf-8")
    start_tag = '<script type="application/octet-stream" id="granular-mpc-commands">'
    a = text.find(start_tag)
    if a < 0:
        raise ValueError("no granular_mpc command block in this page")
    b = text.find("</script>", a)
    body = text[a + len(start_tag):b]
    return [umsgpack.unpackb(base64.b64decode(line)) for line in body.split() if line]


__all__ = ["export_html", "read_html_commands"]
