"""The HTML pages (hydrojam._html): built offline from one file, and opened in headless Chromium,
where the page must load without a console message, its 3D view must draw (a screenshot of the
canvas is not blank: its pixel variance) and turning the view or hiding the membrane must change
the picture. Skipped where Chromium is not installed (Debian: apt-get install chromium; .ci/run
installs it)."""

from __future__ import annotations

import re
import sys
import time
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent / "actuator"))
sys.path.insert(0, str(Path(__file__).parent))
from boxes import bent, box_mesh  # noqa: E402
from chromium import CHROMIUM, Page  # noqa: E402

from hydrojam._html import markdown_html, page_html, table_html  # noqa: E402
from hydrojam.actuator.page import state_view  # noqa: E402

needs_chromium = pytest.mark.skipif(CHROMIUM is None, reason="headless Chromium is not installed "
                                    "(Debian: apt-get install chromium; .ci/run installs it)")
WINDOW = (1000, 760)


def test_page_is_one_file_with_its_figures_inlined(tmp_path):
    """No reference to another file or to the network: images become data URIs, links stay."""
    from PIL import Image

    Image.new("RGB", (8, 8), "blue").save(tmp_path / "f.png")
    md = "# Title\n\n| a | b |\n|---|---|\n| 1 | x |\n\n![a figure](f.png)\n\n[docs](https://example.org)\n"
    body = markdown_html(md, tmp_path) + table_html(["k", "v"], [["angle", 1.5]])
    html = page_html("t", body)
    assert "<table>" in html and 'src="data:image/png;base64,' in html and 'src="f.png"' not in html
    assert '<td class="num">1.5</td>' in html
    assert not re.search(r'<(script|link|img)[^>]+(src|href)="(https?:)?//', html)
    assert 'id="hj-three"' not in html  # no 3D view: no viewer code


def _shot(url: str) -> np.ndarray:
    """The window's picture once the page's views in sight are drawn; its console stayed silent."""
    with Page(url, WINDOW) as p:
        p.wait("document.body.dataset.hjReady")
        shot = p.screenshot()
    assert p.console == []
    return shot


@needs_chromium
@pytest.mark.slow
def test_3d_view_draws_turns_and_hides_the_membrane(tmp_path):
    page = tmp_path / "page.html"
    page.write_text(page_html("view", state_view(bent(box_mesh(), 20.0), "hj-final")))
    canvas = (slice(60, 560), slice(60, 900))  # inside the canvas (the page's first element)
    first, turned, bare = (_shot(page.as_uri() + fragment) for fragment in ("", "#azimuth=90", "#hide=membrane"))
    assert float(first[canvas].std()) > 8.0, "the 3D view is blank"
    assert float(turned[canvas].std()) > 8.0
    assert float(np.abs(turned[canvas].astype(float) - first[canvas]).mean()) > 2.0, "turning the view changed nothing"
    assert float(np.abs(bare[canvas].astype(float) - first[canvas]).mean()) > 1.0, "hiding the membrane changed nothing"


#: the share of a view's canvas pixels that are not the white background (all of them where its
#: WebGL context was lost: the canvas turns black)
_INK = """((i) => {
  const c = document.querySelectorAll(".hj-scene canvas")[i];
  const copy = Object.assign(document.createElement("canvas"), { width: c.width, height: c.height });
  const ctx = copy.getContext("2d", { willReadFrequently: true });
  ctx.drawImage(c, 0, 0);
  const px = ctx.getImageData(0, 0, c.width, c.height).data;
  let ink = 0;
  for (let k = 0; k < px.length; k += 4) ink += px[k] + px[k + 1] + px[k + 2] < 750;
  return ink / (px.length / 4);
})"""
_DRAWN = "document.querySelectorAll('.hj-scene[data-hj-drawn]').length"


@needs_chromium
@pytest.mark.slow
def test_a_page_of_more_views_than_webgl_contexts(tmp_path):
    """20 views, more than a browser keeps WebGL contexts (about 16): the page loads without a
    console message (no context lost); only the views near the window are built, the first drawn;
    each view scrolled to is drawn, the first is still drawn after all were, and a mouse drag
    turns it."""
    n = 20
    page = tmp_path / "page.html"
    views = [state_view(bent(box_mesh(), 2.0 * i), f"hj-point-{i}", title=f"point {i}") for i in range(n)]
    page.write_text(page_html("views", "\n".join(views)))
    with Page(page.as_uri(), WINDOW) as p:
        p.wait("document.body.dataset.hjReady")
        assert 1 <= p.run(_DRAWN) <= 3, "views out of sight were built"
        assert float(p.screenshot()[100:560, 60:900].std()) > 8.0, "the first view is blank"
        for i in range(n):
            p.run(f"document.querySelectorAll('.hj-scene')[{i}].scrollIntoView()")
            p.wait(f"document.querySelectorAll('.hj-scene')[{i}].dataset.hjDrawn")
            assert 0.02 < p.run(f"{_INK}({i})") < 0.9, f"view {i} is blank (or black: its context lost)"
        assert p.run(_DRAWN) == n
        p.run("window.scrollTo(0, 0)")
        assert 0.02 < p.run(f"{_INK}(0)") < 0.9, "the first view was lost"
        before = p.screenshot()[100:560, 60:900].astype(float)
        p.drag((480, 330), (680, 330))  # the first view turned by the mouse, through the shared renderer
        time.sleep(0.5)
        assert float(np.abs(p.screenshot()[100:560, 60:900] - before).mean()) > 2.0, "dragging did not turn the view"
        assert p.console == []
