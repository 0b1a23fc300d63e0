"""DeepMind Control suite's classic-control and reaching domains: cartpole, pendulum, ball_in_cup, reacher,
point_mass and acrobot (dm_control's ``suite/<domain>.py``), on the machinery of ``envs/dmc.py``."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from envs.dmc import DmcTask, _xmat, tolerance
from envs.mujoco_base import _norm

__all__ = ["Acrobot", "BallInCup", "Cartpole", "Pendulum", "PointMass", "Reacher"]


class Cartpole(DmcTask):
    """dm_control's ``cartpole`` (one pole): balance / swingup, smooth or sparse reward.

    obs = [cart x, pole zz, pole xz, qvel] (5). Reset: swingup puts the cart at N(0, 0.01^2) and the pole at
    pi + N(0, 0.01^2) (hanging); balance draws the cart in U(-0.1, 0.1) and the pole in U(-0.034, 0.034);
    qvel ~ N(0, 0.01^2) in both."""

    domain = "cartpole"
    derived_fields = ("xmat",)

    def __init__(self, swing_up: bool = True, sparse: bool = False, early_exit_linesearch: bool = True):
        self.swing_up, self.sparse = bool(swing_up), bool(sparse)
        super().__init__(early_exit_linesearch)

    def _obs_size(self):
        return 5

    def _get_obs(self, xp, data):
        xmat = _xmat(data)
        return xp.concatenate([data.qpos[..., :1], xmat[..., 2, 8:9], xmat[..., 2, 2:3], data.qvel], axis=-1)

    def sample_reset(self, rng):
        k_cart, k_pole, k_vel = jax.random.split(rng, 3)
        if self.swing_up:
            cart = 0.01 * jax.random.normal(k_cart, (), jnp.float32)
            pole = jnp.pi + 0.01 * jax.random.normal(k_pole, (), jnp.float32)
        else:
            cart = self._uniform_in(k_cart, (), -0.1, 0.1)
            pole = self._uniform_in(k_pole, (), -0.034, 0.034)
        qvel = 0.01 * jax.random.normal(k_vel, (self.mj_model.nv,), jnp.float32)
        return self._candidate(jnp.stack([cart, pole]), qvel)[None]

    def _reward(self, xp, data, ctrl):
        cart, cosine = data.qpos[..., 0], _xmat(data)[..., 2, 8]
        if self.sparse:
            return tolerance(xp, cart, (-0.25, 0.25)) * tolerance(xp, cosine, (0.995, 1.0))
        upright = (cosine + 1) / 2
        centered = (1 + tolerance(xp, cart, margin=2, scalar=True)) / 2
        small_control = (4 + tolerance(xp, ctrl[..., 0], margin=1, value_at_margin=0, sigmoid="quadratic")) / 5
        small_velocity = (1 + tolerance(xp, data.qvel[..., 1], margin=5)) / 2
        return upright * small_control * small_velocity * centered


class Pendulum(DmcTask):
    """dm_control's ``pendulum-swingup``: obs = [pole zz, pole xz, angular velocity] (3); reward 1 while the pole
    is within 8 degrees of upright, else 0; reset: the angle U(-pi, pi), at rest."""

    domain = "pendulum"
    derived_fields = ("xmat",)
    _COSINE_BOUND = float(np.cos(np.deg2rad(8)))

    def _obs_size(self):
        return 3

    def _get_obs(self, xp, data):
        xmat = _xmat(data)
        return xp.concatenate([xmat[..., 1, 8:9], xmat[..., 1, 2:3], data.qvel], axis=-1)

    def sample_reset(self, rng):
        return self._candidate(self._uniform_in(rng, (1,), -np.pi, np.pi))[None]

    def _reward(self, xp, data, ctrl):
        return tolerance(xp, _xmat(data)[..., 1, 8], (self._COSINE_BOUND, 1.0))


class BallInCup(DmcTask):
    """dm_control's ``ball_in_cup-catch``: obs = [qpos, qvel] (8); reward 1 while the ball is inside the cup's
    target box, else 0. Control step 0.02 s (10 physics steps). Reset: the cup at rest at its origin, the ball at
    rest at x ~ U(-0.2, 0.2), z ~ U(0.2, 0.5), redrawn while it touches the cup: the first of 16 draws without
    contacts is kept (dm_control redraws without limit; 18% of draws touch the cup, so all 16 touch, and the 16th is
    kept, with probability ~1e-12)."""

    domain = "ball_in_cup"
    control_timestep = 0.02
    derived_fields = ("xpos", "site_xpos")
    reset_tries = 16

    def __init__(self, early_exit_linesearch: bool = True):
        super().__init__(early_exit_linesearch)
        m = self.mj_model
        self._ball, self._target = self._id("body", "ball"), self._id("site", "target")
        # dm_control's in_target: |target - ball| < target half-size - ball radius, in x and z.
        self._inside = np.array(m.site_size[self._target, [0, 2]] - m.geom_size[self._id("geom", "ball"), 0])

    def _obs_size(self):
        return 8

    def _get_obs(self, xp, data):
        return xp.concatenate([data.qpos, data.qvel], axis=-1)

    def sample_reset(self, rng):
        k_x, k_z = jax.random.split(rng)
        n = self.reset_tries
        ball = jnp.stack([self._uniform_in(k_x, (n,), -0.2, 0.2), self._uniform_in(k_z, (n,), 0.2, 0.5)], axis=-1)
        qpos = jnp.concatenate([jnp.broadcast_to(self.init_qpos[:2], (n, 2)), ball], axis=-1)
        return jax.vmap(self._candidate)(qpos)

    def _reward(self, xp, data, ctrl):
        to_target = data.site_xpos[..., self._target, ::2] - data.xpos[..., self._ball, ::2]
        inside = xp.all(abs(to_target) < self._inside.astype(to_target.dtype), axis=-1)
        return inside.astype(to_target.dtype)


class Reacher(DmcTask):
    """dm_control's ``reacher-easy`` / ``reacher-hard`` (target radius 0.05 / 0.015): obs = [qpos, finger-to-target
    xy, qvel] (6); reward 1 while the finger touches the target, else 0. Reset: the shoulder U(-pi, pi), the wrist
    uniform in its range, at rest; the target at angle U(0, 2 pi), radius U(0.05, 0.2) (a per-env model
    parameter: the target geom's position)."""

    domain = "reacher"
    derived_fields = ("geom_xpos",)

    def __init__(self, target_size: float = 0.05, early_exit_linesearch: bool = True):
        self.target_size = float(target_size)
        super().__init__(early_exit_linesearch)
        self._finger = self._id("geom", "finger")
        self._radii = float(self.mj_model.geom_size[self._target, 0] + self.mj_model.geom_size[self._finger, 0])

    def _configure(self, model):
        self._target = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "target")
        model.geom_size[self._target, 0] = self.target_size
        self.model_params = (("geom_pos", 3 * self._target), ("geom_pos", 3 * self._target + 1))
        return model

    def _obs_size(self):
        return 6

    def _to_target(self, data):
        return data.geom_xpos[..., self._target, :2] - data.geom_xpos[..., self._finger, :2]

    def _get_obs(self, xp, data):
        return xp.concatenate([data.qpos, self._to_target(data), data.qvel], axis=-1)

    def sample_reset(self, rng):
        k_joints, k_angle, k_radius = jax.random.split(rng, 3)
        angle = self._uniform_in(k_angle, (), 0.0, 2 * np.pi)
        radius = self._uniform_in(k_radius, (), 0.05, 0.2)
        target = jnp.stack([radius * jnp.sin(angle), radius * jnp.cos(angle)])
        return self._candidate(self.joint_draws(k_joints), params=target)[None]

    def _reward(self, xp, data, ctrl):
        return tolerance(xp, _norm(xp, self._to_target(data)), (0.0, self._radii))


class PointMass(DmcTask):
    """dm_control's ``point_mass-easy``: obs = [qpos, qvel] (4); reward = near_target * (4 + small_control) / 5
    (a Gaussian tolerance of the distance to the target, bounds and margin the target's radius; a quadratic
    tolerance of the two controls, averaged). Reset: both slides uniform in their range, at rest."""

    domain = "point_mass"
    derived_fields = ("geom_xpos",)

    def __init__(self, early_exit_linesearch: bool = True):
        super().__init__(early_exit_linesearch)
        self._mass, self._target = self._id("geom", "pointmass"), self._id("geom", "target")
        self._size = float(self.mj_model.geom_size[self._target, 0])

    def _obs_size(self):
        return 4

    def _get_obs(self, xp, data):
        return xp.concatenate([data.qpos, data.qvel], axis=-1)

    def sample_reset(self, rng):
        return self._candidate(self.joint_draws(rng))[None]

    def _reward(self, xp, data, ctrl):
        dist = _norm(xp, data.geom_xpos[..., self._target, :] - data.geom_xpos[..., self._mass, :])
        near = tolerance(xp, dist, (0.0, self._size), margin=self._size, scalar=True)
        control = tolerance(xp, ctrl, margin=1, value_at_margin=0, sigmoid="quadratic")
        return near * ((xp.mean(control, axis=-1) + 4) / 5)


class Acrobot(DmcTask):
    """dm_control's ``acrobot-swingup`` / ``swingup_sparse``: obs = [arms' xz, arms' zz, qvel] (6); reward: the
    tip within the target sphere (radius 0.2 at height 4) scores 1, the smooth task a Gaussian tolerance of the
    distance (margin 1) outside. Reset: both joints U(-pi, pi), at rest."""

    domain = "acrobot"
    derived_fields = ("xmat", "site_xpos")

    def __init__(self, sparse: bool = False, early_exit_linesearch: bool = True):
        self.sparse = bool(sparse)
        super().__init__(early_exit_linesearch)
        self._target, self._tip = self._id("site", "target"), self._id("site", "tip")
        self._arms = [self._id("body", "upper_arm"), self._id("body", "lower_arm")]
        self._radius = float(self.mj_model.site_size[self._target, 0])

    def _obs_size(self):
        return 6

    def _get_obs(self, xp, data):
        xmat = _xmat(data)[..., self._arms, :]
        return xp.concatenate([xmat[..., 2], xmat[..., 8], data.qvel], axis=-1)

    def sample_reset(self, rng):
        return self._candidate(self._uniform_in(rng, (2,), -np.pi, np.pi))[None]

    def _reward(self, xp, data, ctrl):
        dist = _norm(xp, data.site_xpos[..., self._target, :] - data.site_xpos[..., self._tip, :])
        return tolerance(xp, dist, (0.0, self._radius), margin=0 if self.sparse else 1, scalar=True)
