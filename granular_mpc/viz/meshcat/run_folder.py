"""Replay of a saved run folder (``granular-mpc view RUN_DIR``): live, or as one page.

Reads the run folder written by ``granular-mpc run``: the log (``RUN_DIR/log``) and the
resolved configuration (``RUN_DIR/config.resolved.yaml``) for the terrain and the robot;
file names from :mod:`granular_mpc.columns`.
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path
from typing import Any, Mapping, TextIO

from ...columns import RESOLVED_FILE
from ...config import RobotConfig, load_yaml, validate
from ...exceptions import ConfigError, ModelFileError, OutputError
from ...robot.model import Biped, load_biped
from ...runlog import read_log
from .html_page import export_html
from .live import LiveViewer
from .scene import SceneStyle, TerrainView

DEFAULT_ROBOT = "yobogo10s"
"""Robot loaded when the run folder does not name one."""


def _read_resolved_config(run_dir: Path) -> dict:
    p = run_dir / RESOLVED_FILE
    if not p.is_file():
        return {}
    return load_yaml(p)


def _biped_from_config(robot: Any) -> Biped:
    if robot is None:
        return load_biped(DEFAULT_ROBOT)
    if isinstance(robot, str):
        return load_biped(robot)
    if isinstance(robot, Mapping):
        name = str(robot.get("name", DEFAULT_ROBOT))
        if robot.get("source_dir") and robot.get("urdf"):
            try:
                return Biped.from_config(validate(RobotConfig, dict(robot), source="robot"))
            except ModelFileError:  # run folder moved to another machine: use the name
                warnings.warn(f"robot URDF {robot.get('urdf')!r} not found under "
                              f"{robot.get('source_dir')!r}; loading robot {name!r}",
                              stacklevel=3)
        return load_biped(name)
    raise ConfigError("must be a robot name or a robot mapping", key="robot", value=robot)


def replay(run_dir: str | Path, html_path: str | Path | None = None, *, fps: float = 30.0,
           biped: Biped | None = None, block: bool = True, style: SceneStyle | None = None,
           announce: bool = True, stream: TextIO | None = None) -> Path | LiveViewer:
    """Show a saved run: export it as one HTML page, or serve it live.

    Reads ``run_dir/log`` (:func:`granular_mpc.runlog.read_log`) and
    ``run_dir/config.resolved.yaml`` (its ``terrain:`` mapping and ``robot:``, a name or a
    mapping). Without that file, or without ``terrain:``, the terrain is flat granular
    (surface at z = 0, 12 cm layer) and the robot ``yobogo10s``.

    Args:
        run_dir: the run folder written by ``granular-mpc run``.
        html_path: if given, write the standalone page there and return its path.
        fps: animation frame rate [1/s].
        biped: the robot (default: from the resolved config).
        block: live mode only: serve until Ctrl-C, then stop the server and return the
            (closed) viewer; with ``False`` return the running viewer at once (the
            caller closes it).
        style: drawing options.
        announce: live mode: print the URL (and how to stop).
        stream: where to print (default: the current ``sys.stdout``).

    Returns:
        The HTML path, or the :class:`LiveViewer`.
    """
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise OutputError(f"no run folder {run_dir}")
    log_df = read_log(run_dir)  # RUN_DIR/log (LOG_DIR), or parts in RUN_DIR itself
    cfg = _read_resolved_config(run_dir)
    terrain = TerrainView.from_any(cfg.get("terrain"))
    if biped is None:
        biped = _biped_from_config(cfg.get("robot"))
    if html_path is not None:
        return export_html(biped, log_df, terrain, html_path, fps=fps, style=style,
                           title=run_dir.name)
    viewer = LiveViewer(biped, terrain, style=style, announce=announce, stream=stream)
    try:
        viewer.show_run(log_df, fps=fps)
    except BaseException:
        viewer.close()
        raise
    if not block:
        return viewer
    if announce:
        print("Serving the run; press Ctrl-C to stop.", file=stream or sys.stdout, flush=True)
    try:
        while viewer.alive:
            time.sleep(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        viewer.close()
    return viewer


__all__ = ["replay", "DEFAULT_ROBOT"]
