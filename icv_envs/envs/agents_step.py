"""The multi-agent step every environment of this package shares (issue
10, item 5: one home for it), a mixin of
:class:`icv_envs.envs.base.IcvAgentsEnv`: ``ma_step`` (the PettingZoo
dicts in: action checks and conversion), ``ma_step_rows`` and
``_ma_step_controls`` (arrays in, :class:`StepRows` out), ``ma_reset`` and
``_ma_advance``, the step itself (physics, the world's reaction,
observations, rewards, infos, departures, removals, spawns and the expert's
labels, in that order) with the hooks the envs supply. Moved out of
``envs/base.py`` at stop 43 (it had grown to two rooms: the env's
configuration, spaces, expert and rendering, and this step); the
array -> dict edge it uses is :class:`icv_envs.envs.dict_edge.DictEdge`."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from icv_envs._hooks import hook_table, own_hooks
from icv_envs._ufuncs import count_nonzero
from icv_envs.envs._kernels import expert_match_rows
from icv_envs.envs.actions import ContinuousAction
from icv_envs.envs.dict_edge import same_ids
from icv_envs.envs.ego import EgoEnv
from icv_envs.sim._kernels import controls_rows

__all__ = ["AgentsStep", "StepRows"]

#: the single-agent reset ``ma_reset`` stands for (:class:`~icv_envs.envs.ego.EgoEnv`'s)
_RESET_HOOK = hook_table(EgoEnv, "reset")


class StepRows(NamedTuple):
    """One multi-agent step as rows (:meth:`AgentsStep.ma_step_rows`):
    every agent the PettingZoo dicts would name, in their key order."""

    vid: np.ndarray  # (m,) int64 vehicle ids (agent ``icv_<vid>``)
    obs: np.ndarray  # (m, ...) float32 observations
    rewards: np.ndarray | None  # (m,) float64 (None on the dict path)
    terminated: np.ndarray  # (m,) bool
    truncated: np.ndarray  # (m,) bool


class AgentsStep:
    """The shared multi-agent step of :class:`~icv_envs.envs.base.IcvAgentsEnv` (module docstring)."""

    # ------------------------------------------------------------- multi-agent
    def ma_step(self, actions: dict):
        """Multi-agent step: ``actions`` maps live agent names to actions of
        the configured action type. A malformed action raises ``ValueError``
        naming the agent; agents left out raise too unless
        ``missing_action="expert"`` (the expert then drives them)."""
        if self.world is None:
            raise RuntimeError("call reset() before step()")
        veh = self._vehicles()
        live = self._names_of(veh.vid)
        if not isinstance(actions, dict):
            raise ValueError(f"actions must be a dict {{agent: action}}, got {type(actions).__name__}")
        missing = []
        values = None
        if type(actions) is dict and len(actions) == len(live):
            # the usual case: an action for every live agent and no other key (as many keys as agents)
            # (a plain dict: a subclass's __missing__ could make up the value of an absent agent)
            try:
                values = [actions[a] for a in live]
            except KeyError:
                values = None
        if values is None and (len(actions) != len(live) or actions.keys() != set(live)):
            live_set = set(live)
            unknown = [a for a in actions if a not in live_set]
            if unknown:
                raise ValueError(f"actions for agents that are not live: {unknown[:5]}; live agents: {live[:5]}...")
            missing = [a for a in live if a not in actions]
        if missing and self.config["missing_action"] == "error":
            raise ValueError(
                f"no action for live agents {missing[:5]} ({len(missing)} missing); pass an action for every agent "
                f"or configure missing_action='expert'"
            )
        # 1. the expert drives agents left out; 2. the action type converts the
        # given actions into normalised controls; 3. the simulation advances
        acts = np.zeros((veh.n, 2), dtype=np.float64)
        if missing:
            acts[:] = self.expert_actions()
            given = np.array([i for i, a in enumerate(live) if a in actions], dtype=np.int64)
            names = [live[i] for i in given]
        else:
            given, names = np.arange(veh.n), live
        if names:
            at = self._act_type
            if values is None:
                values = [actions[a] for a in names]
            if isinstance(at, ContinuousAction):
                vals = self._check_actions(names, values)
            else:
                vals = at.check_many(values, names)
            acts[given] = at.controls(given, vals)
        return self._ma_advance(acts)

    # ------------------------------------------- the shared multi-agent step
    # One policy step of every env, in this order: physics (``_advance``),
    # the world's reaction (``_react``: the formation layer, or the
    # intersection's arrivals and coordination layer), observations, rewards
    # and infos of every agent on the road, the agents that left during the
    # step (``_departed``), crashed vehicles removed (``_after_removal``),
    # late spawns (``_spawn_late``: the highway's new vehicles appear after
    # the others have observed), the expert labels from the final state. The
    # envs supply only these hooks and the builders (``_features``,
    # ``_rewards_rows``, ``_observe_rows``, ``_ma_infos``).
    def _frames(self) -> int:
        """Physics steps per policy step."""
        c = self.config
        return int(c["simulation_frequency"] // c["policy_frequency"])

    def _advance(self, actions: np.ndarray):
        """Apply normalised actions (rows in vehicle order) for one policy
        period; rows that leave the simulation between frames drop their
        actions (re-aligned by vehicle id). Returns the world's step events."""
        w = self.world
        events = self._new_events()
        frames = self._frames()
        acts = np.asarray(actions, dtype=np.float64).reshape(-1, 2)
        vids = self._vehicles().vid  # (replaced when vehicles leave, never written in place: no copy, stop 51)
        a, phi = self._controls(acts)
        # without a viewer (nothing to draw between frames), a world that can
        # runs its quiet frames in one call (World.substeps; the same states)
        fused = getattr(self, "viewer", None) is None and callable(getattr(w, "substeps", None))
        frame = 0
        while frame < frames:
            if frame:  # (before the first frame ``vids`` are the vehicles)
                veh = self._vehicles()
                if not same_ids(veh.vid, vids):
                    keep = np.isin(vids, veh.vid)
                    vids, a, phi = vids[keep], a[keep], phi[keep]
            if fused:
                frame += w.substeps(a, phi, frames - frame, events)
            else:
                w.substep(a, phi, events)
                frame += 1
            if frame < frames:
                self._automatic_rendering()
        self._after_frames()
        return events

    def _new_events(self):
        raise NotImplementedError

    _all_rows_kept: np.ndarray | None = None

    def _all_rows(self, n: int) -> np.ndarray:
        """``np.arange(n)``: the rows of every vehicle in order, as a step
        hands them to its builders, remembered by identity (``rows is
        self._all_rows_kept`` tells a builder it has them all, in order; from
        stop 51). A fresh array each step (writable: a read-only one would be
        a second specialisation of every kernel that takes rows)."""
        r = self._all_rows_kept = np.arange(n)
        return r

    def _controls(self, acts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Normalised actions -> (acceleration, steering angle) within the
        configured limits (:func:`~icv_envs.envs.actions.action_to_controls`)."""
        c = self.config
        # compiled (icv_envs.sim._kernels.controls_rows: action_to_controls' operations, one pass)
        return controls_rows(np.ascontiguousarray(acts, dtype=np.float64).reshape(-1, 2),
                             float(c["acceleration_range"][0]), float(c["acceleration_range"][1]),
                             math.radians(c["max_steering_deg"]))

    def _after_frames(self) -> None:
        """Hook: after the physics frames of a policy step."""

    def _before_physics(self, vids: np.ndarray, acts: np.ndarray) -> None:
        """Before the physics of a policy step (``vids``: the vehicles the
        rows of ``acts`` belong to): who drives.  An action equal to the
        expert's (float32) is expert-driven; a vehicle carries the expert's
        lane-change plan out when it is expert-driven or its action type
        says so (``FormationResidual``). With ``config["expert_driven_check"]``
        False no vehicle is expert-driven and the expert is not computed."""
        if len(vids):
            carries = bool(getattr(self.action_type, "carries_expert_plan", False))
            if self.config["expert_driven_check"]:
                ex = self.expert_actions()
                if ex.shape != acts.shape:  # (one row per vehicle on both sides; the kernel does not check)
                    raise RuntimeError(f"expert actions {ex.shape} and actions {acts.shape} do not align")
                # (compiled: envs/_kernels.expert_match_rows, np.all(np.abs(acts - ex) <= 1e-6, axis=1))
                em = expert_match_rows(acts, ex, 1e-6)
            elif not carries:  # nobody expert-driven or carrying the plan: said without masks (stop 51)
                self._policy_drivers(vids)
                return
            else:  # every vehicle policy-driven; the expert is not computed (config docs)
                em = np.zeros(len(vids), dtype=bool)
            # (the plan mask em | carries; em itself when the action type carries no plan)
            self._drivers(vids, em, np.ones(len(em), dtype=bool) if carries else em)

    def _drivers(self, vids: np.ndarray, expert_mask: np.ndarray, plan_mask: np.ndarray) -> None:
        """Hook: who drives in the coming step (see :meth:`_before_physics`)."""

    def _policy_drivers(self, vids: np.ndarray) -> None:
        """Hook: :meth:`_drivers` with no vehicle expert-driven and none
        carrying the expert's plan (a learned policy drives them all); an
        env may say so without the masks."""
        em = np.zeros(len(vids), dtype=bool)
        self._drivers(vids, em, em)

    def _react(self, events) -> list:
        """Hook: the world reacts to the physics before anyone observes;
        returns the ids of vehicles that appeared (they get reward 0)."""
        return []

    def _departed(self, events) -> dict:
        """Hook: ``{vid: info}`` of the agents that left the simulation during
        the step; ``info["exited"]`` is a terminal success,
        ``info["left_road"]`` a truncation."""
        return {}

    def _after_removal(self) -> None:
        """Hook: after crashed vehicles were removed."""

    def _spawn_late(self) -> list:
        """Hook: vehicles that appear after the others observed; their ids."""
        return []

    def _truncations(self, truncated_all: bool, crashed_now: np.ndarray):
        """Per-agent truncation flags (or one bool for all) when the time is up."""
        return truncated_all

    def _info_selection(self) -> tuple[tuple, bool]:
        """``(the info columns to build, whether infos carry the reward
        components)`` from ``config["info_keys"]`` (None: all of
        ``INFO_KEYS``), in ``INFO_KEYS`` order."""
        k = self.config["info_keys"]
        if k is None:
            return self.INFO_KEYS, True
        return tuple(x for x in self.INFO_KEYS if x in k and x != "rewards"), "rewards" in k

    def _ma_infos(self, agents, rows, parts) -> dict:
        """Info dicts of ``agents`` (vehicle ``rows``): the env's selected
        columns (``_ma_info_columns``, ``config["info_keys"]``) and, when
        selected, the reward components ``parts``."""
        if not len(rows):
            return {}
        keys, rewards = self._info_selection()
        return self._info_dicts(agents, self._ma_info_columns(rows, keys), parts if rewards else None)

    def _ma_info_columns(self, rows, keys: tuple) -> dict:
        """Hook: the per-agent info columns named in ``keys`` (lists aligned
        with the non-empty ``rows``), in ``INFO_KEYS`` order."""
        raise NotImplementedError

    def _on_step_end(self, events) -> None:
        """Hook for subclasses (recorders); called once per policy step."""

    def ma_reset(self, seed: int | None = None, options: dict | None = None):
        self._ma_mode = True
        if own_hooks(self, _RESET_HOOK):
            # (EgoEnv.reset without the ego's observation and info, which this
            # reset discarded; a reset replaced on a subclass or the instance
            # is still called)
            self._reset_world(seed, options)
            if self.render_mode == "human":
                self.render()
        else:
            self.reset(seed=seed, options=options)
        veh = self._vehicles()
        rows = np.arange(veh.n)
        agents = self._names(veh.vid.tolist())
        obs = self._observe_rows(rows, self._features() if veh.n else None)
        infos = self._ma_infos(agents, rows, {})
        self._fill_expert_labels(infos)
        observations = dict(zip(agents, obs))
        self._last_obs = (veh.vid.copy(), obs)
        return observations, infos

    def _ma_advance(self, acts: np.ndarray, arrays: bool = False, owned: bool = False):
        """One policy step of the multi-agent API from normalised action rows
        (see the comment above for the order); returns the five PettingZoo
        dicts, or with ``arrays`` a :class:`StepRows` of the same agents and
        values (the step's agents in vehicle order, then those that left,
        then late spawns) and no infos (:meth:`ma_step_rows`). ``owned``
        (with ``arrays``): the caller only reads the returned rows and keeps
        none of them (:meth:`_ma_step_controls`' batch copies them into its
        own arrays), so the step keeps its ids and observations for the
        next step's departures as they are, without copies (stop 51)."""
        c = self.config
        w = self.world
        # (the ids before the physics: the array itself, which a change of the
        # vehicles replaces and nothing writes in place, from stop 51; a copy before)
        before = self._vehicles().vid
        acts = np.asarray(acts, dtype=np.float64).reshape(-1, 2)
        self._before_physics(before, acts)
        events = self._advance(acts)
        self.time += 1.0 / c["policy_frequency"]
        self.steps += 1
        new = self._react(events)
        veh = self._vehicles()
        crashed_now = veh.crashed.copy()
        self._last_actions = self._realign_rows(before, acts, veh.vid)
        rows = self._all_rows(veh.n)
        vid_now = veh.vid
        step_vid = vid_now.copy()
        rew, parts, obs = self._post_rows(rows, crashed_now)
        truncated_all = w.time >= float(c["duration"]) - 1e-9
        trunc = self._truncations(truncated_all, crashed_now)
        # agents that left during the step report their last observation
        # (their state just before they left), reward 0
        departed = self._departed(events)
        if departed:
            departed = sorted(departed.items())
            gone_vid = np.fromiter((v for v, _ in departed), dtype=np.int64, count=len(departed))
            gone_obs = self._last_obs_of(gone_vid)
        else:  # nobody left (most steps)
            departed, gone_vid, gone_obs = [], None, ()
        if arrays:
            infos = None
            rew = np.array(rew, dtype=np.float64)
            if new:
                rew[np.isin(step_vid, np.asarray(new, dtype=np.int64))] = 0.0
        else:
            agents = self._names_of(vid_now)  # (step_vid's ids)
            observations, rewards, terms, truncs = self._agent_dicts(agents, obs, rew, crashed_now, trunc)
            # the agents' info columns now (the state they report), their
            # dicts at the end of the step with the expert's labels, which
            # come from the final state; then the infos of those that left
            # and of late spawns, in this order (``extra``)
            info_keys, info_rewards = self._info_selection()
            cols = self._ma_info_columns(rows, info_keys) if len(rows) else None
            if cols is not None and "crashed" in cols and np.count_nonzero(crashed_now):
                crashed_col = cols["crashed"]
                for i in np.flatnonzero(crashed_now).tolist():
                    crashed_col[i] = True
            extra = []
            for v in new:
                rewards[f"icv_{v}"] = 0.0
            for (vid, info), o in zip(departed, gone_obs):
                a = f"icv_{vid}"
                observations[a] = o
                rewards[a] = 0.0
                terms[a] = bool(info["exited"])
                truncs[a] = bool(info["left_road"])
                extra.append((a, info))
        # crashed vehicles leave the road after reporting
        if count_nonzero(crashed_now):
            w.remove_crashed_vehicles()
            self._after_removal()
        late = self._spawn_late()
        late_obs = None
        if late:
            rows2 = np.searchsorted(self._vehicles().vid, late)
            late_obs = self._observe_rows(rows2)
            if not arrays:
                a2 = self._names(list(late))
                inf2 = self._ma_infos(a2, rows2, {})
                for i, a in enumerate(a2):
                    observations[a] = late_obs[i]
                    rewards[a] = 0.0
                    terms[a] = False
                    truncs[a] = bool(truncated_all)
                    extra.append((a, inf2[a]))
        # every agent reported this step as rows, in the dicts' key order
        if isinstance(trunc, (bool, np.bool_)):  # (np.zeros, the usual case: 0.14 us against np.full's 0.55)
            trunc_rows = np.ones(len(step_vid), dtype=bool) if trunc else np.zeros(len(step_vid), dtype=bool)
        else:
            trunc_rows = np.array(trunc, dtype=bool)
        if departed or late:
            late_vid = np.asarray(late, dtype=np.int64)
            empty = np.zeros((0,) + self.observation_space.shape, dtype=np.float32)
            if gone_vid is None:
                gone_vid, gone_obs = np.zeros(0, dtype=np.int64), empty
            if late_obs is None:
                late_obs = empty
            out = StepRows(
                np.concatenate([step_vid, gone_vid, late_vid]),
                np.concatenate([obs, gone_obs, late_obs]),
                np.concatenate([rew, np.zeros(len(departed) + len(late))]) if arrays else None,
                np.concatenate([crashed_now, np.array([bool(i["exited"]) for _, i in departed], dtype=bool),
                                np.zeros(len(late), dtype=bool)]),
                np.concatenate([trunc_rows, np.array([bool(i["left_road"]) for _, i in departed], dtype=bool),
                                np.full(len(late), bool(truncated_all))]),
            )
        else:  # nobody left or arrived (most steps): the step's own rows (fresh arrays, as concatenate's)
            out = StepRows(step_vid, obs, rew if arrays else None, crashed_now, trunc_rows)
        if not arrays:
            # (the expert is computed only when some info will carry its label)
            lab = self._expert_label_rows(step_vid) if (len(agents) or extra) else None
            infos = {} if cols is None else self._info_dicts(agents, cols, parts if info_rewards else None,
                                                             None if lab is None else list(lab[0]))
            for a, info in extra:
                infos[a] = info
            if lab is not None:
                self._label_rest(infos, lab[1], lab[2], len(agents))
        if count_nonzero(out.terminated) or count_nonzero(out.truncated):
            keep = ~(out.terminated | out.truncated)
            self._last_obs = (out.vid[keep], out.obs[keep])
        elif owned:  # everyone stays; nobody else holds the rows (the batch's step)
            self._last_obs = (out.vid, out.obs)
        else:  # everyone stays (copies, as the selection makes: the caller gets the rows)
            self._last_obs = (out.vid.copy(), out.obs.copy())
        self._on_step_end(events)
        if self.render_mode == "human":
            self.render()
        if arrays:
            return out
        return observations, rewards, terms, truncs, infos

    def _last_obs_of(self, vid: np.ndarray) -> np.ndarray:
        """The observations the agents ``vid`` reported last (zeros for an
        agent never observed), one copy per row."""
        shape = self.observation_space.shape
        out = np.zeros((len(vid),) + shape, dtype=np.float32)
        last = getattr(self, "_last_obs", None)
        if last is not None and len(vid) and len(last[0]):
            lv, lo = last
            order = np.argsort(lv, kind="stable")
            pos = np.minimum(np.searchsorted(lv[order], vid), len(lv) - 1)
            found = lv[order[pos]] == vid
            out[found] = lo[order[pos[found]]]
        return out

    def ma_step_rows(self, actions) -> StepRows:
        """:meth:`ma_step` with arrays in and out (the batch of
        :class:`icv_envs.vector.BatchedWorlds`): ``actions`` is ``(n, 2)``
        for the continuous action types, ``(n,)`` integers for
        ``DiscreteMetaAction`` (from stop 45), row ``i`` the action of the
        vehicle in traffic row ``i`` (vehicle ids ascending); returns the same
        agents and values as the dicts of :meth:`ma_step` (no infos)."""
        if self.world is None:
            raise RuntimeError("call reset() before step()")
        at = self._act_type
        veh = self._vehicles()
        n = veh.n
        if not isinstance(at, ContinuousAction):
            # one integer per agent, checked as the dict step checks them
            # (ActionType.check_many: the error names the agent), then the
            # controls the dict step computes from them
            arr = np.asarray(actions)
            if arr.shape != (n,):
                raise ValueError(f"actions have shape {arr.shape}; allowed: ({n},), one action of "
                                 f"{self.config['action'].get('type')!r} per live agent")
            if not n:
                return self._ma_advance(np.zeros((0, 2)), arrays=True)
            vals = at.check_many(arr.tolist(), self._names(veh.vid.tolist()))
            return self._ma_advance(np.asarray(at.controls(np.arange(n), vals), dtype=np.float64), arrays=True)
        arr = np.asarray(actions, dtype=np.float64)
        if arr.shape != (n, 2):
            raise ValueError(f"actions have shape {arr.shape}; allowed: ({n}, 2), one row per live agent")
        if np.count_nonzero(np.isfinite(arr)) != arr.size:
            i = int(np.flatnonzero(~np.isfinite(arr).all(axis=1))[0])
            raise ValueError(f"action of icv_{int(veh.vid[i])} = {arr[i].tolist()} holds NaN or inf; "
                             f"allowed: finite values in [-1, 1]")
        # (the action type clips to [-1, 1] itself; a fresh array either way)
        acts = np.asarray(at.controls(np.arange(n), arr), dtype=np.float64) if n else np.zeros((0, 2))
        return self._ma_advance(acts, arrays=True)

    def _ma_step_controls(self, controls: np.ndarray) -> StepRows:
        """:meth:`ma_step_rows` from the normalised controls of its rows: a
        fresh ``(n, 2)`` float64 array of finite values in [-1, 1], row
        ``i`` the vehicle in traffic row ``i``, as plain continuous actions
        give them (:class:`~icv_envs.envs.actions.ContinuousAction` clips).
        For a caller that checked and clipped a whole batch at once
        (:class:`icv_envs.vector.BatchedWorlds`, from stop 43); the shape is
        checked, the values are not, so it is not public API (``step_rows``
        checks them). The caller reads the returned rows and keeps none of
        them (the batch copies them into its own arrays; ``owned``)."""
        if self.world is None:
            raise RuntimeError("call reset() before step()")
        n = self._vehicles().n
        if controls.shape != (n, 2):
            raise ValueError(f"controls have shape {controls.shape}; allowed: ({n}, 2), one row per live agent")
        return self._ma_advance(controls, arrays=True, owned=True)
