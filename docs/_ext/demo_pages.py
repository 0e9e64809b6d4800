"""Sphinx extension: the demos (jupytext light-format scripts, ``demos/*.py``) as pages.

Each demo becomes ``docs/demos/<name>.md`` when the build starts: its comment blocks become the
page's Markdown (headings, text, maths), its code cells Python code blocks, in the order of the
script. The pictures a default run of the demo writes (committed under ``docs/img``) follow at the
end. The generated pages are not committed (``docs/demos/.gitignore``); a page is rewritten only
when its text changes, so incremental builds stay incremental.

Configuration (``conf.py``)::

    demo_pages_source = "../demos"          # relative to the documentation's source directory
    demo_pages = {"bar_2d": [("bar_solution.png", "caption"), ...], ...}   # the demos shown

The scripts are read with jupytext (Debian's ``python3-jupytext``), the same reader that turns
them into notebooks.
"""

from __future__ import annotations

import struct
from pathlib import Path

import jupytext

GENERATED = "demos"


def demo_markdown(text: str, name: str, pictures=()) -> str:
    """The MyST Markdown page of a light-format script.

    Args:
        text: The script.
        name: The script's name without ``.py`` (for the note on the source).
        pictures: ``(file name under docs/img, caption)`` or ``(file name, caption, width)``
            tuples shown after the script; the width is a CSS width (default ``80%``).

    Returns:
        The page: Markdown cells as they are, code cells as fenced ``python`` blocks, then a
        section "Output" with the pictures.
    """
    notebook = jupytext.reads(text, fmt="py:light")
    parts = []
    for cell in notebook.cells:
        source = cell.source.strip("\n")
        if not source.strip():
            continue
        if cell.cell_type == "markdown":
            parts.append(source)
        else:
            parts.append(f"```python\n{source}\n```")
    output = [
        "## Output",
        f"This page is the script `demos/{name}.py`; run it with "
        f"`scripts/fenicsx python3 demos/{name}.py`.",
    ]
    if pictures:
        output[-1] += " The pictures are from a run with its default options."
    for picture, caption, *width in pictures:
        output.append(
            f"```{{figure}} ../img/{picture}\n:alt: {caption}\n:width: {(width or ['80%'])[0]}"
            f"\n\n{caption}\n```"
        )
    return "\n\n".join(parts + output) + "\n"


def picture_width(path: Path) -> str:
    """A CSS width for a PNG on a page: narrower for portrait pictures, so they fit a screen.

    Args:
        path: The PNG file.

    Returns:
        ``"30%"`` for a picture taller than wide, else ``"80%"``.
    """
    width, height = struct.unpack(">II", path.read_bytes()[16:24])
    return "30%" if height > width else "80%"


def write_if_changed(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` unless the file already holds it."""
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


def generate(app, config) -> None:
    """Write the demo pages into the source directory (``config-inited``)."""
    srcdir = Path(app.srcdir)
    scripts = (srcdir / config.demo_pages_source).resolve()
    outdir = srcdir / GENERATED
    outdir.mkdir(exist_ok=True)
    for name, pictures in config.demo_pages.items():
        text = (scripts / f"{name}.py").read_text()
        sized = [(png, caption, picture_width(srcdir / "img" / png)) for png, caption in pictures]
        write_if_changed(outdir / f"{name}.md", demo_markdown(text, name, sized))


def setup(app):
    """Register the configuration values and the page generation."""
    app.add_config_value("demo_pages_source", "../demos", "env")
    app.add_config_value("demo_pages", {}, "env")
    app.connect("config-inited", generate)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
