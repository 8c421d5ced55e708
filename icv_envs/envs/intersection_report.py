"""The intersection env's run report (a mixin of
:class:`icv_envs.envs.intersection.IntersectionEnv`): the run totals its
``metrics()`` returns, the served share of the demand that arrived. The
per-vehicle statistics behind them (speed, fluctuation, PET, jams, faults)
are :mod:`icv_envs.sim.intersection_metrics`; the env supplies ``world``,
``layout``, ``expert``, ``config`` and its arrival bookkeeping
(``_queues``, ``_due``, ``_not_spawned``, the warm-up counts)."""

from __future__ import annotations

import numpy as np

__all__ = ["IntersectionReport"]


class IntersectionReport:
    """``metrics()`` of :class:`~icv_envs.envs.intersection.IntersectionEnv` (module docstring)."""

    def _served(self, cleared: int, sim: float) -> dict:
        lay = self.layout
        lag = (lay.R3 + lay.box_half) / float(self.expert.p.v0)  # free flow from R3 to clearing the box
        due = int(np.count_nonzero((self._due >= -lag) & (self._due < sim - lag)))
        return {"realised_demand": due * 3600.0 / sim, "served_share": cleared / due if due else None}

    def metrics(self, **kwargs) -> dict:
        """Run totals; the speed, fluctuation, PET and jam figures are defined
        in :mod:`icv_envs.sim.intersection_metrics`. ``achieved_throughput``
        = vehicles/h that cleared the box over the statistics window;
        ``mean_delay`` = mean over the vehicles that cleared the box of their
        travel time from R3 minus that distance at the free speed (``v_free``); ``lost`` = spawned
        - removed - left_road - remaining - crashed_removed: a bookkeeping
        check that must be 0."""
        w = self.world
        st = w.stats
        remaining = int(w.fleet.n)
        queued = int(sum(len(q) for q in self._queues.values()))
        sim = max(w.time, 1e-9)
        ex = self.expert.stats
        m = {
            "method": self.config["method"],
            "lane_use": self.layout.lane_use_name,
            "throughput": float(self.config["throughput"]),
            "collisions": int(st["collisions"]),
            # during the warm-up (not in the statistics above, never hidden)
            "warmup_collisions": int(self.warmup_collisions),
            "warmup_jammed": int(self.warmup_jammed),
            "spawned": int(st["spawned"]),
            "cleared": int(st["cleared"]),
            "exited": int(st["removed"]),
            "remaining": remaining,
            "queued": queued,
            "not_spawned": int(self._not_spawned),
            "crashed_removed": int(st["crashed_removed"]),
            "left_road": int(st["left_road"]),
            "wrong_exits": int(st["wrong_exits"]),
            "rerouted": int(st["rerouted"]),
            "lost": int(st["spawned"] - st["removed"] - st["left_road"] - remaining - st["crashed_removed"]),
            "achieved_throughput": st["cleared"] * 3600.0 / sim,
            # the demand that actually arrived (the arrival process draws around the
            # nominal ``throughput``) and the share of it served: arrivals due at R3
            # in the window shifted back by the free-flow time from R3 to clearing
            # the box at v0 (what a method serving at free flow clears during the
            # statistics), against the vehicles that did clear
            **self._served(st["cleared"], sim),
            **w.motion.summary(),
            **w.pet.summary(),
            **w.jams.summary(),
            **w.faults.summary(),
            "mean_delay": st["delay_sum"] / st["cleared"] if st["cleared"] else None,
            "mean_travel_time": st["travel_time_sum"] / st["cleared"] if st["cleared"] else None,
            "sim_seconds": float(w.time),
            "vehicle_steps": int(st["vehicle_steps"]),
            "envelope_box_binding": int(ex.get("envelope_box_binding", 0)),
            "envelope_box_binding_member": int(ex.get("envelope_box_binding_member", 0)),
            "virtual_cap_binding": int(ex.get("virtual_cap_binding", 0)),
            "nodes": int(ex.get("nodes", 0)),
            "merges": int(ex.get("merges", 0)),
            "lane_changes": int(ex.get("lane_changes", 0)),
        }
        if self.config["method"] in ("fcfs", "fcfs-tight"):
            m.update({k: ex[k] for k in ("requests", "granted", "rejected", "cancelled", "max_plan_error")})
        return m
