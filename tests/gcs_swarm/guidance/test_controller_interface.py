"""The position-controller interface (gcs_swarm.guidance.controller): SMC and PID both implement it, give the
outputs their equations give on a fixed input (worked out by hand below; the same figures the controllers
gave before the interface existed), hover at the reference with U = (0, 0, g), and the fleet controller flies
either one it is handed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_swarm.guidance.controller import CONTROLLERS, PositionController, make_position_controller
from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.params import PAPER_PLAIN, G, PIDParams, SMCAxisGains, SMCParams
from gcs_swarm.guidance.pid import PIDController
from gcs_swarm.guidance.smc import SMCController

DT = 0.02  # s
# Vehicle 0 is off its reference: e1 = x_d - x = (1, -1, 0.5) m, xd_dot - v = (0.5, -0.3, 0.2) m/s,
# xd_ddot = (0.1, 0.2, 0) m/s^2. Vehicle 1 hovers exactly at its reference.
X_D = np.array([[1.0, -2.0, 10.5], [0.0, 0.0, 20.0]])
XD_DOT = np.array([[0.5, 0.0, 0.2], [0.0, 0.0, 0.0]])
XD_DDOT = np.array([[0.1, 0.2, 0.0], [0.0, 0.0, 0.0]])
X = np.array([[0.0, -1.0, 10.0], [0.0, 0.0, 20.0]])
V = np.array([[0.0, 0.3, 0.0], [0.0, 0.0, 0.0]])
HOVER = np.array([0.0, 0.0, G])


def test_both_controllers_implement_the_interface() -> None:
    for name in CONTROLLERS:
        assert isinstance(make_position_controller(name), PositionController), name
    typed: list[PositionController] = [SMCController(SMCParams()), PIDController(PIDParams())]  # mypy checks
    assert all(isinstance(c, PositionController) for c in typed)
    with pytest.raises(ValueError, match="controller must be one of"):
        make_position_controller("lqr")


def test_pid_output_on_a_fixed_input() -> None:
    """U = xd_ddot + kp e + kd (xd_dot - v) + ki sum(e dt) (+g in z), default gains kp 1.2/2.0, kd 2.3/3.0,
    ki 0.05/0.1 (xy/z): after one call the integral holds ki e dt = (0.001, -0.001, 0.001), after two
    twice that."""
    pid = make_position_controller("pid")
    pid.reset(2)
    first = pid(X_D, XD_DOT, XD_DDOT, X, V, DT)
    second = pid(X_D, XD_DOT, XD_DDOT, X, V, DT)
    expected = np.array(
        [
            0.1 + 1.2 * 1.0 + 2.3 * 0.5 + 0.001,  # 2.451
            0.2 + 1.2 * -1.0 + 2.3 * -0.3 - 0.001,  # -1.691
            0.0 + 2.0 * 0.5 + 3.0 * 0.2 + 0.001 + G,  # 11.401
        ]
    )
    np.testing.assert_allclose(first[0], expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(second[0] - first[0], [0.001, -0.001, 0.001], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(first[1], HOVER)
    np.testing.assert_array_equal(second[1], HOVER)


def smc_eq49(e1: float, s: float, xdd: float, gains: SMCAxisGains) -> float:
    """One channel of Eq 49 written out:
    xd_ddot - c1^2 e1 + c1 s + k1 s + k2 |s|^xi1 sgn s + k3 |s|^xi2 sgn s."""
    sgn = math.copysign(1.0, s)
    reaching = gains.k1 * s + sgn * (gains.k2 * abs(s) ** gains.xi1 + gains.k3 * abs(s) ** gains.xi2)
    return xdd - gains.c1**2 * e1 + gains.c1 * s + reaching


def test_smc_output_on_a_fixed_input() -> None:
    """Default gains (xy c1 0.8, z c1 1.0): s = c1 e1 + xd_dot - v = (1.3, -1.1, 0.7) m/s. The first call is
    Eq 49 (estimates start at zero); the second adds the xy disturbance estimate k_d s dt = (0.026, -0.022)
    (k_d = 1/s), z has none; the drag estimate stays 0 (gamma s.v dt < 0 is clipped at 0)."""
    params = SMCParams()
    smc = make_position_controller("smc", smc=params)
    smc.reset(2)
    first = smc(X_D, XD_DOT, XD_DDOT, X, V, DT)
    second = smc(X_D, XD_DOT, XD_DDOT, X, V, DT)
    expected = [
        smc_eq49(1.0, 1.3, 0.1, params.xy),  # 2.86616...
        smc_eq49(-1.0, -1.1, 0.2, params.xy),  # -2.06232...
        smc_eq49(0.5, 0.7, 0.0, params.z) + G,  # 11.87689...
    ]
    np.testing.assert_allclose(first[0], expected, rtol=0, atol=1e-12)
    # the figures the SMC gave before the interface existed, to the last bit
    assert first[0].tolist() == [2.8661640301611855, -2.062327141100404, 11.876896215124424]
    np.testing.assert_allclose(second[0] - first[0], [0.026, -0.022, 0.0], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(first[1], HOVER)
    np.testing.assert_array_equal(second[1], HOVER)


def test_the_papers_plain_smc_is_static_eq49() -> None:
    """With PAPER_PLAIN's control settings (no disturbance estimate, no drag adaptation) every call is the
    same Eq 49: nothing integrates."""
    plain = SMCParams(
        xy=SMCAxisGains(0.8, 1.5, 0.3, 0.05, **PAPER_PLAIN["control.smc.xy"]),  # type: ignore[arg-type]
        **PAPER_PLAIN["control.smc"],  # type: ignore[arg-type]
    )
    smc = make_position_controller("smc", smc=plain)
    smc.reset(2)
    outputs = [smc(X_D, XD_DOT, XD_DDOT, X, V, DT) for _ in range(3)]
    for out in outputs[1:]:
        np.testing.assert_array_equal(out, outputs[0])


@pytest.mark.parametrize("name", CONTROLLERS)
def test_fleet_controller_hovers_with_either_controller(name: str) -> None:
    """Leader at its goal, follower in its slot (20 m behind, beyond the 10 m inter-UAV range), both still
    and level: no force, no error, so level attitude, the leader's heading and thrust acceleration g."""
    offsets = np.array([[0.0, 0.0, 0.0], [-20.0, 0.0, 0.0]])
    pos = offsets + [0.0, 0.0, 20.0]
    zero = np.zeros((2, 3))
    ctl = FleetController(2, 0, offsets, pos[:1], position_controller=make_position_controller(name))
    ctl.reset(pos, zero, np.zeros(2), zero)
    for k in range(3):
        cmd = ctl.tick(k * DT, pos, zero, zero, np.zeros((0, 3)), np.zeros(0), np.ones(2, dtype=bool))
        np.testing.assert_allclose(cmd.roll_d, 0.0, atol=1e-12)
        np.testing.assert_allclose(cmd.pitch_d, 0.0, atol=1e-12)
        np.testing.assert_allclose(cmd.yaw_d, 0.0, atol=1e-12)
        np.testing.assert_allclose(cmd.thrust_acc, G, rtol=0, atol=1e-12)
