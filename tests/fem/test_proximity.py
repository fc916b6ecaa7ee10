"""The compiled search for close primitive pairs (fem/_proximity.py) against ipctk's exact
distances over every pair: the contact pattern within reach must be ipctk's to the last bit."""

import itertools

import ipctk
import numpy as np
import pytest

from hydrojam.fem._proximity import close_pairs


def _brute(V, first, second, components, limit, distance, same=False):
    """Every pair of different components that ipctk's distance puts below ``limit``."""
    out = set()
    for i, p in enumerate(first):
        for j, q in enumerate(second):
            if (same and j <= i) or components[p[0]] == components[q[0]]:
                continue
            if distance(*V[p], *V[q]) < limit:
                out.add((i, j))
    return out


def _found(V, first, second, components, limit, distance, same=False):
    pairs, unsure = close_pairs(V, first, second, components, limit, same=same)
    assert len({tuple(p) for p in pairs}) == len(pairs), "a pair reported twice"
    return {(int(i), int(j)) for (i, j), u in zip(pairs, unsure) if not u or distance(*V[first[i]], *V[second[j]]) < limit}


def _cloud(rng, n, d, bodies):
    """n vertices in ``bodies`` clumps of a 4 mm box (unit spacing-ish), their component ids."""
    V = rng.uniform(0, 4, (n, d))
    return V, rng.integers(0, bodies, n)


@pytest.mark.parametrize("seed", range(4))
def test_point_segment_pairs_are_ipctks(seed):
    rng = np.random.default_rng(seed)
    V, comp = _cloud(rng, 60, 2, 3)
    E = np.array([(i, i + 1) for i in range(59) if comp[i] == comp[i + 1]])
    points = np.arange(60)[:, None]
    limit = 0.5 ** 2
    got = _found(V, points, E, comp, limit, ipctk.point_edge_distance)
    assert got == _brute(V, points, E, comp, limit, ipctk.point_edge_distance) and got


@pytest.mark.parametrize("seed", range(4))
def test_point_triangle_and_edge_edge_pairs_are_ipctks(seed):
    rng = np.random.default_rng(seed)
    V, comp = _cloud(rng, 45, 3, 3)
    triples = [t for t in itertools.combinations(range(45), 3) if comp[t[0]] == comp[t[1]] == comp[t[2]]]
    F = np.array([triples[k] for k in rng.choice(len(triples), 150, replace=False)])
    E = np.array(sorted({tuple(sorted(e)) for f in F for e in ((f[0], f[1]), (f[1], f[2]), (f[0], f[2]))}))
    points = np.arange(45)[:, None]
    limit = 0.3 ** 2
    fv = _found(V, points, F, comp, limit, ipctk.point_triangle_distance)
    assert fv == _brute(V, points, F, comp, limit, ipctk.point_triangle_distance) and fv
    ee = _found(V, E, E, comp, limit, ipctk.edge_edge_distance, same=True)
    assert ee == _brute(V, E, E, comp, limit, ipctk.edge_edge_distance, same=True) and ee


def test_parallel_and_touching_segments_are_measured_exactly():
    """Degenerate geometry: parallel overlapping segments, collinear ones with a gap, a segment
    crossing another; each pair's squared distance decides as ipctk's does."""
    V = np.array([[0, 0, 0], [2, 0, 0],  # body 0
                  [1, 0.2, 0], [3, 0.2, 0],  # parallel, 0.2 above (d^2 = 0.04)
                  [2.3, 0, 0], [4, 0, 0],  # collinear, 0.3 beyond the end (d^2 = 0.09)
                  [1, -1, 0.1], [1, 1, 0.1]], dtype=float)  # crossing 0.1 above (d^2 = 0.01)
    comp = np.array([0, 0, 1, 1, 2, 2, 3, 3])
    E = np.array([[0, 1], [2, 3], [4, 5], [6, 7]])
    for limit in (0.005, 0.02, 0.05, 0.1):
        got = _found(V, E, E, comp, limit, ipctk.edge_edge_distance, same=True)
        assert got == _brute(V, E, E, comp, limit, ipctk.edge_edge_distance, same=True), limit


def _ipctk_pattern(contact, x):
    """The pattern within reach as ipctk finds it: its broad-phase candidates (boxes grown by
    dhat / 2 + reach) kept where its exact distance is below (dhat + 2 reach)^2."""
    import scipy.sparse as sp

    V = contact._vertices(x)
    cand = ipctk.Candidates()
    cand.build(contact._cm, V, 0.5 * contact.settings.dhat + contact.settings.reach)
    limit = (contact.settings.dhat + 2.0 * contact.settings.reach) ** 2
    E, F = contact._cm.edges, contact._cm.faces
    kept = [(*F[c.face_id], c.vertex_id) for c in cand.fv_candidates
            if ipctk.point_triangle_distance(V[c.vertex_id], *V[F[c.face_id]]) < limit]
    kept += [(*E[c.edge0_id], *E[c.edge1_id]) for c in cand.ee_candidates
             if ipctk.edge_edge_distance(*V[E[c.edge0_id]], *V[E[c.edge1_id]]) < limit]
    st = np.array(kept, dtype=np.int64).reshape(-1, 4)
    vi, vj = np.repeat(st, 4, axis=1).ravel(), np.tile(st, (1, 4)).ravel()
    pairs = sp.csr_matrix((np.ones(len(vi)), (vi, vj)), shape=(contact._cm.num_vertices,) * 2)
    P = sp.csr_matrix(contact._cm.to_full_dof(sp.kron(pairs, np.ones((3, 3)), format="csc")))
    return P, len(kept)


def test_the_contact_pattern_is_ipctks_candidates_kept_by_distance():
    """The 3D actuator's contact term, its particles shaken by 0.2 mm: the pattern within reach
    has exactly the entries of ipctk's candidates kept by ipctk's exact distances."""
    from hydrojam.actuator.design import apply_overrides, default_design
    from hydrojam.actuator.model import build_model

    problem = build_model(apply_overrides(default_design(), ["dimension=3", "particle_layers=1",
                                                             "mesh.size=4"])).problem()
    contact = next(t for t in problem.terms(0.0) if t.name == "contact")
    contact = getattr(contact, "_term", contact)
    for seed in range(2):
        x = problem.X + np.random.default_rng(seed).normal(0.0, 0.2, problem.X.shape)
        ref, kept = _ipctk_pattern(contact, x)
        got = contact.hessian_pattern(x)
        assert kept > 0
        assert np.array_equal(got.indptr, ref.indptr) and np.array_equal(got.indices, ref.indices)
