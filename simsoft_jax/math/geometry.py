"""Reference frames of rod centrelines (plain NumPy; run once when a Model is built).

Every function returns nodal frames ``(R, p)`` with shapes ``(n+1, 3, 3)`` and
``(n+1, 3)``, in the rod's base frame (node 0 at the origin with identity rotation), for
nodes placed at the fractions ``u`` (n+1,) of the arc length (0 = base, 1 = tip;
``i / n`` for equal elements; ``RodSpec.node_fractions`` also for a rod whose segments
have their own lengths). Local x is the centreline tangent.

* straight, arc and helix are curves of constant strain ``f0`` and are placed exactly:
  ``H(s) = exp(s f0)`` (the paper's eq. 3 with constant f, spec S25, S32), so helical elements
  represent them without discretization error.
  - arc of radius ``r``: ``f0 = [1, 0, 0, 0, 0, 1/r]`` (bends toward local +y);
  - helix of radius ``a`` and pitch ``c`` (rise per turn), ``b = c / 2 pi``: curvature
    ``a/(a^2+b^2)`` about local z and torsion ``b/(a^2+b^2)`` about local x; the rod
    starts along local x, curving toward local +y; the helix axis is the direction
    ``(torsion, 0, curvature)`` of the base frame.
* start states (``initial.points``, see
  :func:`simsoft_jax.scene.start_frames.initial_frames`): as many points as
  nodes are the nodes themselves; each stress-free frame is turned by the smallest
  rotation onto the chord ``p[i+1] - p[i-1]`` (:func:`chord_tangents`,
  :func:`aligned_frames`);
  other counts are polylines, resampled like the polyline geometry below.
* polyline: nodes at the fractions ``u`` of the arc length along the points; tangents by central
  differences of the nodes; the section axes follow by parallel transport (rotation-
  minimizing frame) from the base frame.
"""
from __future__ import annotations

import numpy as np

from .lie_np import skew


def _exp_se3_np(xi):
    """NumPy SE(3) exponential (..., 4, 4) of twists ``xi`` (..., 6) by scaling and
    squaring of a Taylor series (reference use); one scaling for the whole batch (that
    of its largest twist)."""
    xi = np.asarray(xi, float)
    X = np.zeros(xi.shape[:-1] + (4, 4))
    X[..., :3, :3] = skew(xi[..., 3:])
    X[..., :3, 3] = xi[..., :3]
    norm = max(np.abs(X).sum(axis=-2).max(initial=0.0), 1e-300)
    squarings = max(0, int(np.ceil(np.log2(norm))) + 1)
    Y = X / 2.0**squarings
    E = term = np.broadcast_to(np.eye(4), X.shape)
    for k in range(1, 25):
        term = term @ Y / k
        E = E + term
    for _ in range(squarings):
        E = E @ E
    return E


def _atan_ratio(s, c):
    """``atan2(s, c) / s`` for ``s >= 0`` (elementwise), safe at ``s = 0``: the series
    ``(1 - y/3 + y^2/5 - ...) / c`` in ``y = s^2/c^2`` where ``s < 0.1 c`` (12 terms: below
    1e-24 relative)."""
    small = s * s < 0.01 * c * c
    y = np.where(small, s * s / np.where(small, c * c, 1.0), 0.0)
    series = np.zeros_like(y)
    for k in reversed(range(12)):
        series = series * y + (-1.0) ** k / (2 * k + 1)
    s_safe = np.where(small, 1.0, s)
    return np.where(small, series / np.where(small, c, 1.0), np.arctan2(s_safe, c) / s_safe)


def log_se3_np(R, p):
    """NumPy SE(3) logarithm of poses ``(R, p)`` (..., 3, 3), (..., 3): twists
    ``[T_SO3^-T(w) p; w]`` (..., 6) (the paper's eq. 126, spec S13, S15), ``w`` of angle in
    [0, pi] from the unit quaternion (Shepperd's pivot: the largest of the trace and the
    diagonal), ``T_SO3^-T(w) = I - W/2 + g2 W^2`` with ``g2 = (1 - (phi/2) cot(phi/2)) /
    phi^2`` (spec S6; its series below phi = 1 rad, spec S24). Used once per model build
    (the reference twists), where a compiled program would cost more than it saves."""
    R, p = np.asarray(R, float), np.asarray(p, float)
    tr = np.trace(R, axis1=-2, axis2=-1)
    a = lambda i, j: R[..., i, j]  # noqa: E731
    candidates = np.stack([
        np.stack([1.0 + tr, a(2, 1) - a(1, 2), a(0, 2) - a(2, 0), a(1, 0) - a(0, 1)], -1),
        np.stack([a(2, 1) - a(1, 2), 1.0 + 2 * a(0, 0) - tr, a(0, 1) + a(1, 0),
                  a(0, 2) + a(2, 0)], -1),
        np.stack([a(0, 2) - a(2, 0), a(0, 1) + a(1, 0), 1.0 + 2 * a(1, 1) - tr,
                  a(1, 2) + a(2, 1)], -1),
        np.stack([a(1, 0) - a(0, 1), a(0, 2) + a(2, 0), a(1, 2) + a(2, 1),
                  1.0 + 2 * a(2, 2) - tr], -1)], -2)
    pivot = np.argmax(np.stack([tr, a(0, 0), a(1, 1), a(2, 2)], -1), axis=-1)
    q = np.take_along_axis(candidates, pivot[..., None, None], axis=-2)[..., 0, :]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    q = np.where(q[..., :1] < 0, -q, q)
    s = np.linalg.norm(q[..., 1:], axis=-1)
    w = (2.0 * _atan_ratio(s, q[..., 0]))[..., None] * q[..., 1:]
    x = np.sum(w * w, axis=-1)
    small = x < 1.0
    g2_series = np.polynomial.polynomial.polyval(x, _G2_SERIES)
    phi = np.sqrt(np.where(small, 1.0, x))
    g2 = np.where(small, g2_series,
                  (1.0 - 0.5 * phi / np.tan(0.5 * phi)) / np.where(small, 1.0, x))
    Wp = np.cross(w, p)
    U = p - 0.5 * Wp + g2[..., None] * np.cross(w, Wp)
    return np.concatenate([U, w], axis=-1)


# Taylor coefficients of g2 = (1 - (phi/2) cot(phi/2)) / phi^2 in x = phi^2 (Bernoulli
# numbers: 1/12, 1/720, 1/30240, ...; spec S6 table)
_G2_SERIES = np.array([1 / 12, 1 / 720, 1 / 30240, 1 / 1209600, 1 / 47900160,
                       691 / 1307674368000, 1 / 74724249600, 3617 / 10670622842880000,
                       43867 / 5109094217170944000, 174611 / 802857662698291200000])


def constant_strain_frames(strain, length, fractions):
    """Frames ``exp(s_i f0)`` at ``s_i = u_i L`` (spec S25 with constant f)."""
    s = np.asarray(fractions, float) * length
    H = _exp_se3_np(s[:, None] * np.asarray(strain, float))
    return H[:, :3, :3], H[:, :3, 3]


def arc_strain(radius):
    """Reference strain ``f0`` (6,) of a circular arc bending toward local +y."""
    return np.array([1.0, 0.0, 0.0, 0.0, 0.0, 1.0 / radius])


def helix_strain(radius, pitch):
    """Reference strain ``f0`` (6,) of a circular helix (radius, rise per turn), unit speed."""
    b = pitch / (2.0 * np.pi)
    denom = radius**2 + b**2
    return np.array([1.0, 0.0, 0.0, b / denom, 0.0, radius / denom])


def polyline_points(points, fractions):
    """Points at the fractions ``u`` (n,) of the arc length along a polyline ``points``
    (P,3)."""
    points = np.asarray(points, float)
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    targets = np.asarray(fractions, float) * cum[-1]
    return np.stack([np.interp(targets, cum, points[:, k]) for k in range(3)], axis=1)


def _rotation_between(a, b):
    """Smallest rotation taking unit vector ``a`` to unit vector ``b`` (3,3)."""
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    if c < -1.0 + 1e-12:  # opposite: turn by pi about any axis normal to a
        axis = np.cross(a, [1.0, 0.0, 0.0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(a, [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis)
        return 2.0 * np.outer(axis, axis) - np.eye(3)
    V = skew(v)
    return np.eye(3) + V + V @ V / (1.0 + c)


def chords(points):
    """Chord ``p[i+1] - p[i-1]`` at every point of ``points`` (P,3), one-sided at the ends
    (``p[1] - p[0]``, ``p[-1] - p[-2]``); not normalized."""
    p = np.asarray(points, float)
    c = np.empty_like(p)
    c[1:-1] = p[2:] - p[:-2]
    c[0], c[-1] = p[1] - p[0], p[-1] - p[-2]
    return c


def chord_tangents(points):
    """Unit tangents ``chords(points) / |chords(points)|`` (P,3)."""
    c = chords(points)
    return c / np.linalg.norm(c, axis=1, keepdims=True)


def aligned_frames(R, tangents):
    """Each frame ``R[i]`` (n,3,3) turned by the smallest rotation taking its x axis to the
    unit vector ``tangents[i]`` (n,3). A frame whose x axis already is that vector is
    returned unchanged (bit for bit)."""
    return np.array([_rotation_between(Ri[:, 0], ti) @ Ri for Ri, ti in zip(R, tangents)])


def polyline_frames(points, fractions, start_rotation=None):
    """Frames of the nodes at ``fractions`` (n+1,) of a polyline's arc length
    (rotation-minimizing, see module doc).

    ``start_rotation`` (3,3) is the frame whose y, z axes are transported (default I).
    Positions are returned as given (no shift to the origin).
    """
    nodes = polyline_points(points, fractions)
    tangents = np.gradient(nodes, axis=0)
    tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
    R = np.empty((len(nodes), 3, 3))
    current = np.eye(3) if start_rotation is None else np.asarray(start_rotation, float)
    previous_tangent = current[:, 0]
    for i, t in enumerate(tangents):
        current = _rotation_between(previous_tangent, t) @ current
        R[i] = current
        previous_tangent = t
    return R, nodes


def reference_frames(geometry, fractions):
    """Stress-free frames of the nodes at ``fractions`` (n+1,) of the arc length of a
    :class:`~simsoft_jax.scene.scene.GeometrySpec`, in the base frame."""
    if geometry.kind == "straight":
        return constant_strain_frames([1.0, 0, 0, 0, 0, 0], geometry.length, fractions)
    if geometry.kind == "arc":
        length = geometry.radius * np.deg2rad(geometry.angle_deg)
        return constant_strain_frames(arc_strain(geometry.radius), length, fractions)
    if geometry.kind == "helix":
        return constant_strain_frames(helix_strain(geometry.radius, geometry.pitch),
                                      geometry.arc_length, fractions)
    if geometry.kind == "polyline":
        R, p = polyline_frames(geometry.points, fractions)
        return R, p - p[0]
    raise ValueError(f"geometry.kind: unknown kind {geometry.kind!r}")


def element_turns(geometry, fractions):
    """Angle (rad) of each element's stress-free relative rotation, (n,), for the nodes at
    ``fractions`` (n+1,) of the arc length.

    Arc: ``angle du``; helix: ``(arc length du) / sqrt(a^2 + b^2)`` (the
    magnitude of its curvature-torsion vector); straight: 0; polyline: the angle between
    the node tangents at the element's two ends (the frames are parallel-transported), pi
    where a node has no tangent (the polyline folds back onto itself there).
    """
    du = np.diff(np.asarray(fractions, float))
    if geometry.kind == "straight":
        return np.zeros_like(du)
    if geometry.kind == "arc":
        return np.deg2rad(geometry.angle_deg) * du
    if geometry.kind == "helix":
        b = geometry.pitch / (2.0 * np.pi)
        return geometry.arc_length * du / np.hypot(geometry.radius, b)
    nodes = polyline_points(geometry.points, fractions)
    tangents = np.gradient(nodes, axis=0)
    norms = np.linalg.norm(tangents, axis=1)
    scale = np.linalg.norm(np.diff(nodes, axis=0), axis=1).max()
    unit = tangents / np.where(norms > 1e-12 * scale, norms, np.inf)[:, None]
    cos = np.clip(np.einsum("ij,ij->i", unit[:-1], unit[1:]), -1.0, 1.0)
    degenerate = (norms[:-1] <= 1e-12 * scale) | (norms[1:] <= 1e-12 * scale)
    return np.where(degenerate, np.pi, np.arccos(cos))


def _constant_strain(geometry):
    """Reference strain f0 (6,) of a straight, arc or helix geometry."""
    if geometry.kind == "straight":
        return np.array([1.0, 0, 0, 0, 0, 0])
    if geometry.kind == "arc":
        return arc_strain(geometry.radius)
    return helix_strain(geometry.radius, geometry.pitch)


def frames_at(geometry, fractions, nodes):
    """Stress-free frames ``{node: (R, p)}`` (base frame) of the given nodes only (the
    constant-strain shapes are evaluated at those nodes, not along the whole rod);
    ``fractions`` (n+1,) place all the nodes."""
    if geometry.kind == "polyline":
        R, p = reference_frames(geometry, fractions)
        return {i: (R[i], p[i]) for i in nodes}
    f0, length = _constant_strain(geometry), geometry.arc_length
    return {i: (H[:3, :3], H[:3, 3]) for i in nodes
            for H in [_exp_se3_np(fractions[i] * length * f0)]}


def element_chords(geometry, fractions):
    """Distance (m) between the two end nodes of each element of the stress-free shape,
    (n,), for the nodes at ``fractions`` (n+1,). A constant-strain shape's chord depends
    only on the element's length: one is computed per distinct length."""
    if geometry.kind == "polyline":
        p = polyline_points(geometry.points, fractions)
        return np.linalg.norm(np.diff(p, axis=0), axis=1)
    du = np.diff(np.asarray(fractions, float))
    sizes, which = np.unique(du, return_inverse=True)
    f0 = _constant_strain(geometry)
    chord = np.array([np.linalg.norm(constant_strain_frames(f0, geometry.arc_length,
                                                            [0.0, u])[1][1]) for u in sizes])
    return chord[which]
