"""3D pictures of an actuator state: its bodies' surfaces, and an off-screen render of them.

:func:`state_surfaces` takes one state as a VTU file holds it (:func:`~hydrojam.actuator.results.vtu_mesh`;
a half model already mirrored to the whole actuator) and gives the straight triangles of every
body's surface, deformed and as prepared, with each triangle's body and swelling ratio, and the
undeformed outline; numpy only. :func:`render_state` draws them off-screen with PyVista over
VTK, the optional extra ``render`` (``pip install 'hydrojam[render]'``; ``make`` installs it):
the membrane translucent, the particles coloured by swelling ratio, the strain-limit layer in its
own colour, the undeformed outline faint. Without PyVista, :func:`renders_available` is False
and says once how to get it; the callers then draw what they drew before. Renders are drawn from
written or final states, never inside the solve.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hydrojam._io import atomic_path
from hydrojam.actuator.model import MEMBRANE_BODY, PARTICLE_BODY, STRAIN_LIMIT_BODY
from hydrojam.fem.elements import ELEMENTS, straight_pieces

#: what a user is told, once, where PyVista cannot be imported
MISSING = ("3D renders need PyVista (the optional extra 'render'): pip install 'hydrojam[render]' "
           "(make installs it); drawing the sections only")

#: colours (RGB in [0, 1]) of the elastomers, shared by the render and the HTML viewer
MEMBRANE_RGB = (0.60, 0.70, 0.82)
STRAIN_LIMIT_RGB = (0.85, 0.45, 0.20)
OUTLINE_RGB = (0.35, 0.35, 0.35)
#: opacity of the membrane in the render: the particles show through it
MEMBRANE_OPACITY = 0.3
#: colour map of the particles' swelling ratio (matplotlib's name)
SWELLING_CMAP = "viridis"

#: an edge of the undeformed walls is drawn in the outline where its two faces meet at more than this
FEATURE_ANGLE_DEG = 30.0


_said = False


def renders_available(say: bool = True) -> bool:
    """Whether PyVista imports; where it does not and ``say``, tell once (a line on stderr, the
    first time in a process) how to get it."""
    global _said
    try:
        import pyvista  # noqa: F401
    except ImportError:
        if say and not _said:
            _said = True
            print(f"hydrojam: note: {MISSING}", file=sys.stderr)
        return False
    return True


@dataclass(frozen=True)
class Surfaces:
    """The surfaces of an actuator state's bodies as straight triangles.

    Attributes
    ----------
    points : ndarray, shape (n, 3)
        Deformed node positions [mm].
    reference : ndarray, shape (n, 3)
        As-prepared node positions [mm].
    triangles : ndarray, shape (k, 3)
        Node indices of the triangles, each pointing out of its body.
    body : ndarray, shape (k,)
        Body id of each triangle (0 membrane, 1 strain-limit layer, 2 + j particle j).
    swelling : ndarray, shape (k,)
        Swelling ratio of each triangle's cell (gel volume over dry-network volume; 1 in the elastomers).
    outline : ndarray, shape (m, 2)
        Node indices of the undeformed walls' feature edges (the outline drawn faintly).
    chamber : ndarray, shape (k,), optional
        A multi-chamber design's: the chamber of each triangle's particle (-1 in the walls); None
        for one chamber.
    """

    points: np.ndarray
    reference: np.ndarray
    triangles: np.ndarray
    body: np.ndarray
    swelling: np.ndarray
    outline: np.ndarray
    chamber: np.ndarray | None = None

    def group(self, name: str) -> np.ndarray:
        """Mask of the triangles of ``name``: "membrane", "strain_limit" or "particles"."""
        if name == "membrane":
            return self.body == MEMBRANE_BODY
        if name == "strain_limit":
            return self.body == STRAIN_LIMIT_BODY
        if name == "particles":
            return self.body >= PARTICLE_BODY
        raise ValueError(f"no group {name!r} (membrane, strain_limit, particles)")


def _faces_once(faces: np.ndarray, keys: np.ndarray) -> np.ndarray:
    """Mask of the faces (f, 6) whose corner set, with their key, occurs once."""
    corners = np.sort(faces[:, :3], axis=1)
    _, inverse, counts = np.unique(np.column_stack([corners, keys]), axis=0, return_inverse=True,
                                   return_counts=True)
    return counts[inverse.ravel()] == 1


def _feature_edges(points: np.ndarray, tris: np.ndarray, angle_deg: float) -> np.ndarray:
    """Edges (m, 2) of a triangle surface used once, or between two triangles whose normals differ
    by more than ``angle_deg``."""
    n = np.cross(points[tris[:, 1]] - points[tris[:, 0]], points[tris[:, 2]] - points[tris[:, 0]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    edges = np.sort(tris[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2), axis=1)
    owner = np.repeat(np.arange(len(tris)), 3)
    order = np.lexsort((edges[:, 1], edges[:, 0]))
    edges, owner = edges[order], owner[order]
    same = np.all(edges[1:] == edges[:-1], axis=1)
    keep = np.ones(len(edges), dtype=bool)  # an edge used once is kept
    first = np.flatnonzero(same)
    keep[first + 1] = False  # the second use of a shared edge
    cos = np.einsum("ij,ij->i", n[owner[first]], n[owner[first + 1]])
    keep[first] = cos < np.cos(np.radians(angle_deg))
    return edges[keep]


def state_surfaces(mesh) -> Surfaces:
    """The bodies' surfaces of a 3D state as a VTU file holds it.

    Parameters
    ----------
    mesh : meshio.Mesh
        Reference points [mm], one block of ``tetra10`` cells, point data ``displacement`` [mm] and
        cell data ``body_id`` and ``swelling_ratio`` (:func:`~hydrojam.actuator.results.vtu_mesh`,
        or ``meshio.read`` of a written step).

    Returns
    -------
    Surfaces
        Every body's boundary faces, each quadratic face split into 4 straight triangles; faces two
        cells of one body share (the interior, and the symmetry plane of a mirrored half model) and
        the bond between the membrane and the strain-limit layer are left out; a particle's
        surface is whole.
    """
    blocks = [b for b in mesh.cells if b.type == "tetra10"]
    if len(blocks) != 1:
        raise ValueError("a 3D state: one block of tetra10 cells expected")
    cells = blocks[0].data
    body = np.asarray(mesh.cell_data["body_id"][0]).ravel().astype(int)
    swell = np.asarray(mesh.cell_data["swelling_ratio"][0], dtype=float).ravel()
    X = np.asarray(mesh.points, dtype=float)
    x = X + np.asarray(mesh.point_data["displacement"], dtype=float)
    local = ELEMENTS["tet10"].facets
    faces = cells[:, local].reshape(-1, local.shape[1])
    owner = np.repeat(np.arange(len(cells)), local.shape[0])
    once = _faces_once(faces, body[owner])
    faces, owner = faces[once], owner[once]
    walls = body[owner] < PARTICLE_BODY
    keep = ~walls
    keep[walls] = _faces_once(faces[walls], np.zeros(int(walls.sum()), dtype=int))  # the bond between them cancels
    faces, owner = faces[keep], owner[keep]
    tris = straight_pieces(faces, 2)
    rep = len(tris) // max(len(faces), 1)
    outline = _feature_edges(X, straight_pieces(faces[body[owner] < PARTICLE_BODY], 2), FEATURE_ANGLE_DEG)
    chamber = None
    if "chamber" in mesh.cell_data:  # a multi-chamber design's
        chamber = np.repeat(np.asarray(mesh.cell_data["chamber"][0]).ravel().astype(int)[owner], rep)
    return Surfaces(points=x, reference=X, triangles=tris, body=np.repeat(body[owner], rep),
                    swelling=np.repeat(swell[owner], rep), outline=outline, chamber=chamber)


def swelling_range(values: np.ndarray) -> tuple[float, float]:
    """A colour range for swelling ratios: their min and max, widened by 5 % where they are
    (nearly) uniform, as prepared."""
    lo, hi = float(np.min(values)), float(np.max(values))
    if hi - lo < 1e-3 * hi:
        lo, hi = 0.95 * lo, 1.05 * hi
    return lo, hi


def _pyvista():
    """PyVista, with VTK's note about a missing X display silenced (it then renders through EGL)."""
    from vtkmodules.vtkCommonCore import vtkLogger

    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    import pyvista as pv

    return pv


def _poly(pv, points: np.ndarray, tris: np.ndarray):
    used, inverse = np.unique(tris, return_inverse=True)
    faces = np.column_stack([np.full(len(tris), 3), inverse.reshape(tris.shape)])
    return pv.PolyData(points[used], faces.ravel())


class Renderer:
    """An off-screen PyVista window that draws actuator states (:func:`render_state`); kept open
    to draw the frames of a movie at one camera and colour range.

    Parameters
    ----------
    size : (int, int)
        Width and height of the image [pixels].
    bounds : array_like, shape (2, 3), optional
        Box [mm] the camera frames (min and max corners); default: each state's own.
    clim : (float, float), optional
        Colour range of the swelling ratio; default: each state's own (:func:`swelling_range`).
    """

    def __init__(self, size: tuple[int, int] = (1000, 900), bounds=None, clim=None):
        self.pv = _pyvista()
        self.size = size
        self.bounds = None if bounds is None else np.asarray(bounds, dtype=float)
        self.clim = clim
        self.plotter = self.pv.Plotter(off_screen=True, window_size=list(size))

    def close(self) -> None:
        """Free the window."""
        self.plotter.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def draw(self, surf: Surfaces, title: str = "", scale_bar: bool = True) -> np.ndarray:
        """The image (h, w, 3) of uint8 of one state, with ``title`` on top and, with
        ``scale_bar``, the swelling ratio's colour bar at the bottom (a figure of several renders
        on one colour range draws one bar itself)."""
        pv, p = self.pv, self.plotter
        p.clear()
        p.set_background("white")
        clim = self.clim or swelling_range(surf.swelling[surf.group("particles")])
        gel = surf.group("particles")
        if gel.any() and surf.chamber is not None:  # each chamber's gel in its own colours, one scale
            from hydrojam.actuator.plots import chamber_cmap

            chambers = np.unique(surf.chamber[gel])
            for i, k in enumerate(chambers):
                mine = gel & (surf.chamber == k)
                mesh = _poly(pv, surf.points, surf.triangles[mine])
                name = f"chamber {k} J"
                mesh.cell_data[name] = surf.swelling[mine]
                mesh = mesh.cell_data_to_point_data()
                p.add_mesh(mesh, scalars=name, cmap=chamber_cmap(int(k)), clim=clim, smooth_shading=True,
                           render=False, show_scalar_bar=scale_bar,
                           scalar_bar_args={"title": name, "vertical": False, "width": 0.6 / len(chambers),
                                            "height": 0.08, "position_x": 0.1 + 0.8 * i / len(chambers),
                                            "position_y": 0.05, "fmt": "%.2f", "n_labels": 2,
                                            "title_font_size": 16, "label_font_size": 14, "color": "black"})
        elif gel.any():
            mesh = _poly(pv, surf.points, surf.triangles[gel])
            mesh.cell_data["swelling ratio J"] = surf.swelling[gel]
            mesh = mesh.cell_data_to_point_data()
            p.add_mesh(mesh, scalars="swelling ratio J", cmap=SWELLING_CMAP, clim=clim, smooth_shading=True, render=False,
                       show_scalar_bar=scale_bar, scalar_bar_args={"title": "", "vertical": False, "width": 0.5,
                                        "height": 0.08, "position_x": 0.25, "position_y": 0.05, "fmt": "%.1f",
                                        "n_labels": 5, "title_font_size": 18, "label_font_size": 16,
                                        "color": "black"})
            if scale_bar:
                p.add_text("particle swelling ratio J", position="lower_edge", font_size=11, color="black", render=False)
        layer = surf.group("strain_limit")
        if layer.any():
            p.add_mesh(_poly(pv, surf.points, surf.triangles[layer]), color=STRAIN_LIMIT_RGB, smooth_shading=False,
                       render=False)
        wall = surf.group("membrane")
        if wall.any():
            p.add_mesh(_poly(pv, surf.points, surf.triangles[wall]), color=MEMBRANE_RGB, opacity=MEMBRANE_OPACITY,
                       smooth_shading=False, render=False)
        if len(surf.outline):
            lines = np.column_stack([np.full(len(surf.outline), 2), surf.outline]).ravel()
            p.add_mesh(pv.PolyData(surf.reference, lines=lines), color=OUTLINE_RGB, opacity=0.35, line_width=1.0, render=False)
        if title:
            p.add_text(title, position="upper_edge", font_size=13, color="black", render=False)
        self._frame(surf)
        p.render()
        return p.screenshot(None, return_img=True)

    def _frame(self, surf: Surfaces) -> None:
        if self.bounds is not None:
            lo, hi = self.bounds
        else:
            both = np.vstack([surf.points, surf.reference])
            lo, hi = both.min(axis=0), both.max(axis=0)
        centre = 0.5 * (lo + hi)
        radius = 0.5 * float(np.linalg.norm(hi - lo))
        view = np.array([0.45, -1.0, 0.3])  # from the +x, -y side, a little above: the bend shows
        view /= np.linalg.norm(view)
        cam = self.plotter.camera
        cam.focal_point = centre
        cam.up = (0.0, 0.0, 1.0)
        cam.view_angle = 30.0
        cam.position = centre + view * radius / np.sin(np.radians(15.0)) * 1.02
        cam.clipping_range = (0.01 * radius, 10.0 * radius)


def render_check() -> None:
    """Draw a small scene off-screen; RuntimeError where the image is blank (no working OpenGL:
    tools/bootstrap.sh then installs EGL and OSMesa)."""
    pv = _pyvista()
    p = pv.Plotter(off_screen=True, window_size=[64, 64])
    try:
        p.set_background("white")
        p.add_mesh(pv.Sphere(), color="red")
        img = p.screenshot(None, return_img=True)
    finally:
        p.close()
    if float(np.std(img)) < 1.0:
        raise RuntimeError("VTK rendered a blank image off-screen")


def render_title(angle_deg: float, tip_dx_mm: float, tip_dz_mm: float, temperature_K: float) -> str:
    """The title of a render: bending angle [deg], free-end displacement [mm], temperature [K]."""
    return (f"bending angle {angle_deg:.1f} deg, tip dx {tip_dx_mm:.1f} mm, dz {tip_dz_mm:.1f} mm, "
            f"T = {temperature_K:.1f} K")


def render_state(mesh, path: str | os.PathLike | None = None, title: str = "",
                 size: tuple[int, int] = (1000, 900)) -> np.ndarray:
    """Render one 3D state off-screen (PyVista) and write it as PNG (atomically) where ``path``.

    Parameters
    ----------
    mesh : meshio.Mesh
        The state as a VTU file holds it (:func:`state_surfaces`).
    path : str or os.PathLike, optional
        The PNG file to write.
    title : str
        Text on top (:func:`render_title`).
    size : (int, int)
        Width and height [pixels].

    Returns
    -------
    ndarray, shape (h, w, 3)
        The image (uint8).
    """
    with Renderer(size) as r:
        img = r.draw(state_surfaces(mesh), title)
    if path is not None:
        write_png(path, img)
    return img


def write_png(path: str | os.PathLike, img: np.ndarray) -> None:
    """Write an RGB image (h, w, 3) of uint8 as PNG, atomically."""
    from PIL import Image

    with atomic_path(Path(path)) as tmp:
        Image.fromarray(img).save(tmp, format="png")


__all__ = ["Surfaces", "state_surfaces", "Renderer", "render_state", "render_title", "renders_available",
           "swelling_range", "write_png", "render_check", "MISSING", "SWELLING_CMAP"]
