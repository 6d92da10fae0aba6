"""Tracks: the known spatial path a vehicle moves along.

A track is a smooth curve in geodetic coordinates (latitude, longitude, height on an
:class:`~navsim.earth.EarthModel`) parameterised by its *true* arc length s, with
annotations (tunnels, stations, urban canyons) by arc length and a cant (superelevation)
profile. Every track satisfies the :class:`Track` protocol that the motion module codes
against; :func:`track_frame` turns a track into the tangent, heading, pitch, curvature and
cant the truth is built from.

Two families:

* :class:`PolynomialTrack` - the spatial track model of seed 003: longitude as a polynomial
  of latitude, lambda(P, phi), and height h(A, lambda, phi) = sum a_ij lambda^i phi^j
  composed into h(A, P, phi) = h(A, lambda(P, phi), phi) (003, introduction), or directly
  a polynomial h(phi). :class:`PiecewisePolynomialTrack` is its piecewise (spline)
  generalisation produced by :func:`fit_polynomial_track`.
* :class:`SplineTrack` - a quintic B-spline (C^4) through or near waypoints
  (lat, lon, h), e.g. from a GeoJSON / GPX / CSV file (:mod:`navsim.trackio`).

Arc length
----------
Each track is first a curve X(u) = [lat, lon, h](u) in some convenient parameter u
(latitude for the polynomial tracks, cumulative chord length for splines). Its speed
sigma(u) = ds/du = |[(R_N + h) lat', (R_E + h) cos(lat) lon', h']| is integrated by
composite 8-point Gauss-Legendre quadrature on a fine table of u; the inverse u(s) starts
from a quintic Hermite interpolant of that table (it uses du/ds = 1/sigma and
d2u/ds2 = -sigma'/sigma^3 at the nodes), already within ~1e-11 m on the bundled tracks,
and is refined by one Newton step on the exact integral (quadratic convergence), so
``geodetic(s)`` is exact to rounding (|s(u(s)) - s| < 4e-12 m on the 35 km mountain
railway). The derivatives with respect to s follow by the chain rule::

    d1 = X' / sigma,    d2 = X'' / sigma^2 - X' sigma' / sigma^3

and are analytic (no finite differences anywhere).

Cant
----
:class:`CantModel`: none, or railway design cant from curvature,
tan(cant) = v_design^2 kappa / g, saturated smoothly at ``max_cant``
(``c = x / (1 + (x / c_max)^8)^(1/8)``, C-infinity, within 0.05 % of x for
|x| < c_max / 2) so the cant stays as smooth as the curvature. The curvature used for cant
is the geodesic curvature of the horizontal projection computed with the radii frozen at
the track's reference point (relative error ~ (h + Delta R) / R < 1e-4 against the exact
:attr:`TrackFrame.curvature`; it needs only third derivatives of the curve).
Positive cant = roll right side down, i.e. a right-hand curve (positive curvature) has
positive cant.

Sign conventions: heading clockwise from north, pitch = grade angle (up positive),
curvature positive turning right; see :class:`TrackFrame`.

Modules
-------
* :mod:`~navsim.track.base`: :class:`TrackSegment`, the :class:`Track` protocol,
  :class:`TrackFrame`, :class:`CantModel`.
* :mod:`~navsim.track.arclength`: the arc-length engine every track is built on.
* :mod:`~navsim.track.latitude`: :class:`PolynomialTrack`, :class:`PiecewisePolynomialTrack`.
* :mod:`~navsim.track.spline`: :class:`SplineTrack`.
* :mod:`~navsim.track.frame`: :func:`track_frame`, :func:`segment_mask`, :func:`with_cant`.
* :mod:`~navsim.track.fitting`: :func:`fit_polynomial_track`, :class:`PolynomialFit`.
* Track files and the bundled tracks: :mod:`navsim.trackio`.

References
----------
.. [1] Sokolov S.V., Vdovichenko S.S. (2012), seed 003: the spatial track models
       lambda(P, phi), h(A, lambda, phi), h(A, P, phi) and the derivatives the filter uses
       (V_X = dlambda/dphi V_Y cos(phi), V_Z = dh/dphi V_Y / (r + h)).
.. [2] Groves P.D., Principles of GNSS, Inertial, and Multisensor Integrated Navigation
       Systems, 2nd ed., 2013, sec. 2.4: curvilinear position, radii of curvature.
.. [3] Lindahl M., Track geometry for high-speed railways, KTH report, 2001: transition
       curves and the cant-curvature relation tan(cant) = v^2 / (g R).
.. [4] de Boor C., A Practical Guide to Splines, 2001 (B-splines; least-squares splines).
"""

from __future__ import annotations

from .base import CantModel, Track, TrackFrame, TrackSegment
from .fitting import PolynomialFit, fit_polynomial_track
from .frame import segment_mask, track_frame, with_cant
from .latitude import PiecewisePolynomialTrack, PolynomialTrack
from .spline import MAX_WAYPOINT_TURN_DEG as MAX_WAYPOINT_TURN_DEG
from .spline import MIN_SPLINE_WAYPOINTS as MIN_SPLINE_WAYPOINTS
from .spline import SplineTrack

__all__ = [
    "Track",
    "TrackSegment",
    "TrackFrame",
    "CantModel",
    "PolynomialTrack",
    "PiecewisePolynomialTrack",
    "SplineTrack",
    "PolynomialFit",
    "track_frame",
    "fit_polynomial_track",
    "with_cant",
    "segment_mask",
]
