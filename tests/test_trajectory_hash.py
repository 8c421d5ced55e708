"""Bit-identity of expert-driven trajectories against a reference recorded
before the compiled kernels and the vectorised API layer went in (issue 10).

A failure means some bit of the state, the observations, the rewards or the
infos' expert actions changed. If the change is intended (a model change
merged from another branch), re-record with
``PYTHONPATH=$PWD python tests/trajectory_hash.py --record`` and say why in
the commit message."""

import json

import pytest

from trajectory_hash import CASES, REFERENCE, fingerprint

_REF = json.loads(REFERENCE.read_text())


@pytest.mark.parametrize("name,module,config,seed,steps", CASES, ids=[c[0] for c in CASES])
def test_trajectory_matches_reference(name, module, config, seed, steps):
    assert fingerprint(module, config, seed, steps) == _REF[name]


def test_fingerprint_detects_a_changed_seed():
    name, module, config, seed, steps = CASES[0]
    assert fingerprint(module, config, seed + 1, 5) != fingerprint(module, config, seed, 5)
