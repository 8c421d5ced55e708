"""The HighwayFormation env's observation features, rewards and their
one-pass step (a mixin of
:class:`icv_envs.envs.highway_formation.HighwayFormationEnv`, as
:mod:`icv_envs.envs.intersection_rows` is the intersection's; split out at
stop 44): the feature rows (``OBS_FEATURES``), their scales, the
along-the-road neighbour search of the ``Kinematics`` observation, the
reward terms and ``_post_rows``, which builds all of them in one compiled
call (:func:`icv_envs.sim._kernels.formation_post_rows`) while those hooks
are the class's own. The env supplies ``world``, ``config``, ``_obs_type``,
``_last_actions`` and ``PERCEPTION_DISTANCE``."""

from __future__ import annotations

import numpy as np

from icv_envs._hooks import own_hooks
from icv_envs._ufuncs import clip as uclip
from icv_envs.envs.observations import KINEMATIC_FEATURES, Kinematics
from icv_envs.sim._kernels import (formation_feature_rows, formation_post_rows, formation_reward_terms,
                                   formation_reward_total, nearest_along_road)

__all__ = ["HighwayRows", "OBS_FEATURES", "STATE_FEATURES", "POST_HOOK_NAMES"]

OBS_FEATURES = KINEMATIC_FEATURES + (
    "target_dx",
    "target_dy",
    "target_dv",
    "member",
    "exit_dx",
    "lane_end_dx",
)
STATE_FEATURES = OBS_FEATURES


class HighwayRows:
    """Features, rewards and observations of :class:`~icv_envs.envs.highway_formation.HighwayFormationEnv` (module docstring)."""

    _post_hooks: tuple = ()  # the env class's hook_table of POST_HOOK_NAMES (none: the separate calls)

    def _features(self) -> np.ndarray:
        """Per-vehicle feature rows in absolute terms (n, F), before
        normalisation: x, y, vx, vy, cos, sin, target dx, dy, dv, member."""
        tr = self.world.traffic
        road = self.world.road
        # compiled, the same arithmetic as the array code it replaced
        # (icv_envs.sim._kernels.formation_feature_rows; tests/test_kernels.py)
        args = self._feature_args()
        F = formation_feature_rows(*args)
        # exit_dx: metres to the own exit's diverge segment / 1000 (1 = no exit);
        # lane_end_dx (column 12): metres to the end of the current lane / 200 (1 = none near)
        if road.n_exits:
            cx = args[0]
            has = tr.exit >= 0
            if has.any():
                F[has, 11] = road.exit_ahead(tr.exit[has], cx[has]) / 1000.0
        return F

    def _feature_args(self) -> tuple:
        """The arguments of :func:`~icv_envs.sim._kernels.formation_feature_rows`
        for the current state (the headings' ``cos``/``sin`` from NumPy), for
        :meth:`_features` and :meth:`_post_rows`."""
        w = self.world
        tr = w.traffic
        road = w.road
        cx, cy = tr.center()
        x_ref, lane_ref, v_ref, member = w.manager.references(tr)
        period = float(road.length) if road.periodic else -1.0
        return (cx, cy, tr.speed, *tr.heading_cos_sin(), x_ref, lane_ref, v_ref, member,
                float(road.lane_width), int(road.total_lanes), period, road.n_lanes, road.lane_ends, road._ob_lane,
                road._ob_lo, road._ob_hi, road._ramp_iv)

    def _obs_scales(self) -> tuple[np.ndarray, np.ndarray]:
        """Feature scales (the module docstring's table): absolute (row 0) and relative (other rows)."""
        c = self.config
        w = self.world
        vmax = float(c["speed_range"][1])
        pd = float(self._obs_type.pd) if hasattr(self._obs_type, "pd") else self.PERCEPTION_DISTANCE
        # kept per road and scales (a reset builds a new road), read-only
        kept = getattr(self, "_obs_scales_kept", None)
        if kept is not None and kept[0] is w.road and kept[1] == (vmax, pd):
            return kept[2]
        width = w.road.total_lanes * w.road.lane_width
        scale_abs = np.array([1, w.road.length, width, vmax, vmax, 1, 1, 100.0, width, vmax, 1, 1, 1])
        scale_rel = np.array([1, pd, width, vmax, vmax, 1, 1, 100.0, width, vmax, 1, 1, 1])
        scale_abs.flags.writeable = scale_rel.flags.writeable = False
        self._obs_scales_kept = (w.road, (vmax, pd), (scale_abs, scale_rel))
        return scale_abs, scale_rel

    def _wrap_dx(self, dx):
        return self.world.road.wrap(dx)

    def _wrap_period(self) -> float | None:
        if type(self)._wrap_dx is not HighwayRows._wrap_dx:
            return None  # a subclass folds differently: the array path
        road = self.world.road
        return float(road.length) if road.periodic else -1.0

    def _neighbours(self, rows: np.ndarray, F: np.ndarray, K: int, pd: float):
        """The ``K`` nearest vehicles by longitudinal distance within ``pd``
        (round the ring each vehicle at most once), nearest first; ties: rear first."""
        # compiled (icv_envs.sim._kernels.nearest_along_road)
        return nearest_along_road(np.ascontiguousarray(F[:, 1]), np.asarray(rows, dtype=np.int64),
                                  *self._neighbour_args(K, pd))

    def _neighbour_args(self, K: int, pd: float) -> tuple:
        """:func:`~icv_envs.sim._kernels.nearest_along_road`'s arguments after
        the x column and the rows (for :meth:`_neighbours` and :meth:`_post_rows`)."""
        road = self.world.road
        return int(K), float(pd), bool(road.periodic), float(road.length)

    def _rewards_rows(self, rows: np.ndarray, crashed_now: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, dict]:
        """Per-agent reward: weighted sum of progress (speed / v_max), safety
        (-1 on a collision, else minus the headway shortfall
        ``max(0, 1 - gap / (s0 + v T))`` with ``s0 = 2 m``, ``T = 1 s``),
        comfort (minus the mean of the squared normalised acceleration and
        steering) and formation keeping (members:
        ``exp(-(dx / L_s)^2 - (dy / lane_width)^2)`` of the target error; free
        vehicles: 0)."""
        # compiled but the exp (icv_envs.sim._kernels.formation_reward_terms; the
        # array code it replaced is its reference in tests/test_kernels.py)
        args = self._reward_args(rows, crashed_now)
        return self._reward_total(formation_reward_terms(*args[:6], F, *args[6:]))

    def _reward_args(self, rows: np.ndarray, crashed_now: np.ndarray) -> tuple:
        """:func:`~icv_envs.sim._kernels.formation_reward_terms`' arguments but
        the feature rows (which come after the sixth), for
        :meth:`_rewards_rows` and :meth:`_post_rows`."""
        c = self.config
        w = self.world
        tr = w.traffic
        wts = c["reward"]
        gap, _ = w._own_lane_gaps_kept()  # (the kernels only read it)
        la = self._last_actions
        if len(la) != tr.n:
            ua = np.zeros((len(rows), 2))
        elif rows is self._all_rows_kept:  # every row in order: the actions as they are (the kernels only read them)
            ua = la
        else:
            ua = la[rows]
        return (np.asarray(rows, dtype=np.int64), tr.speed, float(c["speed_range"][1]), gap,
                np.asarray(crashed_now, dtype=bool), np.ascontiguousarray(ua, dtype=np.float64),
                float(c["formation"]["spacing"]), float(w.road.lane_width), float(wts["progress"]),
                float(wts["safety"]), float(wts["comfort"]))

    def _reward_total(self, terms: tuple) -> tuple[np.ndarray, dict]:
        """The reward and its components from the kernel's terms
        ``(progress, safety, comfort, exponent, member, partial)``: the
        formation term ``exp`` for members, 0 for the others, and the total
        ``partial + w * form`` (compiled from stop 49,
        :func:`~icv_envs.sim._kernels.formation_reward_total`: libm's ``exp``,
        NumPy's at the pinned level; NumPy's ``where``, ``exp`` and two
        array operations before)."""
        progress, safety, comfort, expo, member, partial = terms
        out = formation_reward_total(member, expo, partial, float(self.config["reward"]["formation"]))
        return out[0], {"progress": progress, "safety": safety, "comfort": comfort, "formation": out[1]}

    def _post_rows(self, rows: np.ndarray, crashed_now: np.ndarray) -> tuple:
        """:meth:`IcvAgentsEnv._post_rows` in one compiled call
        (:func:`icv_envs.sim._kernels.formation_post_rows`: the kernels of
        :meth:`_features`, :meth:`_rewards_rows` (with :meth:`_reward_total`'s
        kernel, inside from stop 50) and the ``Kinematics`` observation with
        the arrays those methods give them), the same numbers bit for bit
        (``tests/test_kernels.py``). Taken when the observation is
        ``Kinematics``, the road has no exits (their column is written
        between the features and the observation) and none of the hooks
        it stands for (``POST_HOOK_NAMES``) is replaced, on a subclass, on the
        class or on the instance; otherwise the separate calls."""
        road = self.world.road
        obs_type = self._obs_type
        if (not len(rows) or road.n_exits or type(obs_type) is not Kinematics or not self._post_hooks
                or not own_hooks(self, self._post_hooks)):
            return super()._post_rows(rows, crashed_now)
        options = obs_type.kernel_options()  # (idx, V, s_abs, s_rel, absolute, normalize, clip)
        T, obs = formation_post_rows(*self._feature_args(), *self._reward_args(rows, crashed_now),
                                     *self._neighbour_args(options[1] - 1, obs_type.pd), *options,
                                     float(self._wrap_period()), float(self.config["reward"]["formation"]))
        total, progress, safety, comfort, form = T  # (row views)
        return total, {"progress": progress, "safety": safety, "comfort": comfort, "formation": form}, obs

    def global_state(self, slots: list[str]) -> np.ndarray:
        """Fixed-size global state: one row per possible agent (slot order),
        absolute normalised features, zeros for absent vehicles."""
        c = self.config
        w = self.world
        out = np.zeros((len(slots), len(STATE_FEATURES)), dtype=np.float32)
        tr = w.traffic
        if tr.n:
            F = self._features()
            vmax = float(c["speed_range"][1])
            width = w.road.total_lanes * w.road.lane_width
            scale = np.array([1, w.road.length, width, vmax, vmax, 1, 1, 100.0, width, vmax, 1, 1, 1])
            slot_of = {name: i for i, name in enumerate(slots)}
            idx = np.array([slot_of.get(f"icv_{v}", -1) for v in tr.vid])
            ok = idx >= 0
            out[idx[ok]] = uclip(F[ok] / scale, -1, 1)
        return out


#: the hooks :meth:`HighwayRows._post_rows` stands for; the env class keeps
#: their table (``HighwayFormationEnv._post_hooks``), whose functions they must be
POST_HOOK_NAMES = ("_features", "_rewards_rows", "_observe_rows", "_neighbours", "_wrap_dx", "_wrap_period",
                   "_obs_scales", "_reward_total")
