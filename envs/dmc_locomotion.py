"""DeepMind Control suite's planar locomotion domains: hopper, walker and cheetah (dm_control's
``suite/<domain>.py``), on the machinery of ``envs/dmc.py``.

All three are planar: a root of two slides (x, z) and a hinge (pitch), then limited hinges; no ball or free
joints. Their rewards read the torso's subtree linear velocity sensor (a velocity-stage sensor), so the step
recomputes the sensors at the new state (``reads_sensors``); hopper's touch sensors are acceleration-stage
values of the last substep, as in dm_control (``envs/dmc.py``)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from envs.dmc import DmcTask, _xmat, tolerance

__all__ = ["Cheetah", "Hopper", "Walker"]


class _Planar(DmcTask):
    """What the three share: the torso's subtree linear velocity sensor (``_speed``: its x)."""

    derived_fields = ("sensordata",)
    reads_sensors = True

    def __init__(self, early_exit_linesearch: bool = True):
        super().__init__(early_exit_linesearch)
        self._velocity_x = int(self.mj_model.sensor_adr[self._id("sensor", "torso_subtreelinvel")])

    def _speed(self, data):
        return data.sensordata[..., self._velocity_x]


class Hopper(_Planar):
    """dm_control's ``hopper-stand`` / ``hopper-hop``: obs = [qpos without the root's x (6), qvel (7), the toe's
    and heel's touch sensors log1p (2)] (15). Control step 0.02 s (4 physics steps).

    Reward: standing (1 while the torso's centre of mass is 0.6-2 above the foot's, else 0) times, for hop, a
    linear tolerance of the forward speed (1 at >= 2 m/s, 0.5 at 1 m/s, 0 at <= 0), for stand (4 + the mean
    quadratic tolerance of the controls) / 5. Reset: ``randomize_limited_and_rotational_joints`` (the pitch
    U(-pi, pi), the limited hinges uniform in range; the root's slides stay at 0), at rest."""

    domain = "hopper"
    control_timestep = 0.02
    derived_fields = ("xipos", "sensordata")

    def __init__(self, hopping: bool = True, early_exit_linesearch: bool = True):
        self.hopping = bool(hopping)
        super().__init__(early_exit_linesearch)
        m = self.mj_model
        self._torso, self._foot = self._id("body", "torso"), self._id("body", "foot")
        self._touch = np.array([m.sensor_adr[self._id("sensor", n)] for n in ("touch_toe", "touch_heel")])

    def _obs_size(self):
        return 15

    def _get_obs(self, xp, data):
        return xp.concatenate([data.qpos[..., 1:], data.qvel, xp.log1p(data.sensordata[..., self._touch])], axis=-1)

    def sample_reset(self, rng):
        return self._candidate(self.joint_draws(rng))[None]

    def _reward(self, xp, data, ctrl):
        height = data.xipos[..., self._torso, 2] - data.xipos[..., self._foot, 2]
        standing = tolerance(xp, height, (0.6, 2.0))
        if self.hopping:
            return standing * tolerance(xp, self._speed(data), (2.0, float("inf")), margin=1.0,
                                        value_at_margin=0.5, sigmoid="linear")
        control = tolerance(xp, ctrl, margin=1, value_at_margin=0, sigmoid="quadratic")
        return standing * ((xp.mean(control, axis=-1) + 4) / 5)


class Walker(_Planar):
    """dm_control's ``walker-stand`` / ``walk`` / ``run`` (move speed 0 / 1 / 8): obs = [every body's frame
    xx and xz but the world's (14), the torso's height (1), qvel (9)] (24). Control step 0.025 s (10 physics
    steps).

    Reward: stand = (3 standing + upright) / 4, standing a Gaussian tolerance of the torso's height (1 at >= 1.2,
    margin 0.6), upright (1 + the torso's zz) / 2; walk and run multiply it by (5 move + 1) / 6, move a linear
    tolerance of the forward speed (1 at >= the move speed, 0.5 at half of it). Reset: ``randomize_limited_and_
    rotational_joints`` (the pitch U(-pi, pi), the limited hinges uniform in range; the root's slides stay at 0),
    at rest."""

    domain = "walker"
    control_timestep = 0.025
    derived_fields = ("xmat", "xpos", "sensordata")

    def __init__(self, move_speed: float = 0.0, early_exit_linesearch: bool = True):
        self.move_speed = float(move_speed)
        super().__init__(early_exit_linesearch)
        self._torso = self._id("body", "torso")

    def _obs_size(self):
        return 2 * (self.mj_model.nbody - 1) + 1 + self.mj_model.nv

    def _get_obs(self, xp, data):
        frames = _xmat(data)[..., 1:, :][..., [0, 2]]
        orientations = frames.reshape(*frames.shape[:-2], -1)
        return xp.concatenate([orientations, data.xpos[..., self._torso, 2:3], data.qvel], axis=-1)

    def sample_reset(self, rng):
        return self._candidate(self.joint_draws(rng))[None]

    def _reward(self, xp, data, ctrl):
        standing = tolerance(xp, data.xpos[..., self._torso, 2], (1.2, float("inf")), margin=0.6, scalar=True)
        upright = (1 + _xmat(data)[..., self._torso, 8]) / 2
        stand = (3 * standing + upright) / 4
        if self.move_speed == 0:
            return stand
        move = tolerance(xp, self._speed(data), (self.move_speed, float("inf")), margin=self.move_speed / 2,
                         value_at_margin=0.5, sigmoid="linear")
        return stand * (5 * move + 1) / 6


class Cheetah(_Planar):
    """dm_control's ``cheetah-run``: obs = [qpos without the root's x (8), qvel (9)] (17); one physics step
    (0.01 s) per control step. Reward: a linear tolerance of the forward speed (1 at >= 10 m/s, 0 at <= 0).

    Reset: the limited hinges (all but the root's) uniform in their range, the root at qpos0, at rest; then 200
    physics steps with zero controls let it settle (``settle_steps``: on the C engine ``DmcTask.settle``, on MJX
    a loop that runs only where an episode ends, ``DmcTask.step_with_reset``), time reset to 0."""

    domain = "cheetah"
    settle_steps = 200

    def __init__(self, early_exit_linesearch: bool = True):
        super().__init__(early_exit_linesearch)
        m = self.mj_model
        assert m.nq == m.njnt  # every joint has one coordinate (as dm_control's reset assumes)
        self._limited = np.flatnonzero(m.jnt_limited)
        self._low, self._high = m.jnt_range[self._limited].T

    def _obs_size(self):
        return self.mj_model.nq - 1 + self.mj_model.nv

    def _get_obs(self, xp, data):
        return xp.concatenate([data.qpos[..., 1:], data.qvel], axis=-1)

    def sample_reset(self, rng):
        draw = jax.random.uniform(rng, (len(self._limited),), jnp.float32, self._low, self._high)
        return self._candidate(self.init_qpos.at[self._limited].set(draw))[None]

    def _reward(self, xp, data, ctrl):
        return tolerance(xp, self._speed(data), (10.0, float("inf")), margin=10.0, value_at_margin=0,
                         sigmoid="linear")
