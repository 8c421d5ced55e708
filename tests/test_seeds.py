"""``--seeds``: a count or a list/range (icv_envs.experiments.seeds.parse_seeds)."""

from __future__ import annotations

import pytest

from icv_envs.experiments.seeds import parse_seeds


@pytest.mark.parametrize("text, expected", [
    ("3", [0, 1, 2]), (3, [0, 1, 2]), ("5,7,10-12", [5, 7, 10, 11, 12]), ("7,", [7]), ("7-7", [7]),
    (" 0 - 2 , 9 ", [0, 1, 2, 9]), ("1", [0]),
])
def test_parse_seeds(text, expected):
    assert parse_seeds(text) == expected


@pytest.mark.parametrize("text, match", [
    ("0", "count must be >= 1"), ("", "allowed"), ("a", "'a' is not a seed"), ("5-3", "empty"),
    ("1,1", r"\[1\] are listed more than once"), ("-2", "not a seed"), (True, "allowed"), (None, "allowed"),
    ("2.5", "not a seed"),
])
def test_parse_seeds_bad_input(text, match):
    with pytest.raises(ValueError, match=match):
        parse_seeds(text)


def test_cli_seeds_bad_input(capsys):
    from icv_envs.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["compare", "highway-ramps", "--seeds", "3-1", "--seconds", "5"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--seeds" in err and "'3-1'" in err and "empty" in err
