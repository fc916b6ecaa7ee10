"""Intersection-free contact between bodies through IPC (docs/contact.md).

Every call to the IPC Toolkit (``ipctk``, pinned 1.6.1) lives in this module, so an upgrade is one
file. Contact is an energy term: a smooth log barrier on the distance between boundary primitives
of different bodies, area-weighted ("convergent" formulation) and in physical units, so the
barrier stiffness ``kappa`` is a pressure [MPa]:

    E_c = kappa * sum_k w_k b(d_k),   b(d) = -(d^2 - dhat^2)^2 ln(d^2/dhat^2) / dhat^3 (ipctk),

with w_k the boundary area (2D: length) attached to each collision. The contact pressure at gap
d is kappa |b'(d)|: zero beyond the activation distance ``dhat`` [mm], unbounded as d -> 0.
Every line-search step is capped by continuous collision detection, so no accepted state
interpenetrates. Optional Coulomb friction is IPC's lagged smoothed friction potential, with
normal forces and tangent bases frozen at the start of each load step (``begin_step``).

Quadratic elements enter the collision mesh as their boundary nodes joined by straight
segments (2D) or split triangles (3D). Only primitives of *different* components (a component
is a body, or bodies bonded by shared nodes) can collide, or primitives of one component in
different *regions* of it (self-contact: a long chamber's walls curling onto themselves).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import ipctk
import numpy as np
import scipy.sparse as sp

from hydrojam.fem._env import positive_int
from hydrojam.fem.elements import straight_pieces
from hydrojam.fem.terms import EnergyTerm


# ipctk's parallel sums change the barrier gradient and Hessian in the last bits from call to call
# on 2 threads, which jammed load paths amplify into different paths (docs/contact.md, "Threads"):
# one thread, reproducible, by default.
# HYDROJAM_IPC_THREADS (a positive integer) overrides, read once at import.
ipctk.set_num_threads(positive_int("HYDROJAM_IPC_THREADS", 1))


def collision_primitives(facets: np.ndarray, dim: int) -> np.ndarray:
    """Straight collision primitives (segments in 2D, triangles in 3D) of boundary facets.

    Quadratic facets are split at their mid-nodes, keeping the facets' orientation
    (:func:`~hydrojam.fem.elements.straight_pieces`).
    """
    return straight_pieces(np.asarray(facets, dtype=np.int64), dim - 1)


@dataclass(frozen=True)
class ContactSettings:
    """Barrier and friction parameters.

    Tight Inclusion is conservative at any tolerance (the step it returns is collision-free; a
    looser tolerance only cuts it a little shorter than the time of impact), so the CCD settings
    trade step length for speed, never the guarantee.

    Parameters
    ----------
    dhat : float
        Activation distance [mm].
    kappa : float
        Barrier stiffness [MPa] (the contact pressure scale).
    friction : float, optional
        Coulomb coefficient [-] (0: frictionless).
    friction_eps : float, optional
        Slip displacement below which friction is static [mm] (IPC's eps_v times the step).
    pair_friction : dict, optional
        Coefficients for particular component pairs {(a, b): mu} [-], overriding ``friction``.
    ccd_tolerance : float, optional
        The Tight Inclusion CCD's tolerance [-] (None: ipctk's default, 1e-6).
    ccd_max_iterations : int, optional
        Its iteration cap (None: ipctk's default, 1e7).
    pattern_reach : float, optional
        How far [mm] every vertex may move from a state before its Hessian may leave the
        sparsity pattern :meth:`Contact.hessian_pattern` gives there (None: ``pattern_dhats``
        times dhat).
    """

    dhat: float
    kappa: float
    friction: float = 0.0
    friction_eps: float | None = None
    pair_friction: dict | None = None
    ccd_tolerance: float | None = None
    ccd_max_iterations: int | None = None
    pattern_reach: float | None = None

    pattern_dhats: ClassVar[float] = 0.5
    """The default ``pattern_reach`` in units of dhat (docs/solver.md, "A changing contact
    pattern")."""

    @property
    def reach(self) -> float:
        """The pattern's reach [mm]: ``pattern_reach``, or ``pattern_dhats`` times dhat."""
        return self.pattern_dhats * self.dhat if self.pattern_reach is None else self.pattern_reach

    def __post_init__(self):
        if not self.dhat > 0:
            raise ValueError(f"contact dhat must be > 0 mm (got {self.dhat})")
        if not self.kappa > 0:
            raise ValueError(f"contact kappa must be > 0 MPa (got {self.kappa})")
        if self.friction < 0:
            raise ValueError(f"friction coefficient must be >= 0 (got {self.friction})")
        if self.pattern_reach is not None and not self.pattern_reach >= 0:
            raise ValueError(f"contact pattern_reach must be >= 0 mm (got {self.pattern_reach})")


def default_settings(
    X: np.ndarray,
    facets: np.ndarray,
    shear_modulus: float,
    dhat: float | None = None,
    kappa: float | None = None,
    **kw,
) -> ContactSettings:
    """Contact settings with principled defaults for dhat and kappa.

    dhat = 1% of the mean collision-edge length (mesh-relative, so the barrier layer is a small
    fraction of an element), kappa = 10 x the largest shear modulus of the bodies in contact, so
    that contact pressures of the order of the material's own stresses are carried at gaps well
    inside dhat. Both overridable.

    Parameters
    ----------
    X : ndarray, shape (n, d)
        Reference positions [mm].
    facets : ndarray, shape (nf, nfn)
        The boundary facets in contact.
    shear_modulus : float
        The largest shear modulus of the bodies in contact [MPa].
    dhat : float, optional
        Activation distance [mm] (default: as above).
    kappa : float, optional
        Barrier stiffness [MPa] (default: as above).
    **kw
        Further fields of :class:`ContactSettings`.

    Returns
    -------
    ContactSettings
    """
    if dhat is None:
        prims = collision_primitives(facets, X.shape[1])
        edges = prims if X.shape[1] == 2 else np.concatenate([prims[:, [0, 1]], prims[:, [1, 2]], prims[:, [2, 0]]])
        h = float(np.linalg.norm(X[edges[:, 0]] - X[edges[:, 1]], axis=1).mean())
        dhat = 0.01 * h
    if kappa is None:
        kappa = 10.0 * shear_modulus
    return ContactSettings(dhat=dhat, kappa=kappa, **kw)


def _component_filter(labels: np.ndarray):
    """An ipctk filter (in C++) that blocks pairs of vertices with one label: chain each label's
    vertices with fake edges and let ipctk's connected-components filter do the rest. Its table
    ends at the highest vertex of a fake edge, so a loop on the last vertex makes it cover every
    vertex (an unchained one is a label of its own); without it a pair with an unchained vertex
    past that end read beyond the table (a crash, or pairs blocked or let through at random)."""
    chain = []
    for c in np.unique(labels):
        ids = np.flatnonzero(labels == c)
        if len(ids) > 1:
            chain.append(np.stack([ids[:-1], ids[1:]], axis=1))
    if not chain:
        return None
    chain.append(np.array([[len(labels) - 1, len(labels) - 1]]))
    return ipctk.make_connected_components_filter(np.asfortranarray(np.concatenate(chain).astype(np.int32)))


def _ids(rows: list) -> np.ndarray:
    """Index pairs as an (n, 2) int64 array (also where there are none)."""
    return np.array(rows, dtype=np.int64).reshape(-1, 2)


def _keys(rows: list, base: int, symmetric: bool = False) -> np.ndarray:
    """Index pairs (i, j) as sorted int64 keys i * base + j (``symmetric``: the pair unordered)."""
    p = _ids(rows)
    if symmetric:
        p = np.sort(p, axis=1)
    return np.unique(p[:, 0] * base + p[:, 1])


def _any_pair(keys: np.ndarray, base: int, first: list, second: list, ordered: bool = False) -> np.ndarray:
    """Whether any pair (i, j), i from the arrays ``first`` and j from ``second`` (elementwise),
    is among ``keys`` (:func:`_keys`; unordered unless ``ordered``)."""
    hit = np.zeros(len(first[0]), dtype=bool)
    for i in first:
        for j in second:
            k = i * base + j if ordered else np.minimum(i, j) * base + np.maximum(i, j)
            hit |= np.isin(k, keys)
    return hit


class Contact(EnergyTerm):
    """IPC barrier (and optional lagged friction) between the boundaries of different components,
    and within a self-contacting one.

    Its Hessian is exact (not projected) unless the solver asks: projecting the barrier Hessian
    always doubled Newton iterations and failed a Hertz test; ``fallback_projection`` lets the
    solver project it when the exact Hessian gives no descent.

    Parameters
    ----------
    X : ndarray, shape (n_nodes, d)
        Reference positions [mm].
    facets : ndarray, shape (nf, nfn)
        Boundary facets in full node numbers (meshio order, outward).
    components : ndarray, shape (n_nodes,)
        Component id of every node.
    settings : ContactSettings
        Barrier and friction parameters.
    name : str, optional
        The term's name.
    regions : ndarray, shape (n_nodes,), optional
        Self-contact: two primitives of one component may collide where a vertex of one and a
        vertex of the other lie in different regions (ipctk lets a pair through where any of
        its vertex pairs passes; primitives that share a vertex never collide). None: no
        self-contact; every node its own region: IPC's full self-contact. A self-contacting
        boundary must lie farther than dhat from itself at X, or the barrier would load the
        reference state (a ``ValueError``).
    """

    fallback_projection = True
    cached_states = 2
    """Collision sets kept for the most recent states: the accepted state's survives one trial
    elsewhere (a rejected line-search or curvature-step trial) before the next iteration asks for
    it again."""

    def __init__(self, X: np.ndarray, facets: np.ndarray, components: np.ndarray, settings: ContactSettings,
                 name: str = "contact", regions: np.ndarray | None = None):
        self.name = name
        self.X = np.asarray(X, dtype=float)
        self.dim = self.X.shape[1]
        self.settings = settings
        prims = collision_primitives(facets, self.dim).astype(np.int32)
        V = np.asfortranarray(self.X)
        if self.dim == 2:
            self._cm = ipctk.CollisionMesh.build_from_full_mesh(V, np.asfortranarray(prims))
        else:
            faces = np.asfortranarray(prims)
            self._cm = ipctk.CollisionMesh.build_from_full_mesh(V, np.asfortranarray(ipctk.edges(faces)), faces)
        self.vertex_ids = np.array([self._cm.to_full_vertex_id(i) for i in range(self._cm.num_vertices)], dtype=np.int64)
        if np.any(np.diff(self.vertex_ids) <= 0):  # ipctk builds it in the full mesh's order
            raise RuntimeError("the collision mesh does not keep the full mesh's vertex order")
        self._full_dofs = (self.vertex_ids[:, None] * self.dim + np.arange(self.dim)).ravel()
        self.components = np.asarray(components)[self.vertex_ids]
        self._facets, self._node_components = np.asarray(facets), np.asarray(components)
        self._between = None
        self.self_contact = regions is not None
        labels = self.components
        if self.self_contact:
            pairs = np.stack([self.components, np.asarray(regions)[self.vertex_ids]], axis=1)
            labels = np.unique(pairs, axis=0, return_inverse=True)[1].ravel()
        flt = _component_filter(labels)
        if flt is not None:
            self._cm.can_collide = flt
        self._barrier = ipctk.BarrierPotential(settings.dhat, settings.kappa, True)
        self._ccd = None
        if settings.ccd_tolerance is not None or settings.ccd_max_iterations is not None:
            self._ccd = ipctk.TightInclusionCCD(
                1e-6 if settings.ccd_tolerance is None else float(settings.ccd_tolerance),
                10_000_000 if settings.ccd_max_iterations is None else int(settings.ccd_max_iterations))
        self._cache: dict = {}
        self._friction = None
        self._friction_potential = None
        if settings.friction > 0 or settings.pair_friction:
            eps = settings.friction_eps if settings.friction_eps is not None else 1e-2 * settings.dhat
            self._friction_potential = ipctk.FrictionPotential(eps)
        if self.self_contact and self.self_contacts(self.X):
            raise ValueError(f"contact: a self-contacting boundary lies within dhat = {settings.dhat:g} mm of "
                             "itself in the reference state")

    @property
    def facets(self) -> np.ndarray:
        """The boundary facets the collision mesh was built from (node numbers, as given)."""
        return self._facets

    def between_components(self) -> Contact:
        """This contact without its self-contact (itself where it has none): the pairs between
        different components alone, e.g. for the particles' forces on a wall that also meets
        itself. Built once, then kept."""
        if not self.self_contact:
            return self
        if self._between is None:
            self._between = Contact(self.X, self._facets, self._node_components, self.settings, self.name)
        return self._between

    def fresh(self) -> Contact:
        """This term without the friction frozen by an earlier ``begin_step`` (none until the
        next one), sharing the collision mesh: one per load path, so that a run on a model never
        starts from the friction lag where another run on it ended."""
        other = object.__new__(type(self))
        other.__dict__.update(self.__dict__)
        other._cache, other._friction = {}, None
        return other

    # -- collision sets ------------------------------------------------------------------------

    def _vertices(self, x: np.ndarray) -> np.ndarray:
        return np.asfortranarray(np.asarray(x, dtype=float).reshape(-1, self.dim)[self.vertex_ids])

    def _collisions(self, x: np.ndarray):
        V = self._vertices(x)
        key = V.tobytes()
        hit = self._cache.pop(key, None)
        if hit is None:
            col = ipctk.NormalCollisions()
            col.use_area_weighting = True
            col.build(self._cm, V, self.settings.dhat)
            hit = (V, col)
        self._cache[key] = hit  # the newest last
        while len(self._cache) > self.cached_states:
            del self._cache[next(iter(self._cache))]
        return hit

    def begin_step(self, x: np.ndarray) -> None:
        """Freeze normal forces and tangent bases for friction at the start of a load step."""
        if self._friction_potential is None:
            return
        V, col = self._collisions(x)
        tc = ipctk.TangentialCollisions()
        tc.build(self._cm, V, col, self._barrier, float(self.settings.friction))
        if self.settings.pair_friction:
            table = {tuple(sorted(k)): v for k, v in self.settings.pair_friction.items()}
            for group in (tc.vv_collisions, tc.ev_collisions, tc.ee_collisions, tc.fv_collisions):
                for c in group:
                    comps = self._components_of(c)
                    mu = table.get(tuple(comps[:2]), self.settings.friction) if len(comps) >= 2 else self.settings.friction
                    c.mu_s = mu
                    c.mu_k = mu
        self._friction = (V.copy(), tc)

    # -- energy term ---------------------------------------------------------------------------

    def energy(self, x: np.ndarray) -> float:
        V, col = self._collisions(x)
        e = float(self._barrier(col, self._cm, V))
        if self._friction is not None:
            V0, tc = self._friction
            e += float(self._friction_potential(tc, self._cm, np.asfortranarray(V - V0)))
        return e if np.isfinite(e) else np.inf

    def gradient(self, x: np.ndarray) -> np.ndarray:
        V, col = self._collisions(x)
        g = self._barrier.gradient(col, self._cm, V)
        if self._friction is not None:
            V0, tc = self._friction
            g = g + self._friction_potential.gradient(tc, self._cm, np.asfortranarray(V - V0))
        return self._cm.to_full_dof(g)

    def hessian(self, x: np.ndarray, project: bool = False) -> sp.csr_matrix:
        V, col = self._collisions(x)
        method = ipctk.PSDProjectionMethod.CLAMP if project else ipctk.PSDProjectionMethod.NONE
        H = self._barrier.hessian(col, self._cm, V, method)
        if self._friction is not None:
            V0, tc = self._friction
            H = H + self._friction_potential.hessian(tc, self._cm, np.asfortranarray(V - V0), method)
        return self._to_full(sp.csc_matrix(H))

    def _to_full(self, H: sp.csc_matrix) -> sp.csr_matrix:
        """A matrix over the collision mesh's DOFs as one over the full mesh's (CSR): what
        ipctk's ``to_full_dof`` gives, by renumbering, since the collision mesh keeps the full
        mesh's vertex order (checked in ``__init__``)."""
        n = self._cm.full_ndof
        counts = np.zeros(n + 1, dtype=np.int64)
        counts[self._full_dofs + 1] = np.diff(H.indptr)
        full = sp.csc_matrix((H.data, self._full_dofs[H.indices], np.cumsum(counts)), shape=(n, n))
        return full.tocsr()

    def hessian_pattern(self, x: np.ndarray) -> sp.csr_matrix:
        """Every coupling [full DOFs, (n*d, n*d), values 1] that a collision can bring while no
        vertex moves more than ``settings.reach`` [mm] from x [mm]: the whole stencils (a face
        and a vertex, two edges; 2D: an edge and a vertex) of the primitive pairs closer than
        dhat + 2 reach at x. A pair within dhat after each of its vertices moved by less than
        reach was within dhat + 2 reach at x; whole stencils, not those of the closest
        features ipctk reduces a pair to, so that a point sliding from an edge onto its face
        stays inside. The pairs are ipctk's broad-phase candidates (boxes inflated by
        dhat / 2 + reach) kept where ipctk's exact distance is below dhat + 2 reach: the
        candidates alone couple primitives whose boxes merely overlap, and on a jammed 3D
        packing their fill slowed every factorisation more than the analyses they saved
        (docs/solver.md, "A changing contact pattern").

        ipctk measures the distances, in compiled code: its collisions within dhat + 2 reach
        are the candidates' closest features there, so a candidate is that close exactly where
        one of its features (the pair itself, an edge or vertex of one against the other) is
        among them. A feature lies no closer than the primitive it belongs to, and the closest
        feature of a pair that close is one of its collisions."""
        V = self._vertices(x)
        reach = self.settings.reach
        cand = ipctk.Candidates()
        cand.build(self._cm, V, 0.5 * self.settings.dhat + reach)
        near = ipctk.NormalCollisions()
        near.build(cand, self._cm, V, self.settings.dhat + 2.0 * reach)
        nv, E = self._cm.num_vertices, self._cm.edges
        vv = _keys([(c.vertex0_id, c.vertex1_id) for c in near.vv_collisions], nv, symmetric=True)
        ev = _keys([(c.edge_id, c.vertex_id) for c in near.ev_collisions], nv)
        if self.dim == 2:
            pairs = _ids([(c.edge_id, c.vertex_id) for c in cand.ev_candidates])
            (a, b), v = E[pairs[:, 0]].T, pairs[:, 1]
            kept = np.isin(pairs[:, 0] * nv + v, ev) | _any_pair(vv, nv, [a, b], [v])
            stencils = np.stack([a, b, v], axis=1)[kept]
        else:
            F, FE, ne = self._cm.faces, self._cm.faces_to_edges, len(self._cm.edges)
            fv = _keys([(c.face_id, c.vertex_id) for c in near.fv_collisions], nv)
            ee = _keys([(c.edge0_id, c.edge1_id) for c in near.ee_collisions], ne, symmetric=True)
            pairs = _ids([(c.face_id, c.vertex_id) for c in cand.fv_candidates])
            f, v = pairs[:, 0], pairs[:, 1]
            corners = F[f].T
            kept = (np.isin(f * nv + v, fv) | np.isin(FE[f] * nv + v[:, None], ev).any(axis=1)
                    | _any_pair(vv, nv, list(corners), [v]))
            face_stencils = np.column_stack([*corners, v])[kept]
            pairs = _ids([(c.edge0_id, c.edge1_id) for c in cand.ee_candidates])
            e0, e1 = pairs[:, 0], pairs[:, 1]
            (a, b), (c_, d_) = E[e0].T, E[e1].T
            kept = (np.isin(np.minimum(e0, e1) * ne + np.maximum(e0, e1), ee)
                    | _any_pair(ev, nv, [e0], [c_, d_], ordered=True) | _any_pair(ev, nv, [e1], [a, b], ordered=True)
                    | _any_pair(vv, nv, [a, b], [c_, d_]))
            stencils = np.concatenate([face_stencils, np.column_stack([a, b, c_, d_])[kept]])
        d = self.dim
        stencils = stencils.astype(np.int64).reshape(-1, d + 1)
        m = stencils.shape[1]
        vi, vj = np.repeat(stencils, m, axis=1).ravel(), np.tile(stencils, (1, m)).ravel()
        pairs = sp.csr_matrix((np.ones(len(vi)), (vi, vj)), shape=(nv, nv))
        # vertex pairs -> their d x d DOF blocks (dof = vertex d + component), then to full DOFs
        P = self._to_full(sp.kron(pairs, np.ones((d, d)), format="csc"))
        P.data[:] = 1.0
        return P

    def max_step(self, x: np.ndarray, dx: np.ndarray) -> float:
        """Largest collision-free fraction of the step x -> x + dx (continuous collision detection)."""
        V0 = self._vertices(x)
        V1 = self._vertices(np.asarray(x) + np.asarray(dx).reshape(np.shape(x)))
        if self._ccd is None:
            return float(ipctk.compute_collision_free_stepsize(self._cm, V0, V1))
        return float(ipctk.compute_collision_free_stepsize(self._cm, V0, V1, 0.0, None, self._ccd))

    # -- diagnostics ---------------------------------------------------------------------------

    def minimum_distance(self, x: np.ndarray) -> float:
        """Smallest distance between primitives that may collide (of different components, or of
        one self-contacting component) within reach [mm] (``inf`` when none is closer than dhat)."""
        V, col = self._collisions(x)
        if len(col) == 0:
            return np.inf
        return float(np.sqrt(col.compute_minimum_distance(self._cm, V)))

    def has_intersections(self, x: np.ndarray) -> bool:
        """Whether any two primitives that may collide (see :meth:`minimum_distance`) intersect at x."""
        return bool(ipctk.has_intersections(self._cm, self._vertices(x)))

    def nodal_forces(self, x: np.ndarray) -> np.ndarray:
        """Contact forces on every node (n_nodes, d) [N; N/mm in 2D]: minus the barrier gradient
        (friction included when frozen by a ``begin_step``: never on a model's own term, whose
        load paths use :meth:`fresh` copies)."""
        return -self.gradient(x).reshape(-1, self.dim)

    def contact_pairs(self, x: np.ndarray) -> list[tuple[int, int]]:
        """Sorted unique component pairs with at least one active collision at x."""
        V, col = self._collisions(x)
        pairs = set()
        for i in range(len(col)):
            comps = self._components_of(col[i])
            if len(comps) >= 2:
                pairs.add((comps[0], comps[1]))
        return sorted(pairs)

    def self_contacts(self, x: np.ndarray) -> int:
        """Number of active collisions (within dhat) at x inside one component (self-contact)."""
        if not self.self_contact:
            return 0
        V, col = self._collisions(x)
        return sum(len(self._components_of(col[i])) == 1 for i in range(len(col)))

    def _components_of(self, collision) -> list[int]:
        """Sorted components of a collision's vertices."""
        return sorted({int(self.components[v]) for v in collision.vertex_ids(self._cm.edges, self._cm.faces) if v >= 0})

    def active(self, x: np.ndarray) -> int:
        """Number of active collision primitives pairs (within dhat) at x."""
        return len(self._collisions(x)[1])
