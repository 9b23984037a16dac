"""The compiled field and separation stages (gcs_swarm.guidance.field_kernels) give the same bits as the numpy
functions they mirror, on random scenes with what the closed-loop replay rarely or never produces: sources
unknown since the start (`src_valid` False, NaN positions), NaN evaluation points, vehicles on top of each
other, pairs closing fast, both separation modes, dense and hash-grid pair searches (N above 200)."""

from __future__ import annotations

import numpy as np
import pytest

from gcs_swarm.guidance.failsafe_speed import _brake_table, failsafe_speed_caps
from gcs_swarm.guidance.field import obstacle_repulsion
from gcs_swarm.guidance.params import FieldParams, SeparationParams
from gcs_swarm.guidance.separation import closing_speed_caps, uav_repulsion

fk = pytest.importorskip("gcs_swarm.guidance.field_kernels")


def _scene(n: int, seed: int) -> dict[str, np.ndarray]:
    """Vehicles on a 6 m grid with noise (some stacked, some NaN, some unknown sources), obstacles among
    them."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(n)))
    pos = np.column_stack([np.arange(n) % side * 6.0, np.arange(n) // side * 6.0, np.full(n, 30.0)])
    pos += rng.normal(0.0, 1.5, (n, 3))
    pos[rng.choice(n, max(1, n // 20), replace=False)] = pos[0] + 0.01  # stacked on vehicle 0
    vel = rng.normal(0.0, 6.0, (n, 3))
    valid = rng.uniform(size=n) > 0.1
    src = np.where(valid[:, None], pos + rng.normal(0.0, 0.5, (n, 3)), np.nan)
    at = pos.copy()
    at[rng.choice(n, max(1, n // 25), replace=False)] = np.nan
    k = 12
    centres = rng.uniform(pos.min(axis=0) - 5.0, pos.max(axis=0) + 5.0, (k, 3))
    return {
        "pos": pos, "vel": vel, "valid": valid, "src": src, "at": at, "centres": centres,
        "radii": rng.uniform(0.5, 5.0, k), "dest": pos + rng.normal(0.0, 30.0, (n, 3)),
        "ahead": pos + rng.normal(0.0, 4.0, (n, 3)),
    }  # fmt: skip


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("n", [2, 7, 60, 230])
@pytest.mark.parametrize("mode", ["constant", "formula"])
@pytest.mark.parametrize("brake_accel", [0.0, 1.5])
def test_uav_repulsion_is_the_numpy_bits(n: int, mode: str, brake_accel: float) -> None:
    s = _scene(n, n)
    fp, sep = FieldParams(), SeparationParams(mode=mode)
    with np.errstate(all="ignore"):
        force, emergency = uav_repulsion(
            s["at"], s["src"], s["vel"], fp.k_uav, fp.n_uav, 10.0, sep, fp.l_min, src_valid=s["valid"],
            at_vel=s["vel"], brake_accel=brake_accel,
        )  # fmt: skip
        pairs, e_ji, l = fk.uav_pairs(
            s["at"], s["src"], s["vel"], s["vel"], s["valid"], 10.0, fp.l_min, brake_accel
        )
        c_force, c_emergency = fk.uav_forces(
            n, pairs, e_ji, l, l ** (fp.n_uav - 2.0), s["vel"], fp.k_uav, fp.n_uav, 10.0, mode == "formula",
            min(sep.d_emg, 10.0), sep.a_e, sep.s_s,
        )  # fmt: skip
    assert emergency.any() and len(pairs) > 0  # the scene reaches the emergency range
    assert _same(c_force, force) and _same(c_emergency, emergency)


@pytest.mark.parametrize("n", [1, 9, 230])
@pytest.mark.parametrize("method", ["iaapf", "apf"])
@pytest.mark.parametrize("circulation", [0.0, 0.6])
def test_obstacle_repulsion_is_the_numpy_bits(n: int, method: str, circulation: float) -> None:
    s = _scene(n, 100 + n)
    fp = FieldParams(method=method, circulation=circulation)
    at = s["at"]
    with np.errstate(all="ignore"):
        force, _ = obstacle_repulsion(at, s["dest"], s["centres"], s["radii"], fp, ahead=s["ahead"])
        vehicle, l, n_o, n_g, rho = fk.obstacle_pairs(
            at, s["ahead"], s["dest"], s["centres"], s["radii"], fp.l0, fp.l_min
        )
        c_force = fk.obstacle_forces(
            n, vehicle, l, n_o, n_g, rho, rho**fp.n if method == "iaapf" else rho, method == "iaapf",
            fp.k_rep, fp.l0, fp.n, fp.rho_eps, fp.circulation, fp.obstacle_vertical,
        )  # fmt: skip
    assert _same(c_force, force)


@pytest.mark.parametrize("n", [2, 30, 230])
def test_speed_caps_are_the_numpy_bits(n: int) -> None:
    s = _scene(n, 200 + n)
    pos = np.where(s["valid"][:, None], s["pos"], np.nan)
    with np.errstate(all="ignore"):
        closing = closing_speed_caps(pos, s["vel"], s["valid"], 3.0, 2.0, 20.0)
        reach = 3.0 + 1.0 + (2.0 * 20.0) ** 2 / (2.0 * 2.0)
        assert _same(fk.closing_speed_caps(pos, s["vel"], s["valid"], 3.0, 2.0, min(reach, 200.0)), closing)
        failsafe = failsafe_speed_caps(pos, s["vel"], s["centres"], s["radii"], 3.0, 2.5, 3.0, 5.0)
        speeds, distances = _brake_table(2.5, 5.0)
        caps = fk.failsafe_speed_caps(
            pos, s["vel"], s["centres"], s["radii"], 3.0, speeds * 3.0 + distances, speeds
        )
    assert np.isfinite(failsafe).any() and _same(caps, failsafe)
