"""Self-contained HTML pages: text, tables and figures (PNG and GIF inlined as base64) and
interactive 3D views, in one file that opens offline in a browser.

The 3D view is three.js (MIT, vendored in ``hydrojam/_vendor/three``: its single-file module build
and OrbitControls) driven by ``hydrojam/_viewer.js``, all embedded in the page; it draws
triangle surfaces and line segments given as arrays (:func:`scene_group`), each group with a
check box that shows or hides it.
"""

from __future__ import annotations

import base64
import html
import json
import mimetypes
import os
import re
from functools import cache
from importlib import resources
from pathlib import Path

import numpy as np

_MIME = {".png": "image/png", ".gif": "image/gif", ".jpg": "image/jpeg", ".jpeg": "image/jpeg", ".svg": "image/svg+xml"}

_CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; margin: 0 auto; max-width: 1150px;
       padding: 1.5em; color: #222; line-height: 1.45; }
h1 { font-size: 1.6em; } h2 { font-size: 1.3em; margin-top: 1.6em; border-bottom: 1px solid #ddd; }
table { border-collapse: collapse; margin: 0.8em 0; font-size: 0.92em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: left; }
th { background: #f3f3f3; } td.num { text-align: right; font-variant-numeric: tabular-nums; }
img { max-width: 100%; height: auto; }
pre, code { background: #f6f6f6; font-size: 0.9em; } pre { padding: 0.6em; overflow-x: auto; }
.hj-scene { border: 1px solid #ccc; margin: 1em 0; }
.hj-scene canvas { width: 100%; height: 620px; display: block; cursor: grab; }
.hj-bar { display: flex; flex-wrap: wrap; gap: 1.2em; align-items: center; padding: 0.4em 0.8em;
          background: #f7f7f7; font-size: 0.9em; }
.hj-toggles { display: flex; gap: 1em; flex-wrap: wrap; }
.hj-scale { display: flex; align-items: center; gap: 0.4em; }
.hj-scale span.ramp { display: inline-block; width: 160px; height: 12px; border: 1px solid #999; }
"""


@cache
def _asset(name: str) -> str:
    return resources.files("hydrojam").joinpath(name).read_text(encoding="utf-8")


def _script_text(text: str) -> str:
    """Code safe inside a <script> element: refused where it holds a closing tag or an HTML
    comment opener (the vendored and own scripts hold none)."""
    if re.search(r"</script|<!--", text, flags=re.IGNORECASE):
        raise ValueError("a script holds '</script' or '<!--'")
    return text


def _json_text(data) -> str:
    """JSON safe inside a <script> element: every '<' escaped."""
    return json.dumps(data).replace("<", "\\u003c")


def data_uri(path: str | os.PathLike) -> str:
    """A file as a base64 data URI (its type from its suffix)."""
    path = Path(path)
    mime = _MIME.get(path.suffix.lower()) or mimetypes.guess_type(path.name)[0] or "application/octet-stream"
    return f"data:{mime};base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def figure_html(path: str | os.PathLike, caption: str = "") -> str:
    """A figure file (PNG, GIF) inlined, with its caption."""
    cap = f"<figcaption>{html.escape(caption)}</figcaption>" if caption else ""
    return f'<figure><img src="{data_uri(path)}" alt="{html.escape(caption or Path(path).name)}">{cap}</figure>'


def table_html(header: list[str], rows: list[list]) -> str:
    """A table; numbers right-aligned."""
    def cell(v):
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            return f'<td class="num">{html.escape(f"{v:.6g}" if isinstance(v, float) else str(v))}</td>'
        return f"<td>{html.escape('' if v is None else str(v))}</td>"
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(cell(v) for v in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def markdown_html(text: str, base: str | os.PathLike) -> str:
    """Markdown (CommonMark with tables) as HTML, its local images inlined from ``base``."""
    from markdown_it import MarkdownIt

    out = MarkdownIt("commonmark").enable("table").render(text)
    base = Path(base)

    def inline(m: re.Match) -> str:
        src = html.unescape(m.group(2))
        if re.match(r"^[a-z]+:", src):
            return m.group(0)
        f = base / src
        return f'{m.group(1)}"{data_uri(f)}"' if f.is_file() else m.group(0)

    return re.sub(r'(<img src=)"([^"]*)"', inline, out)


def markdown_page(text: str, base: str | os.PathLike, title: str) -> str:
    """A whole page (:func:`page_html`) of a Markdown report, its local figures inlined from ``base``."""
    return page_html(title, markdown_html(text, base))


def _b64(a: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(a).tobytes()).decode("ascii")


def scene_group(name: str, label: str, points: np.ndarray, elements: np.ndarray, color=(0.6, 0.6, 0.6),
                opacity: float = 1.0, vertex_rgb: np.ndarray | None = None) -> dict:
    """One group of a 3D view: triangles (``elements`` (k, 3)) or line segments ((k, 2)) over
    ``points`` (n, 3) [mm] (only the points used are kept), one colour (RGB in [0, 1]) or a colour
    per point (``vertex_rgb`` (n, 3) in [0, 1]), an opacity."""
    used, inverse = np.unique(elements, return_inverse=True)
    g = {"name": name, "label": label, "kind": "lines" if elements.shape[1] == 2 else "mesh",
         "positions": _b64(points[used].astype("<f4")), "indices": _b64(inverse.reshape(elements.shape).astype("<u4")),
         "color": [float(c) for c in color], "opacity": float(opacity), "colors": None}
    if vertex_rgb is not None:
        g["colors"] = _b64(np.clip(np.round(255 * vertex_rgb[used]), 0, 255).astype(np.uint8))
    return g


def scene_html(key: str, groups: list[dict], title: str = "", up=(0.0, 0.0, 1.0), view=(0.45, -1.0, 0.3),
               scale: tuple[str, float, float, list[str]] | None = None) -> str:
    """An interactive 3D view of ``groups`` (:func:`scene_group`): drag to rotate, wheel to zoom,
    right-drag to pan, a check box per group; ``view``: the direction the camera looks from;
    ``scale``: a colour bar (label, min, max, colours from min to max as CSS colours)."""
    data = {"up": list(up), "view": list(view), "groups": groups}
    ramp = ""
    if scale is not None:
        label, lo, hi, stops = scale
        ramp = (f'<span class="hj-scale">{html.escape(label)}: {lo:.3g} <span class="ramp" style="background: '
                f'linear-gradient(to right, {", ".join(stops)})"></span> {hi:.3g}</span>')
    head = f"<h3>{html.escape(title)}</h3>" if title else ""
    return (f'{head}<div class="hj-scene" data-scene="{key}"><canvas></canvas><div class="hj-bar">'
            f'<span class="hj-toggles"></span>{ramp}<button class="hj-reset" type="button">reset view</button>'
            f"<span>drag: rotate, wheel: zoom, right-drag: pan</span></div></div>"
            f'<script type="application/json" id="{key}">{_json_text(data)}</script>')


def page_html(title: str, body: str) -> str:
    """A whole page: ``body`` (HTML) under ``title``; the 3D viewer's code is embedded when the
    body holds a 3D view (:func:`scene_html`)."""
    scripts = ""
    if 'class="hj-scene"' in body:
        three, orbit = _asset("_vendor/three/three.module.min.js"), _asset("_vendor/three/OrbitControls.js")
        scripts = (f'<script type="text/plain" id="hj-three">{_script_text(three)}</script>'
                   f'<script type="text/plain" id="hj-orbit">{_script_text(orbit)}</script>'
                   f'<script type="module">{_script_text(_asset("_viewer.js"))}</script>')
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"><title>{html.escape(title)}</title>"
            f"<style>{_CSS}</style></head><body>\n{body}\n{scripts}</body></html>\n")


__all__ = ["page_html", "markdown_page", "scene_html", "scene_group", "markdown_html", "table_html", "figure_html",
           "data_uri"]
