"""The batch recorder's slips against the cycle-by-cycle rule they replace, over any split into batches."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from mbctl.jobs.wbc_batch import plant_feet, slips


def _one_by_one(counts, xy):
    """The rule cycle by cycle: a supporting foot's drift from its home; any other cycle moves the home."""
    home, out = None, []
    for c, (x, y) in zip(counts, xy, strict=True):
        if c:
            if home is None:
                home = (x, y)
            out.append(math.hypot(x - home[0], y - home[1]))
        else:
            out.append(0.0)
            home = (x, y)
    return out


@given(st.lists(st.booleans(), min_size=1, max_size=60), st.lists(st.integers(1, 20), min_size=1, max_size=8),
       st.integers(0, 2**31 - 1))
def test_slips_in_batches_equal_the_rule_cycle_by_cycle(counts, cuts, seed):
    xy = np.random.default_rng(seed).normal(scale=0.01, size=(len(counts), 2))
    expected = _one_by_one(counts, xy.tolist())
    got, home, start = [], None, 0
    for n in cuts * (len(counts) // sum(cuts) + 1):
        if start >= len(counts):
            break
        end = min(start + n, len(counts))
        part, home = slips(np.array(counts[start:end]), xy[start:end], home)
        got += part.tolist()
        start = end
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-15)


def test_plant_feet_turns_the_net_contact_into_force_and_cop():
    # a foot pressing 300 N down at (0.1, -0.2) with 20 N of friction along x, its moment about that
    # point zero: the CoP is the point; an unloaded one has no CoP
    exerted = [4, -20.0, 0.0, -300.0, 0.0, 0.0, 0.0, 0.1, -0.2, 0.0]
    moved = [4, -20.0, 0.0, -300.0, 0.0, 300.0 * 0.01, 0.0, 0.1, -0.2, 0.0]  # about p: 1 cm further in x
    out = plant_feet(np.array([exerted + [0.0] * 10, moved + [0.0] * 10]), [0, 1])
    np.testing.assert_allclose(out[0, 0], [20.0, 0.0, 300.0, 0.1, -0.2])
    np.testing.assert_allclose(out[1, 0], [20.0, 0.0, 300.0, 0.11, -0.2])
    assert np.isnan(out[:, 1, 3:]).all() and (out[:, 1, :3] == 0).all()
