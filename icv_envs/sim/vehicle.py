"""The paper's vehicle as a highway-env vehicle.

:class:`ICVVehicle` is a :class:`highway_env.vehicle.kinematics.Vehicle` whose
:meth:`step` integrates the paper's rear-axle kinematic bicycle model (Sec.
2.2, eq. (state); L = 2.8 m, steering within +-30 deg, acceleration within
[-6, 3] m/s^2; lateral acceleration within ``0.5 mu g``, see
:data:`icv_envs.sim.traffic.LAT_ACCEL_MAX`) with the same function the vectorised core uses
(:func:`icv_envs.sim.traffic.bicycle_step`), so it can be dropped into any
highway-env road. Inside :mod:`icv_envs` environments the state lives in
arrays and these objects are views refreshed only for rendering.
"""

from __future__ import annotations

import numpy as np
from highway_env.vehicle.kinematics import Vehicle

from icv_envs.sim.traffic import LAT_ACCEL_MAX, bicycle_step

__all__ = ["ICVVehicle"]


class ICVVehicle(Vehicle):
    """highway-env vehicle with the paper's kinematics.

    ``position`` is the body centre (highway-env's convention); the model is
    integrated about the rear axle, ``WHEELBASE / 2`` behind the centre.
    ``action`` is highway-env's ``{"acceleration": a, "steering": phi}`` in SI
    units, clipped to the paper's limits.
    """

    LENGTH = 5.0
    WIDTH = 2.0
    WHEELBASE = 2.8
    MAX_STEERING = np.deg2rad(30.0)
    ACCEL_RANGE = (-6.0, 3.0)
    MAX_SPEED = 30.0
    MIN_SPEED = 0.0
    LAT_ACCEL_MAX = LAT_ACCEL_MAX

    def __init__(self, road, position, heading: float = 0.0, speed: float = 0.0, vid: int = -1, **kwargs):
        super().__init__(road, position, heading, speed, **kwargs)
        self.vid = vid
        self.color = None

    def step(self, dt: float) -> None:
        a = float(np.clip(self.action.get("acceleration", 0.0), *self.ACCEL_RANGE))
        phi = float(np.clip(self.action.get("steering", 0.0), -self.MAX_STEERING, self.MAX_STEERING))
        if self.crashed:
            a, phi = self.ACCEL_RANGE[0], 0.0
        h = 0.5 * self.WHEELBASE
        rx = self.position[0] - h * np.cos(self.heading)
        ry = self.position[1] - h * np.sin(self.heading)
        rx, ry, heading, speed = bicycle_step(rx, ry, self.heading, self.speed, a, phi, dt, self.WHEELBASE, self.MAX_SPEED,
                                              lat_accel_max=self.LAT_ACCEL_MAX)
        self.heading = float(heading)
        self.speed = float(speed)
        self.position = np.array([rx + h * np.cos(self.heading), ry + h * np.sin(self.heading)])
        self.on_state_update()

    @classmethod
    def proxy(cls, road, vid: int, length: float, width: float) -> "ICVVehicle":
        """A view of vehicle ``vid`` for highway-env's renderer, made without
        ``__init__`` (its state is the env's arrays; the env sets
        ``position``, ``heading``, ``speed``, ``crashed``, ``action`` and
        ``color`` before each frame): road, id, an empty history, the body's
        length and width, no lane."""
        p = object.__new__(cls)
        p.road = road
        p.vid = vid
        p.history = []
        p.LENGTH = float(length)
        p.WIDTH = float(width)
        p.lane_index = None
        p.lane = None
        p.impact = None
        return p
