"""The ``icv-envs`` command line: --version, help text and choices for every
option, ``list``, ``run intersection``, and output that stays clean when it is
not a terminal (progress bars on stderr and only on a tty; JSON last on stdout)."""

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import icv_envs
from icv_envs.cli import ENVS, METHODS, build_parser, main
from icv_envs.envs.highway_ramps import METHODS as RAMP_METHODS
from icv_envs.envs.intersection import METHODS as INTERSECTION_METHODS
from icv_envs.envs.scenarios import SCENARIOS
from icv_envs.policies import POLICIES

ROOT = Path(__file__).resolve().parents[1]


def _env():
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy", MPLBACKEND="Agg")
    env.pop("FORCE_COLOR", None)
    return env


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"icv-envs {icv_envs.__version__}"


def _subparsers(parser):
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return sub.choices


def test_every_option_has_help_text():
    parser = build_parser()
    missing = [f"{name} {'/'.join(a.option_strings) or a.dest}"
               for name, sp in _subparsers(parser).items() for a in sp._actions
               if not isinstance(a, argparse._HelpAction) and not (a.help or "").strip()]
    assert not missing, f"options without help text: {missing}"


@pytest.mark.parametrize("command, option, names", [
    ("run", "env", ENVS),
    ("run", "--scenario", tuple(SCENARIOS)),
    ("run", "--policy", POLICIES),
    ("run", "--method", tuple(RAMP_METHODS) + tuple(INTERSECTION_METHODS)),
    ("run", "--lane-use", ("paper", "exclusive")),
    ("compare", "--methods", tuple(RAMP_METHODS) + tuple(INTERSECTION_METHODS)),
    ("compare", "--backend", ("process", "ray")),
    ("bench", "target", ("highway-formation", "highway-ramps", "train", "intersection")),
    ("conflicts", "--lane-use", ("paper", "exclusive")),
])
def test_help_lists_the_choices(command, option, names):
    sp = _subparsers(build_parser())[command]
    (action,) = [a for a in sp._actions if option in a.option_strings or a.dest == option]
    for n in names:
        assert n in action.help, (command, option, n, action.help)


def test_bad_choice_names_the_value_and_the_allowed_ones(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["run", "intersection", "--lane-use", "warp"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "'warp'" in err and "paper" in err and "exclusive" in err
    assert main(["run", "intersection", "--method", "warp", "--seconds", "5"]) == 2
    err = capsys.readouterr().err
    assert "'warp'" in err and "multi-vp" in err
    assert main(["run", "intersection", "--throughput", "-5", "--seconds", "5"]) == 2
    assert "throughput -5.0 is invalid" in capsys.readouterr().err


def test_list_names_every_env_scenario_method_and_policy(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    data = json.loads(out[-1])
    text = "\n".join(out[:-1])
    assert data["gymnasium"] == sorted(icv_envs.GYM_IDS) and data["pettingzoo"] == sorted(icv_envs.PETTINGZOO_IDS)
    assert data["cli_envs"] == list(ENVS) and "intersection" in ENVS
    assert data["scenarios"] == sorted(SCENARIOS)
    assert data["methods"] == {"highway-ramps": list(RAMP_METHODS), "intersection": list(INTERSECTION_METHODS)}
    assert data["policies"] == list(POLICIES)
    for fam, pols in data["evaluate_policies"].items():
        assert {"expert", "zero", "random", "PATH"} <= set(pols), fam
    names = (list(icv_envs.GYM_IDS) + list(icv_envs.PETTINGZOO_IDS) + list(SCENARIOS) + list(POLICIES)
             + [m for ms in METHODS.values() for m in ms])
    for n in names:  # the human-readable part lists them too
        assert n in text, n


def test_list_json_only(capsys):
    assert main(["list", "--json"]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1 and json.loads(out[0])["scenarios"] == sorted(SCENARIOS)


def test_run_intersection(tmp_path, capsys):
    out = tmp_path / "ix"
    code = main(["run", "intersection", "--method", "fcfs", "--throughput", "1200", "--seconds", "20",
                 "--seed", "3", "--out", str(out)])
    assert code == 0
    m = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert m["env"] == "intersection" and m["method"] == "fcfs" and m["throughput"] == 1200.0 and m["seed"] == 3
    assert m["lane_use"] == "paper" and m["spawned"] > 0 and m["collisions"] == 0 and m["lost"] == 0
    assert 0 < m["mean_speed"] <= 20.0
    assert json.loads((out / "metrics.json").read_text())["spawned"] == m["spawned"]


def test_run_intersection_default_method_and_determinism(capsys):
    runs = []
    for _ in range(2):
        assert main(["run", "intersection", "--seconds", "10", "--lane-use", "exclusive"]) == 0
        m = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
        m.pop("wall_seconds")
        runs.append(m)
    assert runs[0]["method"] == "multi-vp" and runs[0]["lane_use"] == "exclusive"
    assert runs[0] == runs[1]


def test_run_intersection_rejects_a_highway_method(capsys):
    assert main(["run", "intersection", "--method", "idm", "--seconds", "5"]) == 2
    err = capsys.readouterr().err
    assert "idm" in err and "multi-vp" in err


def test_run_intersection_video_needs_out(capsys):
    assert main(["run", "intersection", "--seconds", "1", "--video"]) == 2
    assert "--out" in capsys.readouterr().err


def _run_piped(args, tmp_path):
    return subprocess.run([sys.executable, "-m", "icv_envs.cli", *args], capture_output=True, text=True,
                          env=_env(), cwd=tmp_path, timeout=600)


def test_demo_piped_is_not_interleaved(tmp_path):
    p = _run_piped(["demo", "--seconds", "2", "--no-video", "--out", str(tmp_path / "d")], tmp_path)
    assert p.returncode == 0, p.stderr
    lines = p.stdout.strip().splitlines()
    assert "\r" not in p.stdout and "\r" not in p.stderr
    assert "scenarios:" not in p.stderr and "it/s" not in p.stderr  # no tqdm bar when stderr is not a tty
    assert [ln.split()[0] for ln in lines[:-1]] == ["lane-drop", "lane-change", "off-ramp", "on-ramp"]
    assert json.loads(lines[-1])["demo"] == "highway-formation"


def test_run_piped_prints_only_json(tmp_path):
    p = _run_piped(["run", "highway-formation", "--scenario", "free", "--seconds", "3"], tmp_path)
    assert p.returncode == 0, p.stderr
    lines = p.stdout.strip().splitlines()
    assert len(lines) == 1 and json.loads(lines[0])["steps"] == 15
    assert "\r" not in p.stderr and "it/s" not in p.stderr


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")
def test_progress_bar_shown_on_a_terminal(tmp_path):
    import fcntl
    import struct
    import termios

    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # tqdm draws nothing at 0 columns
    try:
        p = subprocess.run([sys.executable, "-m", "icv_envs.cli", "run", "highway-formation", "--scenario", "free",
                            "--seconds", "3"], stdout=subprocess.PIPE, stderr=slave, env=_env(), cwd=tmp_path,
                           timeout=600)
        os.close(slave)
        slave = None
        chunks = []
        while True:
            try:
                data = os.read(master, 65536)
            except OSError:
                break
            if not data:
                break
            chunks.append(data)
    finally:
        if slave is not None:
            os.close(slave)
        os.close(master)
    err = b"".join(chunks).decode(errors="replace")
    assert p.returncode == 0
    assert "free/expert" in err  # the tqdm bar, on the terminal (stderr)
    assert len(p.stdout.decode().strip().splitlines()) == 1  # stdout: the JSON line only


def test_help_shows_every_default_including_zero():
    from icv_envs.cli import build_parser

    p = build_parser()
    sub = next(a for a in p._actions if a.__class__.__name__ == "_SubParsersAction")
    run_help = sub.choices["run"].format_help()
    assert "episode seed (default: 0)" in " ".join(run_help.split())
    board = " ".join(sub.choices["leaderboard"].format_help().split())
    assert "(default: results/leaderboard)" in board and "(default: 2000)" in board
