"""A Sphinx directive that writes a command's ``--help`` into the page, so the CLI reference is the
command line's own text and cannot drift from it::

    ```{cli-help} run
    ```

The text is click's plain help (the terminal's is the same options drawn by rich), 100 columns.
"""

from __future__ import annotations

import importlib

from docutils import nodes
from sphinx.util.docutils import SphinxDirective


def command_help(name: str, width: int = 100) -> str:
    """The plain-text help of ``hydrojam NAME`` (of ``hydrojam`` itself for an empty name)."""
    import typer.main

    from hydrojam.cli import app

    group = typer.main.get_command(app)
    # the click base class's format_help: the plain layout, not typer's rich panels
    base = next(c for c in type(group).__mro__ if c.__name__ == "Command" and c.__module__.endswith("click.core"))
    core = importlib.import_module(base.__module__)
    settings = dict(group.context_settings or {})
    root = core.Context(group, info_name="hydrojam", max_content_width=width, terminal_width=width, **settings)
    if not name:
        ctx, command = root, group
    else:
        command = group.commands[name]
        ctx = core.Context(command, info_name=name, parent=root, max_content_width=width, terminal_width=width,
                           **settings)
    formatter = ctx.make_formatter()
    base.format_help(command, ctx, formatter)
    # a help text escapes a literal "[" from rich's markup with a backslash; the plain layout drops it
    return formatter.getvalue().replace("\\[", "[").rstrip() + "\n"


class CliHelp(SphinxDirective):
    optional_arguments = 1
    has_content = False

    def run(self):
        name = self.arguments[0] if self.arguments else ""
        try:
            text = command_help(name)
        except KeyError:
            raise self.error(f"hydrojam has no command {name!r}")
        block = nodes.literal_block(text, text)
        block["language"] = "text"
        return [block]


def setup(app):
    app.add_directive("cli-help", CliHelp)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
