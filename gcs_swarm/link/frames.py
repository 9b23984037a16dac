"""Frame conversions used at the MAVLink boundary (spec 1.1).

Inside the ground station: world ENU (x East, y North, z up) metres around the mission origin, body FLU, ZYX
Euler angles `(roll, pitch, yaw)` with yaw counter-clockwise from East. On the wire: lat/lon degrees, altitude
AMSL, NED world and FRD body axes. Every function is vectorised: leading dimensions broadcast, the last axis
holds the components (3 for vectors and Euler angles, 4 for quaternions `(w, x, y, z)`).

Geodesy goes through pymap3d (WGS84). Mission origin altitude and vehicle altitudes (GLOBAL_POSITION_INT.alt,
AMSL) are both used as heights above the ellipsoid: the geoid offset is common to both and cancels in the
local frame to well under a centimetre over a mission area.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
import pymap3d
import pymap3d.ecef
from numpy.typing import ArrayLike, NDArray

from swarm_common.rotations import euler_to_quaternion, quaternion_multiply, wrap_pi

try:  # the fleet's rows converted by compiled loops (the same bits) when numba is there (extra "fast")
    from gcs_swarm.link import link_kernels
except ImportError:  # pragma: no cover - numba is optional
    link_kernels = None  # type: ignore[assignment]

Origin = tuple[float, float, float]
"""Mission origin: latitude deg, longitude deg, altitude m."""

FloatArray = NDArray[np.float64]

# q_ENU<-NED: 180 deg about (1, 1, 0)/sqrt(2); q_FRD<-FLU: 180 deg about x. Both are their own inverse.
_Q_ENU_NED = np.array([0.0, math.sqrt(0.5), math.sqrt(0.5), 0.0])
_Q_FRD_FLU = np.array([0.0, 1.0, 0.0, 0.0])


def geodetic_to_enu(lat_deg: ArrayLike, lon_deg: ArrayLike, alt_m: ArrayLike, origin: Origin) -> FloatArray:
    """Geodetic position(s) -> local ENU metres around `origin`, shape (..., 3).

    pymap3d.geodetic2enu's arithmetic, with the origin's share (its ECEF point, the sines and cosines of its
    latitude and longitude, computed by pymap3d's own functions) kept per origin: a third of the cost of a
    telemetry tick's conversion, the same bits (tests/gcs_swarm/link/test_frames.py)."""
    x0, y0, z0, cos_lat, sin_lat, cos_lon, sin_lon = _enu_origin_terms(origin)
    x, y, z = pymap3d.ecef.geodetic2ecef(
        np.asarray(lat_deg, dtype=float),
        np.asarray(lon_deg, dtype=float),
        np.asarray(alt_m, dtype=float),
        _WGS84,
    )
    u, v, w = x - x0, y - y0, z - z0  # pymap3d.ecef.uvw2enu from here
    t = cos_lon * u + sin_lon * v
    east = -sin_lon * u + cos_lon * v
    up = cos_lat * t + sin_lat * w
    north = -sin_lat * t + cos_lat * w
    return np.stack(np.broadcast_arrays(east, north, up), axis=-1).astype(float)


_WGS84 = pymap3d.Ellipsoid.from_name("wgs84")  # pymap3d's default ellipsoid


@functools.lru_cache(maxsize=8)
def _enu_origin_terms(origin: Origin) -> tuple[Any, ...]:
    """The origin's ECEF point (m) and cos, sin of its latitude and longitude, as pymap3d.geodetic2enu
    computes them on every call (its numpy or math functions, whichever it imported)."""
    lat0, lon0, h0 = origin
    x0, y0, z0 = pymap3d.ecef.geodetic2ecef(lat0, lon0, h0, _WGS84)
    lat_r, lon_r = pymap3d.ecef.radians(lat0), pymap3d.ecef.radians(lon0)
    ecef = pymap3d.ecef
    return x0, y0, z0, ecef.cos(lat_r), ecef.sin(lat_r), ecef.cos(lon_r), ecef.sin(lon_r)


def geodetic_rows_to_enu(geodetic: ArrayLike, origin: Origin) -> FloatArray:
    """(N, 3) rows of lat deg, lon deg, alt m -> (N, 3) ENU m around `origin`: `geodetic_to_enu` of the
    columns, by link_kernels when numba is there (the same bits, about a tenth of the time)."""
    g = np.asarray(geodetic, dtype=float)
    if link_kernels is None or g.ndim != 2 or g.shape[1] != 3:
        return geodetic_to_enu(g[..., 0], g[..., 1], g[..., 2], origin)
    a2, a, b, b_over_a2 = _ELLIPSOID_TERMS
    return link_kernels.geodetic_rows_to_enu(
        np.ascontiguousarray(g), a2, a, b, b_over_a2, _enu_origin_floats(origin)
    )


# pymap3d.ecef.geodetic2ecef's ellipsoid terms: a^2, a, b, (b / a)^2, as it computes them
_ELLIPSOID_TERMS = (
    float(_WGS84.semimajor_axis**2),
    float(_WGS84.semimajor_axis),
    float(_WGS84.semiminor_axis),
    float((_WGS84.semiminor_axis / _WGS84.semimajor_axis) ** 2),
)


@functools.lru_cache(maxsize=8)
def _enu_origin_floats(origin: Origin) -> tuple[float, ...]:
    """`_enu_origin_terms` as 7 floats (link_kernels.geodetic_rows_to_enu's argument)."""
    return tuple(float(term) for term in _enu_origin_terms(origin))


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


def attitude_enu_to_ned(euler_flu_enu: ArrayLike) -> FloatArray:
    """Euler FLU/ENU -> Euler FRD/NED (spec 1.1): roll kept, pitch negated, yaw -> wrap(pi/2 - yaw)."""
    a = np.asarray(euler_flu_enu, dtype=float)
    return np.stack((a[..., 0], -a[..., 1], wrap_pi(0.5 * math.pi - a[..., 2])), axis=-1)


def attitude_ned_to_enu(euler_frd_ned: ArrayLike) -> FloatArray:
    """Euler FRD/NED (MAVLink ATTITUDE) -> Euler FLU/ENU; the map of spec 1.1 is its own inverse."""
    return attitude_enu_to_ned(euler_frd_ned)


def quaternion_ned_to_enu(q_frd_ned: ArrayLike) -> FloatArray:
    """Attitude quaternion body FRD -> world NED (MAVLink) -> body FLU -> world ENU, (..., 4)."""
    return quaternion_multiply(quaternion_multiply(_Q_ENU_NED, q_frd_ned), _Q_FRD_FLU)


def quaternion_enu_to_ned(q_flu_enu: ArrayLike) -> FloatArray:
    """Attitude quaternion body FLU -> world ENU -> body FRD -> world NED (MAVLink), (..., 4)."""
    return quaternion_ned_to_enu(q_flu_enu)


def attitude_target_quaternion(euler_flu_enu: ArrayLike) -> FloatArray:
    """Desired FLU/ENU Euler angles (..., 3) -> SET_ATTITUDE_TARGET quaternion NED -> body FRD (..., 4); a
    fleet's (N, 3) rows by link_kernels when numba is there (the same bits)."""
    e = np.asarray(euler_flu_enu, dtype=float)
    if link_kernels is not None and e.ndim == 2 and e.shape[1] == 3:
        return link_kernels.attitude_target_quaternions(np.ascontiguousarray(e))
    return euler_to_quaternion(attitude_enu_to_ned(e))
