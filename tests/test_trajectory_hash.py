"""Bit-identity of expert-driven trajectories against a reference recorded
before the compiled kernels and the vectorised API layer went in (issue 10).

A failure means some bit of the state, the observations, the rewards or the
infos' expert actions changed. If the change is intended (a model change
merged from another branch), re-record with
``PYTHONPATH=$PWD python tests/trajectory_hash.py --record`` and say why in
the commit message."""

import json

import pytest

from trajectory_hash import CASES, PINNED_LEVEL, REFERENCE, fingerprint, pinned_environment, pinned_fingerprints

_REF = json.loads(REFERENCE.read_text())


@pytest.fixture(scope="module")
def pinned():
    """Every case's fingerprint, computed once in a subprocess whose NumPy
    SIMD dispatch is capped at X86_V3 (see ``trajectory_hash``)."""
    if pinned_environment() is None:
        pytest.skip(f"no {PINNED_LEVEL} (AVX2) SIMD level on this machine: the reference fingerprints need it")
    return pinned_fingerprints()


@pytest.mark.parametrize("name", [c[0] for c in CASES])
def test_trajectory_matches_reference(pinned, name):
    assert pinned[name] == _REF[name]


def test_fingerprint_detects_a_changed_seed():
    name, module, config, seed, steps = CASES[0]
    assert fingerprint(module, config, seed + 1, 5) != fingerprint(module, config, seed, 5)
