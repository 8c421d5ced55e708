"""The intersection env's observation features, rewards and their one-pass
step (a mixin of :class:`icv_envs.envs.intersection.IntersectionEnv`): the
feature rows (``OBS_FEATURES``), their scales, the Euclidean neighbour
search of the ``Kinematics`` observation, the reward terms and the leader
in a vehicle's corridors, and ``_post_rows``, which builds all of them in
one compiled call (:func:`icv_envs.sim._kernels.intersection_post_rows`,
from stop 42) while those hooks are the class's own. The env supplies
``world``, ``layout``, ``expert``, ``config``, ``_obs_type`` and
``_last_actions``."""

from __future__ import annotations

import numpy as np

from icv_envs._hooks import own_hooks
from icv_envs.envs.base import IcvAgentsEnv
from icv_envs.envs.observations import Kinematics
from icv_envs.policies.platoon_common import Corridors
from icv_envs.sim._kernels import (corridor_leaders, intersection_feature_rows, intersection_post_rows,
                                   intersection_reward_rows, nearest_euclidean)

__all__ = ["IntersectionRows", "POST_HOOK_NAMES"]


class IntersectionRows:
    """Features, rewards and observations of :class:`~icv_envs.envs.intersection.IntersectionEnv` (module docstring)."""

    _post_hooks: tuple = ()  # the env class's hook_table of POST_HOOK_NAMES (none: the separate calls)

    def _features(self) -> np.ndarray:
        """Per-vehicle absolute features (n, F) before normalisation."""
        # (compiled: sim/_kernels/observation.intersection_feature_rows, the
        # heading's cosine and sine from numpy; the array code it replaced is
        # frozen in tests/test_expert_kernels.py)
        F = intersection_feature_rows(*self._feature_args())
        if getattr(self._obs_type, "extra", ()):  # OBS_EXTRA_FEATURES, in that order
            pd = self._perception_distance()
            gap, dv = self._leaders()
            has = np.isfinite(gap)
            F = np.column_stack([F, np.where(has, np.minimum(gap, pd), pd), np.where(has, dv, 0.0)])
        return F

    def _feature_args(self) -> tuple:
        """The arguments of :func:`~icv_envs.sim._kernels.intersection_feature_rows`
        for the current state (the heading's ``cos``/``sin`` from NumPy; the
        expert's references ``has``, ``d`` at 6 and 7), for :meth:`_features`
        and :meth:`_post_rows`."""
        w = self.world
        f = w.fleet
        lay = self.layout
        rs = w.route()
        has, d, dv, go = self.expert.references(w)
        return (rs.cx, rs.cy, f.speed, np.cos(f.heading), np.sin(f.heading), rs.dist, np.asarray(has, dtype=bool),
                np.asarray(d, dtype=np.float64), np.asarray(dv, dtype=np.float64), rs.phase, rs.lat_leg, f.klane,
                float(lay.lane_width), rs.lat, f.mv, float(lay.R1), float(lay.R2), np.asarray(go, dtype=np.float64))

    def _reward_args(self, rows: np.ndarray, crashed_now: np.ndarray) -> tuple:
        """``(rows, lo, span, gap, crashed, ua)`` and the four weights of the
        reward terms (``reward_speed_range`` or ``[0, v_max]`` as ``lo`` and
        ``span``; the leaders' gaps; the last actions of ``rows``), for
        :meth:`_rewards_rows` and :meth:`_post_rows`."""
        c = self.config
        wts = c["reward"]
        lo, hi = c["reward_speed_range"] or (0.0, c["speed_range"][1])
        rows = np.asarray(rows, dtype=np.int64)
        ua = self._last_actions[rows] if len(self._last_actions) == self.world.fleet.n else np.zeros((len(rows), 2))
        return ((rows, float(lo), float(hi) - float(lo), self._leaders()[0], np.asarray(crashed_now, dtype=bool),
                 np.ascontiguousarray(ua, dtype=np.float64)),
                (float(wts["progress"]), float(wts["safety"]), float(wts["comfort"]), float(wts["tracking"])))

    PERCEPTION_DISTANCE = 100.0

    def _scales(self, relative: bool) -> np.ndarray:
        c = self.config
        lay = self.layout
        vmax = float(c["speed_range"][1])
        pd = self._perception_distance()
        pos = pd if relative else lay.R3
        scales = [1.0, pos, pos, vmax, vmax, 1.0, 1.0, lay.R3, 100.0, vmax, lay.lane_width * 3, 1.0, 1.0, 1.0]
        if getattr(self._obs_type, "extra", ()):
            scales += [pd, vmax]  # lead_gap, lead_dv
        return np.array(scales)

    def _perception_distance(self) -> float:
        return float(self._obs_type.pd) if hasattr(self._obs_type, "pd") else self.PERCEPTION_DISTANCE

    def _obs_scales(self) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_scales` absolute and relative, read-only (one numba
        specialisation of ``kinematics_rows``), kept while the layout (a new
        one with every config change), the observation type and the top
        speed are the same (from stop 42; every step asked for new ones)."""
        key = (self.layout, self._obs_type, float(self.config["speed_range"][1]))
        kept = getattr(self, "_obs_scales_kept", None)
        if kept is not None and kept[0][0] is key[0] and kept[0][1] is key[1] and kept[0][2] == key[2]:
            return kept[1]
        out = self._scales(False), self._scales(True)
        for arr in out:
            arr.flags.writeable = False
        self._obs_scales_kept = (key, out)
        return out

    def _neighbours(self, rows: np.ndarray, F: np.ndarray, K: int, pd: float):
        """The up-to-``K`` nearest vehicles (Euclidean distance of body centres) within ``pd``, nearest first,
        ties by row (compiled: :func:`icv_envs.sim._kernels.nearest_euclidean`). Until stop 40 the order of
        exactly tied distances (formations spawn symmetric about a vehicle) was ``np.argpartition``'s, which
        depends on the CPU's SIMD path."""
        K = min(K, len(F) - 1)
        return nearest_euclidean(np.ascontiguousarray(F[:, 1]), np.ascontiguousarray(F[:, 2]),
                                 np.asarray(rows, dtype=np.int64), K, float(pd))

    def _rewards_rows(self, rows: np.ndarray, crashed_now: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, dict]:
        """Per agent: progress (speed / v_max, or with ``reward_speed_range``
        = [lo, hi] highway-env's ``clip((v - lo) / (hi - lo), 0, 1)``), safety (-1 on a collision, else
        ``-max(0, 1 - gap / (2 m + v * 1 s))`` towards the leader in its
        corridors), comfort (``-(u_a^2 + u_s^2) / 2``), tracking
        (``exp(-(dx / 10 m)^2)`` of the reference error for vehicles with a
        reference, else 0)."""
        (rows, lo, span, gap, crashed, ua), weights = self._reward_args(rows, crashed_now)
        # (compiled: sim/_kernels/observation.intersection_reward_rows, the
        # tracking term's exp libm's from stop 49, numpy's before; frozen in
        # tests/test_expert_kernels.py)
        total, progress, safety, comfort, track = intersection_reward_rows(
            rows, self.world.fleet.speed, lo, span, gap, crashed, ua, F, *weights)
        return total, {"progress": progress, "safety": safety, "comfort": comfort, "tracking": track}

    def _leaders(self) -> tuple[np.ndarray, np.ndarray]:
        """Per vehicle: bumper gap to the nearest leader over its corridors
        (inf without one) and its speed minus that leader's (0 without one)."""
        key = self._expert_key()  # the world, its clock and its vehicles: one state
        cached = getattr(self, "_leaders_cache", None)
        if cached is not None and cached[0] == key:
            return cached[1]
        w = self.world
        f = w.fleet
        if f.n < 2:
            out = (np.full(f.n, np.inf), np.zeros(f.n))
        else:
            # (compiled: sim/_kernels.corridor_leaders; the leader of the smallest gap, ties: the first
            # corridor listed)
            cor = Corridors.plain(w, w.route())
            out = corridor_leaders(cor.lead, cor.rows, cor.coord, f.length, f.speed, f.n)
        self._leaders_cache = (key, out)
        return out

    def _post_rows(self, rows: np.ndarray, crashed_now: np.ndarray) -> tuple:
        """:meth:`IcvAgentsEnv._post_rows` in one compiled call
        (:func:`icv_envs.sim._kernels.intersection_post_rows`: the kernels of
        :meth:`_features`, :meth:`_rewards_rows` and the ``Kinematics``
        observation with the arrays those methods give them; the cosine and
        sine of the heading from NumPy, the tracking term's ``exp`` libm's, as
        there), the same numbers bit for bit
        (``tests/test_intersection_api.py``). Taken when the observation is
        ``Kinematics`` without the leader columns (``OBS_EXTRA_FEATURES``)
        and none of the hooks it stands for (``POST_HOOK_NAMES``) is replaced,
        on a subclass, on the class or on the instance; otherwise the
        separate calls."""
        obs_type = self._obs_type
        if (not len(rows) or type(obs_type) is not Kinematics or getattr(obs_type, "extra", ())
                or not self._post_hooks or not own_hooks(self, self._post_hooks)):
            return IcvAgentsEnv._post_rows(self, rows, crashed_now)
        fa = self._feature_args()
        ra, weights = self._reward_args(rows, crashed_now)
        V = obs_type.V
        T, obs = intersection_post_rows(
            *fa, *ra, *weights,
            min(V - 1, self.world.fleet.n - 1), float(obs_type.pd), *obs_type.kernel_options(),
            float(self._wrap_period()))
        total, progress, safety, comfort, track = T  # (row views)
        return total, {"progress": progress, "safety": safety, "comfort": comfort, "tracking": track}, obs


#: the hooks the one-pass ``_post_rows`` stands for, by name; their table
#: (:func:`icv_envs._hooks.hook_table`) is made on the env class
#: (``IntersectionEnv._post_hooks``), whose functions they must be
POST_HOOK_NAMES = ("_features", "_rewards_rows", "_observe_rows", "_neighbours", "_wrap_dx", "_wrap_period",
                   "_obs_scales", "_leaders")
