"""Rewrite the shipped random track profile: ``python examples/make_track_irregularity.py``.

The profile (circuitsim/mechanics/models/track_irregularity.csv) is made by
:func:`circuitsim.mechanics.profiles.track_irregularity` with a fixed seed, so this gives the
same file every time; tests/mechanics/test_forcing_track.py checks that it is current.
"""

from pathlib import Path

from circuitsim.atomic import write_files_atomic
from circuitsim.mechanics.profiles import profile_csv_text

if __name__ == "__main__":
    import circuitsim

    target = Path(circuitsim.__file__).parent / "mechanics" / "models" / "track_irregularity.csv"
    write_files_atomic({target: profile_csv_text()})
    print(f"wrote {target}")
