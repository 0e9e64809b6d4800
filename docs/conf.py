"""Sphinx configuration of the dwr_signorini site (``make docs``).

Built with Debian's packages (Sphinx, MyST, furo, jupytext, MathJax) inside ``scripts/fenicsx``,
offline: autodoc imports ``dwr_signorini``, and MathJax is served from the built site.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS.parent))
sys.path.insert(0, str(DOCS / "_ext"))

import dwr_signorini  # noqa: E402

project = "dwr_signorini"
author = "the dwr_signorini authors"
copyright = "the dwr_signorini authors, MIT licence"
version = release = dwr_signorini.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "demo_pages",
]
source_suffix = {".md": "markdown"}
exclude_patterns = ["_build", "screenshots", "README.md"]
root_doc = "index"
# Untagged code blocks (shell lines in the demos' comments, logs) are shown as they are.
highlight_language = "text"

myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence"]
myst_heading_anchors = 4
myst_dmath_double_inline = True

autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_typehints_description_target = "documented_params"
autodoc_default_options: dict[str, object] = {}
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_rtype = False
nitpicky = False

html_theme = "furo"
html_title = "dwr_signorini"
html_static_path: list[str] = []
html_copy_source = False
html_show_sourcelink = False

# MathJax 2 from Debian's libjs-mathjax, copied into the site (no network at build or view time).
MATHJAX_SOURCE = Path("/usr/share/javascript/mathjax")
MATHJAX_PARTS = [
    "MathJax.js",
    "config/TeX-AMS_CHTML.js",
    "extensions",
    "jax/element",
    "jax/input/TeX",
    "jax/output/CommonHTML",
    "fonts/HTML-CSS/TeX/woff",
]
mathjax_path = "mathjax/MathJax.js?config=TeX-AMS_CHTML"
# MathJax 2 is configured by MathJax.Hub.Config, not by the window.MathJax object of MathJax 3 that
# MyST would write: typeset the elements of Sphinx's class "math" only.
myst_update_mathjax = False
mathjax3_config = None
mathjax2_config = {
    "tex2jax": {"inlineMath": [["\\(", "\\)"]], "displayMath": [["\\[", "\\]"]],
                "processEscapes": True, "ignoreClass": "document", "processClass": "math"},
    "CommonHTML": {"linebreaks": {"automatic": True}},
    "showMathMenu": False,
    "messageStyle": "none",
}

# The demos, rendered from demos/*.py (docs/_ext/demo_pages.py), with the pictures of a run.
demo_pages_source = "../demos"
demo_pages = {
    "bar_2d": [
        ("bar_convergence_cells.png", "Relative error and estimate against the number of cells."),
        ("bar_convergence_time.png", "Relative error and estimate against the run time."),
        ("bar_mesh_level05.png", "The adaptive mesh of level 5 (the paper's Figure 7)."),
        ("bar_solution.png", "The deformed bar, coloured by the von Mises stress."),
    ],
    "analytic_2d": [
        ("analytic_effectivity.png", "Effectivity of eta_p and eta beside the paper's Tables 1-2."),
        ("analytic_sweep.png", "Effectivity against the midpoint m of the goal (Figure 4)."),
    ],
    "obstacle_3d": [
        ("obstacle_solution.png", "The 3D body and its contact zone on the finest adaptive mesh."),
    ],
    "hertz": [
        ("hertz_pressure_profile.png", "2D: the contact force of the last level, and Hertz's."),
        ("hertz_errors_dofs.png", "2D: the estimate and the errors against Hertz's formulas."),
    ],
    "two_bodies": [
        ("two_bodies_meshes.png", "The first and the last adaptive macro mesh of both bodies."),
        ("two_bodies_pressure_profile.png",
         "The contact force of the last level along the interface, and Hertz's."),
        ("two_bodies_interval.png", "J_h and its interval [J_low, J_high] per level."),
    ],
    "friction": [
        ("friction_tractions.png", "lambda_n and lambda_t along Gamma_C, stick and slip zones."),
        ("friction_interval.png", "The friction force and its interval per level."),
        ("friction_convergence_cells.png", "Error and estimate against the number of cells."),
        ("friction_mesh_level06.png", "The adaptive mesh of level 6."),
    ],
    "finite_strain": [
        ("finite_strain_deformed_meshes.png",
         "The deformed meshes: first and last press step, and slid by one radius."),
        ("finite_strain_contact_pressure.png",
         "The Cauchy contact pressure along the contact per press step, and after the slide."),
        ("finite_strain_force_displacement.png",
         "The contact force against the approach with its interval (left); both goals' "
         "intervals relative to J_h per load step (right)."),
    ],
    "cattaneo_mindlin": [
        ("cattaneo_mindlin_traction.png",
         "lambda_t of the last shear step against Cattaneo and Mindlin's traction."),
        ("cattaneo_mindlin_stick_zone.png", "The stick half-width against the theory, per step."),
        ("cattaneo_mindlin_friction_force.png", "The friction force per step and its interval."),
    ],
}


def copy_mathjax(app, exception) -> None:
    """Copy the parts of MathJax the pages use into ``_static/mathjax`` (``build-finished``)."""
    if exception is not None or app.builder.format != "html":
        return
    target = Path(app.outdir) / "_static" / "mathjax"
    if (target / "MathJax.js").exists():
        return
    if not MATHJAX_SOURCE.is_dir():
        raise RuntimeError(f"MathJax not found in {MATHJAX_SOURCE}: install libjs-mathjax")
    for part in MATHJAX_PARTS:
        source, dest = MATHJAX_SOURCE / part, target / part
        dest.parent.mkdir(parents=True, exist_ok=True)
        if source.is_dir():
            shutil.copytree(source, dest, dirs_exist_ok=True)
        else:
            shutil.copy2(source, dest)


def setup(app):
    """Register the MathJax copy."""
    app.connect("build-finished", copy_mathjax)
