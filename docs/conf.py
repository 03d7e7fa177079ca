"""Sphinx configuration of the sklearn-gpcd documentation.

Build with ``docs/build.sh`` (``sphinx-build -W --keep-going``): every
warning is an error. Generated content (API stubs, gallery, CLI help,
``gpcd reproduce`` tables) goes to ``generated/``, ``auto_examples/`` and
``gen_modules/``, all git-ignored.
"""

import os
import re
import sys
import warnings
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))

import gpcd_docs  # noqa: E402
from sphinx_gallery.sorting import FunctionSortKey  # noqa: E402

import sklearn_gpcd  # noqa: E402

# -- project -------------------------------------------------------------------

project = "sklearn-gpcd"
author = "sklearn-gpcd developers"
copyright = "sklearn-gpcd developers, BSD-3-Clause"
release = sklearn_gpcd.__version__
version = ".".join(release.split(".")[:2])

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
]

templates_path = ["_templates"]
exclude_patterns = ["_build", "**.ipynb_checkpoints", "**/*.rst.inc"]
root_doc = "index"
default_role = "literal"
pygments_style = "sphinx"
nitpicky = False

# -- pages generated from the package ----------------------------------------

API_NAMES = gpcd_docs.write_api_pages(HERE)
CLI_COMMANDS = gpcd_docs.write_cli_help(HERE)
REPRODUCE_FOUND = gpcd_docs.write_reproduce_results(HERE)

# -- autodoc / autosummary / numpydoc ------------------------------------------

autosummary_generate = True
autosummary_generate_overwrite = True
autodoc_typehints = "none"
autodoc_member_order = "groupwise"
autoclass_content = "class"

numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_attributes_as_param_list = True
numpydoc_xref_param_type = False
# Missing sections are checked by tests/test_docs.py (with a per-name report)
# rather than here, so that one module in progress cannot hide the rest.
numpydoc_validation_checks = set()

# -- sphinx-gallery --------------------------------------------------------------

# Only examples whose file name starts with ``plot_`` are executed (each runs
# in seconds on tiny simulator sizes); the others are shown with their code
# but not run, e.g. the ones that read real robot logs.
sphinx_gallery_conf = {
    "examples_dirs": str(HERE.parent / "examples"),
    "gallery_dirs": "auto_examples",
    "filename_pattern": re.escape(os.sep) + "plot_",
    "ignore_pattern": r"__init__\.py|(^|/)_",
    "backreferences_dir": "gen_modules/backreferences",
    "doc_module": ("sklearn_gpcd",),
    "within_subsection_order": FunctionSortKey(gpcd_docs.example_sort_key,
                                               "gpcd_docs.example_sort_key"),
    "abort_on_example_error": False,
    "only_warn_on_example_error": False,
    "min_reported_time": 0,
    "show_memory": False,
    "plot_gallery": "True",
    "remove_config_comments": True,
    "matplotlib_animations": False,
    "reset_modules": ("matplotlib",),
    "capture_repr": (),  # only what the examples print
    "ignore_repr_types": r"matplotlib[_.a-z]*",
}

# matplotlib without a display; quiet third-party noise that is not ours.
os.environ.setdefault("MPLBACKEND", "Agg")
warnings.filterwarnings("ignore", category=UserWarning,
                        message="Matplotlib is currently using agg")

# -- HTML --------------------------------------------------------------------------

html_theme = "pydata_sphinx_theme"
html_title = f"sklearn-gpcd {release}"
html_static_path = ["_static"]
html_css_files = ["gpcd.css"]
html_show_sourcelink = False
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 6,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
html_sidebars = {"index": [], "results_*": [], "install": []}
html_context = {"default_mode": "light"}


# -- hooks ----------------------------------------------------------------------

_SKLEARN_ROUTING = re.compile(r"^(set_\w+_request|get_metadata_routing)$")


def _skip_member(app, what, name, obj, skip, options):
    """Hide scikit-learn's generated metadata-routing methods (``set_fit_request``,
    ...): they are the same on every estimator, documented by scikit-learn, and
    their docstrings point into scikit-learn's glossary."""
    if _SKLEARN_ROUTING.match(name):
        return True
    return None


def setup(app):
    app.connect("autodoc-skip-member", _skip_member)
