"""Self-contained HTML pages: text, tables and figures (PNG and GIF inlined as base64) and
interactive 3D views, in one file that opens offline in a browser.

The 3D view is three.js (MIT, vendored in ``hydrojam/_vendor/three``: its single-file module build
and OrbitControls) driven by ``hydrojam/_viewer.js``, all embedded in the page (the vendored
code zlib-compressed); it draws triangle surfaces and line segments given as arrays
(:func:`scene_group`: positions quantised to uint16, zlib-compressed), each group with a check
box that shows or hides it. Views are built as they come into sight and share one WebGL context.
"""

from __future__ import annotations

import base64
import html
import json
import mimetypes
import os
import re
import zlib
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


def _quantised(points: np.ndarray) -> tuple[np.ndarray, list[float], list[float]]:
    """``points`` (n, 3) [mm] as uint16 steps over their box: (steps, origin [mm], step [mm]), each
    point within half a step (1/131070 of the box's extent) of where it was."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    step = np.where(hi > lo, (hi - lo) / 65535.0, 1.0)
    q = np.clip(np.round((points - lo) / step), 0, 65535).astype("<u2")
    return q, [float(v) for v in lo], [float(v) for v in step]


def scene_group(name: str, label: str, points: np.ndarray, elements: np.ndarray, color=(0.6, 0.6, 0.6),
                opacity: float = 1.0, vertex_rgb: np.ndarray | None = None) -> dict:
    """One group of a 3D view: triangles (``elements`` (k, 3)) or line segments ((k, 2)) over
    ``points`` (n, 3) [mm] (only the points used are kept, each within 1/131070 of the group's
    extent), one colour (RGB in [0, 1]) or a colour per point (``vertex_rgb`` (n, 3) in [0, 1]),
    an opacity."""
    used, inverse = np.unique(elements, return_inverse=True)
    q, origin, step = _quantised(np.asarray(points, dtype=float)[used])
    index = inverse.reshape(elements.shape).astype("<u2" if len(used) <= 65536 else "<u4")
    g = {"name": name, "label": label, "kind": "lines" if elements.shape[1] == 2 else "mesh",
         "origin": origin, "step": step, "color": [float(c) for c in color], "opacity": float(opacity),
         "arrays": {"positions": q, "indices": index}}
    if vertex_rgb is not None:
        g["arrays"]["colors"] = np.clip(np.round(255 * vertex_rgb[used]), 0, 255).astype(np.uint8)
    return g


def _packed(groups: list[dict]) -> tuple[list[dict], str]:
    """The groups' arrays in one zlib-compressed, base64 buffer (each array at a multiple of 4
    bytes); each group's JSON names its arrays' [byte offset, element count, bytes an element]."""
    chunks, offset, out = [], 0, []
    for g in groups:
        g = dict(g)
        for key, a in g.pop("arrays").items():
            a = np.ascontiguousarray(a)
            g[key] = [offset, int(a.size), int(a.itemsize)]
            pad = -a.nbytes % 4
            chunks.append(a.tobytes() + b"\0" * pad)
            offset += a.nbytes + pad
        g.setdefault("colors", None)
        out.append(g)
    return out, base64.b64encode(zlib.compress(b"".join(chunks), 9)).decode("ascii")


def scene_html(key: str, groups: list[dict], title: str = "", up=(0.0, 0.0, 1.0), view=(0.45, -1.0, 0.3),
               scale: tuple[str, float, float, list[str]] | None = None) -> str:
    """An interactive 3D view of ``groups`` (:func:`scene_group`): drag to rotate, wheel to zoom,
    right-drag to pan, a check box per group; ``view``: the direction the camera looks from;
    ``scale``: a colour bar (label, min, max, colours from min to max as CSS colours). The view is
    built when it first comes near the window (or is clicked); all views of a page draw through
    one WebGL context, so a page may hold any number of them."""
    packed, blob = _packed(groups)
    data = {"up": list(up), "view": list(view), "groups": packed, "data": blob}
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


@cache
def _packed_asset(name: str) -> str:
    """A vendored script zlib-compressed and base64 (the viewer inflates it in the browser)."""
    return base64.b64encode(zlib.compress(_script_text(_asset(name)).encode("utf-8"), 9)).decode("ascii")


def page_html(title: str, body: str) -> str:
    """A whole page: ``body`` (HTML) under ``title``; the 3D viewer's code is embedded when the
    body holds a 3D view (:func:`scene_html`)."""
    scripts = ""
    if 'class="hj-scene"' in body:
        three, orbit = _packed_asset("_vendor/three/three.module.min.js"), _packed_asset("_vendor/three/OrbitControls.js")
        scripts = (f'<script type="text/plain" id="hj-three">{three}</script>'
                   f'<script type="text/plain" id="hj-orbit">{orbit}</script>'
                   f'<script type="module">{_script_text(_asset("_viewer.js"))}</script>')
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"><title>{html.escape(title)}</title>"
            f"<style>{_CSS}</style></head><body>\n{body}\n{scripts}</body></html>\n")


__all__ = ["page_html", "markdown_page", "scene_html", "scene_group", "markdown_html", "table_html", "figure_html",
           "data_uri"]
