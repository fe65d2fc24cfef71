"""Building a closed-loop :class:`Simulation` from a scenario (robot, terrains, plant,
controller, push windows, step counts).

Timing. The plant steps at ``sim.dt``; the controller (``mode: walk``: the walking
controller; ``mode: drop``: joint PD holding the pose; ``mode: playback``: joint PD
tracking a recorded run, :mod:`~granular_mpc.runner.playback`) is evaluated every ``1 / controller.wbc.rate_hz``
and a log row is written every ``1 / output.log_rate_hz``; both periods are whole numbers
of plant steps (:func:`step_count`).

Pushes (``pushes:``) put a constant world-frame force/torque on the trunk
(``PlantData.base_wrench``) during ``[start, start + duration)``; a ``mid_stance`` push
starts at the first planned mid-stance at or after ``time``. In ``mode: drop`` the trunk
hangs on the guide rig (:class:`~granular_mpc.runner.rig.GuideRig`) instead.

Plant. ``sim.plant`` chooses the plant that steps
(:func:`granular_mpc.dynamics.select.select_plant`): the compiled one by default, the
reference :class:`~granular_mpc.dynamics.Plant` when asked for or when the compiled one
does not model the scenario (a ``track`` terrain, ``sim.actuators``); the fallback is
printed as one line on stderr and :attr:`Simulation.plant_choice` records the choice.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..config import ScenarioConfig, load_terrain
from ..control.controller import WalkingController
from ..dynamics import Plant
from ..dynamics.select import PlantChoice, select_plant
from ..exceptions import ConfigError
from ..robot.kinematics import balanced_stance
from ..robot.model import SIDES, Biped
from ..terrain import build_terrain
from .playback import JointPlayback, JointReference
from .rig import GuideRig
from .state import LoopState


@dataclass(frozen=True)
class PushWindow:
    """A push resolved to times: wrench (f_W [N], m_W [N·m]) on the trunk in [start, end).

    Attributes:
        start: start time [s].
        end: end time [s] (exclusive).
        wrench: (6,) force [N] then torque [N·m], world frame, at the trunk origin.
        index: position of the push in the scenario's ``pushes:`` list.
    """

    start: float
    end: float
    wrench: np.ndarray
    index: int

    @property
    def impulse(self) -> np.ndarray:
        """Linear impulse [N·s], world frame."""
        return self.wrench[:3] * (self.end - self.start)


@dataclass(frozen=True)
class Simulation:
    """Immutable closed-loop model of one scenario (state lives in :class:`LoopState`).

    Attributes:
        scenario: the validated scenario.
        biped: the robot.
        plant: the plant (its ``terrain`` is the plant's terrain model).
        controller_terrain: the ground model the controller believes in (the plant's own
            object when ``controller.terrain`` is ``plant``).
        controller: the walking controller (``None`` in ``mode: drop`` and ``playback``).
        q0: initial configuration.
        pushes: push windows, in time order.
        control_every: plant steps per controller tick.
        log_every: plant steps per log row.
        n_steps: plant steps of the whole run.
        plant_choice: the plant asked for (``sim.plant``) and the one stepping, with the
            reason of a fallback.
        playback: the joint PD law of ``mode: playback`` (``None`` otherwise).
    """

    scenario: ScenarioConfig
    biped: Biped
    plant: Any
    controller_terrain: Any
    controller: Any
    q0: np.ndarray
    pushes: tuple[PushWindow, ...]
    control_every: int
    log_every: int
    n_steps: int
    plant_choice: PlantChoice = PlantChoice("reference", "reference")
    playback: JointPlayback | None = None

    @property
    def plant_terrain(self):
        """The plant's terrain model."""
        return self.plant.terrain

    @property
    def dt(self) -> float:
        """Plant step [s]."""
        return self.plant.dt

    @property
    def surface_height(self) -> float:
        """Height of the free surface in W [m]."""
        return self.plant.terrain.surface_height

    @property
    def controller_terrain_name(self) -> str:
        """Name of the controller's ground model."""
        return self.controller_terrain.name

    def new_state(self) -> LoopState:
        """Fresh changing state at t = 0."""
        pdata = self.plant.new_data(self.q0)
        cdata = None
        if self.controller is not None:
            cdata = self.controller.new_data(self.q0, dt_wbc=self.control_every * self.dt)
        elif self.scenario.mode == "drop":
            pdata.base_wrench = GuideRig(self.scenario.rig, self.q0)
        rng = np.random.default_rng(np.random.SeedSequence(self.scenario.sim.seed))
        return LoopState(plant=pdata, controller=cdata, rng=rng)


def step_count(period: float, dt: float, what: str) -> int:
    """Plant steps per ``period`` [s] (rounded), at least one.

    Args:
        period: the period [s] (e.g. 1 / controller rate).
        dt: plant step [s].
        what: the setting the period comes from, for the error message.

    Raises:
        ConfigError: ``period`` is shorter than ``dt`` (key ``sim.dt``).
    """
    n = int(round(period / dt))
    if n < 1:
        raise ConfigError(f"{what} period {period:g} s is shorter than sim.dt = {dt:g} s",
                          key="sim.dt")
    return n


def build_simulation(scenario: ScenarioConfig, *, biped: Biped | None = None,
                     extra_effects: Sequence = ()) -> Simulation:
    """Build robot, plant terrain, controller terrain, plant and controller.

    Args:
        scenario: the validated scenario.
        biped: a robot model built from ``scenario.robot`` (built here if ``None``).
        extra_effects: more :class:`~granular_mpc.config.EffectSpec` for the **plant's**
            terrain only (e.g. ``synth --effect``); the controller never sees them.

    Raises:
        ConfigError: a period shorter than ``sim.dt``, or a terrain/controller that
            cannot be built from the scenario.
    """
    if biped is None:
        biped = Biped.from_config(scenario.robot)
    plant_terrain = build_terrain(scenario.terrain, scenario.robot, extra_effects=extra_effects)
    ct_name = scenario.controller.terrain
    if ct_name == "plant" and plant_terrain.kind == "track" and scenario.mode == "walk":
        raise ConfigError("a track terrain changes along x, and the controller's ground "
                          "model is one medium: name the one it believes in",
                          key="controller.terrain", value="plant",
                          allowed="a terrain name, e.g. rigid or dry_sand")
    if ct_name == "plant" and not extra_effects:
        ctrl_terrain = plant_terrain
    elif ct_name == "plant":
        ctrl_terrain = build_terrain(scenario.terrain, scenario.robot)
    else:
        cfg = scenario.controller_terrain or load_terrain(ct_name)
        ctrl_terrain = build_terrain(cfg, scenario.robot)
    plant, choice = stepping_plant(Plant(biped, plant_terrain, scenario.sim), scenario)
    dt = scenario.sim.dt
    control_every = step_count(1.0 / scenario.controller.wbc.rate_hz, dt,
                               "controller.wbc.rate_hz")
    log_every = step_count(1.0 / scenario.log_rate_hz, dt, "output.log_rate_hz")
    # the soles roll: start with the CoM exactly over their contact line (else the
    # standing robot tips at e^{ωt} before the first step)
    q0 = balanced_stance(biped, clearance=scenario.start_clearance)
    q0[2] += plant_terrain.surface_height
    controller = None
    pushes: tuple[PushWindow, ...] = ()
    playback = None
    if scenario.mode == "walk":
        controller = WalkingController.build(scenario.controller, scenario.command, biped,
                                             ctrl_terrain)
        pushes = push_windows(scenario, controller.schedule, dt)
    elif scenario.mode == "playback":
        pb = scenario.playback
        playback = JointPlayback(JointReference.from_run(pb.reference, biped.joint_names),
                                 kp=pb.kp, kd=pb.kd, feedforward=pb.feedforward,
                                 tau_max=biped.torque_limits)
    return Simulation(scenario=scenario, biped=biped, plant=plant,
                      controller_terrain=ctrl_terrain, controller=controller, q0=q0,
                      pushes=pushes, control_every=control_every, log_every=log_every,
                      n_steps=int(round(scenario.sim.duration / dt)), plant_choice=choice,
                      playback=playback)


def stepping_plant(plant: Plant, scenario: ScenarioConfig):
    """The plant that steps ``plant``'s model as ``scenario.sim.plant`` asks
    (:func:`~granular_mpc.dynamics.select.select_plant`); a fallback to the reference
    plant is printed as one line on stderr.

    Returns:
        ``(plant to step, PlantChoice)``.
    """
    stepping, choice = select_plant(plant, scenario.sim.plant)
    if choice.note:
        print(f"{scenario.name}: {choice.note}", file=sys.stderr)
    return stepping, choice


def push_windows(scenario: ScenarioConfig, schedule, dt: float) -> tuple[PushWindow, ...]:
    """Resolve the scenario's pushes to start/end times, in time order.

    A ``mid_stance`` push starts at :func:`next_mid_stance` (dropped if there is none
    before the end of the run).

    Args:
        scenario: the validated scenario.
        schedule: the controller's gait schedule.
        dt: plant step [s].
    """
    out = []
    for i, p in enumerate(scenario.pushes):
        start = p.time
        if p.at == "mid_stance":
            start = next_mid_stance(schedule, p.time, p.side, scenario.sim.duration, dt)
            if start is None:
                continue
        wrench = np.array(list(p.force_W) + list(p.torque), dtype=float)
        out.append(PushWindow(float(start), float(start + p.duration), wrench, i))
    return tuple(sorted(out, key=lambda w: w.start))


def next_mid_stance(schedule, t0: float, side: str, t_max: float, dt: float) -> float | None:
    """First time ≥ ``t0`` [s] at which a planned stance (of ``side``) passes 50 %.

    Args:
        schedule: the gait schedule.
        t0: earliest start [s].
        side: ``left``, ``right`` or ``any``.
        t_max: end of the search [s].
        dt: search step [s] (the plant step).

    Returns:
        The time [s] on the ``dt`` grid from ``t0``, or ``None`` if none before ``t_max``.
    """
    feet = (0, 1) if side == "any" else (SIDES.index(side),)
    n = int(math.ceil((t_max - t0) / dt))
    for k in range(max(n, 0) + 1):
        t = t0 + k * dt
        if schedule.standing(t):
            continue
        for f in feet:
            if schedule.in_stance(t, f) and schedule.stance_phase(t, f) >= 0.5:
                # step back to the crossing: stance_phase rose past 0.5 within this dt
                if (k == 0 or schedule.stance_phase(t - dt, f) < 0.5
                        or not schedule.in_stance(t - dt, f)):
                    return t
    return None


__all__ = ["PushWindow", "Simulation", "build_simulation", "stepping_plant", "step_count",
           "push_windows", "next_mid_stance"]
