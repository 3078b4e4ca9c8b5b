"""The shipped random track profile is reproducible and is what the wheelset's
``irregularity`` forcing reads."""

from importlib import resources
from pathlib import Path

import numpy as np

from circuitsim.mechanics import load_model
from circuitsim.mechanics.profiles import RMS_MM, profile_csv_text, track_irregularity

SHIPPED = Path(str(resources.files("circuitsim.mechanics") / "models")) / "track_irregularity.csv"


def test_the_shipped_profile_is_current():
    assert SHIPPED.read_text() == profile_csv_text(), (
        "run python examples/make_track_irregularity.py"
    )


def test_the_profile_has_its_stated_rms_and_starts_at_rest():
    distance, lateral = track_irregularity()
    assert np.isclose(np.sqrt(np.mean(lateral**2)), RMS_MM, rtol=1e-12)
    assert lateral[0] == 0.0 and abs(lateral[-1]) < 1e-12
    assert np.all(np.diff(distance) > 0)


def test_the_wheelset_runs_over_it_at_its_speed():
    model = load_model()
    assert model.forcing_terms["irregularity"] is False  # the paper's sinusoid stays the default
    system = model.system(parameters={"V": 40.0}, forcing={"track": False, "irregularity": True})
    (irregularity,) = system.forcing
    distance, lateral = track_irregularity()
    rows = np.loadtxt(SHIPPED, delimiter=",", comments="#", skiprows=3)
    np.testing.assert_allclose(irregularity.times, distance / 40.0)
    np.testing.assert_allclose(irregularity.values, rows[:, 1] * 1e-3)  # mm -> m
    np.testing.assert_allclose(rows[:, 1], lateral, atol=5e-5)  # 4 decimals in the file
