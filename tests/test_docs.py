"""The documentation site: the demo pages' converter, the site checker, and the built site.

`test_site` builds the whole site as `make docs-check` does (warnings are errors, every page
read anew) into a temporary directory, then checks that every internal link, anchor and image
resolves, that the demo pages carry their code, maths and pictures, and that the API reference
shows the public names. It takes about 10 s.
"""

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"

pytestmark = [pytest.mark.docs, pytest.mark.serial]


def _load(name, path):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


check_site = _load("check_site", DOCS / "check_site.py")

LIGHT_SCRIPT = """\
# # A title
#
# Text with $a^2$ and
#
# $$
# J(u) = \\int_\\Omega u \\, dx
# $$

# +
import math

x = math.pi
# -

# ## Next
#
# More text.

print(x)
"""


def test_demo_markdown():
    demo_pages = _load("demo_pages", DOCS / "_ext" / "demo_pages.py")
    page = demo_pages.demo_markdown(LIGHT_SCRIPT, "example", [("pic.png", "A picture.")])
    maths = "$$\nJ(u) = \\int_\\Omega u \\, dx\n$$"
    assert page.startswith("# A title\n\nText with $a^2$ and\n\n" + maths)
    assert "```python\nimport math\n\nx = math.pi\n```" in page
    assert "## Next\n\nMore text." in page
    assert "```python\nprint(x)\n```" in page
    assert "# +" not in page and "# -" not in page
    assert page.index("A title") < page.index("import math") < page.index("## Next")
    assert page.index("print(x)") < page.index("## Output")
    assert "```{figure} ../img/pic.png" in page and "`demos/example.py`" in page


def _site(tmp_path, pages):
    for name, html in pages.items():
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(html)
    return tmp_path


def test_check_site_finds_what_is_broken(tmp_path):
    site = _site(tmp_path, {
        "index.html": '<a href="sub/page.html#here">ok</a> <a href="https://example.org">out</a>'
                      '<img src="img/a.png"> <a href="#top" id="top">self</a>',
        "sub/page.html": '<h1 id="here">x</h1> <a href="../index.html">up</a>',
        "img/a.png": "not empty",
    })
    problems, checked = check_site.check_site(site)
    assert problems == [] and checked == 4
    (site / "sub" / "page.html").write_text('<a href="../missing.html">x</a> <img src="b.png">'
                                            '<a href="../index.html#nowhere">y</a>')
    (site / "img" / "a.png").write_text("")
    problems, _ = check_site.check_site(site)
    assert len(problems) == 5, problems
    text = "\n".join(problems)
    for expected in ("'here'", "missing.html", "b.png", "'nowhere'", "img/a.png: empty"):
        assert expected in text


def test_site(tmp_path):
    out = tmp_path / "html"
    proc = subprocess.run(
        [sys.executable, "-m", "sphinx", "-E", "-W", "--keep-going", "-q", "-b", "html",
         str(DOCS), str(out)],
        cwd=ROOT, capture_output=True, text=True, timeout=300, check=False,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    problems, checked = check_site.check_site(out)
    assert problems == [], "\n".join(problems)
    assert checked > 500
    for demo in ("bar_2d", "analytic_2d", "obstacle_3d", "hertz"):
        html = (out / "demos" / f"{demo}.html").read_text()
        assert '<div class="highlight-python' in html and "\\(" in html, demo
    assert (out / "demos" / "bar_2d.html").read_text().count("<img") >= 4
    assert (out / "_static" / "mathjax" / "MathJax.js").is_file()
    api = (out / "api.html").read_text()
    import dwr_signorini

    for name in dwr_signorini.__all__:
        if name not in ("__version__", "obstacles"):
            assert f'id="dwr_signorini.{name}"' in api, name
    for name in dwr_signorini.obstacles.__all__:
        assert f'id="dwr_signorini.obstacles.{name}"' in api, name
    guide = (out / "guide" / "estimate.html").read_text()
    assert 'id="how-far-can-i-trust-the-number"' in guide
