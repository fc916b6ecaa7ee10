"""The HTML pages (hydrojam._html): built offline from one file, and opened in headless Chromium,
where the page must load without a console message, its 3D view must draw (a screenshot of the
canvas is not blank: its pixel variance) and turning the view or hiding the membrane must change
the picture. Skipped where Chromium is not installed (Debian: apt-get install chromium; .ci/run
installs it)."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent / "actuator"))
from boxes import bent, box_mesh  # noqa: E402

from hydrojam._html import markdown_html, page_html, table_html  # noqa: E402
from hydrojam.actuator.page import state_view  # noqa: E402

CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)), None)
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


def _open(page: Path, tmp_path: Path, fragment: str = "") -> tuple[np.ndarray, str, list[str]]:
    """Open ``page`` in headless Chromium: (screenshot (h, w, 3), the DOM after load, the console's messages)."""
    from PIL import Image

    shot = tmp_path / f"shot{len(list(tmp_path.glob('shot*.png')))}.png"
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
           "--enable-unsafe-swiftshader", "--hide-scrollbars", "--no-first-run", f"--window-size={WINDOW[0]},{WINDOW[1]}",
           f"--user-data-dir={tmp_path / 'profile'}", "--enable-logging=stderr", "--v=0", "--virtual-time-budget=15000",
           f"--screenshot={shot}", "--dump-dom", page.as_uri() + fragment]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert shot.is_file(), done.stderr[-2000:]
    # the console's messages; WebGL's driver notes (software GL reading pixels back) are not the page's
    console = [line for line in done.stderr.splitlines() if ":CONSOLE" in line and "GL Driver Message" not in line]
    return np.asarray(Image.open(shot).convert("RGB")), done.stdout, console


@needs_chromium
@pytest.mark.slow
def test_3d_view_draws_turns_and_hides_the_membrane(tmp_path):
    page = tmp_path / "page.html"
    page.write_text(page_html("view", state_view(bent(box_mesh(), 20.0), "hj-final")))
    canvas = (slice(60, 560), slice(60, 900))  # inside the canvas (the page's first element)
    first, dom, console = _open(page, tmp_path)
    assert console == []
    assert 'data-hj-ready="1"' in dom, "the viewer did not finish"
    assert float(first[canvas].std()) > 8.0, "the 3D view is blank"
    turned, _, console = _open(page, tmp_path, "#azimuth=90")
    assert console == []
    assert float(turned[canvas].std()) > 8.0
    assert float(np.abs(turned[canvas].astype(float) - first[canvas]).mean()) > 2.0, "turning the view changed nothing"
    bare, _, console = _open(page, tmp_path, "#hide=membrane")
    assert console == []
    assert float(np.abs(bare[canvas].astype(float) - first[canvas]).mean()) > 1.0, "hiding the membrane changed nothing"
