"""The PID baseline on the spec 11.2 reference: it tracks, and its integral is limited."""

from __future__ import annotations

import numpy as np

from gcs_swarm.guidance.params import G, PIDParams
from gcs_swarm.guidance.pid import PIDController
from tests.gcs_swarm.guidance.spec_reference import spec_reference


def test_pid_tracks_and_limits_its_integral():
    ctl = PIDController(PIDParams())
    ctl.reset(1)
    dt = 0.01
    x, v = np.zeros((1, 3)), np.zeros((1, 3))
    for k in range(3000):
        xd, vd, ad = spec_reference(k * dt)
        u = ctl(xd, vd, ad, x, v, dt)
        v = v + (u - np.array([0.0, 0.0, G])) * dt
        x = x + v * dt
    assert np.abs(spec_reference(3000 * dt)[0] - x).max() < 0.05
    ctl.reset(1)
    far = np.full((1, 3), 1e4)
    zero = np.zeros((1, 3))
    for _ in range(1000):
        ctl(far, zero, zero, zero, zero, 0.1)
    assert np.all(np.abs(ctl.integral) <= PIDParams().i_limit)
    ctl.reset_rows(np.array([True]))
    assert not ctl.integral.any()
