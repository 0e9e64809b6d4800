"""The documentation site: the demo pages' converter, the site checker, the built site, and the
docstrings of everything the API reference shows.

`test_site` builds the whole site as `make docs-check` does (warnings are errors, every page
read anew) into a temporary directory, then checks that every internal link, anchor and image
resolves, that the demo pages carry their code, maths and pictures, and that the API reference
shows the public names. It takes about 10 s.
"""

import ast
import dataclasses
import importlib
import importlib.util
import inspect
import re
import subprocess
import sys
import textwrap
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
    assert "```{figure} ../img/pic.png\n:alt: A picture.\n:width: 80%" in page
    assert "`demos/example.py`" in page


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
            # ds.NAME, or where it is defined, for data whose doc comment is there
            assert re.search(rf'id="dwr_signorini\.(\w+\.)?{name}"', api), name
    for name in dwr_signorini.obstacles.__all__:
        assert f'id="dwr_signorini.obstacles.{name}"' in api, name
    # the public modules beside ds: their pages' names and what they export
    for module in ("obstacles", "interval", "examples", "cases", "viz", "io", "meshes"):
        assert f'id="module-dwr_signorini.{module}"' in api, module
    for name in ("plot_convergence", "plot_interval", "plot_friction"):
        assert f'id="dwr_signorini.viz.{name}"' in api, name
    for name in ("bar_problem", "friction_problem", "goal_bar"):
        assert f'id="dwr_signorini.examples.{name}"' in api, name
    assert 'id="dwr_signorini.cases.cattaneo_mindlin_path"' in api
    assert 'id="dwr_signorini.io.write_csv"' in api
    guide = (out / "guide" / "estimate.html").read_text()
    assert 'id="how-far-can-i-trust-the-number"' in guide


API_DIRECTIVE = re.compile(r"^\.\. auto(\w+):: (\S+)\n((?:   :.*\n)*)", re.M)


def _sections(doc):
    return set(re.findall(r"^(Args|Returns|Yields|Raises|Attributes):$", doc or "", re.M))


def _raises(func):
    """Whether the function's own body (not nested functions) has a raise statement."""
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(func)))
    except (OSError, TypeError):
        return False
    top = tree.body[0]
    return any(
        isinstance(node, ast.Raise)
        for node in ast.walk(top)
        if not any(node in ast.walk(f) for f in ast.walk(top)
                   if isinstance(f, ast.FunctionDef) and f is not top)
    )


def _missing(func, doc, *, returns=True):
    missing = []
    signature = inspect.signature(func)
    if [p for p in signature.parameters if p not in ("self", "cls")] and "Args" not in doc:
        missing.append("Args")
    annotation = signature.return_annotation
    if returns and annotation not in (None, "None", inspect.Signature.empty) and not (
        {"Returns", "Yields"} & doc
    ):
        missing.append("Returns")
    if _raises(func) and "Raises" not in doc:
        missing.append("Raises")
    return missing


def _api_objects():
    """(name, object, members) for every autodoc directive of docs/api.md."""
    text = (DOCS / "api.md").read_text()
    for kind, name, options in API_DIRECTIVE.findall(text):
        module, _, attr = name.rpartition(".")
        obj = importlib.import_module(name) if kind == "module" else getattr(
            importlib.import_module(module), attr)
        listed = re.search(r":members:(.*)", options)
        members = None if listed is None else [m.strip() for m in listed.group(1).split(",")
                                               if m.strip()]
        if kind == "module":
            for sub in obj.__all__:
                yield f"{name}.{sub}", getattr(obj, sub), members
        else:
            yield name, obj, members


def test_api_docstrings_complete():
    """Every function, class and method the API reference shows documents its arguments, what
    it returns and what it raises (Google style: Args, Returns, Raises; Attributes for data)."""
    problems = []
    for name, obj, members in _api_objects():
        if inspect.isfunction(obj):
            problems += [f"{name}: {m}" for m in _missing(obj, _sections(inspect.getdoc(obj)))]
        if not inspect.isclass(obj):
            continue
        doc = _sections(inspect.getdoc(obj))
        own_init = getattr(vars(obj).get("__init__"), "__module__", "") or ""
        if own_init.startswith("dwr_signorini"):    # not typing.Protocol's, say
            init = vars(obj)["__init__"]
            missing = _missing(init, doc, returns=False)
            if "Args" in missing and "Attributes" in doc and dataclasses.is_dataclass(obj):
                missing.remove("Args")
            problems += [f"{name}: {m}" for m in missing]
        elif dataclasses.is_dataclass(obj) and "Attributes" not in doc:
            problems.append(f"{name}: Attributes")
        if members is None:
            continue
        fields = {f.name for f in dataclasses.fields(obj)} if dataclasses.is_dataclass(obj) else ()
        names = members or [n for n in vars(obj) if not n.startswith("_") and n not in fields]
        for member in names:
            value = inspect.getattr_static(obj, member)
            if isinstance(value, property):
                if not inspect.getdoc(getattr(obj, member, None)) and not (
                        inspect.getdoc(value)):
                    problems.append(f"{name}.{member}: no docstring")
                elif _raises(value.fget) and "Raises" not in _sections(inspect.getdoc(value)):
                    problems.append(f"{name}.{member}: Raises")
            elif inspect.isfunction(value):
                doc = _sections(inspect.getdoc(getattr(obj, member)))
                problems += [f"{name}.{member}: {m}" for m in _missing(value, doc)]
    assert problems == [], "\n".join(problems)


# --------------------------------------------------------------------------------------------------
# Every ```python block of README.md and docs/ runs
# --------------------------------------------------------------------------------------------------

#: The pages whose code blocks are run: the README, every Markdown page of the site and the
#: measurement logs the site includes. Not the demos' pages, which the build generates from
#: ``demos/*.py`` (not committed: ``docs/demos/.gitignore``); test_demos runs the demos.
DOC_PAGES = [
    ROOT / "README.md",
    *sorted(p for p in DOCS.rglob("*.md")
            if "_build" not in p.relative_to(DOCS).parts
            and not (p.parent == DOCS / "demos" and p.name != "index.md")),
    ROOT / "benchmarks" / "README.md",
]

FENCE = re.compile(r"^```([^\n]*)\n(.*?)^```[ \t]*$", re.M | re.S)
#: A block's set-up, hidden on the rendered page: an HTML comment right before the block,
#: ``<!-- set-up:`` on its own line, then Python, then ``-->``.
SET_UP = re.compile(r"<!-- set-up:\n(.*?)^-->\s*\Z", re.M | re.S)
#: Fences that would hold Python under another name: not allowed, so that no block is skipped
#: because of how it is marked.
OTHER_PYTHON = re.compile(
    r"^(py|python3|pycon|ipython3?|\{code-block\}\s*python.*|\{code-cell\}.*)$")


def doc_blocks(page):
    """``(line, set_up, code)`` of every ```python block of a page, in order."""
    text = page.read_text()
    blocks, end = [], 0
    for fence in FENCE.finditer(text):
        info = fence.group(1).strip()
        assert not OTHER_PYTHON.match(info), f"{page}: a ```{info} block is not run; mark it python"
        if info != "python":
            continue
        before = SET_UP.search(text, end, fence.start())
        line = text.count("\n", 0, fence.start()) + 1
        blocks.append((line, before.group(1) if before else "", fence.group(2)))
        end = fence.end()
    assert len(blocks) == text.count("```python"), f"{page}: a ```python block was not parsed"
    assert sum(1 for b in blocks if b[1]) == len(re.findall(r"^<!-- set-up:$", text, re.M)), (
        f"{page}: a set-up that is not right before a ```python block")
    return blocks


def run_page(page, name=None):
    """Run a page's blocks as test_doc_blocks_run does; the number of blocks run."""
    name = name or str(page)
    namespace = {"__name__": "__doc_block__"}
    ran = 0
    try:
        for line, set_up, code in doc_blocks(page):
            where = f"{name}:{line}"
            try:
                if set_up:
                    exec(compile(set_up, f"{where} (set-up)", "exec"), namespace)
                exec(compile(code, where, "exec"), namespace)
            except Exception as error:
                raise AssertionError(
                    f"the block at {where} raised {type(error).__name__}: {error}") from error
            ran += 1
    finally:
        for value in list(namespace.values()):     # what the blocks left open, collectively
            if hasattr(value, "destroy") and hasattr(value, "__exit__"):
                value.destroy()
    return ran


def _page_id(page):
    return str(page.relative_to(ROOT))


@pytest.mark.parametrize(
    "page", [p for p in DOC_PAGES if "```python" in p.read_text()], ids=_page_id)
def test_doc_blocks_run(page, tmp_path, monkeypatch):
    """The page's ```python blocks run, in order and in one namespace (as a reader pastes them
    into one session), each after its marked set-up, in a scratch directory; a block that
    raises fails the test with its page and line, and every block of the page must have run."""
    monkeypatch.chdir(tmp_path)
    assert run_page(page, _page_id(page)) == len(doc_blocks(page))


def test_doc_blocks_all_found():
    """Every page with a ```python block is run by test_doc_blocks_run, and none hides Python
    under another fence name; the total is what the tests above run."""
    total = sum(len(doc_blocks(page)) for page in DOC_PAGES)
    assert total == sum(page.read_text().count("```python") for page in DOC_PAGES)
    assert total >= 15


PAGE = """\
# A page

<!-- set-up:
x = 2
-->
```python
y = x + 1
```

```bash
not python
```

```python
assert y == 3
z = y / ({zero})
```
"""


def test_doc_block_runner(tmp_path):
    """The runner itself: set-up, order, one namespace, shell blocks left out, a raising block
    fails with its line, and a set-up without its block or Python under another fence name is
    refused."""
    page = tmp_path / "page.md"
    page.write_text(PAGE.format(zero=1))
    assert [line for line, _, _ in doc_blocks(page)] == [6, 14]
    assert run_page(page) == 2
    page.write_text(PAGE.format(zero=0))
    with pytest.raises(AssertionError, match=r"page.md:14 raised ZeroDivisionError"):
        run_page(page)
    page.write_text(PAGE.format(zero=1).replace("```python\ny =", "```\ny ="))
    with pytest.raises(AssertionError, match="set-up that is not right before"):
        doc_blocks(page)
    page.write_text(PAGE.format(zero=1).replace("```python\nassert", "```py\nassert"))
    with pytest.raises(AssertionError, match="```py block is not run"):
        doc_blocks(page)


def test_api_docstrings_parameters_first():
    """Every entry of the API reference gives its parameters (or attributes) after a short
    description of at most three lines; what the implementation does follows them."""
    long = []
    for name, obj, _ in _api_objects():
        lines = (inspect.getdoc(obj) or "").splitlines()
        heads = [i for i, line in enumerate(lines)
                 if re.fullmatch(r"(Args|Attributes|Returns|Yields|Raises):", line)]
        if heads and len([line for line in lines[1:heads[0]] if line.strip()]) > 3:
            long.append(name)
    assert long == [], "\n".join(long)
