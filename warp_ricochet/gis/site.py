"""A map's local coordinates on a site's CRS (pyproj). Local (u, v): metres on the map's plane, u
downrange, v to its left; `local` (2 x 3) takes them to horizontal metres (d downrange, l to the left)
from the shooter. Those are laid on a local azimuthal equidistant projection centred on the shooter
(on the CRS's own datum: distances from the shooter and true bearings exact), d along the true
azimuth, and carried to the CRS by pyproj. The azimuth is clockwise from the CRS's grid north for a
projected CRS (turned to true north by the grid's convergence at the shooter), from true north for a
geographic one."""

from __future__ import annotations

import math

import numpy as np
import pyproj
from pyproj.crs import ProjectedCRS
from pyproj.crs.coordinate_operation import AzimuthalEquidistantConversion

LEVEL = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0))  # `local` of a level map with the shooter above its origin


def parse_crs(text: str):
    """(pyproj.CRS, None) or (None, why it cannot be a site's CRS)."""
    try:
        crs = pyproj.CRS.from_user_input(text)
    except pyproj.exceptions.CRSError:
        return None, 'is not a CRS pyproj knows; give one by an authority code, e.g. "EPSG:32630"'
    if not (crs.is_projected or crs.is_geographic) or len(crs.axis_info) != 2:
        return None, f'is a {crs.type_name}; give a 2D projected or geographic one, e.g. "EPSG:32630"'
    if crs.to_authority() is None:
        return None, 'has no authority code (GeoJSON and GeoTIFF name it by one); give one, e.g. "EPSG:32630"'
    return crs, None


def check_site(crs_text: str, shooter) -> tuple[str, str] | None:
    """None, or (key, why) for a CRS pyproj does not know or a shooter it cannot place."""
    crs, why = parse_crs(crs_text)
    if crs is None:
        return "crs", why
    x, y = shooter
    if crs.is_geographic:
        if not (-180.0 <= x <= 180.0 and -90.0 < y < 90.0):
            return "shooter", "must be [lon, lat] in degrees (lon in [-180, 180], lat in (-90, 90)) in a geographic CRS"
        return None
    lon, lat = pyproj.Transformer.from_crs(crs, crs.geodetic_crs, always_xy=True).transform(x, y)
    back = pyproj.Transformer.from_crs(crs.geodetic_crs, crs, always_xy=True).transform(lon, lat)
    if not all(map(math.isfinite, (lon, lat, *back))) or math.hypot(back[0] - x, back[1] - y) > 1e-3 or abs(lat) >= 90:
        return "shooter", f"is outside the domain of {crs_text}: give [easting, northing] in its units"
    return None


class Georeference:
    """Local map coordinates <-> the site's CRS (module docstring); `azimuth` in degrees."""

    def __init__(self, crs_text: str, shooter, azimuth: float, local=LEVEL):
        crs, why = parse_crs(crs_text)
        if crs is None:
            raise ValueError(f"{crs_text!r} {why}")
        self.crs, self.local = crs, np.asarray(local, dtype=np.float64)
        x, y = map(float, shooter)
        if crs.is_geographic:
            lon, lat = x, y
        else:
            lon, lat = pyproj.Transformer.from_crs(crs, crs.geodetic_crs, always_xy=True).transform(x, y)
        self.aeqd = ProjectedCRS(
            conversion=AzimuthalEquidistantConversion(latitude_natural_origin=lat, longitude_natural_origin=lon),
            geodetic_crs=crs.geodetic_crs,
            name=f"local azimuthal equidistant at the shooter ({lon:.9f}, {lat:.9f})",
        )
        self._to_crs = pyproj.Transformer.from_crs(self.aeqd, crs, always_xy=True)
        self._from_crs = pyproj.Transformer.from_crs(crs, self.aeqd, always_xy=True)
        self.convergence = 0.0  # deg: the grid bearing of true north at the shooter
        if crs.is_projected:
            (x0, x1), (y0, y1) = self._to_crs.transform([0.0, 0.0], [0.0, 1.0])
            self.convergence = math.degrees(math.atan2(x1 - x0, y1 - y0))
        self.true_azimuth = float(azimuth) - self.convergence  # deg clockwise from true north

    def to_aeqd(self, u, v):
        """Local (u, v) -> metres east and north of the shooter on `aeqd` (an exact linear map)."""
        u, v = np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64)
        m, t = self.local, math.radians(self.true_azimuth)
        d, left = m[0, 0] * u + m[0, 1] * v + m[0, 2], m[1, 0] * u + m[1, 1] * v + m[1, 2]
        return d * math.sin(t) - left * math.cos(t), d * math.cos(t) + left * math.sin(t)

    def from_aeqd(self, east, north):
        m, t = self.local, math.radians(self.true_azimuth)
        east, north = np.asarray(east, dtype=np.float64), np.asarray(north, dtype=np.float64)
        d = east * math.sin(t) + north * math.cos(t) - m[0, 2]
        left = -east * math.cos(t) + north * math.sin(t) - m[1, 2]
        inv = np.linalg.inv(m[:, :2])
        return inv[0, 0] * d + inv[0, 1] * left, inv[1, 0] * d + inv[1, 1] * left

    def to_crs(self, u, v):
        """Local (u, v), m -> (x, y) of the CRS (always x first: easting or lon)."""
        return self._to_crs.transform(*self.to_aeqd(u, v))

    def to_local(self, x, y):
        """(x, y) of the CRS -> local (u, v), m."""
        return self.from_aeqd(*self._from_crs.transform(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)))


def local_matrix(setup) -> np.ndarray:
    """`local` (2 x 3) of a run's map (tallies.counts.TallySetup): its axes and origin in horizontal
    metres from the shooter, d along the horizontal part of u, l = up x d (up: -g, else the plane's
    normal u x v). On a level map with the shooter above its origin: LEVEL."""
    u, v = np.asarray(setup.map_u, dtype=np.float64), np.asarray(setup.map_v, dtype=np.float64)
    up = np.asarray(setup.up, dtype=np.float64)
    if not np.any(up):
        up = np.cross(u, v)
    up = up / np.linalg.norm(up)
    d = u - np.dot(u, up) * up
    d /= np.linalg.norm(d)
    left = np.cross(up, d)
    offset = np.asarray(setup.map_origin, dtype=np.float64) - np.asarray(setup.shooter, dtype=np.float64)
    return np.array([[np.dot(u, d), np.dot(v, d), np.dot(offset, d)], [np.dot(u, left), np.dot(v, left), np.dot(offset, left)]])
