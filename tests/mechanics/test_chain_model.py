"""The chain model family (circuitsim.mechanics.chain): a model file of any size."""

from __future__ import annotations

import numpy as np
import pytest

from circuitsim.mechanics import load_model, solve, state_matrix
from circuitsim.mechanics.chain import chain_model_text


def _load(tmp_path, masses):
    path = tmp_path / f"chain{masses}.toml"
    path.write_text(chain_model_text(masses))
    return load_model(path)


@pytest.mark.parametrize("masses", [1, 3, 8])
def test_free_chain_frequencies_are_the_fixed_free_chains(tmp_path, masses):
    """Without dashpots and contacts the chain (ground - k - m - ... - m) has the analytic
    frequencies w_j^2 = (4 k / m) sin^2((2j - 1) pi / (2 (2N + 1))), j = 1..N."""
    model = _load(tmp_path, masses)
    assert model.states[:masses] == tuple(f"x{i + 1}" for i in range(masses))
    assert len(model.nonlinear_terms) == masses
    A = state_matrix(model, parameters={"c": 0.0})
    omega = np.sort(np.abs(np.linalg.eigvals(A).imag))[::2]
    k, m = model.parameters["k"], model.parameters["m"]
    j = np.arange(1, masses + 1)
    expected = np.sqrt(4 * k / m) * np.sin((2 * j - 1) * np.pi / (2 * (2 * masses + 1)))
    np.testing.assert_allclose(omega, np.sort(expected), rtol=1e-10)


def test_every_contact_closes(tmp_path):
    """The drive on every mass takes each past the half gap d (each dead zone works)."""
    model = _load(tmp_path, 4)
    system = model.system(nonlinear={g: True for g in model.nonlinear_terms})
    result = solve(system, t_span=(0.0, 5.0))
    d = model.parameters["d"]
    for i in range(4):
        assert result.max_abs(f"x{i + 1}") > 1.5 * d


def test_no_masses_is_an_error():
    with pytest.raises(ValueError, match="at least one mass"):
        chain_model_text(0)
