"""Task-set generator: seeded, filtered as the thesis says, period model fitted to the data."""

import math

import numpy as np
import pytest

from c4d_sched.generator import (
    PAPARAZZI_ROTORCRAFT_PERIODS_MS,
    fit_exponents,
    generate_tasksets,
    paparazzi_period_model,
    utilisations,
)


def test_reproducible_and_filtered():
    a = generate_tasksets(8, 0.7, 50, seed=4)
    b = generate_tasksets(8, 0.7, 50, seed=4)
    assert [t.tasks for t in a] == [t.tasks for t in b]
    assert [t.tasks for t in a] != [t.tasks for t in generate_tasksets(8, 0.7, 50, seed=5)]
    for ts in a:
        assert len(ts.tasks) == 8 and min(ts.wcets) > 0
        assert math.gcd(*ts.periods) >= max(ts.wcets)
        assert abs(ts.utilisation - 0.7) < 0.05 * 8 / min(ts.periods) + 0.05


def test_period_model_is_the_fit_of_the_paparazzi_periods():
    assert len(PAPARAZZI_ROTORCRAFT_PERIODS_MS) == 85
    fitted = fit_exponents(PAPARAZZI_ROTORCRAFT_PERIODS_MS)
    assert set(fitted) == {2, 3, 5, 7, 11, 13, 17, 31, 41}
    model = paparazzi_period_model()
    assert [p for p, _ in model.exponents] == [2, 3, 5]
    for p, probs in model.exponents:
        assert probs == tuple(fitted[p].get(e, 0) / 85 for e in range(len(probs)))
    assert model.max_hyperperiod == 2**6 * 3**2 * 5**4
    full = paparazzi_period_model(0.0)
    assert [p for p, _ in full.exponents] == [2, 3, 5, 7, 11, 13, 17, 31, 41]
    samples = model.sample(np.random.default_rng(0), 5000)
    assert (model.max_hyperperiod % samples == 0).all()


def test_utilisations_sum_and_caps():
    rng = np.random.default_rng(1)
    u = utilisations(rng, 6, 0.9, 200)
    assert np.allclose(u.sum(axis=1), 0.9) and (u >= 0).all()
    capped = utilisations(rng, 6, 0.9, 20, u_max=0.2)  # binding cap: rejection keeps the uniform law
    assert np.allclose(capped.sum(axis=1), 0.9) and (capped <= 0.2 + 1e-9).all()
    with pytest.raises(ValueError):
        utilisations(rng, 2, 0.9, 1, u_max=0.3)
