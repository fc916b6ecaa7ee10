"""Sphinx configuration of hydrojam's documentation site (``make docs``; built with warnings as
errors by tests/test_docs.py). The pages are Markdown (MyST); the API reference is generated from
the numpydoc docstrings. No theme or extension here needs the network at build time."""

import sys
from pathlib import Path

import hydrojam

sys.path.insert(0, str(Path(__file__).parent / "_ext"))

project = "hydrojam"
author = "the hydrojam developers"
copyright = "the hydrojam developers, MIT licence"
release = version = hydrojam.__version__

extensions = [
    "myst_parser",
    "numpydoc",
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
    "hydrojam_cli",
    "hydrojam_fields",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store"]

# MyST: links to headings (page.md#a-heading) as GitHub renders them, $...$ maths, ::: fences
myst_heading_anchors = 4
myst_enable_extensions = ["dollarmath", "colon_fence"]

# autodoc + numpydoc: document what each package's __all__ names, in source order
autodoc_default_options = {"members": True, "member-order": "bysource",
                           # pydantic's class attributes are not hydrojam's API
                           "exclude-members": "model_config, model_fields, model_computed_fields, model_post_init"}
autodoc_typehints = "none"
autodoc_preserve_defaults = True
numpydoc_show_class_members = False
numpydoc_xref_param_type = False
numpydoc_attributes_as_param_list = False

# alabaster ships with Sphinx: nothing is fetched at build time (MathJax is loaded by the reader's
# browser only on pages with maths)
html_theme = "alabaster"
html_static_path = ["_static"]
html_title = f"hydrojam {release}"
html_theme_options = {
    "description": "Active particle jamming actuators: FE + IPC contact",
    "fixed_sidebar": True,
    "page_width": "1100px",
    "sidebar_width": "240px",
}
html_sidebars = {"**": ["about.html", "navigation.html", "searchbox.html"]}


# The docstrings are plain text that numpydoc structures: |x| is a magnitude, never a substitution,
# and a lone * (ABAQUS's *STATIC) is not the start of an emphasis. Escape both before numpydoc
# (priority 500) and docutils read them.
def _plain_text_marks(app, what, name, obj, options, lines):
    import re

    for i, line in enumerate(lines):
        line = line.replace("|", "\\|")
        if len(re.findall(r"(?<![*\\])\*(?!\*)", line)) % 2:
            line = re.sub(r"(?<![*\\])\*(?!\*)", r"\\*", line)
        lines[i] = line


def setup(app):
    app.connect("autodoc-process-docstring", _plain_text_marks, priority=400)
