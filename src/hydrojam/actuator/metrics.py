"""Actuator metrics as pure functions of node positions (docs/actuator.md, "Metrics"), and the one
pass that measures a state with them (:func:`measure`, from the model's :class:`Gauges`).

Every function takes reference positions ``X`` and current positions ``x`` as arrays of shape
(m, 2) in mm, in the (x, z) plane of docs/decisions.md, "Geometry" (a 3D actuator's are (m, 3), (x, y, z),
for :func:`bending_angle_3d_deg` and :func:`enclosed_volume`; the others take its (x, z) columns): x is the bending direction (the
strain-limit layer lies on the -x side), z the actuator axis, the clamp at z = 0 and the free end
at z = -L.

Sign convention for rotations: bending *toward the strain-limit side* swings the tip to -x, which
is a **clockwise** rotation in the (x right, z up) plane, and counts **positive**. For example the
centreline bent into an arc of radius R centred at (-R, 0), from the clamp at the origin, has the
points (-R + R cos p, -R sin p); its tangent at p has turned clockwise by p, and its bending
angle is +p.

The names, units and meanings of the metrics an actuator run reports are defined once here, in
:data:`STATE_METRICS` (measured on a state: :func:`measure`), :data:`RUN_FIELDS`
(about the run: ``SimulationResult.metrics``) and :data:`HISTORY_FIELDS` (the columns of
history.csv); metrics.json, history.csv, the sweep table and the CLI summary derive from them.
"""

from __future__ import annotations

from collections.abc import Hashable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

if TYPE_CHECKING:  # the gauges hold the model's solid and contact; the pure functions need neither
    from hydrojam.fem.assembly import Solid
    from hydrojam.fem.contact import Contact

@dataclass(frozen=True)
class Metric:
    """One reported quantity: its key in the output files, unit, meaning and value type.

    Attributes
    ----------
    name : str
        The key in metrics.json and the column in history.csv / the sweep table.
    unit : str
        "deg", "mm", "1/mm", "K", "k_B T", "s", "-" (dimensionless) or "" (not a quantity).
    description : str
        One line, what the value means.
    type : type
        The Python type of a defined value (float, int, bool or str); any metric may be None
        where it is undefined (never NaN).
    kind : str
        "state" (measured on one state), "run" (about the whole run) or "step" (about one
        accepted load step, in history.csv).
    symbol : str
        A short label for figures and reports ("" where the name serves).
    """

    name: str
    unit: str
    description: str
    type: type
    kind: Literal["state", "run", "step"]
    symbol: str = ""

    @property
    def label(self) -> str:
        """The name and unit, e.g. "bending_angle_deg [deg]" (no unit for "" and "-")."""
        return self.name if self.unit in ("", "-") else f"{self.name} [{self.unit}]"


#: the metrics measured on a state, in the order of metrics.json and history.csv
STATE_METRICS: tuple[Metric, ...] = (
    Metric("bending_angle_deg", "deg", "free-end face rotation, positive toward the strain-limit side "
           "(past 180 for a curled actuator)", float, "state", "θ"),
    Metric("bending_plane_deg", "deg", "direction in x-y toward which the free end swings, from +x toward +y "
           "(180: toward -x, the single chamber's strain-limit side; None while straight)", float, "state", "φ"),
    Metric("twist_deg", "deg", "free-end rotation about the axis left after its swing, right-handed about +z "
           "(None near a half turn of bending)", float, "state", "ψ"),
    Metric("tip_dx_mm", "mm", "free-end face centroid displacement along x", float, "state", "δx"),
    Metric("tip_dy_mm", "mm", "free-end face centroid displacement along y (0 in 2D)", float, "state", "δy"),
    Metric("tip_dz_mm", "mm", "free-end face centroid displacement along z", float, "state", "δz"),
    Metric("curling_index", "-", "share of the centreline rotation in the clamp half (None while straight)",
           float, "state", "curling index"),
    Metric("max_curvature_per_mm", "1/mm", "largest centreline curvature", float, "state", "κ_max"),
    Metric("packing_fraction", "-", "particle area / cavity area (3D: volumes)", float, "state", "φ"),
    Metric("contacts_per_particle", "-", "mean coordination number", float, "state", "Z"),
    Metric("mean_swelling_ratio", "-", "particle area / as-prepared area (3D: volumes)", float, "state"),
    Metric("column_folds", "-", "particle layers out of the column's line: further from the centreline than the "
           "median layer, or not beyond the layer before, by half a particle diameter (0: the column stays one "
           "arc; docs/replicas.md, \"States\")", int, "state", "folds"),
)

#: what a run reports besides its final state's metrics, in the order of metrics.json
RUN_FIELDS: tuple[Metric, ...] = (
    Metric("converged", "", "the target stimulus (s = 1) was reached", bool, "run"),
    Metric("message", "", "the solver's message: why the run stopped, or \"converged\"", str, "run"),
    Metric("s_reached", "-", "load parameter of the last converged state", float, "run", "s"),
    Metric("temperature_K", "K", "temperature of the last converged state", float, "run", "T"),
    Metric("mu_kT", "k_B T", "solvent chemical potential of the last converged state", float, "run", "μ"),
    Metric("load_steps", "-", "accepted load steps", int, "run"),
    Metric("newton_iterations", "-", "Newton iterations in total", int, "run"),
    Metric("rejected_steps", "-", "load steps tried and rejected", int, "run"),
    Metric("wall_time_s", "s", "wall time of the load path and the release (meshing and writing excluded)",
           float, "run"),
    Metric("stabilisation_energy_ratio", "-",
           "largest ratio of stabilisation energy to elastomer strain energy over the path", float, "run"),
    Metric("stabilisation_released", "", "the final state is an equilibrium without the viscous stabilisation",
           bool, "run"),
    Metric("buckled_at_s", "-",
           "first load parameter at which the physical Hessian had a negative eigenvalue: where the path passed "
           "an instability and the answer became path dependent (None: never)", float, "run", "s_b"),
    Metric("unstable_states", "-", "accepted states whose physical Hessian had a negative eigenvalue", int, "run"),
    # time-resolved runs only (stimulus.schedule; None otherwise): docs/actuator.md "Actuation in time"
    Metric("time_s", "s", "time of the last converged state since the particles met the solvent (timed runs)",
           float, "run", "t"),
    Metric("particle_time_constant_s", "s",
           "Tanaka-Fillmore time constant a^2/(pi^2 D) of the kinetics' particle radius a (timed runs)",
           float, "run", "τ"),
    Metric("time_to_90_percent_angle_s", "s",
           "first time the bending angle has made 90% of its change from t = 0 to the last state (timed runs)",
           float, "run", "t90"),
    Metric("swelling_time_to_90_percent_s", "s",
           "first time the free particle's mean ln J has made 90% of its change over the schedule (timed runs)",
           float, "run"),
    Metric("max_bending_angle_deg", "deg", "largest bending angle over the accepted states (timed runs)",
           float, "run", "θ_max"),
    Metric("cycle_return_deg", "deg",
           "on a cycle (last temperature = first): final angle minus the angle when the temperature first "
           "left its start; 0 = full return", float, "run"),
    Metric("hysteresis_deg", "deg",
           "largest gap in bending angle between the heating and the cooling ramps at equal temperature "
           "(schedules that rise and fall)", float, "run"),
)

#: the columns of history.csv, one row per accepted load step
HISTORY_FIELDS: tuple[Metric, ...] = (
    Metric("step", "-", "index of the accepted load step (0: the as-prepared state)", int, "step"),
    Metric("s", "-", "load parameter", float, "step", "s"),
    Metric("mu_kT", "k_B T", "solvent chemical potential", float, "step", "μ"),
    Metric("temperature_K", "K", "temperature", float, "step", "T"),
    Metric("time_s", "s", "time since the particles met the solvent (empty for untimed runs)", float, "step", "t"),
    *STATE_METRICS,
    Metric("newton_iterations", "-", "Newton iterations of this step", int, "step"),
    Metric("wall_time_s", "s", "wall time from the start of the run to this step", float, "step"),
    Metric("negative_eigenvalues", "-",
           "negative eigenvalues of the physical energy's Hessian at this state (0: stable; empty: not checked)",
           int, "step"),
    Metric("residual_N", "N", "residual of the physics alone at this state, the stabilisation left out "
           "(N/mm in 2D): at most tolerance_N at an equilibrium", float, "step"),
    Metric("tolerance_N", "N", "the tolerance the residual is held to: rtol x the forces in play (N/mm in 2D)",
           float, "step"),
)

_BY_NAME = {m.name: m for m in (*STATE_METRICS, *RUN_FIELDS)}


def metric(name: str) -> Metric:
    """The metric or run field (a key of metrics.json) called ``name``.

    Parameters
    ----------
    name : str
        The key, e.g. "bending_angle_deg".

    Returns
    -------
    Metric

    Raises
    ------
    KeyError
        Naming the known ones.
    """
    try:
        return _BY_NAME[name]
    except KeyError:
        raise KeyError(f"{name}: no such metric (known: {', '.join(_BY_NAME)})") from None


def metric_names() -> list[str]:
    """The keys of metrics.json in their order, without ``timings_s``: state metrics, run fields.

    Returns
    -------
    list of str
    """
    return list(_BY_NAME)


def time_to_fraction(times, values, fraction: float = 0.9) -> float | None:
    """First time [s] at which ``values`` has made ``fraction`` of its change from the first to
    the last sample, linear between samples (``times`` increasing); None without a change."""
    t = np.asarray(times, dtype=float)
    v = np.asarray(values, dtype=float)
    change = v[-1] - v[0]
    if t.size < 2 or change == 0.0 or not np.isfinite(change):
        return None
    progress = (v - v[0]) / change
    k = int(np.argmax(progress >= fraction))  # the first sample at or past the fraction
    if k == 0:
        return float(t[0])
    p0, p1 = progress[k - 1], progress[k]
    return float(t[k - 1] + (fraction - p0) / (p1 - p0) * (t[k] - t[k - 1]))


def branch_gap(T_rising, v_rising, T_falling, v_falling, samples: int = 201) -> float | None:
    """Largest |v_rising(T) - v_falling(T)| over the temperatures both branches cover: each branch
    sorted by T and interpolated linearly (meant for one heating and one cooling ramp); None
    when a branch has fewer than 2 samples or the ranges do not overlap."""
    branches = []
    for T, v in ((T_rising, v_rising), (T_falling, v_falling)):
        T, v = np.asarray(T, dtype=float), np.asarray(v, dtype=float)
        if T.size < 2:
            return None
        order = np.argsort(T, kind="stable")
        branches.append((T[order], v[order]))
    lo = max(b[0][0] for b in branches)
    hi = min(b[0][-1] for b in branches)
    if not hi > lo:
        return None
    grid = np.linspace(lo, hi, samples)
    return float(np.max(np.abs(np.interp(grid, *branches[0]) - np.interp(grid, *branches[1]))))


# Below this total rotation [rad] a centreline counts as straight: the curling index is undefined.
STRAIGHT_ROTATION_RAD = 1.0e-3


def _as_points(points, name: str) -> np.ndarray:
    arr = np.asarray(points, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"{name} must have shape (m, 2), got {arr.shape}")
    return arr


def _as_pair(X, x, min_nodes: int) -> tuple[np.ndarray, np.ndarray]:
    X = _as_points(X, "X")
    x = _as_points(x, "x")
    if X.shape != x.shape:
        raise ValueError(f"reference and current positions differ in shape: {X.shape} vs {x.shape}")
    if X.shape[0] < min_nodes:
        raise ValueError(f"need at least {min_nodes} nodes, got {X.shape[0]}")
    return X, x


def _clockwise_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Clockwise angle [rad] from direction(s) a to direction(s) b, in [-pi, pi]."""
    cross = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    dot = np.sum(a * b, axis=-1)
    return -np.arctan2(cross, dot)


def _principal_direction(centred: np.ndarray) -> np.ndarray:
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    return vt[0]


def face_rotation_deg(X_face, x_face) -> float:
    """Rotation [deg] of a face from its reference to its current orientation, positive clockwise.

    The face's orientation is its best-fit line: the principal axis (SVD) of the centred node
    positions. The current axis is oriented like the reference one, with the sign that keeps the
    order of the nodes' projections on it (sum of p_ref * p_cur >= 0), so rotations beyond 90
    degrees are told apart from flips. Positive is clockwise in the (x, z) plane, i.e. toward the
    strain-limit side (-x) for a face at the free end. Result in (-180, 180].

    X_face, x_face: reference and current node positions, shape (m, 2), m >= 2 [mm].
    """
    X, x = _as_pair(X_face, x_face, min_nodes=2)
    P = X - X.mean(axis=0)
    p = x - x.mean(axis=0)
    d_ref = _principal_direction(P)
    d_cur = _principal_direction(p)
    if np.sum((P @ d_ref) * (p @ d_cur)) < 0.0:
        d_cur = -d_cur
    angle = float(np.degrees(_clockwise_angle(d_ref, d_cur)))
    return 180.0 if angle <= -180.0 else angle


def bending_angle_deg(X_face, x_face) -> float:
    """Bending angle theta (docs/actuator.md, "Metrics"): rotation of the free-end face.

    The face rotation (``face_rotation_deg``) of the free-end face's nodes: positive toward the
    strain-limit side (-x, clockwise in the (x, z) plane), in (-180, 180].

    Parameters
    ----------
    X_face, x_face : ndarray, shape (m, 2)
        Reference and current positions of the free-end face's nodes [mm].

    Returns
    -------
    float
        theta [deg].
    """
    return face_rotation_deg(X_face, x_face)


def _best_fit_plane_axis(centred: np.ndarray) -> np.ndarray:
    """The direction in the best-fit plane of centred 3D points that is normal to y, as (x, z).

    The plane's normal n is the last right-singular vector (least spread); y x n lies in the plane
    and in the x-z plane. Falls back to the points' principal direction in (x, z) when the plane
    holds the y axis' normal (n along y: the face turned edge-on to the x-z plane)."""
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    n = vt[-1]
    axis = np.array([n[2], -n[0]])  # (y x n) in (x, z): (n_z, -n_x)
    if np.linalg.norm(axis) < 1e-6:
        return _principal_direction(centred[:, [0, 2]])
    return axis / np.linalg.norm(axis)


def bending_angle_3d_deg(X_face, x_face) -> float:
    """Bending angle theta [deg] of a 3D actuator (docs/actuator.md, "3D"): the rotation about y of
    the free-end face's best-fit plane, positive toward the strain-limit side (-x), in (-180, 180].

    The face's orientation is the line its best-fit plane (least-squares, SVD of the centred node
    positions) cuts in the x-z plane; the current line is oriented like the reference one by the
    order of the nodes' projections on it, and theta is the clockwise angle between the two in
    the (x right, z up) plane, exactly as :func:`face_rotation_deg` in 2D. For a face that only
    turns about y this is its rotation; a twist about the axis or a tilt about x does not count.

    X_face, x_face: reference and current positions of the face's nodes, shape (m, 3), m >= 3 [mm]
    (the half y >= 0 of the face in a half model gives the same plane).
    """
    X, x = np.asarray(X_face, dtype=float), np.asarray(x_face, dtype=float)
    if X.ndim != 2 or X.shape[1] != 3 or X.shape != x.shape or len(X) < 3:
        raise ValueError(f"need reference and current face positions of equal shape (m >= 3, 3), got {X.shape}, {x.shape}")
    P, p = X - X.mean(axis=0), x - x.mean(axis=0)
    d_ref, d_cur = _best_fit_plane_axis(P), _best_fit_plane_axis(p)
    if np.sum((P[:, [0, 2]] @ d_ref) * (p[:, [0, 2]] @ d_cur)) < 0.0:
        d_cur = -d_cur
    angle = float(np.degrees(_clockwise_angle(d_ref, d_cur)))
    return 180.0 if angle <= -180.0 else angle


def face_rotation_matrix(X_face, x_face) -> np.ndarray:
    """The rotation (3, 3) that best carries a face's centred reference node positions onto its
    current ones (least squares: Kabsch's SVD, with the sign fixed to a proper rotation).

    X_face, x_face: (m, 3) positions [mm], m >= 3, not all on one line (a flat face is enough).
    """
    X, x = np.asarray(X_face, dtype=float), np.asarray(x_face, dtype=float)
    if X.ndim != 2 or X.shape[1] != 3 or X.shape != x.shape or len(X) < 3:
        raise ValueError(f"need reference and current face positions of equal shape (m >= 3, 3), got {X.shape}, {x.shape}")
    H = (X - X.mean(axis=0)).T @ (x - x.mean(axis=0))
    U, _, Vt = np.linalg.svd(H)
    sign = 1.0 if np.linalg.det(Vt.T @ U.T) >= 0.0 else -1.0
    return Vt.T @ np.diag([1.0, 1.0, sign]) @ U.T


#: below this [rad] of bending, swing-twist is measured but the bending plane is undefined; within
#: this of a half turn the swing's axis is undefined, and so is the twist
_HALF_TURN_MARGIN = 1.0e-6


def swing_twist_deg(R) -> tuple[float | None, float | None]:
    """The bending plane's direction and the twist [deg] of a free-end rotation ``R`` (3, 3).

    ``R`` is split into a swing (the least rotation taking the axis e_z to R e_z, about an axis
    in x-y) after a twist about e_z: R = S T. The bending plane's direction is that in x-y of the
    free end's outward axis R (-e_z), from +x toward +y: 180 for bending toward -x (the single
    chamber's strain-limit side), 0 toward +x; None below :data:`STRAIGHT_ROTATION_RAD` of swing.
    The twist is T's angle, right-handed about +z, in (-180, 180]; None where the swing is within
    1e-6 rad of a half turn (its axis undefined).
    """
    R = np.asarray(R, dtype=float)
    t = R[:, 2]
    horizontal = float(np.hypot(t[0], t[1]))
    swing = float(np.arctan2(horizontal, t[2]))
    plane = None if swing < STRAIGHT_ROTATION_RAD else float(np.degrees(np.arctan2(-t[1], -t[0])))
    if plane is not None and plane <= -180.0:  # (-180, 180]: a bend toward -x reads 180 whatever the sign of 0
        plane = 180.0
    if 1.0 + t[2] < _HALF_TURN_MARGIN:
        return plane, None
    v = np.array([-t[1], t[0], 0.0])  # e_z x t
    vx = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    S = np.eye(3) + vx + vx @ vx / (1.0 + t[2])  # Rodrigues: e_z onto t
    T = S.T @ R
    twist = float(np.degrees(np.arctan2(T[1, 0], T[0, 0])))
    return plane, (180.0 if twist <= -180.0 else twist)


def enclosed_volume(points, triangles) -> float:
    """Volume [mm^3] enclosed by triangles (k, 3) of node indices into ``points`` (m, 3) [mm],
    oriented consistently: |sum of a . (b x c)| / 6 (the divergence theorem, cones from the
    origin). An open surface whose rim lies on a plane through the origin (a half model's cut
    on y = 0) gives the volume it closes off with that plane: the missing cap adds no cone."""
    p = np.asarray(points, dtype=float)
    t = np.asarray(triangles, dtype=np.int64)
    a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    return abs(float(np.einsum("ij,ij->", a, np.cross(b, c)))) / 6.0


def tip_displacement(X_face, x_face) -> tuple[float, float]:
    """Free-end displacement (docs/actuator.md, "Metrics"): the face centroid's displacement.

    The centroid is the plain mean of the face's nodes, so this is the mean of the node
    displacements (not an area-weighted centroid: with unevenly spaced nodes the two differ).

    Parameters
    ----------
    X_face, x_face : ndarray, shape (m, 2)
        Reference and current positions of the free-end face's nodes [mm].

    Returns
    -------
    dx, dz : float
        The displacement [mm].
    """
    X, x = _as_pair(X_face, x_face, min_nodes=1)
    dx, dz = (x - X).mean(axis=0)
    return float(dx), float(dz)


@dataclass(frozen=True)
class CentrelineProfile:
    """Rotation and curvature along a centreline, nodes ordered from the clamp to the free end.

    Parameters
    ----------
    reference_arc_length : ndarray, shape (m,)
        Arc length from the clamp in the reference state [mm].
    arc_length : ndarray, shape (m,)
        Arc length from the clamp in the current state [mm] (along the polyline).
    rotation : ndarray, shape (m,)
        Rotation of the tangent from its reference direction [rad], positive clockwise (toward
        the strain-limit side, -x), unwrapped along the line: it exceeds pi for a curled actuator.
    curvature : ndarray, shape (m,)
        d(rotation)/d(arc_length) [1/mm], positive when bending toward -x. For a straight
        reference centreline this is the current (signed) curvature.
    """

    reference_arc_length: np.ndarray
    arc_length: np.ndarray
    rotation: np.ndarray
    curvature: np.ndarray

    @property
    def total_rotation_deg(self) -> float:
        """Rotation [deg] accumulated along the centreline, from the clamp node to the free end.

        With the clamp node held (no rotation there) this is the free end's tangent rotation; it
        is not wrapped to (-180, 180].
        """
        return float(np.degrees(self.rotation[-1] - self.rotation[0]))


def _quadratic(s, s0, s1, s2, f0, f1, f2):
    """The quadratic through (s0, f0), (s1, f1), (s2, f2), evaluated at s (Lagrange form)."""
    return (
        f0 * (s - s1) * (s - s2) / ((s0 - s1) * (s0 - s2))
        + f1 * (s - s0) * (s - s2) / ((s1 - s0) * (s1 - s2))
        + f2 * (s - s0) * (s - s1) / ((s2 - s0) * (s2 - s1))
    )


def _nodes_from_segments(seg_length: np.ndarray, seg_value: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Node arc lengths and node values of a quantity known at the segments' midpoints.

    Quadratic interpolation in arc length through three neighbouring midpoints (the mean of the
    two stencils straddling an interior node; one-sided at the end nodes): third-order accurate
    interpolation on any spacing, exact for a quantity linear in arc length. Two segments:
    linear; one: constant.
    """
    s = np.concatenate(([0.0], np.cumsum(seg_length)))
    n_seg = seg_value.size
    if n_seg == 1:
        return s, np.full(2, seg_value[0])
    s_mid = 0.5 * (s[:-1] + s[1:])
    if n_seg == 2:
        slope = (seg_value[1] - seg_value[0]) / (s_mid[1] - s_mid[0])
        return s, seg_value[0] + slope * (s - s_mid[0])

    def through(first: np.ndarray, at: np.ndarray) -> np.ndarray:
        j = (first, first + 1, first + 2)
        return _quadratic(at, *(s_mid[k] for k in j), *(seg_value[k] for k in j))

    node = np.arange(n_seg + 1)
    behind = through(np.clip(node - 2, 0, n_seg - 3), s)  # midpoints i-2, i-1, i
    ahead = through(np.clip(node - 1, 0, n_seg - 3), s)  # midpoints i-1, i, i+1
    return s, 0.5 * (behind + ahead)


def _polyline_tangents(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Arc length [mm] and unwrapped counter-clockwise tangent angle [rad] at the nodes of a curve.

    A segment's chord is the tangent at its midpoint up to O(h^2) (exactly on a circular arc).
    The chord is shorter than the arc it spans, by the factor sin(d/2) / (d/2) for a turning d
    across it; that factor, with d from a first pass, makes the arc length exact on circular arcs
    with even spacing and removes the chord's leading O(h^2) error elsewhere. On uneven spacing
    the first pass interpolates in chord length, so an arc keeps a small error of higher order.
    """
    seg = np.diff(points, axis=0)
    chord = np.linalg.norm(seg, axis=1)
    if np.any(chord <= 0.0):
        raise ValueError("centreline nodes must be distinct (zero-length segment)")
    seg_angle = np.unwrap(np.arctan2(seg[:, 1], seg[:, 0]))
    _, angle = _nodes_from_segments(chord, seg_angle)
    turning = np.diff(angle)
    return _nodes_from_segments(chord / np.sinc(turning / (2.0 * np.pi)), seg_angle)


def centreline_profile(X_line, x_line) -> CentrelineProfile:
    """Tangent rotation and curvature along a centreline (docs/actuator.md, "Metrics").

    Tangent directions at the nodes come from the segments' chords (each the tangent at its
    segment's midpoint, up to O(h^2)), unwrapped along the line and interpolated quadratically in
    arc length to the nodes (one-sided at the two ends): second-order accurate on uneven spacing,
    exact for rigid motions and for uniform bending (circular arcs) with even spacing (uneven: a
    small error of higher order). Arc lengths are the chord lengths corrected for the turning
    across each segment (exact on evenly spaced circular arcs). The rotation
    is the clockwise angle from the reference to the current tangent, node by node, shifted by a
    whole number of turns so that the clamp node's rotation lies in (-pi, pi]. The curvature is
    the second-order finite difference (``np.gradient``, one-sided second order at the ends) of
    the rotation over current arc length: second-order accurate where the spacing varies
    smoothly; at the two nodes nearest each end it drops to first order where the spacing jumps
    from segment to segment (the rotation's O(h^2) error is then not smooth there).

    Parameters
    ----------
    X_line, x_line : ndarray, shape (m, 2)
        Reference and current node positions [mm], m >= 2, ordered from the clamp to the free
        end; the spacing need not be even.

    Returns
    -------
    CentrelineProfile
        Arc lengths [mm], rotation [rad] and curvature [1/mm] at the nodes.
    """
    X, x = _as_pair(X_line, x_line, min_nodes=2)
    S, angle_ref = _polyline_tangents(X)
    s, angle_cur = _polyline_tangents(x)
    rotation = angle_ref - angle_cur  # counter-clockwise angles: clockwise rotation is positive
    rotation -= 2.0 * np.pi * np.ceil((rotation[0] - np.pi) / (2.0 * np.pi))
    curvature = np.gradient(rotation, s, edge_order=2) if s.size >= 3 else np.zeros(2)
    return CentrelineProfile(reference_arc_length=S, arc_length=s, rotation=rotation, curvature=curvature)


def centreline_points(arc_length, rotation, start=(0.0, 0.0)) -> np.ndarray:
    """Node positions (m, 2) [mm], (x, z), of a centreline whose reference runs straight along -z
    (from the clamp toward the free end) and starts at ``start`` [mm], from its current arc length
    [mm] and rotation [rad] at the nodes (a :class:`CentrelineProfile`'s, as centreline.csv holds
    them): the inverse of :func:`centreline_profile` for such a line, the first node at ``start``.

    Each segment is taken as a circular arc, its rotation linear in arc length: its chord points
    along the tangent at the mean rotation and is sin(d/2) / (d/2) of the arc for a turning d. A
    circular arc comes back exactly; elsewhere the error is second order in the spacing.
    """
    s = np.asarray(arc_length, dtype=float).reshape(-1)
    rot = np.asarray(rotation, dtype=float).reshape(-1)
    if s.size != rot.size or s.size < 1:
        raise ValueError(f"arc_length and rotation must be non-empty and of one length, got {s.size} and {rot.size}")
    mean, turning = 0.5 * (rot[:-1] + rot[1:]), np.diff(rot)
    chord = np.diff(s) * np.sinc(turning / (2.0 * np.pi))
    steps = np.column_stack((-np.sin(mean), -np.cos(mean))) * chord[:, None]  # clockwise from -z
    return np.asarray(start, dtype=float) + np.vstack((np.zeros(2), np.cumsum(steps, axis=0)))


def unwrapped_angle_deg(angle: float, near: float) -> float:
    """``angle`` [deg] shifted by whole turns to the value nearest ``near`` [deg].

    A face's rotation is known only modulo 360 degrees (:func:`face_rotation_deg` reports it in
    (-180, 180]); the centreline's rotation at the free end, unwrapped along the line
    (:class:`CentrelineProfile`), tells the turns: an actuator curled to 190 degrees reads 190,
    not -170.

    Parameters
    ----------
    angle : float
        The face's rotation [deg], any branch.
    near : float
        A continuous estimate of the same rotation [deg], within 180 degrees of the true value.

    Returns
    -------
    float
        ``angle + 360 k`` [deg], k the integer that brings it nearest ``near``.
    """
    return float(angle + 360.0 * np.round((near - angle) / 360.0))


def curling_index(profile: CentrelineProfile) -> float | None:
    """Share of the total rotation accumulated in the half of the centreline nearest the clamp.

    (rot(s_end / 2) - rot(0)) / (rot(s_end) - rot(0)), the halves taken by *current* arc length and
    the rotation interpolated linearly at s_end / 2. It is 0.5 for uniform bending (a circular
    arc), tends to 1 when the rotation is concentrated near the clamp (curling, paper Sec. IV-B)
    and to 0 when it is concentrated near the tip.

    Parameters
    ----------
    profile : CentrelineProfile
        The centreline's rotation along its arc length.

    Returns
    -------
    float or None
        The index [-]; None when |rot(s_end) - rot(0)| < 1e-3 rad: the share is undefined for a
        (nearly) straight actuator.
    """
    rot = profile.rotation
    total = rot[-1] - rot[0]
    if abs(total) < STRAIGHT_ROTATION_RAD:
        return None
    s = profile.arc_length
    half = np.interp(0.5 * s[-1], s, rot)
    return float((half - rot[0]) / total)


def polygon_area(points, segments=None) -> float:
    """Area [mm^2] enclosed by a closed polygon (shoelace formula, absolute value).

    points: (m, 2) vertices [mm]. segments: (k, 2) indices of the polygon's edges in any order,
    each oriented consistently around it (a mesh's boundary facets); None: the points are the
    vertices in order around the polygon (either sense), the first not repeated at the end.
    """
    p = _as_points(points, "points")
    if segments is None:
        idx = np.arange(len(p))
        segments = np.column_stack((idx, np.roll(idx, -1)))
    a, b = p[segments[:, 0]], p[segments[:, 1]]
    return abs(0.5 * float(np.sum(a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1])))


def packing_fraction(particle_area: float, cavity_area: float) -> float:
    """Packing fraction [-]: the share of the cavity filled by particles (2D: areas in mm^2; 3D:
    volumes in mm^3, the same function).

    particle_area: total area of the particles [mm^2]; cavity_area: area of the cavity [mm^2], > 0.
    """
    if cavity_area <= 0.0:
        raise ValueError(f"cavity_area must be positive, got {cavity_area}")
    return float(particle_area) / float(cavity_area)


def contacts_per_particle(
    pairs: Iterable[tuple[Hashable, Hashable]], particle_ids: Iterable[Hashable]
) -> float:
    """Mean coordination number Z = (2 N_pp + N_pw) / N_particles [-].

    pairs: (a, b) component ids in contact. A pair of two particles (N_pp) counts for both; a
    pair of a particle with anything not in particle_ids (a wall, N_pw) counts once; a pair with
    no particle is ignored. particle_ids: the particles' ids. Returns 0 with no particles.
    """
    particles = set(particle_ids)
    if not particles:
        return 0.0
    ends = sum(int(a in particles) + int(b in particles) for a, b in pairs)
    return ends / len(particles)


def column_folds(layer_centres, line, diameter: float) -> int:
    """Folds of a particle column: layers that leave the column's line [-].

    Each layer's centre is projected on the centreline (its nearest point on the polyline) and
    read as an arc length from the clamp and a distance from the line. A column that stays one arc
    advances by about a particle diameter a layer and keeps its layers at one distance from the
    strain-limit layer; where it folds, a layer is pushed out of that line (further from the
    strain-limit layer than the median layer by half a diameter or more) or set beside the layer
    before it (an advance along the line below half a diameter). The count is the number of
    layers pushed out plus the number of neighbouring pairs that do not advance: 0 for one arc.

    Parameters
    ----------
    layer_centres : array_like, shape (n, 2)
        The layers' centres in the bending plane (x, z) [mm], in the as-prepared order from the clamp.
    line : array_like, shape (c, 2)
        The centreline's points (x, z) [mm], ordered from the clamp.
    diameter : float
        The as-prepared particle diameter d [mm].

    Returns
    -------
    int
    """
    centres = _as_points(layer_centres, "layer_centres")
    line = _as_points(line, "line")
    if len(centres) < 2 or len(line) < 2:
        return 0
    a, b = line[:-1], line[1:]
    seg = b - a
    seg_len2 = np.einsum("ij,ij->i", seg, seg)
    start = np.concatenate([[0.0], np.cumsum(np.sqrt(seg_len2))])
    arc = np.empty(len(centres))
    dist = np.empty(len(centres))
    for k, c in enumerate(centres):
        t = np.clip(np.einsum("ij,ij->i", c - a, seg) / np.where(seg_len2 > 0, seg_len2, 1.0), 0.0, 1.0)
        dist2 = np.sum((a + t[:, None] * seg - c) ** 2, axis=1)
        i = int(np.argmin(dist2))
        arc[k] = start[i] + t[i] * np.sqrt(seg_len2[i])
        dist[k] = np.sqrt(dist2[i])
    half = 0.5 * float(diameter)
    return int(np.sum(dist - np.median(dist) > half) + np.sum(np.diff(arc) < half))


# ------------------------------------------------------------------------------------------------
# Measuring a state: every state metric in one pass


@dataclass(frozen=True, eq=False)
class Gauges:
    """What the state metrics read of an actuator, fixed when its model is built
    (:func:`hydrojam.actuator.model.build_model`, ``ActuatorModel.gauges``): :func:`measure`
    needs nothing else. Node indices are into the model's mesh.

    Parameters
    ----------
    reference : ndarray, shape (n, d)
        The nodes' as-prepared positions [mm] (d = 2 or 3: the model's dimension).
    free_end_nodes : ndarray of int, shape (m,)
        The free-end face's nodes.
    centreline_nodes : ndarray of int, shape (c,)
        The strain-limit layer's mid-line (3D: its mid-surface's line on y = 0), ordered from the
        clamp.
    cavity_segments : ndarray of int, shape (k, d)
        The cavity wall's straight pieces: segments in 2D, triangles in 3D.
    particle_ids : tuple of int
        The particles' contact components.
    reference_volume : float
        The particles' as-prepared total area [mm^2] (2D: of circles of the design's particle
        diameter) or volume [mm^3] (3D: of the meshed particles, their halves in a half model).
    solid : Solid
        The model's solid (:class:`hydrojam.fem.assembly.Solid`): the particles' current volumes.
    particle_block : str or tuple of str
        The name of its block holding the particles' cells, particle by particle (a multi-chamber
        design: one block per chamber, in order).
    particle_bounds : ndarray of int, shape (n_particles - 1,)
        Where each particle's cells start in that block, after the first particle's.
    contact : Contact
        The model's contact (:class:`hydrojam.fem.contact.Contact`): the component pairs in contact.
    particle_nodes : tuple of ndarray of int
        Each particle's nodes, in the order of ``particle_ids`` (layer by layer from the clamp).
    particles_per_layer : int
        Particles side by side in a layer.
    particle_diameter : float
        The as-prepared particle diameter d [mm] (several chambers: the smallest).
    chamber_layers : tuple of (int, int)
        A multi-chamber design's (layers, particles per layer) of each chamber, in the order of
        ``particle_nodes``; empty for one chamber (``particles_per_layer`` then holds).
    mirror_y : bool
        The 3D half model: the free-end face is mirrored about y = 0 for its rotation.
    round_axis : bool
        Three chambers round the axis: no strain-limit side, so the bending angle and the
        centreline's profile are read in the bending plane (:func:`measure`).
    """

    reference: np.ndarray
    free_end_nodes: np.ndarray
    centreline_nodes: np.ndarray
    cavity_segments: np.ndarray
    particle_ids: tuple[int, ...]
    reference_volume: float
    solid: Solid
    particle_block: str
    particle_bounds: np.ndarray
    contact: Contact
    particle_nodes: tuple[np.ndarray, ...] = ()
    particles_per_layer: int = 1
    particle_diameter: float = 0.0
    chamber_layers: tuple[tuple[int, int], ...] = ()
    mirror_y: bool = False
    round_axis: bool = False


def turned_to_plane(points: np.ndarray, plane_deg: float) -> np.ndarray:
    """3D positions (m, 3) [mm] turned about z so that the direction ``plane_deg`` in x-y (from +x
    toward +y) becomes -x: a bend in that plane then reads as a bend toward -x, positive."""
    a = np.radians(180.0 - plane_deg)
    c, s = np.cos(a), np.sin(a)
    p = np.asarray(points, dtype=float)
    return np.column_stack([c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1], p[:, 2]])


def particle_volumes(gauges: Gauges, x: np.ndarray) -> np.ndarray:
    """Current area (2D) [mm^2] or volume (3D) [mm^3] of each particle, det F integrated over its
    reference cells (the half of each particle in a 3D half model).

    Parameters
    ----------
    gauges : Gauges
        The actuator's gauges.
    x : ndarray, shape (n, d)
        Positions of the mesh's nodes [mm].

    Returns
    -------
    ndarray, shape (n_particles,)
    """
    volumes = gauges.solid.current_volumes(x)
    block = gauges.particle_block
    per_cell = volumes[block] if isinstance(block, str) else np.concatenate([volumes[b] for b in block])
    return np.array([part.sum() for part in np.split(per_cell, gauges.particle_bounds)])


def measure(gauges: Gauges, x: np.ndarray) -> dict:
    """The state metrics (docs/actuator.md, "Metrics") at one state, in one pass.

    One value per entry of :data:`STATE_METRICS` (names, units and meanings are defined there),
    in that order. The bending angle is the free-end face's rotation (its best-fit line in 2D;
    in 3D the line its best-fit plane cuts in the x-z plane), taken on the turn that the
    centreline's unwrapped rotation picks; the tip displacement is that of the face's node
    centroid (in 3D its x and z); the centreline profile is in the x-z plane. Particle and cavity
    areas (3D: volumes) give the packing fraction and the mean swelling ratio (over
    ``reference_volume``); a 3D half model measures its half, whose ratios are the whole
    actuator's by symmetry. Contacts per particle: particle-particle pairs count for both,
    particle-wall pairs once.

    Parameters
    ----------
    gauges : Gauges
        The actuator's gauges (``ActuatorModel.gauges``).
    x : ndarray, shape (n, d)
        Positions of the mesh's nodes [mm] (d = 2 or 3, the model's dimension).

    Returns
    -------
    dict
        Metric name -> value in the metric's unit (None where undefined).
    """
    X = gauges.reference
    fe, cl = gauges.free_end_nodes, gauges.centreline_nodes
    if X.shape[1] == 3:
        xz = [0, 2]
        dx, dz = tip_displacement(X[fe][:, xz], x[fe][:, xz])
        Xf, xf = X[fe], x[fe]
        if gauges.mirror_y:  # the whole face: the half and its mirror image
            flip = np.array([1.0, -1.0, 1.0])
            Xf, xf = np.vstack([Xf, Xf * flip]), np.vstack([xf, xf * flip])
        direction, twist = swing_twist_deg(face_rotation_matrix(Xf, xf))
        dy = float((xf[:, 1] - Xf[:, 1]).mean())
        Xp, xp = X, x  # what the angle, the profile and the folds are read on
        if gauges.round_axis:  # no strain-limit side: they are read in the bending plane
            Xp, xp = (turned_to_plane(p, 180.0 if direction is None else direction) for p in (X, x))
        profile = centreline_profile(Xp[cl][:, xz], xp[cl][:, xz])
        angle = bending_angle_3d_deg(Xp[fe], xp[fe])
        cavity = enclosed_volume(x, gauges.cavity_segments)
    else:
        dx, dz = tip_displacement(X[fe], x[fe])
        profile = centreline_profile(X[cl], x[cl])
        angle = bending_angle_deg(X[fe], x[fe])
        dy, twist, direction = 0.0, 0.0, None  # plane strain: no y, no twist; the plane from the angle's sign below
        xp = x
        cavity = polygon_area(x, gauges.cavity_segments)
    particles = float(particle_volumes(gauges, x).sum())
    ci = curling_index(profile)
    plane = [0, 2] if X.shape[1] == 3 else [0, 1]
    folds = 0
    if gauges.particle_nodes:
        centres = np.array([xp[nodes][:, plane].mean(axis=0) for nodes in gauges.particle_nodes])
        shapes = gauges.chamber_layers or ((len(centres) // gauges.particles_per_layer, gauges.particles_per_layer),)
        start = 0
        for n_layers, per_layer in shapes:  # each chamber's column on its own
            chamber = centres[start:start + n_layers * per_layer]
            start += n_layers * per_layer
            layers = chamber.reshape(-1, per_layer, 2).mean(axis=1)
            folds += column_folds(layers, xp[cl][:, plane], gauges.particle_diameter)
    # the face's rotation is known modulo a turn: the centreline's, unwrapped, picks the turn
    angle = unwrapped_angle_deg(angle, float(np.degrees(profile.rotation[-1])))
    if X.shape[1] == 2 and abs(angle) >= np.degrees(STRAIGHT_ROTATION_RAD):
        direction = 180.0 if angle > 0.0 else 0.0
    values = {
        "bending_angle_deg": float(angle) + 0.0,  # + 0.0: no "-0.0" in results
        "bending_plane_deg": None if direction is None else float(direction) + 0.0,
        "twist_deg": None if twist is None else float(twist) + 0.0,
        "tip_dx_mm": float(dx) + 0.0,
        "tip_dy_mm": float(dy) + 0.0,
        "tip_dz_mm": float(dz) + 0.0,
        "curling_index": None if ci is None else float(ci),
        "max_curvature_per_mm": float(np.max(np.abs(profile.curvature))),
        "packing_fraction": packing_fraction(particles, cavity),
        "contacts_per_particle": contacts_per_particle(gauges.contact.contact_pairs(x), gauges.particle_ids),
        "mean_swelling_ratio": float(particles / gauges.reference_volume),
        "column_folds": folds,
    }
    return {m.name: values[m.name] for m in STATE_METRICS}
