"""The pictures of a run (hydrojam.actuator.render, movie, page): the bodies' surfaces checked
against the boxes' closed-form areas, volumes and edges (tests/actuator/boxes.py), the render
off-screen (with the extra ``render``), the movie's frames and the run's HTML page; no solver."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from boxes import bent, box_mesh, write_run

from hydrojam.actuator import render as render_mod
from hydrojam.actuator.movie import NoStates, mp4_encoder, write_movie, written_states
from hydrojam.actuator.page import run_page, write_run_page
from hydrojam.actuator.render import MISSING, render_title, renders_available, state_surfaces
from hydrojam.cli import main

HAVE_PYVISTA = renders_available(say=False)
needs_pyvista = pytest.mark.skipif(not HAVE_PYVISTA, reason="PyVista (the extra 'render') is not installed")


def _area(points, tris):
    return 0.5 * np.linalg.norm(np.cross(points[tris[:, 1]] - points[tris[:, 0]], points[tris[:, 2]] - points[tris[:, 0]]),
                                axis=1).sum()


def _volume(points, tris):
    """Enclosed volume by the divergence theorem: positive where the triangles point outward."""
    p = points
    return np.einsum("ij,ij->i", p[tris[:, 0]], np.cross(p[tris[:, 1]], p[tris[:, 2]])).sum() / 6.0


def test_surfaces_of_the_boxes_match_their_areas_volume_and_edges():
    """Membrane 10 mm cube less its bonded face: 500 mm^2; strain-limit layer 3 x 10 x 10 mm less the
    bond: 220 mm^2; particle 4 mm cube: 96 mm^2 enclosing 64 mm^3 (faces outward); interior faces
    (shared by two cells of a body) gone; the walls' outline is the 12 edges of the 13 x 10 x 10 mm
    box they make together, 132 mm long (the bond's edges lie in flat faces: no feature)."""
    surf = state_surfaces(box_mesh())
    P, T = surf.points, surf.triangles
    assert _area(P, T[surf.group("membrane")]) == pytest.approx(500.0, rel=1e-12)
    assert _area(P, T[surf.group("strain_limit")]) == pytest.approx(220.0, rel=1e-12)
    gel = T[surf.group("particles")]
    assert _area(P, gel) == pytest.approx(96.0, rel=1e-12)
    assert _volume(P, gel) == pytest.approx(64.0, rel=1e-12)
    assert len(gel) == 6 * 2 * 4  # 6 faces, 2 tri6 each, 4 straight pieces each
    seg = surf.reference[surf.outline]
    assert np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1).sum() == pytest.approx(4 * (13 + 10 + 10), rel=1e-12)
    assert set(np.round(surf.swelling[surf.group("membrane")], 12)) == {1.0}


def test_surfaces_follow_the_displacement_the_outline_stays_as_prepared():
    """A rigid rotation by 30 deg about y: every deformed point is the rotated reference point; the
    enclosed volume is kept; the outline uses the reference points."""
    mesh = bent(box_mesh(), 30.0)
    surf = state_surfaces(mesh)
    a = np.radians(30.0)
    R = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
    assert np.allclose(surf.points, surf.reference @ R.T, atol=1e-12)
    assert _volume(surf.points, surf.triangles[surf.group("particles")]) == pytest.approx(64.0, rel=1e-12)
    assert np.array_equal(surf.reference, box_mesh().points)


def test_without_pyvista_it_says_once_how_to_get_the_renders(monkeypatch, capsys):
    monkeypatch.setitem(__import__("sys").modules, "pyvista", None)  # import pyvista -> ImportError
    monkeypatch.setattr(render_mod, "_said", False)
    assert renders_available() is False
    assert renders_available() is False
    err = capsys.readouterr().err
    assert err.count(MISSING) == 1 and "pip install 'hydrojam[render]'" in err


@needs_pyvista
@pytest.mark.slow
def test_render_draws_the_bodies_in_their_colours(tmp_path):
    """The render off-screen: a PNG of the asked size whose pixels hold the strain-limit layer's
    colour and the swelling colour map's (not a blank image)."""
    from PIL import Image

    img = render_mod.render_state(bent(box_mesh(), 20.0), tmp_path / "r.png", title=render_title(20.0, -1.0, -2.0, 275.0),
                                  size=(320, 240))
    assert img.shape == (240, 320, 3)
    assert np.array_equal(np.asarray(Image.open(tmp_path / "r.png").convert("RGB")), img)
    assert float(img.std()) > 10.0
    assert _orange_share(img) > 0.01  # the strain-limit layer


def _orange_share(img) -> float:
    """Share of the pixels in the strain-limit layer's colour (lit or shaded)."""
    return float(np.all(np.abs(img.astype(int) - np.array([217, 115, 51])) < 60, axis=2).mean())


@needs_pyvista
@pytest.mark.slow
def test_a_renderer_draws_every_state_anew():
    """A movie's window draws each frame whole: the second state's frame has the strain-limit
    layer too (VTK's screenshot of a window whose actors changed without a render was the stale
    first frame's particles alone), and it differs from the first."""
    with render_mod.Renderer((240, 200)) as r:
        a = r.draw(state_surfaces(bent(box_mesh(), 0.0)), "first")
        b = r.draw(state_surfaces(bent(box_mesh(), 30.0)), "second")
    assert _orange_share(a) > 0.01 and _orange_share(b) > 0.01
    assert float(np.abs(a.astype(float) - b).mean()) > 1.0


def test_written_states_read_the_pvd_and_history(tmp_path):
    angles = write_run(tmp_path / "run", n=3)
    states = written_states(tmp_path / "run")
    assert [st.step for st in states] == [0, 1, 2]
    assert [st.angle_deg for st in states] == pytest.approx(angles)
    assert states[-1].s == 1.0 and states[-1].temperature_K == pytest.approx(275.0)
    assert "s = 1.000" in states[-1].caption() and "T = 275.0 K" in states[-1].caption()
    with pytest.raises(NoStates, match="no results.pvd"):
        written_states(tmp_path)


@pytest.mark.parametrize("dim", [2, 3])
def test_movie_has_a_frame_per_state(tmp_path, monkeypatch, dim):
    """One frame per written state, the last held longer; 3D without PyVista: the section y = 0."""
    from PIL import Image

    monkeypatch.setattr("hydrojam.actuator.movie.renders_available", lambda: False)
    write_run(tmp_path / "run", dim=dim, n=3)
    path = write_movie(tmp_path / "run", size=(320, 280))
    assert path == tmp_path / "run" / "movie.gif"
    with Image.open(path) as gif:
        assert gif.n_frames == 3 and gif.size == (320, 280)
        gif.seek(2)
        assert gif.info["duration"] > 1000


@needs_pyvista
@pytest.mark.slow
def test_3d_movie_is_rendered_and_thinned(tmp_path):
    from PIL import Image

    write_run(tmp_path / "run", dim=3, n=5)
    path = write_movie(tmp_path / "run", tmp_path / "m.gif", max_frames=3, size=(240, 200))
    with Image.open(path) as gif:
        assert gif.n_frames == 3 and gif.size == (240, 200)


@pytest.mark.skipif(mp4_encoder() is None, reason="no ffmpeg (on PATH or from imageio-ffmpeg, the extra 'render')")
def test_mp4_movie_holds_a_frame_per_state_and_the_last_a_second(tmp_path, monkeypatch):
    """An MP4 (H.264) where an encoder is found: one frame per state, then the last for a second
    (fps frames), frame sides padded even; ffmpeg's own reader counts them."""
    import subprocess

    monkeypatch.setattr("hydrojam.actuator.movie.renders_available", lambda: False)
    write_run(tmp_path / "run", dim=2, n=3)
    path = write_movie(tmp_path / "run", tmp_path / "m.mp4", fps=4.0, size=(321, 281))
    assert path.read_bytes()[4:8] == b"ftyp"
    probe = subprocess.run([mp4_encoder(), "-hide_banner", "-i", str(path), "-map", "0:v", "-f", "null", "-"],
                           capture_output=True, text=True, check=True)
    assert "Video: h264" in probe.stderr and "322x282" in probe.stderr
    assert re.findall(r"frame=\s*(\d+)", probe.stderr)[-1] == "7"
    assert not list(tmp_path.glob(".m.*"))  # no temporary left


def test_mp4_without_an_encoder_is_one_line_and_writes_nothing(tmp_path, monkeypatch, capsys):
    import hydrojam.actuator

    monkeypatch.setattr("hydrojam.actuator.movie.mp4_encoder", lambda: None)
    monkeypatch.setattr(hydrojam.actuator, "mp4_encoder", lambda: None, raising=False)
    write_run(tmp_path / "run", dim=2, n=2)
    assert main(["animate", str(tmp_path / "run"), "--movie", str(tmp_path / "m.mp4")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("hydrojam: error: --movie: an MP4 needs ffmpeg")
    assert not (tmp_path / "m.mp4").exists()
    with pytest.raises(ValueError, match="an MP4 needs ffmpeg"):
        write_movie(tmp_path / "run", tmp_path / "m.mp4")


def test_animate_command(tmp_path, capsys):
    """`hydrojam animate`: bad input is one line and exit 2; a run's folder gets movie.gif."""
    assert main(["animate", str(tmp_path / "none")]) == 2
    assert main(["animate", str(tmp_path), "--fps", "0"]) == 2
    assert main(["animate", str(tmp_path), "--max-frames", "1"]) == 2
    assert main(["animate", str(tmp_path), "--movie", str(tmp_path / "m.avi")]) == 2
    assert main(["animate", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 5 and all(line.startswith("hydrojam: error: ") for line in err)
    write_run(tmp_path / "run", dim=2, n=2)
    assert main(["animate", str(tmp_path / "run")]) == 0
    assert (tmp_path / "run" / "movie.gif").is_file()


def test_run_page_holds_metrics_figures_and_the_3d_view(tmp_path):
    """report.html: the metrics table, the figures inlined (no reference to a file beside it) and,
    in 3D, the viewer's data with one group per body kind and the outline."""
    out = tmp_path / "run"
    write_run(out, dim=3, n=2)
    (out / "metrics.json").write_text(json.dumps({"bending_angle_deg": 30.0, "tip_dx_mm": -3.0, "message": "converged",
                                                  "timings_s": {"total": 1.0}}))
    from PIL import Image

    Image.new("RGB", (20, 10), "red").save(out / "final.png")
    path = write_run_page(out)
    text = path.read_text()
    assert "bending angle 30.0 deg" in text and "<td>bending_angle_deg</td>" in text
    assert "data:image/png;base64," in text and 'src="final.png"' not in text
    scene = json.loads(text.split('<script type="application/json" id="hj-final">', 1)[1].split("</script>", 1)[0])
    assert [g["name"] for g in scene["groups"]] == ["particles", "strain_limit", "membrane", "outline"]
    assert scene["groups"][0]["colors"] is not None
    assert 'id="hj-three"' in text and "three.js authors" not in text.split('id="hj-three"')[0]
    write_run(tmp_path / "run2d", dim=2, n=2)
    page_2d = run_page(tmp_path / "run2d")
    assert 'class="hj-scene"' not in page_2d and 'id="hj-three"' not in page_2d  # 2D: no 3D view, no viewer code
