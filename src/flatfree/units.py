"""Unit conversions for the edges only (display, config files that say so).

Everything inside flatfree is SI (m, s, rad, N, N m, kg). A non-SI value appears only at an
edge, and the name that holds it carries its unit (``speed_kph``, ``angle_deg``).
"""

from __future__ import annotations

import math

__all__ = ["G", "deg_to_rad", "rad_to_deg", "kph_to_mps", "mps_to_kph"]

#: Standard gravity [m/s^2] (CGPM 1901, ISO 80000-3).
G = 9.80665


def deg_to_rad(angle_deg):
    """Degrees to radians."""
    return angle_deg * (math.pi / 180.0)


def rad_to_deg(angle_rad):
    """Radians to degrees."""
    return angle_rad * (180.0 / math.pi)


def kph_to_mps(speed_kph):
    """km/h to m/s."""
    return speed_kph / 3.6


def mps_to_kph(speed_mps):
    """m/s to km/h."""
    return speed_mps * 3.6
