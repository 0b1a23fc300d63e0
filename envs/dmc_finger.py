"""DeepMind Control suite's ``finger`` domain (dm_control's ``suite/finger.py``): spin, turn_easy, turn_hard, on
the machinery of ``envs/dmc.py``."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from envs.dmc import DmcTask
from envs.mujoco_base import _norm

__all__ = ["Finger"]


class Finger(DmcTask):
    """dm_control's ``finger``: a two-link finger (proximal, distal; limited hinges) and a free-spinning body on
    an unlimited hinge (no gravity). Control step 0.02 s (2 physics steps); everything observed comes from the
    model's sensors.

    obs = [proximal, distal, tip x/z relative to the spinner's hinge (4), the three joints' velocities (3), the
    two touch sensors log1p (2)] (9), and for turn also [target x/z relative to the hinge (2), the tip's signed
    distance to the target's surface (1)] (12).
    Reward: spin 1 while the hinge turns at <= -15 rad/s; turn 1 while the tip is inside the target (radius 0.07
    turn_easy, 0.03 turn_hard), else 0.
    Reset: the target (turn) at angle U(-pi, pi) on the circle of radius cap1's size sum (0.13) around the hinge
    (a per-env model parameter: the target site's x and z); the joints as ``randomize_limited_and_rotational_
    joints`` (finger hinges uniform in range, the spinner U(-pi, pi)), at rest, redrawn while any geoms touch:
    the first of 16 draws without contacts is kept (dm_control gives up after 1,000 draws; 8.9% of draws touch,
    so all 16 touch with probability ~1e-17). Spin sets the spinner's damping to 0.03 (dm_control sets it at
    every reset; here in the model once)."""

    domain = "finger"
    control_timestep = 0.02
    derived_fields = ("sensordata",)
    reads_sensors = True
    reset_tries = 16
    _SPIN_VELOCITY = 15.0

    def __init__(self, turn: bool = True, target_radius: float = 0.03, early_exit_linesearch: bool = True):
        self.turn, self.target_radius = bool(turn), float(target_radius)
        super().__init__(early_exit_linesearch)
        m = self.mj_model

        def adr(name, size=1):
            start = int(m.sensor_adr[self._id("sensor", name)])
            return np.arange(start, start + size)

        self._joints = np.concatenate([adr("proximal"), adr("distal")])
        self._velocity = np.concatenate([adr("proximal_velocity"), adr("distal_velocity"), adr("hinge_velocity")])
        self._touch = np.concatenate([adr("touchtop"), adr("touchbottom")])
        self._tip, self._spinner, self._target_xz = adr("tip", 3)[::2], adr("spinner", 3)[::2], adr("target", 3)[::2]
        self._hinge_velocity = int(adr("hinge_velocity")[0])

    def _configure(self, model):
        if self.turn:
            target = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "target")
            model.site_size[target, 0] = self.target_radius
            self.model_params = (("site_pos", 3 * target), ("site_pos", 3 * target + 2))
            # dm_control's reset reads the hinge's anchor (fixed: the spinner's body does not move) after its
            # mj_forward at qpos0, and the radius as the sum of cap1's sizes.
            data = mujoco.MjData(model)
            mujoco.mj_forward(model, data)
            hinge = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "hinge")
            self._hinge_xz = np.array(data.xanchor[hinge, ::2], np.float32)
            self._radius = float(model.geom_size[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "cap1")].sum())
        else:
            model.dof_damping[model.jnt_dofadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "hinge")]] = 0.03
        return model

    def _obs_size(self):
        return 12 if self.turn else 9

    def _tip_position(self, s):
        return s[..., self._tip] - s[..., self._spinner]

    def _target_position(self, s):
        return s[..., self._target_xz] - s[..., self._spinner]

    def _dist_to_target(self, xp, s):
        return _norm(xp, self._target_position(s) - self._tip_position(s)) - self.target_radius

    def _get_obs(self, xp, data):
        s = data.sensordata
        obs = [s[..., self._joints], self._tip_position(s), s[..., self._velocity], xp.log1p(s[..., self._touch])]
        if self.turn:
            obs += [self._target_position(s), self._dist_to_target(xp, s)[..., None]]
        return xp.concatenate(obs, axis=-1)

    def sample_reset(self, rng):
        k_target, k_joints = jax.random.split(rng)
        qpos = jax.vmap(self.joint_draws)(jax.random.split(k_joints, self.reset_tries))
        params = ()
        if self.turn:
            angle = self._uniform_in(k_target, (), -np.pi, np.pi)
            params = self._hinge_xz + self._radius * jnp.stack([jnp.sin(angle), jnp.cos(angle)])
        return jax.vmap(lambda q: self._candidate(q, params=params))(qpos)

    def _reward(self, xp, data, ctrl):
        s = data.sensordata
        if self.turn:
            hit = self._dist_to_target(xp, s) <= 0
        else:
            hit = s[..., self._hinge_velocity] <= -self._SPIN_VELOCITY
        return hit.astype(s.dtype)
