"""Steady wind direction convention, turbulence statistics and determinism of sitl_sim.vehicle_model.wind."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sitl_sim.vehicle_model.wind import Wind


@pytest.mark.parametrize(
    "direction_deg, expected",
    [(0.0, [0.0, -4.0, 0.0]), (90.0, [-4.0, 0.0, 0.0]), (180.0, [0.0, 4.0, 0.0]), (-90.0, [4.0, 0.0, 0.0])],
)
def test_direction_is_where_the_wind_comes_from(direction_deg, expected):
    wind = Wind(3, seed=1, speed=4.0, direction_deg=direction_deg)
    sample = wind.sample(0.01)
    assert sample.shape == (3, 3)
    assert np.allclose(sample, expected)  # no turbulence: exactly the steady wind, every vehicle


def test_turbulence_is_deterministic_for_a_seed():
    a = Wind(4, seed=42, speed=3.0, direction_deg=45.0, turbulence=2.0)
    b = Wind(4, seed=42, speed=3.0, direction_deg=45.0, turbulence=2.0)
    c = Wind(4, seed=43, speed=3.0, direction_deg=45.0, turbulence=2.0)
    run_a = np.array([a.sample(0.02) for _ in range(50)])
    run_b = np.array([b.sample(0.02) for _ in range(50)])
    run_c = np.array([c.sample(0.02) for _ in range(50)])
    assert np.array_equal(run_a, run_b)
    assert not np.allclose(run_a, run_c)
    assert not np.allclose(run_a[:, 0], run_a[:, 1])  # each vehicle has its own gusts


def test_turbulence_has_configured_std_and_correlation_time():
    sigma, tau, dt = 1.5, 2.0, 0.5
    wind = Wind(200, seed=7, speed=5.0, direction_deg=30.0, turbulence=sigma, time_constant=tau)
    samples = np.array([wind.sample(dt) for _ in range(600)]) - wind.steady
    assert samples.mean() == pytest.approx(0.0, abs=0.05)
    assert samples.std(axis=(0, 1)) == pytest.approx([sigma] * 3, rel=0.05)
    lagged = np.mean(samples[1:] * samples[:-1]) / np.mean(samples * samples)
    assert lagged == pytest.approx(math.exp(-dt / tau), abs=0.03)


def test_set_changes_wind_at_run_time_and_validates():
    wind = Wind(2, seed=0)
    assert np.allclose(wind.sample(0.1), 0.0)
    wind.set(10.0, 270.0, 0.0)  # from the West: blowing East
    assert np.allclose(wind.sample(0.1), [[10.0, 0.0, 0.0]] * 2)
    for bad in ((-1.0, 0.0, 0.0), (1.0, math.nan, 0.0), (1.0, 0.0, -0.5), ("5", 0.0, 0.0)):
        with pytest.raises(ValueError, match="wind"):
            wind.set(*bad)
    with pytest.raises(ValueError, match="dt"):
        wind.sample(-0.1)
    with pytest.raises(ValueError, match="time_constant"):
        Wind(1, seed=0, time_constant=0.0)
    with pytest.raises(ValueError, match="count"):
        Wind(0, seed=0)
