"""Meshcat views of a biped on granular or rigid terrain: live view and standalone HTML.

Two ways to look at a run, one scene:

* :class:`LiveViewer` starts a Meshcat server bound to 127.0.0.1 (no browser is opened),
  prints its URL and is fed one log row at a time (``viewer.update(row)``) while a run
  goes on. Rows are accepted at most ``rate_hz`` times per wall-clock second and sent by a
  background thread, so the caller never waits for the viewer, watched or not.
* :func:`export_html` writes ONE self-contained HTML file (viewer JavaScript, geometry and
  animation inlined, no network needed) that plays the run in a loop.
* :func:`replay` does either for a saved run folder (``granular-mpc view RUN_DIR``).

What is drawn (frames and units: ``docs/notation.md``; everything in ``W``, metres):

* the robot, from the URDF visual primitives in ``biped.visual_model`` (boxes, cylinders,
  spheres, capsules, mesh files) placed at their world placement ``oMg`` each frame;
* the terrain: granular → a sand-coloured box ``layer_depth`` thick over a grey floor
  slab; rigid → a grey slab; both with the free surface at ``surface_height``;
* footprints: a dark disc on the free surface at the ``(x, y)`` of the contact point ``C``
  of every touchdown (a foot's ``contact`` going 0 → 1); they stay;
* ground reaction force arrows (force of the ground on the foot, ``W``) starting at the
  contact point of each foot in contact, ``grf_scale`` metres per newton (1 cm per 10 N by
  default). Meshcat has no arrow: a unit cylinder (scaled per frame) and a cone. They are
  drawn on top of the scene, so the part inside the foot or below the sand stays visible.

The view follows the robot: everything hangs under one group whose translation is
``-(base_x, base_y, surface_height + look_height)``, so the camera, which orbits the
viewer's origin, stays on the trunk (``SceneStyle(follow=False)``: centred on the middle
of the run instead).

Meshcat scene tree (under ``/meshcat/granular_mpc/world``)::

    robot/<geometry name>        pose oMg per frame; child ``shape`` holds the primitive
    terrain/{sand,floor,ground}  static
    footprints/<k>               static pose; visibility switched on at touchdown
    grf/<side>                   origin at C, +y along the force; children ``shaft``, ``head``

The standalone page records transforms per frame (a :class:`meshcat.animation.Animation`
built with ``at_frame``) and sends each geometry once. meshcat 0.3.2's own
``Visualizer.static_html()`` needs a running server, and although it does embed the last
``set_animation`` command, it emits it before any geometry and loads every command through
an asynchronous ``fetch`` of a ``data:`` URL; :func:`export_html` writes the page itself,
with the same viewer script (``meshcat/viewer/dist/main.min.js``) and the same msgpack
commands, applied synchronously and in order, geometry first, the animation last with
``play = true`` and endless repetitions.
"""

from __future__ import annotations

import base64
import html
import json
import math
import sys
import threading
import time
import warnings
import weakref
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping, TextIO

import numpy as np
import pinocchio as pin

from ..exceptions import (ConfigError, DataFormatError, DataProblem, GranularMpcError,
                          ModelFileError, OutputError)
from ..robot.model import SIDES, Biped

ROOT = "granular_mpc"
"""Name of the Meshcat group under ``/meshcat`` that holds everything this module draws."""


def _mc():
    """The meshcat package, imported on first use (it pulls in zmq, tornado, PIL and
    IPython: ≈ 0.3 s), without the DeprecationWarning its server module triggers."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        import meshcat
        import meshcat.animation
        import meshcat.commands
        import meshcat.geometry
    return meshcat


_BASE_COLS = ("base_x", "base_y", "base_z", "base_qx", "base_qy", "base_qz", "base_qw")
_FOOT_KEYS = ("contact", "grf_x", "grf_y", "grf_z", "px", "py", "pz")

_SAND_RGB = (0.86, 0.74, 0.52)
_FLOOR_RGB = (0.42, 0.42, 0.44)
_RIGID_RGB = (0.58, 0.58, 0.60)
_PRINT_SAND_RGB = (0.36, 0.27, 0.16)
_PRINT_RIGID_RGB = (0.22, 0.22, 0.24)
_GRF_RGB = (0.10, 0.78, 0.22)


class ViewerError(GranularMpcError, RuntimeError):
    """The Meshcat server could not be started or stopped answering.

    Attributes:
        detail: what failed (server output, timeout …).
    """

    def __init__(self, message: str, *, detail: str = "") -> None:
        self.detail = detail
        super().__init__(message + (f": {detail}" if detail else ""))


# --------------------------------------------------------------------------------------
# What to draw: terrain and style
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TerrainView:
    """What the viewer needs to know about the terrain.

    Attributes:
        kind: ``"granular"`` or ``"rigid"``.
        surface_height: height of the free surface in ``W`` [m].
        layer_depth: thickness of the granular layer over its rigid floor [m]
            (granular only).
    """

    kind: str = "granular"
    surface_height: float = 0.0
    layer_depth: float = 0.12

    def __post_init__(self) -> None:
        if self.kind not in ("granular", "rigid"):
            raise ConfigError(f"unknown terrain kind {self.kind!r}", key="terrain.kind",
                              value=self.kind, allowed="granular, rigid")
        if not math.isfinite(self.surface_height):
            raise ConfigError("must be finite", key="terrain.surface_height",
                              value=self.surface_height)
        if not (math.isfinite(self.layer_depth) and self.layer_depth > 0.0):
            raise ConfigError("must be a positive length [m]", key="terrain.layer_depth",
                              value=self.layer_depth)

    @classmethod
    def from_any(cls, terrain: Any = None) -> "TerrainView":
        """Build from a terrain config object, a :class:`~granular_mpc.terrain.TerrainModel`,
        a mapping (e.g. the ``terrain:`` entry of ``config.resolved.yaml``) or ``None``
        (flat granular terrain: surface at z = 0, 12 cm layer).

        Only ``kind``, ``surface_height`` and ``layer_depth`` are read; other keys are
        ignored so that a viewer never refuses a run because of a newer terrain schema.
        """
        if terrain is None:
            return cls()
        if isinstance(terrain, TerrainView):
            return terrain
        if isinstance(terrain, (str, Path)):  # a terrain file name, e.g. "dry_sand"
            from ..config import load_terrain

            terrain = load_terrain(str(terrain))
        if isinstance(terrain, Mapping):
            get = terrain.get
        else:
            cfg = getattr(terrain, "config", terrain)  # TerrainModel → its config
            def get(key, default=None, _cfg=cfg):
                return getattr(_cfg, key, default)
        kind = get("kind", "granular") or "granular"
        try:
            surface = float(get("surface_height", 0.0) or 0.0)
            layer = get("layer_depth", None)
            layer = 0.12 if layer is None else float(layer)
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"not a number: {exc}", key="terrain") from None
        return cls(kind=str(kind), surface_height=surface, layer_depth=layer)


@dataclass(frozen=True)
class SceneStyle:
    """Drawing options (lengths in metres, forces in newtons).

    Attributes:
        grf_scale: arrow length per unit force [m/N] (1e-3: 1 cm per 10 N).
        min_grf: forces below this magnitude are not drawn [N].
        follow: keep the view centred on the trunk (else on the run's middle).
        look_height: height of the view centre above the free surface [m].
        camera_offset: camera position relative to the view centre, ``W`` [m].
        footprint_radius: radius of a footprint disc [m].
        arrow_radius: radius of an arrow's shaft [m].
        head_length, head_radius: size of an arrow's cone [m].
        terrain_margin: terrain drawn this far beyond the run, each side [m].
    """

    grf_scale: float = 1.0e-3
    min_grf: float = 0.5
    follow: bool = True
    look_height: float = 0.25
    camera_offset: tuple[float, float, float] = (0.45, -0.90, 0.25)
    footprint_radius: float = 0.022
    arrow_radius: float = 0.006
    head_length: float = 0.025
    head_radius: float = 0.012
    terrain_margin: float = 1.5


# --------------------------------------------------------------------------------------
# Reading log rows
# --------------------------------------------------------------------------------------


class _Columns:
    """Maps log columns to the numbers the scene needs, for dict rows and DataFrames.

    Layout of one extracted vector: ``q`` (nq, Pinocchio order) then per side
    ``contact, grf_x, grf_y, grf_z, px, py, pz``.
    """

    def __init__(self, biped: Biped, available: Iterable[str] | None = None,
                 source: str = "log") -> None:
        self.biped = biped
        self.joint_cols = ["q_" + n for n in biped.joint_names]
        required = list(_BASE_COLS) + self.joint_cols
        self.sides: list[str] = []
        if available is None:
            self.sides = list(SIDES)
        else:
            have = set(available)
            problems = [DataProblem(source, "required column is missing", column=c)
                        for c in required if c not in have]
            for side in SIDES:
                cols = [f"{side}_{k}" for k in _FOOT_KEYS]
                present = [c for c in cols if c in have]
                if len(present) == len(cols):
                    self.sides.append(side)
                elif present:  # some but not all: a broken log, say so
                    problems += [DataProblem(source, "per-foot column is missing", column=c)
                                 for c in cols if c not in have]
            if problems:
                raise DataFormatError(problems, root=source)
        self.nq = biped.model.nq

    def from_row(self, row: Mapping[str, Any]) -> np.ndarray:
        """Extract from one row (a mapping such as a dict or a pandas Series)."""
        b = self.biped
        out = np.zeros(self.nq + 7 * len(SIDES))
        q = out[: self.nq]
        q[:] = pin.neutral(b.model)
        try:
            for i, c in enumerate(_BASE_COLS):
                q[i] = float(row[c])
            for i, c in enumerate(self.joint_cols):
                q[b.idx_q[i]] = float(row[c])
            for k, side in enumerate(SIDES):
                if side not in self.sides:
                    continue
                o = self.nq + 7 * k
                for j, key in enumerate(_FOOT_KEYS):
                    out[o + j] = float(row.get(f"{side}_{key}", 0.0))
        except KeyError as exc:
            raise DataFormatError([DataProblem("row", "required column is missing",
                                               column=str(exc.args[0]))]) from None
        return out

    def from_frame(self, df) -> np.ndarray:
        """Extract every row of a DataFrame as an array (rows × layout)."""
        b = self.biped
        n = len(df)
        out = np.zeros((n, self.nq + 7 * len(SIDES)))
        out[:, : self.nq] = pin.neutral(b.model)
        out[:, 0:7] = df[list(_BASE_COLS)].to_numpy(dtype=float)
        out[:, b.idx_q] = df[self.joint_cols].to_numpy(dtype=float)
        for k, side in enumerate(SIDES):
            if side in self.sides:
                o = self.nq + 7 * k
                out[:, o:o + 7] = df[[f"{side}_{key}" for key in _FOOT_KEYS]].to_numpy(dtype=float)
        return out


# --------------------------------------------------------------------------------------
# The scene: geometry once, node states per frame
# --------------------------------------------------------------------------------------


def _rgb_int(rgb) -> int:
    r, g, b = (int(round(255 * min(max(float(c), 0.0), 1.0))) for c in rgb[:3])
    return (r << 16) | (g << 8) | b


def _material(rgb, opacity: float = 1.0, **extra):
    mg = _mc().geometry

    return mg.MeshLambertMaterial(color=_rgb_int(rgb), opacity=float(opacity), **extra)


def _translation(p) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


_R_Y_TO_Z = np.array([[1.0, 0, 0, 0], [0, 0, -1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]])
"""Rotation about x by +90°: maps three.js's cylinder axis (y) onto the URDF's (z)."""


@dataclass
class _NodeState:
    """Pose of one scene node in its parent (``W``-aligned groups), SI units.

    ``quaternion`` is (x, y, z, w) as three.js wants it; ``None`` fields are not set.
    """

    position: tuple | None = None
    quaternion: tuple | None = None
    scale: tuple | None = None
    visible: bool | None = None

    def matrix(self) -> np.ndarray:
        T = np.eye(4)
        if self.quaternion is not None:
            x, y, z, w = self.quaternion
            T[:3, :3] = pin.Quaternion(w, x, y, z).toRotationMatrix()
        if self.scale is not None:
            T[:3, :3] = T[:3, :3] @ np.diag(self.scale)
        if self.position is not None:
            T[:3, 3] = self.position
        return T


@dataclass
class SceneData:
    """Mutable per-viewer buffers (Pinocchio data) for a :class:`BipedScene`."""

    data: pin.Data
    geom_data: Any


class BipedScene:
    """Immutable description of what to draw for one robot on one terrain.

    Turns a row of log numbers into the pose of every moving node (:meth:`frame_states`)
    and draws the static geometry once (:meth:`draw_static`). Used by both the live viewer
    and the HTML export.

    Args:
        biped: the robot (its ``visual_model`` is drawn; must not be ``None``).
        terrain: anything :meth:`TerrainView.from_any` accepts.
        style: drawing options.
    """

    def __init__(self, biped: Biped, terrain: Any = None, style: SceneStyle | None = None) -> None:
        if biped.visual_model is None:
            raise GranularMpcError("the robot was loaded without visuals "
                                   "(load_biped(..., with_visuals=True) is needed to draw it)")
        self.biped = biped
        self.terrain = TerrainView.from_any(terrain)
        self.style = style or SceneStyle()
        self.geom_names = tuple(g.name for g in biped.visual_model.geometryObjects)

    # ------------------------------------------------------------------ data
    def create_data(self) -> SceneData:
        return SceneData(self.biped.model.createData(),
                         pin.GeometryData(self.biped.visual_model))

    # ------------------------------------------------------------------ paths
    @staticmethod
    def robot_path(name: str) -> str:
        return f"world/robot/{name}"

    @staticmethod
    def footprint_path(k: int) -> str:
        return f"world/footprints/{k}"

    # ------------------------------------------------------------------ static geometry
    def draw_static(self, vis, extent) -> None:
        """Send the geometry that never changes: robot primitives, terrain, arrows.

        Args:
            vis: a ``meshcat.Visualizer`` rooted at ``/meshcat/granular_mpc``.
            extent: ``((x_min, x_max), (y_min, y_max))`` of the terrain in ``W`` [m].
        """
        self._draw_robot(vis)
        self.draw_terrain(vis, extent)
        self._draw_arrows(vis)
        self._viewer_settings(vis)

    def _draw_robot(self, vis) -> None:
        mg = _mc().geometry

        for go in self.biped.visual_model.geometryObjects:
            node = vis[self.robot_path(go.name)]
            color = np.asarray(go.meshColor, dtype=float)
            if not np.any(color[:3]) and color[3] == 0:  # unset: neutral grey
                color = np.array([0.6, 0.6, 0.6, 1.0])
            mat = _material(color[:3], float(color[3]))
            geom = go.geometry
            kind = type(geom).__name__
            if kind == "Box":
                node["shape"].set_object(mg.Box((2.0 * np.asarray(geom.halfSide)).tolist()), mat)
            elif kind == "Cylinder":
                node["shape"].set_object(mg.Cylinder(2.0 * float(geom.halfLength),
                                                     float(geom.radius)), mat)
                node["shape"].set_transform(_R_Y_TO_Z)
            elif kind == "Sphere":
                node["shape"].set_object(mg.Sphere(float(geom.radius)), mat)
            elif kind == "Capsule":
                r, h = float(geom.radius), float(geom.halfLength)
                node["shape"].set_object(mg.Cylinder(2.0 * h, r), mat)
                node["shape"].set_transform(_R_Y_TO_Z)
                for name, z in (("cap_top", h), ("cap_bottom", -h)):
                    node[name].set_object(mg.Sphere(r), mat)
                    node[name].set_transform(_translation([0.0, 0.0, z]))
            elif go.meshPath and Path(go.meshPath).suffix.lower() in (".stl", ".obj", ".dae"):
                loader = {".stl": mg.StlMeshGeometry, ".obj": mg.ObjMeshGeometry,
                          ".dae": mg.DaeMeshGeometry}[Path(go.meshPath).suffix.lower()]
                node["shape"].set_object(loader.from_file(go.meshPath), mat)
                S = np.diag(list(np.asarray(go.meshScale, dtype=float)) + [1.0])
                node["shape"].set_transform(S)
            else:
                warnings.warn(f"visual geometry {go.name!r} of type {kind} is not drawn "
                              "(supported: box, cylinder, sphere, capsule, STL/OBJ/DAE mesh)",
                              stacklevel=3)

    def draw_terrain(self, vis, extent) -> None:
        """(Re)draw the terrain over ``extent`` = ((x_min, x_max), (y_min, y_max)) [m, W]."""
        mg = _mc().geometry

        (x0, x1), (y0, y1) = extent
        cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
        lx, ly = max(x1 - x0, 0.1), max(y1 - y0, 0.1)
        zs = self.terrain.surface_height
        vis["world/terrain"].delete()
        if self.terrain.kind == "granular":
            d = self.terrain.layer_depth
            vis["world/terrain/sand"].set_object(mg.Box([lx, ly, d]), _material(_SAND_RGB))
            vis["world/terrain/sand"].set_transform(_translation([cx, cy, zs - d / 2.0]))
            floor = 0.03
            vis["world/terrain/floor"].set_object(mg.Box([lx, ly, floor]), _material(_FLOOR_RGB))
            vis["world/terrain/floor"].set_transform(_translation([cx, cy, zs - d - floor / 2.0]))
        else:
            slab = 0.05
            vis["world/terrain/ground"].set_object(mg.Box([lx, ly, slab]), _material(_RIGID_RGB))
            vis["world/terrain/ground"].set_transform(_translation([cx, cy, zs - slab / 2.0]))

    def _draw_arrows(self, vis) -> None:
        mg = _mc().geometry

        st = self.style
        # Transparent (opacity < 1) puts the arrows in three.js's second render pass; with
        # the depth test off they are then drawn over the foot and the sand.
        mat = _material(_GRF_RGB, 0.95, depthTest=False, depthWrite=False)
        for side in SIDES:
            node = vis[f"world/grf/{side}"]
            node["shaft"].set_object(mg.Cylinder(1.0, st.arrow_radius), mat)
            node["head"].set_object(mg.Cylinder(st.head_length, radiusTop=0.0,
                                                radiusBottom=st.head_radius), mat)
            node.set_property("visible", False)

    def footprint_object(self):
        """Geometry and material of one footprint disc."""
        mg = _mc().geometry

        rgb = _PRINT_SAND_RGB if self.terrain.kind == "granular" else _PRINT_RIGID_RGB
        return mg.Cylinder(0.002, self.style.footprint_radius), _material(rgb)

    def footprint_transform(self, x: float, y: float) -> np.ndarray:
        """Pose of a footprint disc at (x, y) [m, W], lying flat 1 mm above the surface."""
        T = _R_Y_TO_Z.copy()
        T[:3, 3] = [x, y, self.terrain.surface_height + 0.001]
        return T

    def _viewer_settings(self, vis) -> None:
        vis["/Grid"].set_property("visible", False)
        vis["/Axes"].set_property("visible", False)
        cx, cy, cz = self.style.camera_offset
        # The camera lives in meshcat's y-up "rotated" frame: W (x, y, z) → (x, z, −y).
        vis["/Cameras/default/rotated/<object>"].set_property("position", [cx, cz, -cy])

    # ------------------------------------------------------------------ per frame
    def view_centre(self, values: np.ndarray) -> np.ndarray:
        """Point of ``W`` shown at the viewer's origin for one extracted row [m]."""
        h = self.terrain.surface_height + self.style.look_height
        return np.array([values[0], values[1], h])

    def frame_states(self, sd: SceneData, values: np.ndarray,
                     centre: np.ndarray | None = None) -> dict[str, _NodeState]:
        """Pose of every moving node for one extracted row (see :class:`_Columns`).

        Args:
            sd: buffers from :meth:`create_data` (overwritten).
            values: one extracted row: ``q`` then per side contact, GRF [N, W], ``C`` [m, W].
            centre: view centre in ``W`` [m]; default :meth:`view_centre` (follow mode).

        Returns:
            path (relative to the scene root) → state.
        """
        b = self.biped
        nq = b.model.nq
        q = np.array(values[:nq], dtype=float)
        quat = q[3:7]
        norm = float(np.linalg.norm(quat))
        q[3:7] = quat / norm if norm > 1e-9 else np.array([0.0, 0.0, 0.0, 1.0])
        pin.forwardKinematics(b.model, sd.data, q)
        pin.updateGeometryPlacements(b.model, sd.data, b.visual_model, sd.geom_data)
        out: dict[str, _NodeState] = {}
        if centre is None:
            centre = self.view_centre(values)
        out["world"] = _NodeState(position=tuple((-np.asarray(centre, dtype=float)).tolist()))
        for i, name in enumerate(self.geom_names):
            M = sd.geom_data.oMg[i]
            qc = pin.Quaternion(M.rotation).coeffs()  # x, y, z, w
            out[self.robot_path(name)] = _NodeState(position=tuple(M.translation.tolist()),
                                                    quaternion=tuple(qc.tolist()))
        st = self.style
        for k, side in enumerate(SIDES):
            o = nq + 7 * k
            contact = values[o] > 0.5
            f = np.asarray(values[o + 1:o + 4], dtype=float)
            p = np.asarray(values[o + 4:o + 7], dtype=float)
            mag = float(np.linalg.norm(f))
            base = f"world/grf/{side}"
            if not (contact and mag >= st.min_grf and np.all(np.isfinite(f))
                    and np.all(np.isfinite(p))):
                out[base] = _NodeState(visible=False)
                continue
            u = f / mag
            rot = pin.Quaternion.FromTwoVectors(np.array([0.0, 1.0, 0.0]), u).coeffs()
            length = st.grf_scale * mag
            h = st.head_length
            s = min(1.0, length / h)
            shaft = max(length - h, 0.0)
            out[base] = _NodeState(position=tuple(p.tolist()), quaternion=tuple(rot.tolist()),
                                   visible=True)
            out[base + "/shaft"] = _NodeState(position=(0.0, shaft / 2.0, 0.0),
                                              scale=(1.0, max(shaft, 1e-6), 1.0))
            out[base + "/head"] = _NodeState(position=(0.0, shaft + s * h / 2.0, 0.0),
                                             scale=(s, s, s))
        return out


def _touchdowns(values: np.ndarray, times: np.ndarray,
                nq: int) -> list[tuple[float, str, float, float]]:
    """Touchdowns in extracted rows: a foot's contact going 0 → 1 (or 1 in the first row).

    Returns:
        ``(time [s], side, x [m], y [m])`` of the contact point ``C`` at each touchdown, in
        time order.
    """
    out = []
    for k, side in enumerate(SIDES):
        o = nq + 7 * k
        c = values[:, o] > 0.5
        starts = np.flatnonzero(c & ~np.concatenate([[False], c[:-1]]))
        for i in starts:
            x, y = values[i, o + 4], values[i, o + 5]
            if np.isfinite(x) and np.isfinite(y):
                out.append((float(times[i]), side, float(x), float(y)))
    out.sort(key=lambda e: e[0])
    return out


# --------------------------------------------------------------------------------------
# Animation of a whole log (shared by export_html and LiveViewer.show_run)
# --------------------------------------------------------------------------------------


@dataclass
class _Recorded:
    """Everything needed to play a log: the animation and the touchdowns it reveals."""

    animation: Any
    n_frames: int
    fps: float
    t0: float
    footprints: list = field(default_factory=list)  # (frame, side, x, y)
    extent: tuple = ((-1.0, 1.0), (-1.0, 1.0))
    first_states: dict = field(default_factory=dict)  # node states of frame 0


def sample_frames(times: np.ndarray, fps: float) -> np.ndarray:
    """Row index shown at each animation frame: frame k is the row nearest ``t0 + k/fps``.

    Args:
        times: log times [s], non-decreasing.
        fps: frames per second of the animation [1/s].
    """
    if fps <= 0 or not math.isfinite(fps):
        raise ConfigError("must be a positive number of frames per second", key="fps", value=fps)
    t0, t1 = float(times[0]), float(times[-1])
    n = int(math.floor((t1 - t0) * fps + 1e-9)) + 1
    want = t0 + np.arange(n) / fps
    if len(times) == 1:
        return np.zeros(n, dtype=int)
    j = np.clip(np.searchsorted(times, want), 1, len(times) - 1)
    left_closer = (want - times[j - 1]) <= (times[j] - want)
    return np.where(left_closer, j - 1, j).astype(int)


def _log_arrays(biped: Biped, log_df, source: str = "log"):
    if log_df is None or len(log_df) == 0:
        raise DataFormatError([DataProblem(source, "the log has no rows")], root=source)
    if "time" not in log_df.columns:
        raise DataFormatError([DataProblem(source, "required column is missing", column="time")],
                              root=source)
    cols = _Columns(biped, log_df.columns, source=source)
    times = log_df["time"].to_numpy(dtype=float)
    bad = np.flatnonzero(~np.isfinite(times))
    if bad.size:
        raise DataFormatError([DataProblem(source, "time is not finite", column="time",
                                           row=int(bad[0]))], root=source)
    back = np.flatnonzero(np.diff(times) < 0)
    if back.size:
        raise DataFormatError([DataProblem(source, "time goes backwards", column="time",
                                           row=int(back[0]) + 1)], root=source)
    return cols, times, cols.from_frame(log_df)


def _record(scene: BipedScene, vis, log_df, fps: float) -> _Recorded:
    """Build the animation of a log: node transforms per frame, no geometry."""
    ma = _mc().animation

    biped = scene.biped
    cols, times, values = _log_arrays(biped, log_df)
    nq = biped.model.nq
    idx = sample_frames(times, fps)
    # Rows with a non-finite pose (e.g. the last rows of a diverged run) show the last
    # finite pose before them.
    finite = np.flatnonzero(np.all(np.isfinite(values[:, :nq]), axis=1))
    if finite.size == 0:
        raise DataFormatError([DataProblem("log", "no row has a finite base pose and joint "
                                           "angles")], root="log")
    idx = finite[np.maximum(np.searchsorted(finite, idx, side="right") - 1, 0)]
    n = len(idx)
    t0 = float(times[0])
    sd = scene.create_data()
    centre = None
    if not scene.style.follow:
        xs, ys = values[:, 0], values[:, 1]
        centre = np.array([0.5 * (xs.min() + xs.max()), 0.5 * (ys.min() + ys.max()),
                           scene.terrain.surface_height + scene.style.look_height])
    anim = ma.Animation(default_framerate=fps)
    first_states: dict = {}
    for k, i in enumerate(idx):
        states = scene.frame_states(sd, values[i], centre)
        if k == 0:
            first_states = states
        with anim.at_frame(vis, k) as frame:
            for path, s in states.items():
                node = frame[path]
                if s.position is not None:
                    node.set_property("position", "vector3", list(s.position))
                if s.quaternion is not None:
                    node.set_property("quaternion", "quaternion", list(s.quaternion))
                if s.scale is not None:
                    node.set_property("scale", "vector3", list(s.scale))
                if s.visible is not None:
                    node.set_property("visible", "boolean", bool(s.visible))
    # Footprints: frame at which each touchdown becomes visible.
    prints = []
    for t, side, x, y in _touchdowns(values, times, nq):
        frame_k = min(int(math.ceil((t - t0) * fps - 1e-9)), n - 1)
        prints.append((frame_k, side, x, y))
    for j, (frame_k, _side, _x, _y) in enumerate(prints):
        keys = {0: frame_k == 0, frame_k: True, n - 1: True}
        for k in sorted(keys):
            with anim.at_frame(vis, k) as frame:
                frame[scene.footprint_path(j)].set_property("visible", "boolean", keys[k])
    # Arrow tracks have keys only while the arrow is shown, footprint tracks only at a few
    # frames: pad every track to span frames 0 … n−1, since three.js loops each clip over
    # its own duration and clips of different lengths would drift apart.
    for clip in anim.clips.values():
        for track in clip.tracks.values():
            if track.frames[0] != 0:
                track.frames.insert(0, 0)
                track.values.insert(0, track.values[0])
            if track.frames[-1] != n - 1:
                track.frames.append(n - 1)
                track.values.append(track.values[-1])
            _drop_redundant_keys(track)
    xs = np.concatenate([values[:, 0]] + [values[:, nq + 7 * k + 4] for k in range(len(SIDES))
                                          if SIDES[k] in cols.sides])
    ys = np.concatenate([values[:, 1]] + [values[:, nq + 7 * k + 5] for k in range(len(SIDES))
                                          if SIDES[k] in cols.sides])
    xs, ys = xs[np.isfinite(xs)], ys[np.isfinite(ys)]
    m = scene.style.terrain_margin
    extent = ((float(xs.min()) - m, float(xs.max()) + m),
              (float(ys.min()) - m, float(ys.max()) + m))
    return _Recorded(anim, n, float(fps), t0, prints, extent, first_states)


def _drop_redundant_keys(track) -> None:
    """Remove keys equal to both neighbours (exact for linear, slerp and step tracks)."""
    fr, va = track.frames, track.values
    if len(fr) <= 2:
        return
    keep_f, keep_v = [fr[0]], [va[0]]
    for i in range(1, len(fr) - 1):
        if va[i] == va[i - 1] and va[i] == va[i + 1]:
            continue
        keep_f.append(fr[i])
        keep_v.append(va[i])
    keep_f.append(fr[-1])
    keep_v.append(va[-1])
    track.frames[:] = keep_f
    track.values[:] = keep_v


def _set_states(vis, states: Mapping[str, _NodeState]) -> None:
    """Send node states as plain transforms and visibility (no animation)."""
    for path, s in states.items():
        if s.position is not None or s.quaternion is not None or s.scale is not None:
            vis[path].set_transform(s.matrix())
    for path, s in states.items():
        if s.visible is not None:
            vis[path].set_property("visible", bool(s.visible))


def _draw_footprints(scene: BipedScene, vis, prints, *, hidden: bool) -> None:
    geom, mat = scene.footprint_object()
    for j, (_frame, _side, x, y) in enumerate(prints):
        node = vis[scene.footprint_path(j)]
        node["disc"].set_object(geom, mat)
        node.set_transform(scene.footprint_transform(x, y))
        if hidden:
            node.set_property("visible", False)


# --------------------------------------------------------------------------------------
# Standalone HTML
# --------------------------------------------------------------------------------------


class _RecordingWindow:
    """A stand-in for meshcat's server connection that keeps the lowered commands."""

    def __init__(self) -> None:
        self.commands: list[dict] = []

    def send(self, command) -> None:
        self.commands.append(command.lower())


def _viewer_js() -> str:
    path = Path(_mc().__file__).resolve().parent / "viewer" / "dist" / "main.min.js"
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


def _meshcat_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("meshcat")
    except PackageNotFoundError:  # pragma: no cover - vendored copies
        return "unknown"


def _pack(command: dict) -> str:
    import umsgpack

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
    meshcat = _mc()
    Visualizer, SetAnimation = meshcat.Visualizer, meshcat.commands.SetAnimation

    path = Path(path)
    scene = BipedScene(biped, terrain_cfg, style)
    window = _RecordingWindow()
    vis = Visualizer(window=window)[ROOT]
    rec = _record(scene, vis, log_df, fps)
    scene.draw_static(vis, rec.extent)
    _draw_footprints(scene, vis, rec.footprints, hidden=True)
    _set_states(vis, rec.first_states)  # the first frame, also shown if paused at load
    window.send(SetAnimation(rec.animation, play=True, repetitions=math.inf))
    commands = window.commands
    label = f"granular_mpc · {scene.terrain.kind} terrain · {rec.n_frames} frames @ {fps:g} fps"
    page = _PAGE.format(
        meshcat_version=html.escape(_meshcat_version()),
        title=html.escape(title or path.stem),
        viewer_js=_viewer_js(),
        commands="\n".join(_pack(c) for c in commands),
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
    import umsgpack

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


# --------------------------------------------------------------------------------------
# Live viewer
# --------------------------------------------------------------------------------------

# The meshcat 0.3.2 server listens for HTTP/WebSocket on every interface (tornado's
# Application.listen(port) without an address). Ours binds 127.0.0.1 only.
_SERVER_CODE = r"""
import sys
import tornado.web
_listen = tornado.web.Application.listen
def _listen_local(self, port, address=None, **kwargs):
    return _listen(self, port, "127.0.0.1", **kwargs)
tornado.web.Application.listen = _listen_local
sys.argv = [sys.argv[0]]
from meshcat.servers.zmqserver import main
main()
"""


class _Server:
    """A meshcat server subprocess bound to 127.0.0.1 (ZMQ for commands, HTTP for browsers)."""

    def __init__(self, start_timeout_s: float = 20.0) -> None:
        import os
        import selectors
        import subprocess
        import tempfile

        env = dict(os.environ)
        site = str(Path(_mc().__file__).resolve().parent.parent)
        env["PYTHONPATH"] = site + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        # stderr goes to an anonymous file: read only to explain a failed start.
        err = tempfile.TemporaryFile()
        self.proc = subprocess.Popen([sys.executable, "-u", "-c", _SERVER_CODE],
                                     stdout=subprocess.PIPE, stderr=err,
                                     stdin=subprocess.DEVNULL, env=env, start_new_session=True)
        self._finalizer = weakref.finalize(self, _stop_process, self.proc, err)
        sel = selectors.DefaultSelector()
        sel.register(self.proc.stdout, selectors.EVENT_READ)
        deadline = time.monotonic() + start_timeout_s
        urls: dict[str, str] = {}
        seen = []
        buf = b""
        try:
            while len(urls) < 2:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise ViewerError("the meshcat server did not start in time",
                                      detail=" | ".join(seen))
                if not sel.select(timeout=left):
                    continue
                chunk = os.read(self.proc.stdout.fileno(), 4096)
                if not chunk:
                    self.proc.wait(timeout=5.0)
                    err.seek(0)
                    tail = err.read()[-2000:].decode("utf-8", "replace")
                    raise ViewerError("the meshcat server exited at start",
                                      detail=f"exit code {self.proc.returncode}; "
                                             + " | ".join(seen + [tail]))
                buf += chunk
                while b"\n" in buf:
                    line, buf = buf.split(b"\n", 1)
                    text = line.decode("utf-8", "replace").strip()
                    seen.append(text)
                    for key in ("zmq_url", "web_url"):
                        if text.startswith(key + "="):
                            urls[key] = text[len(key) + 1:]
        except BaseException:
            self.close()
            self.proc.stdout.close()
            raise
        finally:
            sel.close()
        self.zmq_url = urls["zmq_url"]
        self.web_url = urls["web_url"]
        # Keep reading the server's stdout so that it never blocks on a full pipe.
        threading.Thread(target=_drain, args=(self.proc.stdout,), daemon=True).start()

    @property
    def pid(self) -> int:
        return self.proc.pid

    def alive(self) -> bool:
        return self.proc.poll() is None

    def close(self) -> None:
        self._finalizer()


def _stop_process(proc, err_file) -> None:
    """Stop our server child (SIGTERM, then SIGKILL after 3 s). Its stdout is closed by
    the drain thread once it reads end-of-file, never under that thread's feet."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=3.0)
        except Exception:
            proc.kill()
            proc.wait()
    err_file.close()


def _drain(stream) -> None:
    """Read and drop a pipe until end-of-file, then close it."""
    import os

    try:
        fd = stream.fileno()
        while os.read(fd, 4096):
            pass
    except (OSError, ValueError):
        pass
    finally:
        stream.close()


class _ZmqWindow:
    """Connection to the server's command socket, with time-outs (meshcat's has none)."""

    def __init__(self, zmq_url: str, timeout_s: float) -> None:
        import zmq

        self._zmq = zmq
        self._ctx = zmq.Context.instance()
        self.zmq_url = zmq_url
        self.timeout_ms = max(1, int(1000 * timeout_s))
        self._sock = None
        self.n_sent = 0
        self._connect()

    def _connect(self) -> None:
        zmq = self._zmq
        if self._sock is not None:
            self._sock.close(linger=0)
        s = self._ctx.socket(zmq.REQ)
        s.setsockopt(zmq.LINGER, 0)
        s.setsockopt(zmq.RCVTIMEO, self.timeout_ms)
        s.setsockopt(zmq.SNDTIMEO, self.timeout_ms)
        s.connect(self.zmq_url)
        self._sock = s

    def request(self, frames: list[bytes]) -> bytes:
        try:
            self._sock.send_multipart(frames)
            reply = self._sock.recv()
        except self._zmq.Again:
            self._connect()  # a REQ socket that timed out cannot be used again
            raise ViewerError("the meshcat server did not answer",
                              detail=f"no reply within {self.timeout_ms} ms") from None
        return reply

    def send(self, command) -> None:
        import umsgpack

        data = command.lower()
        self.request([data["type"].encode("utf-8"), data["path"].encode("utf-8"),
                      umsgpack.packb(data)])
        self.n_sent += 1

    def get_scene(self) -> str:
        return self.request([b"get_scene"]).decode("utf-8")

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close(linger=0)
            self._sock = None


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

    Use as a context manager, or call :meth:`close`::

        with LiveViewer(biped, terrain_cfg) as viewer:
            for row in run_rows():          # dicts with the run-log columns
                viewer.update(row)
    """

    def __init__(self, biped: Biped, terrain: Any = None, *, style: SceneStyle | None = None,
                 rate_hz: float = 30.0, extent=((-3.0, 30.0), (-3.0, 3.0)),
                 max_footprints: int = 400, timeout_s: float = 2.0,
                 announce: bool = True, stream: TextIO | None = None) -> None:
        Visualizer = _mc().Visualizer

        if not (rate_hz > 0 and math.isfinite(rate_hz)):
            raise ConfigError("must be a positive rate [Hz]", key="rate_hz", value=rate_hz)
        self.scene = BipedScene(biped, terrain, style)
        self.period = 1.0 / float(rate_hz)
        self.max_footprints = int(max_footprints)
        self._cols = _Columns(biped)
        self._window: _ZmqWindow | None = None
        self._server = _Server()
        try:
            self._window = _ZmqWindow(self._server.zmq_url, timeout_s)
            self._vis = Visualizer(window=self._window)[ROOT]
            self.scene.draw_static(self._vis, extent)
        except BaseException:
            self._shutdown_transport()
            raise
        self.url: str = self._server.web_url
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
        self._last_visible: dict[str, bool] = {f"world/grf/{s}": False for s in SIDES}
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
                now_contact = float(row.get(f"{side}_contact", 0.0)) > 0.5
            except (TypeError, ValueError):
                now_contact = False
            if now_contact and not self._was_contact[side]:
                try:
                    x, y = float(row[f"{side}_px"]), float(row[f"{side}_py"])
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
        return not self._closed and self.error is None and self._server.alive()

    @property
    def server_pid(self) -> int:
        """Process id of the meshcat server (a child of this process)."""
        return self._server.pid

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
        SetAnimation = _mc().commands.SetAnimation

        self._animation_mode = True
        self.flush(timeout=2.0)
        rec = _record(self.scene, self._vis, log_df, fps)
        with self._io_lock:
            self._vis["world/footprints"].delete()
            self.scene.draw_terrain(self._vis, rec.extent)
            _draw_footprints(self.scene, self._vis, rec.footprints, hidden=True)
            _set_states(self._vis, rec.first_states)
            self._window.send(SetAnimation(rec.animation, play=True, repetitions=math.inf))
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
        self._server.close()

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


# --------------------------------------------------------------------------------------
# Saved runs
# --------------------------------------------------------------------------------------


def _read_resolved_config(run_dir: Path) -> dict:
    p = run_dir / "config.resolved.yaml"
    if not p.is_file():
        return {}
    from ..config import load_yaml

    return load_yaml(p)


def _biped_from_config(robot: Any) -> Biped:
    from ..config import RobotConfig, validate
    from ..robot.model import load_biped

    if robot is None:
        return load_biped("yobogo10s")
    if isinstance(robot, str):
        return load_biped(robot)
    if isinstance(robot, Mapping):
        name = str(robot.get("name", "yobogo10s"))
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
           announce: bool = True, stream: TextIO | None = None):
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
    from ..runlog import read_log

    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise OutputError(f"no run folder {run_dir}")
    log_df = read_log(run_dir)
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


__all__ = ["LiveViewer", "export_html", "replay", "read_html_commands", "BipedScene",
           "SceneData", "SceneStyle", "TerrainView", "ViewerError", "sample_frames", "ROOT"]
