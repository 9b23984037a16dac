"""The compiled step-4 shaping (gcs_swarm.guidance.shaping_kernels) gives the same bits as the numpy
functions it mirrors (shaping.shape_vel_accel_xy, shape_vel_accel), for random rows that reach every branch
(zero, tiny and huge errors, demands along and across the velocity, limits hit or not) and for rows with
+-inf, +-0, huge values and zero or infinite limits, NaN outputs included; its scalar helpers follow numpy's
NaN and signed-zero rules.

One thing is left to the compiler: when two NaNs meet in one commutative operation, x86 returns the first
operand's, and which operand is first is the compiler's choice (LLVM reorders, as numpy's own loops may), so
with NaN inputs the sign of a NaN output may differ. Those rows are checked to be NaN in the same places and
bit-identical elsewhere. (In the tick such rows are inactive vehicles, whose reference state is kept, not
shaped: the closed-loop replay, test_tick_replay.py, compares every byte with the numpy path.)"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from gcs_swarm.guidance.shaping import shape_vel_accel, shape_vel_accel_xy

kernels = pytest.importorskip("gcs_swarm.guidance.shaping_kernels")

FINITE_AND_INF = [0.0, -0.0, 1.0, -1.0, 0.5, 1e-300, -1e-300, 1e300, -1e300, np.inf, -np.inf]
SPECIAL = np.array([*FINITE_AND_INF, np.nan, -np.nan])
DT = 0.02


def _numpy_reference(v_cmd, a_ff, vel, accel, accel_xy, jerk_xy, accel_z, jerk_z, dt):
    out = np.empty_like(v_cmd)
    with np.errstate(all="ignore"):
        out[:, :2] = shape_vel_accel_xy(
            v_cmd[:, :2], a_ff[:, :2], vel[:, :2], accel[:, :2], accel_xy, jerk_xy, dt
        )
        out[:, 2] = shape_vel_accel(v_cmd[:, 2], a_ff[:, 2], vel[:, 2], accel[:, 2], accel_z, jerk_z, dt)
    return out


def _rows(
    rng: np.random.Generator, n: int, special_share: float, special: np.ndarray = SPECIAL
) -> list[np.ndarray]:
    """v_cmd, a_ff, vel, accel (N, 3) and accel_xy, jerk_xy, jerk_z (N,): errors from 1e-6 to 100 m/s,
    demands along, against and across the velocity, some exactly equal, a share replaced by special values."""
    scale = 10.0 ** rng.uniform(-6, 2, (n, 1))
    vel = rng.normal(0.0, 5.0, (n, 3))
    v_cmd = vel + rng.normal(0.0, 1.0, (n, 3)) * scale
    v_cmd[::5] = vel[::5] * rng.uniform(-2.0, 3.0, (len(vel[::5]), 1))  # along / against the velocity
    v_cmd[1::7] = vel[1::7]  # no error
    v_cmd[2::9, :2] = 0.0  # no horizontal demand
    a_ff = rng.normal(0.0, 2.0, (n, 3)) * (rng.uniform(size=(n, 1)) < 0.5)
    accel = rng.normal(0.0, 2.0, (n, 3))
    accel_xy = rng.choice([1.0, 2.5, 5.0, 6.9], n)
    jerk_xy = rng.choice([1.0, 5.0, 12.0, 30.0], n)
    jerk_z = rng.choice([2.0, 5.0, 20.0], n)
    arrays = [v_cmd, a_ff, vel, accel, accel_xy, jerk_xy, jerk_z]
    for a in arrays:
        mask = rng.uniform(size=a.shape) < special_share
        a[mask] = rng.choice(special, int(mask.sum()))
    return arrays


def _kernel(v_cmd, a_ff, vel, accel, accel_xy, jerk_xy, accel_z, jerk_z, dt):
    return kernels.shape_reference_acceleration(
        v_cmd, a_ff, vel, accel, accel_xy, jerk_xy, accel_z, jerk_z, dt
    )


@pytest.mark.parametrize(("seed", "special_share"), [(0, 0.0), (1, 0.0), (2, 0.02), (3, 0.1), (4, 0.4)])
@pytest.mark.parametrize("dt", [DT, 0.0])
def test_the_kernel_gives_the_numpy_bits(seed: int, special_share: float, dt: float) -> None:
    """Bitwise equal (tobytes: signed zeros and the NaNs that inf - inf, 0 * inf... make) to the numpy
    reference, 4000 rows without NaN inputs."""
    rng = np.random.default_rng(seed)
    rows = _rows(rng, 4000, special_share, np.array(FINITE_AND_INF))
    for accel_z in (2.5, 0.0):
        args = (*rows[:6], accel_z, rows[6], dt)
        assert _kernel(*args).tobytes() == _numpy_reference(*args).tobytes()


@pytest.mark.parametrize(("seed", "special_share"), [(5, 0.02), (6, 0.1), (7, 0.4)])
def test_with_nan_inputs_only_the_sign_of_nan_outputs_may_differ(seed: int, special_share: float) -> None:
    """NaN and infinite inputs and limits (accel_z NaN or inf too): NaN in the same places, every other
    element bit-identical."""
    rng = np.random.default_rng(seed)
    rows = _rows(rng, 4000, special_share)
    for accel_z in (2.5, np.inf, np.nan):
        args = (*rows[:6], accel_z, rows[6], DT)
        got, expected = _kernel(*args), _numpy_reference(*args)
        assert (np.isnan(got) == np.isnan(expected)).all()
        assert got[~np.isnan(got)].tobytes() == expected[~np.isnan(expected)].tobytes()
        assert np.isnan(expected).any() and not np.isnan(expected).all()


def test_the_kernel_takes_column_views_and_small_fleets() -> None:
    """Non-contiguous inputs (views) and N = 0, 1 give the numpy bits."""
    rng = np.random.default_rng(5)
    for n in (0, 1, 3):
        v_cmd, a_ff, vel, accel, accel_xy, jerk_xy, jerk_z = _rows(rng, n, 0.0)
        wide = np.zeros((n, 6))
        wide[:, ::2] = a_ff
        expected = _numpy_reference(v_cmd, wide[:, ::2], vel, accel, accel_xy, jerk_xy, 2.5, jerk_z, DT)
        got = _kernel(v_cmd, wide[:, ::2], vel, accel, accel_xy, jerk_xy, 2.5, jerk_z, DT)
        assert got.shape == (n, 3) and got.tobytes() == expected.tobytes()


@pytest.mark.parametrize(
    ("helper", "reference"),
    [
        ("_maximum", np.maximum),
        ("_sign", lambda a, _: np.sign(a)),
    ],
)
def test_the_binary_helpers_follow_numpy(helper, reference) -> None:
    """Every pair of special values (NaN sign, +-0 order) for each array length numpy loops differently."""
    function = getattr(kernels, helper)
    for a, b in itertools.product(SPECIAL, repeat=2):
        for n in (1, 17):
            expected = reference(np.full(n, a), np.full(n, b))[-1]
            assert (
                np.float64(function(a, b) if helper != "_sign" else function(a)).tobytes()
                == expected.tobytes()
            )


def test_the_clips_follow_numpy() -> None:
    """np.clip's NaN and signed-zero rules, with per-row bounds (_clip) and scalar bounds (_clip_to_scalars),
    for every triple of special values and array lengths numpy loops over differently."""
    for x, lo, hi in itertools.product(SPECIAL, repeat=3):
        for n in (1, 17):
            with np.errstate(all="ignore"):
                per_row = np.clip(np.full(n, x), np.full(n, lo), np.full(n, hi))[-1]
                scalar = np.clip(np.full(n, x), lo, hi)[-1]
            assert np.float64(kernels._clip(x, lo, hi)).tobytes() == per_row.tobytes(), (x, lo, hi)
            assert np.float64(kernels._clip_to_scalars(x, lo, hi)).tobytes() == scalar.tobytes(), (x, lo, hi)
