"""The scene: what the viewer draws and where each moving part is, frame by frame.

What is drawn (frames and units: ``docs/notation.md``; everything in ``W``, metres):

* the robot, from the URDF visual primitives in ``biped.visual_model`` (boxes, cylinders,
  spheres, capsules, mesh files) placed at their world placement ``oMg`` each frame;
* the terrain: granular → a sand-coloured box ``layer_depth`` thick over a grey floor
  slab; rigid → a grey slab; both with the free surface at ``surface_height``;
* footprints: a dark disc on the free surface at the ``(x, y)`` of the contact point ``C``
  of every touchdown; they stay;
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
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pinocchio as pin

from ...config import load_terrain
from ...exceptions import ConfigError, GranularMpcError
from ...robot.model import SIDES, Biped
from ...rotations import matrix_from_quat_xyzw
from .backend import geometry as mg
from .log_rows import FOOT_STRIDE

ROOT = "granular_mpc"
"""Name of the Meshcat group under ``/meshcat`` that holds everything this package draws."""

_SAND_RGB = (0.86, 0.74, 0.52)
_FLOOR_RGB = (0.42, 0.42, 0.44)
_RIGID_RGB = (0.58, 0.58, 0.60)
_PRINT_SAND_RGB = (0.36, 0.27, 0.16)
_PRINT_RIGID_RGB = (0.22, 0.22, 0.24)
_GRF_RGB = (0.10, 0.78, 0.22)


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
# The scene: geometry once, node states per frame
# --------------------------------------------------------------------------------------


def _rgb_int(rgb) -> int:
    r, g, b = (int(round(255 * min(max(float(c), 0.0), 1.0))) for c in rgb[:3])
    return (r << 16) | (g << 8) | b


def _material(rgb, opacity: float = 1.0, **extra):
    return mg.MeshLambertMaterial(color=_rgb_int(rgb), opacity=float(opacity), **extra)


def _translation(p) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


_R_Y_TO_Z = np.array([[1.0, 0, 0, 0], [0, 0, -1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]])
"""Rotation about x by +90°: maps three.js's cylinder axis (y) onto the URDF's (z)."""


@dataclass(frozen=True)
class NodeState:
    """Pose of one scene node in its parent (``W``-aligned groups), SI units.

    ``quaternion`` is (x, y, z, w) as three.js wants it; ``None`` fields are not set.
    """

    position: tuple | None = None
    quaternion: tuple | None = None
    scale: tuple | None = None
    visible: bool | None = None

    def matrix(self) -> np.ndarray:
        """Homogeneous transform (4, 4): translation · rotation · scale."""
        T = np.eye(4)
        if self.quaternion is not None:
            T[:3, :3] = matrix_from_quat_xyzw(self.quaternion)
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
        """Fresh buffers for :meth:`frame_states` (one per thread)."""
        return SceneData(self.biped.model.createData(),
                         pin.GeometryData(self.biped.visual_model))

    # ------------------------------------------------------------------ paths
    @staticmethod
    def robot_path(name: str) -> str:
        """Scene path of the robot geometry ``name``."""
        return f"world/robot/{name}"

    @staticmethod
    def footprint_path(k: int) -> str:
        """Scene path of the ``k``-th footprint."""
        return f"world/footprints/{k}"

    @staticmethod
    def grf_path(side: str) -> str:
        """Scene path of the ground-reaction-force arrow of foot ``side``."""
        return f"world/grf/{side}"

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
        st = self.style
        # Transparent (opacity < 1) puts the arrows in three.js's second render pass; with
        # the depth test off they are then drawn over the foot and the sand.
        mat = _material(_GRF_RGB, 0.95, depthTest=False, depthWrite=False)
        for side in SIDES:
            node = vis[self.grf_path(side)]
            node["shaft"].set_object(mg.Cylinder(1.0, st.arrow_radius), mat)
            node["head"].set_object(mg.Cylinder(st.head_length, radiusTop=0.0,
                                                radiusBottom=st.head_radius), mat)
            node.set_property("visible", False)

    def footprint_object(self):
        """Geometry and material of one footprint disc."""
        rgb = _PRINT_SAND_RGB if self.terrain.kind == "granular" else _PRINT_RIGID_RGB
        return mg.Cylinder(0.002, self.style.footprint_radius), _material(rgb)

    def footprint_transform(self, x: float, y: float) -> np.ndarray:
        """Pose of a footprint disc at (x, y) [m, W], lying flat 1 mm above the surface."""
        T = _R_Y_TO_Z.copy()
        T[:3, 3] = [x, y, self.terrain.surface_height + 0.001]
        return T

    def draw_footprints(self, vis, prints, *, hidden: bool) -> None:
        """Draw footprint discs ``(frame, side, x [m], y [m])``, numbered in order."""
        geom, mat = self.footprint_object()
        for j, (_frame, _side, x, y) in enumerate(prints):
            node = vis[self.footprint_path(j)]
            node["disc"].set_object(geom, mat)
            node.set_transform(self.footprint_transform(x, y))
            if hidden:
                node.set_property("visible", False)

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
                     centre: np.ndarray | None = None) -> dict[str, NodeState]:
        """Pose of every moving node for one extracted row (see :mod:`.log_rows`).

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
        out: dict[str, NodeState] = {}
        if centre is None:
            centre = self.view_centre(values)
        out["world"] = NodeState(position=tuple((-np.asarray(centre, dtype=float)).tolist()))
        for i, name in enumerate(self.geom_names):
            M = sd.geom_data.oMg[i]
            qc = pin.Quaternion(M.rotation).coeffs()  # x, y, z, w
            out[self.robot_path(name)] = NodeState(position=tuple(M.translation.tolist()),
                                                    quaternion=tuple(qc.tolist()))
        st = self.style
        for k, side in enumerate(SIDES):
            o = nq + FOOT_STRIDE * k
            contact = values[o] > 0.5
            f = np.asarray(values[o + 1:o + 4], dtype=float)
            p = np.asarray(values[o + 4:o + 7], dtype=float)
            mag = float(np.linalg.norm(f))
            base = self.grf_path(side)
            if not (contact and mag >= st.min_grf and np.all(np.isfinite(f))
                    and np.all(np.isfinite(p))):
                out[base] = NodeState(visible=False)
                continue
            u = f / mag
            rot = pin.Quaternion.FromTwoVectors(np.array([0.0, 1.0, 0.0]), u).coeffs()
            length = st.grf_scale * mag
            h = st.head_length
            s = min(1.0, length / h)
            shaft = max(length - h, 0.0)
            out[base] = NodeState(position=tuple(p.tolist()), quaternion=tuple(rot.tolist()),
                                   visible=True)
            out[base + "/shaft"] = NodeState(position=(0.0, shaft / 2.0, 0.0),
                                              scale=(1.0, max(shaft, 1e-6), 1.0))
            out[base + "/head"] = NodeState(position=(0.0, shaft + s * h / 2.0, 0.0),
                                             scale=(s, s, s))
        return out


def set_states(vis, states: Mapping[str, NodeState]) -> None:
    """Send node states as plain transforms, then visibility (no animation)."""
    for path, s in states.items():
        if s.position is not None or s.quaternion is not None or s.scale is not None:
            vis[path].set_transform(s.matrix())
    for path, s in states.items():
        if s.visible is not None:
            vis[path].set_property("visible", bool(s.visible))


__all__ = ["ROOT", "TerrainView", "SceneStyle", "NodeState", "SceneData", "BipedScene",
           "set_states"]
