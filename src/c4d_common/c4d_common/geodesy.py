"""Local ENU frame ↔ WGS-84 geodetic coordinates around a home origin.

Local tangent plane with the ellipsoid's meridian and prime-vertical radii of curvature at
the origin: east = ΔλR_N cos φ0, north = Δφ R_M, up = Δh. Accurate to centimetres within a few
kilometres of home, which covers multirotor operations; both the simulator and the estimator
use this one definition so their frames agree exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

A = 6378137.0  # WGS-84 semi-major axis [m]
E2 = 6.69437999014e-3  # first eccentricity squared


@dataclass(frozen=True)
class GeoOrigin:
    latitude: float  # [deg]
    longitude: float  # [deg]
    altitude: float  # [m] AMSL

    @property
    def _radii(self) -> tuple[float, float]:
        s = math.sin(math.radians(self.latitude))
        w = math.sqrt(1.0 - E2 * s * s)
        return A * (1.0 - E2) / (w ** 3), A / w  # meridian R_M, prime vertical R_N

    def to_enu(self, latitude: float, longitude: float, altitude: float) -> tuple[float, float, float]:
        rm, rn = self._radii
        north = math.radians(latitude - self.latitude) * rm
        east = math.radians(longitude - self.longitude) * rn * math.cos(math.radians(self.latitude))
        return east, north, altitude - self.altitude

    def to_geodetic(self, east: float, north: float, up: float) -> tuple[float, float, float]:
        rm, rn = self._radii
        latitude = self.latitude + math.degrees(north / rm)
        longitude = self.longitude + math.degrees(east / (rn * math.cos(math.radians(self.latitude))))
        return latitude, longitude, self.altitude + up


def pressure_at_altitude(altitude: float) -> float:
    """ISA troposphere static pressure [Pa] at an AMSL altitude [m]."""
    return float(101325.0 * (1.0 - 2.25577e-5 * altitude) ** 5.25588)


def altitude_at_pressure(pressure: float) -> float:
    """Inverse of pressure_at_altitude [m]."""
    return float((1.0 - (pressure / 101325.0) ** (1.0 / 5.25588)) / 2.25577e-5)
