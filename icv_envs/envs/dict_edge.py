"""The array -> PettingZoo dict edge of the multi-agent step (issue 10,
item 1): the envs build observations, rewards and infos as arrays over
their vehicle rows; :class:`DictEdge` checks the agents' actions as one
array and turns the rows into the per-agent dicts PettingZoo's API requires,
once, at the edge. A mixin of :class:`icv_envs.envs.base.IcvAgentsEnv`,
whose ``config``, ``_vehicles``, ``expert_actions`` and ``_check_action``
it uses."""

from __future__ import annotations

import functools
import itertools
import operator

import numpy as np

from icv_envs._ufuncs import clip as uclip

__all__ = ["DictEdge", "same_ids"]


def same_ids(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two id arrays hold the same ids in the same order: their
    bytes compared (``np.array_equal``'s answer for two arrays of one
    integer dtype, at a tenth of its cost on a 20-vehicle world); arrays
    of different dtypes are not the same (one array object is the same as
    itself: id arrays are replaced, never written in place)."""
    if a is b:
        return True
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


class DictEdge:
    """Action check and per-agent dicts of :class:`~icv_envs.envs.base.IcvAgentsEnv` (module docstring)."""

    def _check_actions(self, names: list, values: list) -> np.ndarray:
        """Continuous actions of all agents checked and converted at once: one
        array, one finiteness check, clipped to [-1, 1]. Anything the fast
        path cannot take as one real ``(n, 2)`` array (a wrong shape, a
        string, a dict, complex or boolean values) goes through the action
        type's per-agent check, whose error names the agent; non-finite values
        raise naming every bad agent."""
        arr = None
        # the fast path takes real numpy arrays only: np.array() of a mixed
        # list would silently upcast one agent's bool / int-list action
        # (the test runs in C: one map over the types, one over the dtypes, whose
        # distinct ones give their kinds: a third less than one kind per value)
        if set(map(type, values)) == _NDARRAY_ONLY and {d.kind for d in set(map(_DTYPE, values))} <= _REAL_KINDS:
            try:
                arr = np.array(values)
            except (ValueError, TypeError, OverflowError):
                arr = None
        if arr is None or arr.shape != (len(names), 2) or arr.dtype.kind not in "fiu":
            arr = np.stack([self._check_action(v, a) for a, v in zip(names, values)])
        else:
            arr = arr.astype(np.float64, copy=False)
        fin = np.isfinite(arr)
        if np.count_nonzero(fin) != fin.size:  # (the count first: ~0.3 us against .all(axis=1)'s ~6 us on 480 rows)
            finite = fin.all(axis=1)
            bad = [names[i] for i in np.flatnonzero(~finite)]
            more = f" (and {len(bad) - 1} more: {bad[1:10]}{' ...' if len(bad) > 10 else ''})" if len(bad) > 1 else ""
            raise ValueError(f"action of {bad[0]} = {arr[~finite][0].tolist()} holds NaN or inf{more}; "
                             f"allowed: finite values in [-1, 1]")
        return uclip(arr, -1.0, 1.0)

    # ------------------------------------------- array -> PettingZoo dicts
    # The env builds observations, rewards and infos as arrays over its rows;
    # these turn them into the per-agent dicts once, at the API's edge.
    @staticmethod
    def _agent_dicts(agents: list, obs: np.ndarray, rew: np.ndarray, term: np.ndarray, trunc) -> tuple:
        """``(observations, rewards, terminations, truncations)`` dicts from
        row arrays (``trunc`` an array or one bool for all)."""
        observations = dict(zip(agents, obs))
        rewards = dict(zip(agents, np.asarray(rew, dtype=np.float64).tolist()))
        terms = dict(zip(agents, np.asarray(term, dtype=bool).tolist()))
        if np.ndim(trunc) == 0:
            truncs = dict.fromkeys(agents, bool(trunc))
        else:
            truncs = dict(zip(agents, np.asarray(trunc, dtype=bool).tolist()))
        return observations, rewards, terms, truncs

    @staticmethod
    def _info_dicts(agents: list, columns: dict, parts: dict | None = None, labels=None) -> dict:
        """One info dict per agent from per-agent columns (lists aligned with
        ``agents``), the reward components (``info["rewards"]``) and, given
        ``labels`` (rows aligned with ``agents``), the expert's labels
        (``info["expert_action"]``, last); otherwise the labels are added by
        :meth:`_label_infos`."""
        keys = list(columns)
        vals = [columns[k] for k in keys]
        pk = list(parts) if parts else []
        vals += [np.asarray(parts[k], dtype=np.float64).tolist() for k in pk]
        tail = ()
        if labels is not None:
            tail = ("expert_action",)
            vals.append(labels)
        if not vals:  # no key selected (``info_keys=[]`` without the expert's label): one empty dict each
            return {a: {} for a in agents}
        return _dict_builder(tuple(keys), tuple(pk), tail)(agents, vals)

    @staticmethod
    def _realign_rows(before_vid: np.ndarray, values: np.ndarray, vid: np.ndarray) -> np.ndarray:
        """``values`` (rows aligned with the sorted ids ``before_vid``) moved
        to the rows of the sorted ids ``vid``; zeros for ids not in
        ``before_vid`` (vehicles that appeared since)."""
        if same_ids(before_vid, vid):  # nobody left or appeared
            return values.copy()
        out = np.zeros((len(vid),) + values.shape[1:], dtype=values.dtype)
        if len(before_vid) and len(vid):
            pos = np.minimum(np.searchsorted(before_vid, vid), len(before_vid) - 1)
            ok = before_vid[pos] == vid
            out[ok] = values[pos[ok]]
        return out

    def _fill_expert_labels(self, infos: dict) -> None:
        """``infos[a]["expert_action"]`` for every agent of ``infos`` (a
        reset's), from the current state: exactly what :meth:`expert_actions`
        returns for the next step. Agents not on the road get zeros."""
        if not infos:
            return
        lab = self._expert_label_rows(np.zeros(0, dtype=np.int64))
        if lab is not None:
            self._label_rest(infos, lab[1], lab[2], 0)

    def _expert_label_rows(self, agents_vid: np.ndarray):
        """The expert's labels from the current state (a step's final one,
        after its removals and spawns, so each label is exactly what
        :meth:`expert_actions` returns for the next step), computed once:
        ``(rows aligned with the sorted ids agents_vid (zeros for agents no
        longer on the road), ids of the vehicles on the road not among them,
        their rows)``, or None when the infos carry no labels."""
        if not self.config["expert_in_info"]:
            return None
        veh = self._vehicles()
        ex = self.expert_actions() if veh.n else np.zeros((0, 2), dtype=np.float32)
        rows = np.array(ex, dtype=np.float32, copy=True)
        aligned = DictEdge._realign_rows(veh.vid, rows, agents_vid)
        if same_ids(veh.vid, agents_vid):  # nobody came or went
            return aligned, veh.vid[:0], rows[:0]
        late = ~np.isin(veh.vid, agents_vid)
        return aligned, veh.vid[late], rows[late]

    @staticmethod
    def _label_rest(infos: dict, rest_vid: np.ndarray, rest_rows: np.ndarray, skip: int) -> None:
        """Labels of the infos after the first ``skip`` (the step's agents,
        labelled when their dicts were built): vehicles that appeared late
        in the step by name (``rest_vid``, ``rest_rows``), zeros for the
        others (agents that left)."""
        for a, row in zip([f"icv_{v}" for v in rest_vid.tolist()], rest_rows):
            info = infos.get(a)
            if info is not None:
                info["expert_action"] = row
        for info in itertools.islice(infos.values(), skip, None):
            if "expert_action" not in info:
                info["expert_action"] = np.zeros(2, dtype=np.float32)

    @staticmethod
    def _label_infos(infos: dict, vid: np.ndarray, ex: np.ndarray) -> None:
        """Label the infos of vehicles ``vid`` by name with a row view of a
        copy of ``ex`` each, zeros for the other infos (:meth:`_label_rest`
        with nothing labelled before)."""
        DictEdge._label_rest(infos, vid, np.array(ex, dtype=np.float32, copy=True), 0)


_NDARRAY_ONLY = {np.ndarray}
_REAL_KINDS = {"f", "i", "u"}
_DTYPE = operator.attrgetter("dtype")


@functools.lru_cache(maxsize=64)
def _dict_builder(keys: tuple, reward_keys: tuple, tail_keys: tuple = ()):
    """A function ``(agents, columns) -> {agent: {key: value, ...}}`` for
    these keys, written as one dict display per agent (about twice as fast
    as ``dict(zip(keys, row))``; CPython builds a literal in one opcode). The
    keys are the envs' own info names, never user input; ``repr`` quotes
    them. ``reward_keys`` go into a nested ``"rewards"`` dict, ``tail_keys``
    after it (the columns in that order: keys, reward keys, tail keys)."""
    names = [f"c{i}" for i in range(len(keys) + len(reward_keys) + len(tail_keys))]
    items = [f"{k!r}: {v}" for k, v in zip(keys, names)]
    if reward_keys:
        inner = ", ".join(f"{k!r}: {v}" for k, v in zip(reward_keys, names[len(keys):]))
        items.append(f"'rewards': {{{inner}}}")
    items += [f"{k!r}: {v}" for k, v in zip(tail_keys, names[len(keys) + len(reward_keys):])]
    src = (f"lambda agents, cols: {{a: {{{', '.join(items)}}} "
           f"for a, {', '.join(names) + ','} in zip(agents, *cols)}}")
    return eval(src, {})  # noqa: S307 - the source is built from the repr of the envs' constant key names
