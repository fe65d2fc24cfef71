"""Live view: a Meshcat server on 127.0.0.1 fed one log row at a time.

:class:`LiveViewer` starts a :class:`~.server.MeshcatServer` (no browser is opened),
prints its URL and is fed one log row at a time (``viewer.update(row)``) while a run goes
on. Rows are accepted at most ``rate_hz`` times per wall-clock second and sent by a
background thread, so the caller never waits for the viewer, watched or not.
"""

from __future__ import annotations

import math
import sys
import threading
import time
import warnings
from typing import Any, Mapping, TextIO

import numpy as np

from ...columns import FOOT_CONTACT, FOOT_POINT, foot_column
from ...exceptions import ConfigError
from ...robot.model import SIDES, Biped
from .backend import Visualizer, commands
from .log_rows import LogColumns
from .recording import record_animation
from .scene import ROOT, BipedScene, SceneStyle, set_states
from .server import MeshcatServer, ZmqWindow


class LiveViewer:
    """Live Meshcat view of a running simulation, fed one log row at a time.

    Starts a meshcat server on 127.0.0.1 (free ports from 6000 for ZMQ and 7000 for HTTP),
    never opens a browser, prints the URL to ``stream``. :meth:`update` is cheap (a few
    microseconds): it watches every row for touchdowns, keeps at most ``rate_hz`` rows per
    wall-clock second and hands them to a background thread that computes the poses and
    sends them, only what changed. The caller never waits for the server, whether a
    browser watches or not; if the server stops answering, the viewer turns itself off
    (see :attr:`error`, one warning) and the caller goes on.

    Args:
        biped: the robot.
        terrain: terrain config/model/mapping/name, or ``None`` (flat granular terrain).
        style: drawing options.
        rate_hz: most poses sent per wall-clock second [Hz].
        extent: terrain drawn over ((x_min, x_max), (y_min, y_max)) [m, W].
        max_footprints: oldest footprints are removed beyond this number.
        timeout_s: how long to wait for the server's answer to one command [s].
        announce: print the URL.
        stream: where to print it (default: the current ``sys.stdout``).

    Raises:
        ViewerError: the server did not start or did not answer while the scene was drawn.
        ConfigError: ``rate_hz`` is not a positive number.

    Use as a context manager, or call :meth:`close`::

        with LiveViewer(biped, terrain_cfg) as viewer:
            for row in run_rows():          # dicts with the run-log columns
                viewer.update(row)
    """

    def __init__(self, biped: Biped, terrain: Any = None, *, style: SceneStyle | None = None,
                 rate_hz: float = 30.0, extent=((-3.0, 30.0), (-3.0, 3.0)),
                 max_footprints: int = 400, timeout_s: float = 2.0,
                 announce: bool = True, stream: TextIO | None = None) -> None:
        if not (rate_hz > 0 and math.isfinite(rate_hz)):
            raise ConfigError("must be a positive rate [Hz]", key="rate_hz", value=rate_hz)
        self.scene = BipedScene(biped, terrain, style)
        self.period = 1.0 / float(rate_hz)
        self.max_footprints = int(max_footprints)
        self._cols = LogColumns(biped)
        self._window: ZmqWindow | None = None
        #: The meshcat server process (:class:`~.server.MeshcatServer`).
        self.server = MeshcatServer()
        try:
            self._window = ZmqWindow(self.server.zmq_url, timeout_s)
            self._vis = Visualizer(window=self._window)[ROOT]
            self.scene.draw_static(self._vis, extent)
        except BaseException:
            self._shutdown_transport()
            raise
        self.url: str = self.server.web_url
        #: Why the view stopped (``None`` while it runs).
        self.error: str | None = None
        self.frames_sent = 0      # poses sent to the server
        self.footprints_sent = 0  # footprints drawn so far
        self.rows_seen = 0        # rows offered to update()
        self.rows_accepted = 0    # rows kept for display (throttled)
        self._closed = False
        self._warned = False
        self._animation_mode = False
        self._sd = self.scene.create_data()
        self._last_tf: dict[str, tuple] = {}
        self._last_visible: dict[str, bool] = {self.scene.grf_path(s): False for s in SIDES}
        self._was_contact = {side: False for side in SIDES}
        self._next_accept = 0.0
        self._first_footprint = 0
        self._lock = threading.Lock()     # guards the hand-over fields below
        self._io_lock = threading.Lock()  # one command at a time on the socket
        self._pending: np.ndarray | None = None
        self._pending_prints: list[tuple[float, float]] = []
        self._busy = False
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="granular-mpc-meshcat",
                                        daemon=True)
        self._thread.start()
        if announce:
            print(f"Meshcat viewer: {self.url}", file=stream or sys.stdout, flush=True)

    # ------------------------------------------------------------------ caller side
    def update(self, row: Mapping[str, Any], *, force: bool = False) -> bool:
        """Offer one log row (a mapping with the run-log columns, e.g. a dict).

        Every row is checked for touchdowns (``<side>_contact`` going 0 → 1 leaves a
        footprint at ``<side>_px, <side>_py``); the pose is kept for display only if
        ``1/rate_hz`` s of wall-clock time have passed since the last kept row, or if
        ``force``. Never blocks on the server.

        Returns:
            True if the row was kept for display.

        Raises:
            DataFormatError: the row lacks a base-pose or joint-angle column.
        """
        self.rows_seen += 1
        if self._closed or self._animation_mode:
            return False
        if self.error is not None:
            if not self._warned:
                self._warned = True
                warnings.warn(f"Meshcat live view stopped: {self.error}", stacklevel=2)
            return False
        for side in SIDES:
            try:
                now_contact = float(row.get(foot_column(side, FOOT_CONTACT), 0.0)) > 0.5
            except (TypeError, ValueError):
                now_contact = False
            if now_contact and not self._was_contact[side]:
                try:
                    x, y = (float(row[foot_column(side, key)]) for key in FOOT_POINT[:2])
                except (KeyError, TypeError, ValueError):
                    x = y = math.nan
                if math.isfinite(x) and math.isfinite(y):
                    with self._lock:
                        self._pending_prints.append((x, y))
                    self._wake.set()
            self._was_contact[side] = now_contact
        now = time.monotonic()
        if not force and now < self._next_accept:
            return False
        values = self._cols.from_row(row)
        if not np.all(np.isfinite(values[: self._cols.nq])):
            return False  # nothing sensible to show; keep the last pose
        self._next_accept = now + self.period
        with self._lock:
            self._pending = values
        self.rows_accepted += 1
        self._wake.set()
        return True

    def flush(self, timeout: float = 5.0) -> bool:
        """Wait until every kept row and footprint has been sent to the server.

        Returns:
            True if everything was sent, False on time-out or if the view stopped.
        """
        deadline = time.monotonic() + timeout
        while True:
            with self._lock:
                busy = self._busy or self._pending is not None or bool(self._pending_prints)
            if not busy:
                return self.error is None
            if self.error is not None or not self._thread.is_alive():
                return False
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.002)

    @property
    def alive(self) -> bool:
        """True while the server runs and answers."""
        return not self._closed and self.error is None and self.server.alive()

    @property
    def server_pid(self) -> int:
        """Process id of the meshcat server (a child of this process)."""
        return self.server.pid

    def scene_html(self) -> str:
        """The server's current scene as a standalone page (meshcat's ``static_html``)."""
        with self._io_lock:
            return self._window.get_scene()

    def show_run(self, log_df, fps: float = 30.0) -> int:
        """Load a whole run as a looping animation (replaces the streamed view).

        Every browser that connects receives the scene and the animation, with play /
        pause / time controls in its "Animations" panel. Rows offered to :meth:`update`
        afterwards are ignored.

        Args:
            log_df: the run log (see :func:`export_html` for the columns).
            fps: animation frame rate [1/s].

        Returns:
            The number of animation frames.
        """
        self._animation_mode = True
        self.flush(timeout=2.0)
        rec = record_animation(self.scene, self._vis, log_df, fps)
        with self._io_lock:
            self._vis["world/footprints"].delete()
            self.scene.draw_terrain(self._vis, rec.extent)
            self.scene.draw_footprints(self._vis, rec.footprints, hidden=True)
            set_states(self._vis, rec.first_states)
            self._window.send(commands.SetAnimation(rec.animation, play=True, repetitions=math.inf))
        return rec.n_frames

    def close(self) -> None:
        """Stop the sender thread and the server (idempotent)."""
        self._closed = True
        self._stop.set()
        self._wake.set()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout=5.0)
        self._shutdown_transport()

    def _shutdown_transport(self) -> None:
        if self._window is not None:
            self._window.close()
        self.server.close()

    def __enter__(self) -> "LiveViewer":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------------ sender thread
    def _run(self) -> None:
        while not self._stop.is_set():
            self._wake.wait(timeout=0.5)
            self._wake.clear()
            if self._stop.is_set():
                break
            with self._lock:
                values, self._pending = self._pending, None
                prints, self._pending_prints = self._pending_prints, []
                self._busy = values is not None or bool(prints)
            if not self._busy:
                continue
            started = time.monotonic()
            try:
                with self._io_lock:
                    for x, y in prints:
                        self._send_footprint(x, y)
                    if values is not None:
                        self._send_pose(values)
                        self.frames_sent += 1
            except Exception as exc:  # server gone or not answering: turn the view off
                self.error = f"{type(exc).__name__}: {exc}"
                with self._lock:
                    self._busy = False
                return
            with self._lock:
                self._busy = False
            # The sender keeps to rate_hz too (rows are already throttled in update()).
            self._stop.wait(max(0.0, started + self.period - time.monotonic()))

    def _send_footprint(self, x: float, y: float) -> None:
        k = self.footprints_sent
        node = self._vis[self.scene.footprint_path(k)]
        geom, mat = self.scene.footprint_object()
        node["disc"].set_object(geom, mat)
        node.set_transform(self.scene.footprint_transform(x, y))
        self.footprints_sent += 1
        while self.footprints_sent - self._first_footprint > self.max_footprints:
            self._vis[self.scene.footprint_path(self._first_footprint)].delete()
            self._first_footprint += 1

    def _send_pose(self, values: np.ndarray) -> None:
        states = self.scene.frame_states(self._sd, values)
        for path, s in states.items():  # transforms first, then visibility: no stale flash
            if s.position is None and s.quaternion is None and s.scale is None:
                continue
            key = (s.position, s.quaternion, s.scale)
            if self._last_tf.get(path) != key:
                self._vis[path].set_transform(s.matrix())
                self._last_tf[path] = key
        for path, s in states.items():
            if s.visible is not None and self._last_visible.get(path) != s.visible:
                self._vis[path].set_property("visible", bool(s.visible))
                self._last_visible[path] = s.visible


__all__ = ["LiveViewer"]
