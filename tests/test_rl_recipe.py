"""baselines/ppo_recipe.py on a tiny budget: it trains, writes the curve and a loadable model."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from baseline_scripts import load_baseline

torch = pytest.importorskip("torch")
pytest.importorskip("stable_baselines3")
torch.set_num_threads(1)



def _recipe():
    return load_baseline("ppo_recipe")


TINY = ["--total-timesteps", "96", "--n-steps", "8", "--batch-size", "32", "--n-epochs", "1", "--eval-every", "48",
        "--eval-episodes", "1", "--net-arch", "16,16"]


@pytest.mark.parametrize("action_type", ["ContinuousAction", "DiscreteMetaAction"])
def test_recipe_tiny_run(tmp_path, action_type):
    from icv_envs.rl.models import load_model

    out = tmp_path / "run"
    cfg = json.dumps({"scenario": "on-ramp", "duration": 2})
    assert _recipe().main(["--config", cfg, "--action-type", action_type, "--out", str(out)] + TINY) == 0
    with open(out / "curve.csv") as f:
        rows = list(csv.DictReader(f))
    assert rows and rows[-1]["val_return"] != "" and int(rows[-1]["slot_steps"]) >= 96
    run = json.loads((out / "run.json").read_text())
    assert run["action_type"] == action_type and run["algo"] == "ppo_recipe"
    assert (out / "curve.png").stat().st_size > 5000
    m = load_model(out)
    acts = m.act(np.zeros((3, *m.observation_space.shape), dtype=np.float32))
    assert acts.shape[0] == 3
    if action_type == "ContinuousAction":  # the exploration noise of the docstring
        std = np.exp(m.model.policy.log_std.detach().numpy())
        assert run["config"].get("action") is None
        assert np.allclose(std, [0.3, 0.01], rtol=0.2)
    else:
        assert run["config"]["action"] == {"type": "DiscreteMetaAction"}


def test_recipe_init_from_clone_keeps_the_actor(tmp_path):
    """--init copies the clone's actor; during the critic warm-up the actor does not move."""
    from stable_baselines3 import PPO

    from icv_envs.rl.envs import make_parallel_env
    from icv_envs.rl.models import write_run_json
    from icv_envs.rl.vec_env import ParallelVecEnv

    cfg = {"scenario": "on-ramp", "duration": 2}
    clone = tmp_path / "clone"
    venv = ParallelVecEnv(lambda: make_parallel_env("highway_formation_v0", cfg), seed=0)
    PPO("MlpPolicy", venv, n_steps=8, seed=1, device="cpu",
        policy_kwargs={"net_arch": {"pi": [16, 16], "vf": [16, 16]}, "activation_fn": torch.nn.ReLU}
        ).save(clone / "model.zip")
    write_run_json(clone, {"algo": "bc_expert", "env": "icv_envs/highway_formation-v0", "config": cfg})
    out = tmp_path / "run"
    args = ["--config", json.dumps(cfg), "--init", str(clone), "--out", str(out), "--critic-warmup", "10000"] + TINY
    assert _recipe().main(args) == 0
    a = PPO.load(clone / "model.zip", device="cpu").policy.state_dict()
    b = PPO.load(out / "final.zip", device="cpu").policy.state_dict()
    for k in a:
        if k.startswith(("mlp_extractor.policy_net", "action_net")):
            assert torch.equal(a[k], b[k]), k
    assert any(not torch.equal(a[k], b[k]) for k in a if k.startswith("value_net"))


def test_recipe_bad_arguments(tmp_path):
    rec = _recipe()
    with pytest.raises(SystemExit):
        rec.parse_args(["--action-std", "0.3"])
    with pytest.raises(SystemExit):
        rec.parse_args(["--config", '{"action": {"type": "DiscreteMetaAction"}}'])
    with pytest.raises(SystemExit):
        rec.parse_args(["--action-type", "Nope"])


def test_recipe_on_the_intersection_trains_on_the_k_vehicle_slots(tmp_path):
    """--layout auto on an open road: K reused slots (per-vehicle episodes), not one per possible arrival;
    the validation rows carry the throughput the open-road selection uses."""
    from icv_envs.rl.slots import slot_parallel_env

    out = tmp_path / "run"
    cfg = {"throughput": 1500, "duration": 6, "warmup": 20}
    tiny = ["--total-timesteps", "200", "--n-steps", "4", "--batch-size", "32", "--n-epochs", "1",
            "--eval-every", "100", "--eval-episodes", "1", "--net-arch", "16,16"]
    assert _recipe().main(["--env", "intersection_v0", "--config", json.dumps(cfg), "--action-type",
                           "DiscreteMetaAction", "--out", str(out)] + tiny) == 0
    run = json.loads((out / "run.json").read_text())
    K = slot_parallel_env("intersection_v0", dict(cfg, action={"type": "DiscreteMetaAction"})).K
    assert run["train"]["slots"] == K
    with open(out / "curve.csv") as f:
        rows = [r for r in csv.DictReader(f) if r["val_return"] != ""]
    assert rows and all(r["val_throughput"] != "" for r in rows)
    assert len(run["train"]["chosen_validation"]) == 4  # (-score, collisions, -return, steps)


@pytest.mark.parametrize("env,layout", [("highway_formation_v0", "agents"), ("icv_envs/highway_formation-v0", "agents"),
                                        ("highway_ramps_v0", "slots"), ("icv_envs/intersection-v0", "slots")])
def test_recipe_auto_layout_by_env_family(env, layout):
    """--layout auto: one slot per agent where every agent is there from the start, K reused slots on the
    open roads; decided by the env family, whatever name form the env was given in."""
    assert _recipe().parse_args(["--env", env]).layout == layout


def test_reselect_checkpoint_picks_the_fewest_stage2_collisions(tmp_path):
    """baselines/reselect_checkpoint.py: stage 2 over the checkpoints tied at the fewest stage-1
    collisions; the copy is the chosen checkpoint and the choice follows the stated rule."""
    import filecmp

    out = tmp_path / "run"
    cfg = json.dumps({"scenario": "on-ramp", "duration": 2})
    assert _recipe().main(["--config", cfg, "--action-type", "DiscreteMetaAction", "--out", str(out)] + TINY) == 0
    sel = tmp_path / "resel"
    res = load_baseline("reselect_checkpoint")
    assert res.main([str(out), "--episodes", "1", "--out", str(sel)]) == 0
    meta = json.loads((sel / "run.json").read_text())["reselection"]
    rows = meta["results"]
    assert rows and meta["chosen"] in {r["checkpoint"] for r in rows}
    best = min(rows, key=lambda r: (r["collisions"], -r["episode_return"]))
    assert meta["chosen"] == best["checkpoint"]
    assert filecmp.cmp(sel / "model.zip", out / "checkpoints" / meta["chosen"] / "model.zip", shallow=False)
    with open(out / "curve.csv") as f:
        stage1 = [float(r["val_collisions_per_100"]) for r in csv.DictReader(f) if r["val_return"]]
    assert all(r["stage1_collisions_per_100"] == min(stage1) for r in rows)
    with pytest.raises(SystemExit):
        res.main([str(out), "--episodes", "0", "--out", str(sel)])
