# SPDX-License-Identifier: BSD-3-Clause
"""Small cases and the k-sigma comparison shared by the tests."""

import numpy as np

K_SIGMA = 4.0   #: Monte Carlo estimates must lie within K_SIGMA standard errors of the answer


def small_case(**groups):
    """A one-layer case with a small photon budget; ``groups`` replace or add groups."""
    case = {
        "control": {"n_photons_per_batch": 2000, "n_batches": 10, "seed": 7, "verbose": 0},
        "atmosphere": {"nz": 1, "z_levels": [0.0, 1000.0]},
        "output": {"file": "out.nc"},
    }
    case.update(groups)
    return case


def assert_within(actual, expected, sigma, label, k=K_SIGMA, atol=1e-12):
    """|actual - expected| <= k sigma + atol, element by element (atol: round-off)."""
    actual, expected, sigma = np.broadcast_arrays(
        *(np.asarray(v, dtype=float) for v in (actual, expected, sigma)))
    bad = ~(np.abs(actual - expected) <= k * sigma + atol)
    assert not np.any(bad), (f"{label}: {actual[bad]} differ from {expected[bad]} by more than "
                             f"{k:g} sigma = {k * sigma[bad]}")
