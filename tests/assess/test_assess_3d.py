"""The assessment in 3D, verified (docs/assess.md): a slender 3D bilayer cantilever's tip
stiffness against Euler-Bernoulli for the composite section, the empty 3D chamber (half model,
doubled) between its Euler-Bernoulli bounds, the pneumatic chamber pressurised to an angle, the
contact pressure on flat triangles, and (slow) the tangent stiffness of a jammed 3D state against
the secant of a small tip load."""

import gmsh
import numpy as np
import pytest

from hydrojam import Design
from hydrojam.assess.chamber import empty_chamber
from hydrojam.assess.confinement import segment_pressure
from hydrojam.assess.loading import Structure, tangent_stiffness, tip_curve
from hydrojam.fem.assembly import Block, Solid
from hydrojam.fem.elements import element_for_meshio_type
from hydrojam.fem.meshing import add_groups, bounding_box, generate, gmsh_session, set_mesh_size
from hydrojam.fem.problem import fixed
from hydrojam.materials.energies import NeoHookean

STIFF = NeoHookean(shear_modulus=0.2, poisson_ratio=0.45)
SOFT = NeoHookean(shear_modulus=0.023, poisson_ratio=0.45)
H_STIFF, H_SOFT, WIDTH, LENGTH = 2.0, 3.0, 5.0, 80.0  # mm: L/H = 16


def _modulus(m):
    return 2 * m.shear_modulus * (1 + m.poisson_ratio)


def _bilayer_mesh(size):
    """Two boxes bonded on x = H_STIFF (shared nodes): [0, H_STIFF] (stiff) and [H_STIFF,
    H_STIFF + H_SOFT] (soft) in x, [0, WIDTH] in y, [-LENGTH, 0] in z; clamp z = 0, free end
    z = -LENGTH."""
    with gmsh_session():
        set_mesh_size(size)
        occ = gmsh.model.occ
        a = occ.addBox(0.0, 0.0, -LENGTH, H_STIFF, WIDTH, LENGTH)
        b = occ.addBox(H_STIFF, 0.0, -LENGTH, H_SOFT, WIDTH, LENGTH)
        out, _ = occ.fragment([(3, a)], [(3, b)])
        occ.synchronize()
        vols = [t for d, t in out if d == 3]
        stiff = [t for t in vols if bounding_box(3, t)[1, 0] <= H_STIFF + 1e-6]
        soft = [t for t in vols if t not in stiff]
        faces = [t for _, t in gmsh.model.getBoundary([(3, v) for v in vols], oriented=False)]

        def at_z(t, z):
            bb = bounding_box(2, t)
            return abs(bb[0, 2] - z) < 1e-6 and abs(bb[1, 2] - z) < 1e-6

        add_groups(3, {"stiff": stiff, "soft": soft},
                   {"clamp": [t for t in faces if at_z(t, 0.0)], "free_end": [t for t in faces if at_z(t, -LENGTH)]})
        return generate(3, 2)


def test_3d_bilayer_cantilever_matches_euler_bernoulli():
    """Tangent tip stiffness (exact Hessian) of the 3D bilayer (Dragon Skin 30-class 2 mm on
    Ecoflex 00-30 3 mm, 5 mm wide, 80 mm long, quadratic tetrahedra of 1.5 mm) and the secant of
    a tip load of L/100 in +x and -x: within 3 % of Euler-Bernoulli 3 EI / L^3 of the composite
    section (E = 2G(1 + nu)). Left out: Timoshenko shear, (E/kappa G)(H/2L)^2 of the soft layer's
    share, ~1 %, the clamp's restraint of the lateral contraction and the coarse mesh (measured
    in docs/assess.md)."""
    mesh = _bilayer_mesh(1.5)
    el = element_for_meshio_type(mesh.cell_type)
    solid = Solid(mesh.points, [Block(mesh.cells[mesh.cell_groups["stiff"]], el, STIFF, "stiff"),
                                Block(mesh.cells[mesh.cell_groups["soft"]], el, SOFT, "soft")])
    beam = Structure(mesh.points, (solid,), (fixed(mesh.group_nodes("clamp"), 3),), mesh.facet_groups["free_end"],
                     SOFT.shear_modulus * H_SOFT**2)
    E = [_modulus(STIFF), _modulus(SOFT)]
    h, centre = [H_STIFF, H_SOFT], [H_STIFF / 2, H_STIFF + H_SOFT / 2]
    neutral = sum(e * t * c for e, t, c in zip(E, h, centre)) / sum(e * t for e, t in zip(E, h))
    EI = WIDTH * sum(e * (t**3 / 12 + t * (c - neutral) ** 2) for e, t, c in zip(E, h, centre))
    k_eb = 3 * EI / LENGTH**3
    k = tangent_stiffness(beam, beam.X)
    assert k / k_eb == pytest.approx(1.0, abs=0.03)
    curve = tip_curve(beam, beam.X, 0.01 * LENGTH * k_eb, fractions=(1.0,))
    assert curve.converged
    for sign in (1, -1):
        assert curve.secant(sign) / k_eb == pytest.approx(1.0, abs=0.03)


def _rect_I(x0, x1, y0, y1, about):
    """Second moment about x = ``about`` and area of the rectangle [x0, x1] x [y0, y1]."""
    b, t, c = y1 - y0, x1 - x0, (x0 + x1) / 2
    return b * (t**3 / 12 + t * (c - about) ** 2), b * t, c


def test_empty_3d_chamber_lies_between_the_euler_bernoulli_bounds():
    """The empty 3D chamber of the default design (half model, quick mesh 4 mm; the whole
    actuator's stiffness is twice the half model's): above its walls bending apart (the sum of
    each wall's own EI: the strain-limit layer, the two side walls in x, the two in y), below
    the whole section acting as one (composite, parallel axes). A closed tube, it lies near the
    composite bound (shear and the end walls' give take the rest; measured in docs/assess.md)."""
    design = Design(dimension=3, mesh={"size": 4.0}).resolved()
    half = empty_chamber(design)
    k = 2 * tangent_stiffness(half, half.X)
    Em, Es = _modulus(design.membrane), _modulus(design.strain_limit_layer)
    w, D = design.resolved_cavity_width, design.resolved_cavity_depth
    t0, h = design.side_wall_thickness, design.strain_limit_thickness
    xo, yo = w / 2 + t0, D / 2 + t0
    # (E, x0, x1, y0, y1): the strain-limit layer, the walls at -x and +x, the walls at -y and +y
    pieces = [(Es, -xo - h, -xo, -yo, yo), (Em, -xo, -w / 2, -D / 2, D / 2), (Em, w / 2, xo, -D / 2, D / 2),
              (Em, -xo, xo, -yo, -D / 2), (Em, -xo, xo, D / 2, yo)]
    EA = [(E, *_rect_I(x0, x1, y0, y1, 0.0)[1:]) for E, x0, x1, y0, y1 in pieces]
    neutral = sum(E * A * c for E, A, c in EA) / sum(E * A for E, A, _ in EA)
    composite = sum(E * _rect_I(x0, x1, y0, y1, neutral)[0] for E, x0, x1, y0, y1 in pieces)
    apart = sum(E * _rect_I(x0, x1, y0, y1, (x0 + x1) / 2)[0] for E, x0, x1, y0, y1 in pieces)
    L = design.length
    assert 3 * apart / L**3 < k < 3 * composite / L**3


def test_contact_pressure_on_triangles_recovers_a_uniform_pressure():
    """Nodal forces of a uniform pressure on a flat triangulated square (each triangle's force
    p A split equally among its three corners) give back p as the mean and at every node, and
    the contact area; the nodal field is zero off the wall."""
    n = 5
    xs, ys = np.meshgrid(np.linspace(0, 2, n), np.linspace(0, 3, n), indexing="ij")
    x = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(n * n)])
    x = np.vstack([x, [[9.0, 9.0, 9.0]]])  # a node off the wall
    tris = []
    for i in range(n - 1):
        for j in range(n - 1):
            a, b, c, d = i * n + j, (i + 1) * n + j, (i + 1) * n + j + 1, i * n + j + 1
            tris += [[a, b, c], [a, c, d]]
    tris = np.array(tris)
    p = 0.004
    f = np.zeros_like(x)
    area = 0.5 * np.linalg.norm(np.cross(x[tris[:, 1]] - x[tris[:, 0]], x[tris[:, 2]] - x[tris[:, 0]]), axis=1)
    np.add.at(f[:, 2], tris.ravel(), np.repeat(p * area / 3, 3))
    cp = segment_pressure(tris, x, f)
    assert cp.mean == pytest.approx(p, rel=1e-12) and cp.maximum == pytest.approx(p, rel=1e-12)
    assert cp.contact_length == pytest.approx(6.0, rel=1e-12)
    assert np.allclose(cp.nodal[:-1], p, rtol=1e-12) and cp.nodal[-1] == 0.0


@pytest.mark.slow
def test_3d_tangent_stiffness_of_the_jammed_state_matches_a_small_load():
    """The one-layer 3D actuator (half model, quick mesh 4 mm, frictionless: the secant of a
    frictionless load is the tangent's to its curvature) actuated to 275 K: the Hessian's tangent
    stiffness at the jammed state against the secant of a small tip load (2 % of the force that
    deflects the unactuated actuator by 5 % of L) in +x and -x, solved by Newton from the state:
    within 3 % (the load's curvature and Newton's tolerance, 1e-6 of the forces in play)."""
    from hydrojam.actuator.model import build_model
    from hydrojam.actuator.simulate import simulate
    from hydrojam.assess.chamber import actuator_structure

    design = Design(dimension=3, particle_layers=1, mesh={"size": 4.0}, friction=0.0)
    model = build_model(design)
    run = simulate(model)
    assert run.converged
    structure = actuator_structure(model, 1.0)
    k = tangent_stiffness(structure, run.final.x)
    k0 = tangent_stiffness(actuator_structure(model, 0.0), model.mesh.points)
    curve = tip_curve(structure, run.final.x, 0.02 * 0.05 * design.resolved().length * k0, fractions=(1.0,))
    assert curve.converged
    for sign in (1, -1):
        assert curve.secant(sign) == pytest.approx(k, rel=0.03)
