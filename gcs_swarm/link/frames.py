"""Frame conversions used at the MAVLink boundary (spec 1.1).

Inside the ground station: world ENU (x East, y North, z up) metres around the mission origin, body FLU, ZYX
Euler angles `(roll, pitch, yaw)` with yaw counter-clockwise from East. On the wire: lat/lon degrees, altitude
AMSL, NED world and FRD body axes. Every function is vectorised: leading dimensions broadcast, the last axis
holds the components (3 for vectors and Euler angles, 4 for quaternions `(w, x, y, z)`).

Geodesy goes through pymap3d (WGS84). Mission origin altitude and vehicle altitudes (GLOBAL_POSITION_INT.alt,
AMSL) are both used as heights above the ellipsoid: the geoid offset is common to both and cancels in the
local frame to well under a centimetre over a mission area. The two conversions of the fleet's rows made on
every tick (positions in, attitude targets out) are compiled loops (swarm_common.jit), called from Python.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pymap3d
import pymap3d.ecef
from numpy.typing import ArrayLike, NDArray

from swarm_common.jit import kernel
from swarm_common.rotations import quaternion_multiply, yaw_ned_enu

Origin = tuple[float, float, float]
"""Mission origin: latitude deg, longitude deg, altitude m."""

FloatArray = NDArray[np.float64]

# q_ENU<-NED: 180 deg about (1, 1, 0)/sqrt(2); q_FRD<-FLU: 180 deg about x. Both are their own inverse.
_Q_ENU_NED = np.array([0.0, math.sqrt(0.5), math.sqrt(0.5), 0.0])
_Q_FRD_FLU = np.array([0.0, 1.0, 0.0, 0.0])


_WGS84 = pymap3d.Ellipsoid.from_name("wgs84")  # pymap3d's default ellipsoid
# pymap3d.ecef.geodetic2ecef's ellipsoid terms: a^2, a, b, (b / a)^2, as it computes them
_ELLIPSOID_TERMS = (
    float(_WGS84.semimajor_axis**2),
    float(_WGS84.semimajor_axis),
    float(_WGS84.semiminor_axis),
    float((_WGS84.semiminor_axis / _WGS84.semimajor_axis) ** 2),
)
_RAD_PER_DEG = math.pi / 180.0  # numpy.radians(x) = x * (pi / 180)


@functools.lru_cache(maxsize=8)
def _enu_origin_terms(origin: Origin) -> tuple[float, ...]:
    """The origin's ECEF point (m) and cos, sin of its latitude and longitude, as pymap3d.geodetic2enu
    computes them on every call (its numpy or math functions, whichever it imported)."""
    lat0, lon0, h0 = origin
    x0, y0, z0 = pymap3d.ecef.geodetic2ecef(lat0, lon0, h0, _WGS84)
    lat_r, lon_r = pymap3d.ecef.radians(lat0), pymap3d.ecef.radians(lon0)
    ecef = pymap3d.ecef
    terms = (x0, y0, z0, ecef.cos(lat_r), ecef.sin(lat_r), ecef.cos(lon_r), ecef.sin(lon_r))
    return tuple(float(term) for term in terms)


def geodetic_rows_to_enu(geodetic: ArrayLike, origin: Origin) -> FloatArray:
    """(N, 3) rows of lat deg, lon deg, alt m -> (N, 3) ENU m around `origin`: pymap3d.geodetic2enu's
    arithmetic (geodetic2ecef, then uvw2enu of the offset from the origin's ECEF point)."""
    rows = np.ascontiguousarray(np.asarray(geodetic, dtype=np.float64).reshape(-1, 3))
    a2, a, b, b_over_a2 = _ELLIPSOID_TERMS
    return _geodetic_rows_to_enu(rows, a2, a, b, b_over_a2, _enu_origin_terms(origin))  # type: ignore[no-any-return]


@kernel
def _geodetic_rows_to_enu(
    geodetic: np.ndarray, a2: float, a: float, b: float, b_over_a2: float, origin_terms: tuple[float, ...]
) -> np.ndarray:
    """geodetic_rows_to_enu with the origin's `origin_terms` (x0, y0, z0 ECEF m, cos lat0, sin lat0, cos
    lon0, sin lon0) and the ellipsoid's semimajor axis `a` m, its square `a2`, semiminor axis `b` m and
    (b / a)^2."""
    x0, y0, z0, cos_lat0, sin_lat0, cos_lon0, sin_lon0 = origin_terms
    n = geodetic.shape[0]
    out = np.empty((n, 3))
    for i in range(n):
        lat = geodetic[i, 0] * _RAD_PER_DEG
        lon = geodetic[i, 1] * _RAD_PER_DEG
        alt = geodetic[i, 2]
        cos_lat, sin_lat = math.cos(lat), math.sin(lat)
        # pymap3d.ecef.geodetic2ecef
        prime = a2 / math.hypot(a * cos_lat, b * sin_lat)  # radius of curvature of the prime vertical
        x = (prime + alt) * cos_lat * math.cos(lon)
        y = (prime + alt) * cos_lat * math.sin(lon)
        z = (prime * b_over_a2 + alt) * sin_lat
        # pymap3d.ecef.uvw2enu of the offset from the origin
        u, v, w = x - x0, y - y0, z - z0
        t = cos_lon0 * u + sin_lon0 * v
        out[i, 0] = -sin_lon0 * u + cos_lon0 * v
        out[i, 1] = -sin_lat0 * t + cos_lat0 * w
        out[i, 2] = cos_lat0 * t + sin_lat0 * w
    return out


def enu_to_geodetic(enu: ArrayLike, origin: Origin) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Local ENU metres (..., 3) around `origin` -> (lat deg, lon deg, alt m), each of shape (...)."""
    p = np.asarray(enu, dtype=float)
    lat, lon, alt = pymap3d.enu2geodetic(p[..., 0], p[..., 1], p[..., 2], origin[0], origin[1], origin[2])
    return np.asarray(lat, dtype=float), np.asarray(lon, dtype=float), np.asarray(alt, dtype=float)


def ned_to_enu(v: ArrayLike) -> FloatArray:
    """NED vector(s) (..., 3) -> ENU: `(y, x, -z)` (spec 1.1). Same map as `enu_to_ned`."""
    a = np.asarray(v, dtype=float)
    return np.stack((a[..., 1], a[..., 0], -a[..., 2]), axis=-1)


def enu_to_ned(v: ArrayLike) -> FloatArray:
    """ENU vector(s) (..., 3) -> NED: `(y, x, -z)` (spec 1.1)."""
    return ned_to_enu(v)


def quaternion_ned_to_enu(q_frd_ned: ArrayLike) -> FloatArray:
    """Attitude quaternion body FRD -> world NED (MAVLink) -> body FLU -> world ENU, (..., 4)."""
    return quaternion_multiply(quaternion_multiply(_Q_ENU_NED, q_frd_ned), _Q_FRD_FLU)


def attitude_target_quaternion(euler_flu_enu: ArrayLike) -> FloatArray:
    """Desired roll, pitch, yaw rad (body FLU in world ENU) (..., 3) -> SET_ATTITUDE_TARGET quaternion
    (w, x, y, z) world NED -> body FRD (..., 4): roll kept, pitch negated, yaw_ned_enu(yaw) (spec 1.1),
    then ZYX Euler -> quaternion (R = Rz Ry Rx, rotations.euler_to_quaternion's formula)."""
    e = np.asarray(euler_flu_enu, dtype=np.float64)
    rows = np.ascontiguousarray(e.reshape(-1, 3))
    return _attitude_target_quaternions(rows).reshape(e.shape[:-1] + (4,))  # type: ignore[no-any-return]


@kernel
def _attitude_target_quaternions(euler_flu_enu: np.ndarray) -> np.ndarray:
    """attitude_target_quaternion of (N, 3) rows."""
    n = euler_flu_enu.shape[0]
    out = np.empty((n, 4))
    for i in range(n):
        r = euler_flu_enu[i, 0] * 0.5
        p = -euler_flu_enu[i, 1] * 0.5
        y = yaw_ned_enu(euler_flu_enu[i, 2]) * 0.5
        cr, sr = math.cos(r), math.sin(r)
        cp, sp = math.cos(p), math.sin(p)
        cy, sy = math.cos(y), math.sin(y)
        out[i, 0] = cr * cp * cy + sr * sp * sy
        out[i, 1] = sr * cp * cy - cr * sp * sy
        out[i, 2] = cr * sp * cy + sr * cp * sy
        out[i, 3] = cr * cp * sy - sr * sp * cy
    return out


def warm_up() -> None:
    """Compile the two row conversions (or load them from numba's cache) before a tick needs them."""
    rows = np.zeros((1, 3))
    geodetic_rows_to_enu(rows, (0.0, 0.0, 0.0))
    attitude_target_quaternion(rows)
