"""A reproducible random track profile: the shipped ``models/track_irregularity.csv``.

Lateral alignment irregularity as a sum of sinusoids in distance with random phases (numpy's
PCG64 generator, a fixed seed), over the wavelengths of EN 13848's D1 and D2 ranges (3 to 70 m),
with amplitudes falling like the wavelength squared over a flat part (a one-sided spectral
density ~ 1 / (1 + (lambda_c / lambda)^2) / k^2 shape, a common textbook form), scaled to a
chosen RMS. It is an example input, not a measured track: ``python
examples/make_track_irregularity.py`` rewrites the file, and a test checks that the shipped
file is what this module makes.
"""

from __future__ import annotations

import numpy as np

#: Seed, length (m), spacing (m), RMS (mm) and wavelength range (m) of the shipped profile.
SEED = 20260
LENGTH = 300.0
SPACING = 0.5
RMS_MM = 1.5
WAVELENGTHS = (3.0, 70.0)
CORNER_WAVELENGTH = 20.0
COMPONENTS = 60


def track_irregularity(
    seed: int = SEED,
    length: float = LENGTH,
    spacing: float = SPACING,
    rms_mm: float = RMS_MM,
) -> tuple[np.ndarray, np.ndarray]:
    """Distance (m) and lateral irregularity (mm) of a random profile.

    Parameters
    ----------
    seed : int
        Of ``numpy.random.default_rng``.
    length, spacing : float
        Metres.
    rms_mm : float
        RMS of the profile, mm.

    Returns
    -------
    distance : ndarray, shape (p,)
        0, spacing, ... length, m.
    lateral : ndarray, shape (p,)
        mm, starting and ending at 0 (a cosine taper over the first and last 10 m, so the
        input does not jump at the start).
    """
    rng = np.random.default_rng(seed)
    distance = np.arange(0.0, length + spacing / 2, spacing)
    shortest, longest = WAVELENGTHS
    wavelengths = np.geomspace(shortest, longest, COMPONENTS)
    k = 2 * np.pi / wavelengths
    density = 1.0 / (1.0 + (CORNER_WAVELENGTH / wavelengths) ** 2) / k**2
    # geometric spacing: each component stands for a band of width ~ k d(ln k)
    amplitude = np.sqrt(density * k)
    phases = rng.uniform(0.0, 2 * np.pi, COMPONENTS)
    lateral = (amplitude[None, :] * np.sin(np.outer(distance, k) + phases)).sum(axis=1)
    taper = np.ones_like(distance)
    ramp = distance < 10.0
    taper[ramp] = 0.5 * (1 - np.cos(np.pi * distance[ramp] / 10.0))
    end = distance > length - 10.0
    taper[end] = 0.5 * (1 - np.cos(np.pi * (length - distance[end]) / 10.0))
    lateral = lateral * taper
    lateral *= rms_mm / np.sqrt(np.mean(lateral**2))
    return distance, lateral


def profile_csv_text() -> str:
    """The CSV text of the shipped profile (header, then ``distance_m,lateral_mm`` rows)."""
    distance, lateral = track_irregularity()
    lines = [
        f"# lateral track irregularity, random (circuitsim.mechanics.profiles, seed {SEED}):",
        f"# {COMPONENTS} sinusoids, wavelengths {WAVELENGTHS[0]:g}-{WAVELENGTHS[1]:g} m, "
        f"RMS {RMS_MM:g} mm",
        "distance_m,lateral_mm",
    ]
    lines += [f"{s:g},{z:.4f}" for s, z in zip(distance, lateral, strict=True)]
    return "\n".join(lines) + "\n"
