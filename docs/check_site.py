"""Check the built site as a reader would meet it: links, images, and two pages on screen.

    python3 docs/check_site.py docs/_build/html                 # links, anchors, images
    python3 docs/check_site.py docs/_build/html --screenshots docs/screenshots

Every ``href`` and ``src`` of every page that points into the site must name an existing file,
and a ``#fragment`` an element id of the page it points to; every image must be a non-empty file.
Links to other sites (``http:``, ``https:``, ``mailto:``) are not followed. With
``--screenshots`` the landing page and one demo page are rendered by headless Chromium to PNG.
Used by ``make docs-check`` and ``tests/test_docs.py``.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import shutil
import subprocess
import sys
import threading
from collections.abc import Iterator
from html.parser import HTMLParser
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import unquote, urlsplit

# The pages rendered by --screenshots: (page, PNG name, window width, window height).
SCREENSHOTS = (
    ("index.html", "landing.png", 1280, 1000),
    ("demos/bar_2d.html", "demo_bar_2d.png", 1280, 1400),
)


class _Page(HTMLParser):
    """The ids of a page and the references it makes (tag, attribute value)."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.ids: set[str] = set()
        self.refs: list[tuple[str, str]] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        values = {key: value for key, value in attrs if value is not None}
        if "id" in values:
            self.ids.add(values["id"])
        if tag == "a" and "name" in values:
            self.ids.add(values["name"])
        if tag in ("a", "link") and "href" in values:
            self.refs.append((tag, values["href"]))
        if tag in ("img", "script", "source", "iframe") and "src" in values:
            self.refs.append((tag, values["src"]))


def _parse(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8"))
    return page


def check_site(root: str | Path) -> tuple[list[str], int]:
    """Check the internal links, anchors and images of a built HTML site.

    Args:
        root: The directory of the site (``docs/_build/html``).

    Returns:
        The problems found, one line each (empty when the site is sound), and the number of
        references checked.

    Raises:
        FileNotFoundError: If ``root`` has no ``index.html``.
    """
    root = Path(root).resolve()
    if not (root / "index.html").is_file():
        raise FileNotFoundError(f"{root} holds no built site (no index.html)")
    pages = {path: _parse(path) for path in sorted(root.rglob("*.html"))}
    problems: list[str] = []
    checked = 0
    for path, page in pages.items():
        name = path.relative_to(root)
        for tag, ref in page.refs:
            parts = urlsplit(ref)
            if parts.scheme or parts.netloc or ref.startswith(("mailto:", "javascript:", "data:")):
                continue
            checked += 1
            target = (path.parent / unquote(parts.path)).resolve() if parts.path else path
            if target.is_dir():
                target = target / "index.html"
            if not target.is_file():
                problems.append(f"{name}: <{tag}> {ref}: no such file")
                continue
            if tag == "img" and target.stat().st_size == 0:
                problems.append(f"{name}: <img> {ref}: empty file")
            fragment = unquote(parts.fragment)
            if fragment and target.suffix == ".html":
                ids = pages[target].ids if target in pages else _parse(target).ids
                if fragment not in ids:
                    problems.append(f"{name}: {ref}: no element with id {fragment!r}")
    return problems, checked


def chromium() -> str:
    """The Chromium executable.

    Returns:
        Its path.

    Raises:
        FileNotFoundError: If neither ``chromium`` nor ``chromium-browser`` is on the PATH
            (``make docs-env`` installs Debian's).
    """
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    raise FileNotFoundError("chromium not found: run `make docs-env` (env/docs-packages.txt)")


class _QuietHandler(SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: object) -> None:
        pass


@contextlib.contextmanager
def serve(root: Path) -> Iterator[str]:
    """Serve ``root`` over HTTP on a free port of 127.0.0.1 while the context lasts.

    Pages are shown as a reader's browser shows a published site: over ``file://`` Chromium
    refuses the theme's JavaScript modules.

    Args:
        root: The directory to serve.

    Yields:
        The base URL, ending in ``/``.
    """
    handler = functools.partial(_QuietHandler, directory=str(root))
    with ThreadingHTTPServer(("127.0.0.1", 0), handler) as server:
        thread = threading.Thread(target=server.serve_forever, daemon=True)
        thread.start()
        try:
            yield f"http://127.0.0.1:{server.server_address[1]}/"
        finally:
            server.shutdown()


def screenshot(url: str, png: Path, width: int, height: int) -> None:
    """Render the page at ``url`` with headless Chromium to the PNG ``png``.

    Args:
        url: The page.
        png: The PNG to write.
        width: Window width in pixels.
        height: Window height in pixels.

    Raises:
        RuntimeError: If Chromium fails or writes no picture.
    """
    png.parent.mkdir(parents=True, exist_ok=True)
    png.unlink(missing_ok=True)
    command = [
        chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
        "--no-first-run", "--force-device-scale-factor=1", f"--window-size={width},{height}",
        "--virtual-time-budget=20000", f"--screenshot={png.resolve()}", url,
    ]
    done = subprocess.run(command, capture_output=True, text=True, timeout=180, check=False)
    if done.returncode != 0 or not png.is_file() or png.stat().st_size == 0:
        raise RuntimeError(f"chromium failed ({done.returncode}) on {url}:\n{done.stderr[-2000:]}")


def main(argv: list[str] | None = None) -> int:
    """Command line: check a site, optionally take the screenshots; exit status 1 on problems."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("site", type=Path, help="the built site, e.g. docs/_build/html")
    parser.add_argument("--screenshots", type=Path, help="write the PNG screenshots here")
    args = parser.parse_args(argv)
    problems, checked = check_site(args.site)
    for line in problems:
        print(line)
    print(f"{checked} internal links and images checked, {len(problems)} broken")
    if problems:
        return 1
    if args.screenshots:
        with serve(args.site) as base:
            for page, png, width, height in SCREENSHOTS:
                screenshot(base + page, args.screenshots / png, width, height)
                print(f"screenshot of {page}: {args.screenshots / png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
