"""Read-only views of the formation layer's state (a mixin of
:class:`icv_envs.sim.formations.FormationManager`, split out at stop 48
when that file passed 500 lines): snapshots by live formation id of the
front targets, lengths, member counts, stall clocks and lane sets, the
count of formations and of join plans, each vehicle's slot and a summary,
for tests, plots, reports and rendering. Nothing here changes the state.
The manager supplies ``_gids``, ``_A``, ``_L``, ``_cnt``, ``_stall``,
``_lanes``, ``_plans``, ``_slot_x``."""

from __future__ import annotations

import numpy as np

from icv_envs._ufuncs import flatnonzero

__all__ = ["FormationViews"]


class FormationViews:
    """Snapshots of :class:`~icv_envs.sim.formations.FormationManager`'s state (module docstring)."""

    def _view(self, arr: np.ndarray) -> dict:
        """``arr`` by live formation id, as a dict (a snapshot)."""
        return dict(zip(self._gids().tolist(), arr[self._gids()].tolist()))

    @property
    def anchor(self) -> dict[int, float]:
        """Front target by live formation id (a snapshot)."""
        return self._view(self._A)

    @property
    def length(self) -> dict[int, float]:
        """Length (front target to rearmost target) by live formation id (a snapshot)."""
        return self._view(self._L)

    @property
    def count(self) -> dict[int, int]:
        """Member count by live formation id, as of the last re-forming (a snapshot)."""
        return self._view(self._cnt)

    @property
    def stalled_for(self) -> dict[int, float]:
        """Seconds each live formation has been stalled (a snapshot)."""
        return self._view(self._stall)

    @property
    def lanes(self) -> dict[int, tuple[int, ...]]:
        """Lane set by live formation id (a snapshot)."""
        return {g: self._lanes[g] for g in self._gids().tolist() if g in self._lanes}

    @property
    def n_formations(self) -> int:
        """How many formations there are."""
        return len(self._gids())

    @property
    def plans(self) -> int:
        """How many join plans were made so far."""
        return self._plans.count

    def slots(self, traffic) -> np.ndarray:
        """Per-vehicle target position ``X_slot = anchor - x_g`` (``nan`` for
        free vehicles), the end point of every member's reference."""
        out = np.full(traffic.n, np.nan)
        m = flatnonzero(traffic.group >= 0)
        if len(m):
            out[m] = self._slot_x(traffic, m)
            if traffic.period is not None:
                out[m] = np.mod(out[m], traffic.period)
        return out

    def summary(self) -> list[dict]:
        """One dict per live formation: its id, front target, lane set and member count."""
        return [
            {"id": g, "anchor": float(self._A[g]), "lanes": list(self._lanes.get(g, ())), "members": int(self._cnt[g])}
            for g in self._gids().tolist()
        ]
