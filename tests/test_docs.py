"""Documentation checks: docstrings of every public name, doctests, docs build.

* every public class and function (``__all__`` of ``sklearn_gpcd`` and of
  each public submodule) has a numpydoc docstring with a Parameters section
  naming every argument (when it takes any) and an Examples section with
  code; every public constant has a doc comment (``#:``);
* the docstring examples of the whole package pass as doctests, run the way
  the style guide says (``python -m pytest --doctest-modules sklearn_gpcd``);
* the examples of the user guide pages pass as doctests;
* (slow) ``sphinx-build -W`` succeeds and the gallery shows the figures of
  the executed examples.

The list of public modules is the one the API reference is generated from
(``docs/_ext/gpcd_docs.py``), so the reference and this test cannot drift.
"""

import dataclasses
import doctest
import enum
import importlib
import importlib.util
import inspect
import os
import pkgutil
import re
import subprocess
import sys
from pathlib import Path

import pytest

import sklearn_gpcd

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"


def _load_docs_helpers():
    spec = importlib.util.spec_from_file_location("gpcd_docs", DOCS / "_ext" / "gpcd_docs.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


gpcd_docs = _load_docs_helpers()
PUBLIC_MODULES = list(gpcd_docs.PUBLIC_MODULES)


def _public_names():
    """(module, name) for every name in a public ``__all__``; (module, None)
    for a module that does not import, so that it shows up as a skip."""
    params = []
    for short in PUBLIC_MODULES:
        try:
            module = importlib.import_module(f"sklearn_gpcd.{short}")
        except Exception:  # reported by the test as a skip with the reason
            params.append(pytest.param(short, None, id=f"{short}-IMPORT"))
            continue
        params += [pytest.param(short, name, id=f"{short}.{name}") for name in module.__all__]
    return params


def _import_or_skip(short):
    try:
        return importlib.import_module(f"sklearn_gpcd.{short}")
    except Exception as exc:
        pytest.skip(f"sklearn_gpcd.{short} does not import yet: {type(exc).__name__}: {exc}")


# -- numpydoc sections, parsed without numpydoc (not a test dependency) --------

SECTION = re.compile(r"^(?P<title>[A-Z][A-Za-z ]+)\n(?P<rule>-+)[ \t]*$", re.MULTILINE)


def docstring_sections(doc):
    """Map numpydoc section titles to their text.

    >>> docstring_sections("Summary.\\n\\nParameters\\n----------\\nx : int\\n")["Parameters"]
    'x : int'
    """
    matches = [m for m in SECTION.finditer(doc)
               if len(m.group("rule")) == len(m.group("title"))]
    sections = {}
    for m, following in zip(matches, matches[1:] + [None]):
        end = following.start() if following else len(doc)
        sections[m.group("title")] = doc[m.end():end].strip("\n")
    return sections


def documented_names(section):
    """Parameter names of a Parameters / Attributes section.

    >>> documented_names("x, y : float\\n    Coordinates.\\n**kwargs\\n    Passed on.")
    ['x', 'y', 'kwargs']
    """
    names = []
    for line in section.splitlines():
        if not line.strip() or line[0].isspace():
            continue
        head = line.split(" : ")[0]
        names += [n.strip().lstrip("\\*").lstrip("*") for n in head.split(",") if n.strip()]
    return names


def signature_names(obj):
    """Arguments a caller passes, or None when the signature is not the object's own."""
    if inspect.isclass(obj):
        if issubclass(obj, (enum.Enum, BaseException)):
            return None  # the signature belongs to Enum / BaseException
        if obj.__init__ is object.__init__:
            return []
    try:
        signature = inspect.signature(obj)
    except (TypeError, ValueError):
        return None
    return [p.name for p in signature.parameters.values() if p.name not in ("self", "cls")
            and not p.name.startswith("_")]


def docstring_problems(obj):
    """What keeps ``obj``'s docstring from being a complete numpydoc docstring."""
    doc = inspect.getdoc(obj) if obj.__doc__ else None
    if not doc or not doc.strip():
        return ["no docstring"]
    problems = []
    sections = docstring_sections(doc)
    wanted = signature_names(obj)
    if wanted:
        titles = ["Parameters"]
        if dataclasses.is_dataclass(obj):  # fields may be documented as attributes
            titles.append("Attributes")
        documented = sum((documented_names(sections.get(t, "")) for t in titles), [])
        if not any(t in sections for t in titles):
            problems.append(f"no {' or '.join(titles)} section (arguments: {', '.join(wanted)})")
        else:
            missing = [name for name in wanted if name not in documented]
            if missing:
                problems.append(f"{' or '.join(titles)} does not document {', '.join(missing)}")
    examples = sections.get("Examples")
    if examples is None:
        problems.append("no Examples section")
    elif ">>>" not in examples:
        problems.append("Examples section has no code (>>>)")
    return problems


# -- the tests -----------------------------------------------------------------


def test_every_public_module_is_in_the_api_reference():
    """A new public submodule must be added to the reference (and to this test)."""
    found = {m.name for m in pkgutil.iter_modules(sklearn_gpcd.__path__)
             if not m.name.startswith("_")}
    assert found <= set(PUBLIC_MODULES), (
        f"public modules missing from docs/_ext/gpcd_docs.py PUBLIC_MODULES: "
        f"{sorted(found - set(PUBLIC_MODULES))}"
    )
    assert set(PUBLIC_MODULES) <= found, sorted(set(PUBLIC_MODULES) - found)


@pytest.mark.parametrize("name", [n for n in sklearn_gpcd.__all__ if n != "__version__"])
def test_top_level_name_is_documented_in_its_submodule(name):
    """``sklearn_gpcd.X`` is the object documented as ``sklearn_gpcd.<sub>.X``."""
    short = sklearn_gpcd._EXPORTS[name]
    module = _import_or_skip(short)
    assert name in module.__all__, f"{name} is exported at top level but not in {short}.__all__"
    assert getattr(sklearn_gpcd, name) is getattr(module, name)


@pytest.mark.parametrize("short", PUBLIC_MODULES)
def test_public_module_has_a_docstring(short):
    module = _import_or_skip(short)
    assert module.__doc__ and module.__doc__.strip(), f"sklearn_gpcd.{short} has no docstring"
    assert hasattr(module, "__all__"), f"sklearn_gpcd.{short} defines no __all__"


@pytest.mark.parametrize("short, name", _public_names())
def test_public_name_has_numpydoc_docstring(short, name):
    module = _import_or_skip(short)
    obj = getattr(module, name)
    if inspect.isclass(obj) or callable(obj):
        problems = docstring_problems(obj)
    else:
        problems = [] if gpcd_docs.data_docstring(module, name) else [
            "constant without a doc comment (#: above its assignment)"]
    assert not problems, f"sklearn_gpcd.{short}.{name}: " + "; ".join(problems)


@pytest.mark.parametrize("short", PUBLIC_MODULES)
def test_api_page_lists_every_public_name(short):
    module = _import_or_skip(short)
    text, groups = gpcd_docs.module_page(short, "title")
    for name in module.__all__:
        assert re.search(rf"(^   {re.escape(name)}$|^\.\. py:data:: {re.escape(name)}$)",
                         text, re.MULTILINE), f"{name} missing from the {short} API page"
    assert sorted(sum(groups.values(), [])) == sorted(module.__all__)


def test_package_doctests():
    """The docstring examples, run exactly as the style guide says."""
    result = subprocess.run(
        [sys.executable, "-m", "pytest", "--doctest-modules", "sklearn_gpcd", "-q",
         "-p", "no:cacheprovider"],
        cwd=REPO, capture_output=True, text=True, env={**os.environ, "MPLBACKEND": "Agg"},
    )
    failed = [line for line in result.stdout.splitlines() if line.startswith(("FAILED", "ERROR"))]
    assert result.returncode == 0, (
        "doctests failed:\n" + "\n".join(failed or result.stdout.splitlines()[-30:]))


USER_GUIDE_PAGES = sorted(p for p in DOCS.rglob("*.rst")
                          if "_build" not in p.parts and "generated" not in p.parts
                          and "auto_examples" not in p.parts and ">>>" in p.read_text())


@pytest.mark.parametrize("page", USER_GUIDE_PAGES, ids=lambda p: str(p.relative_to(DOCS)))
def test_user_guide_doctests(page):
    result = doctest.testfile(str(page), module_relative=False, verbose=False,
                              optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples failed in {page}"


def test_user_guide_has_doctested_pages():
    """Guard against the collection above silently finding nothing."""
    names = {p.name for p in USER_GUIDE_PAGES}
    assert {"model.rst", "kernels.rst", "io.rst"} <= names


@pytest.mark.slow
def test_docs_build_with_warnings_as_errors(tmp_path):
    """``sphinx-build -W`` from scratch; the executed examples show their figures."""
    pytest.importorskip("sphinx")
    pytest.importorskip("numpydoc")
    pytest.importorskip("sphinx_gallery")
    pytest.importorskip("pydata_sphinx_theme")
    out = tmp_path / "html"
    result = subprocess.run(
        [sys.executable, "-m", "sphinx", "-b", "html", "-E", "-W", "--keep-going", "-q",
         "-d", str(tmp_path / "doctrees"), str(DOCS), str(out)],
        cwd=DOCS, capture_output=True, text=True, env={**os.environ, "MPLBACKEND": "Agg"},
    )
    assert result.returncode == 0, result.stderr[-5000:]
    assert (out / "index.html").is_file()
    executed = sorted((REPO / "examples").glob("plot_*.py"))
    assert executed, "no executed gallery example"
    for example in executed:
        page = (out / "auto_examples" / f"{example.stem}.html").read_text()
        skipped = re.search(r'sphx-glr-script-out[^>]*>(<[^>]+>)*[^<]*Skipping this example',
                            page)
        if example.stem.endswith("_real_data") and skipped:
            continue  # real robot logs, not shipped: its output says they were not found
        assert f"sphx_glr_{example.stem}_001.png" in page, f"{example.name} shows no figure"
        assert (out / "_images" / f"sphx_glr_{example.stem}_001.png").is_file()
    for example in sorted(set((REPO / "examples").glob("[!_]*.py")) - set(executed)):
        assert (out / "auto_examples" / f"{example.stem}.html").is_file()  # shown, not run


# -- the README: a manual, not a lab notebook (issue 46) ---------------------

README = REPO / "README.md"


def _quick_start_commands():
    """The command lines of the README's quick-start block."""
    block = README.read_text().split("## Quick start", 1)[1].split("```bash", 1)[1]
    return [line for line in block.split("```", 1)[0].splitlines() if line.strip()]


def _extras(pyproject_text):
    """``{extra: {distribution, ...}}`` of pyproject.toml's optional dependencies."""
    section = pyproject_text.split("[project.optional-dependencies]", 1)[1].split("\n[", 1)[0]
    return {name: {re.split(r"[\[<>=]", dep)[0] for dep in re.findall(r'"([^"]+)"', deps)}
            for name, deps in re.findall(r"^([a-z-]+) = \[(.*)\]$", section, flags=re.M)}


def test_readme_is_short():
    n_lines = len(README.read_text().splitlines())
    assert n_lines < 120, f"README.md has {n_lines} lines; the measurements go to docs/results_*"


def test_readme_quick_start_is_what_ci_runs():
    """Two commands: the main job, then the tests; .ci/run runs the second verbatim."""
    commands = _quick_start_commands()
    assert len(commands) == 2, commands
    assert "gpcd reproduce --quick" in commands[0]
    ci_lines = [line.strip() for line in (REPO / ".ci" / "run").read_text().splitlines()]
    assert commands[1].strip() in ci_lines, (
        f".ci/run does not run the README's test command {commands[1]!r}")
    assert "python -m pytest" in commands[1]


def test_readme_recipe_runs_after_the_quick_start_install():
    """The recipe writes .skops files: the quick start's install brings skops."""
    readme = README.read_text()
    recipe = readme.split("**The recipe.**", 1)[1].split("```bash", 1)[1].split("```", 1)[0]
    assert ".skops" in recipe
    install = re.search(r'pip install "\.\[([a-z,-]+)\]"', _quick_start_commands()[0])
    assert install, "the quick start's first command installs the package with extras"
    extras = _extras((REPO / "pyproject.toml").read_text())
    installed = set().union(*(extras[name] for name in install.group(1).split(",")))
    assert "skops" in installed, f"extras {install.group(1)} do not bring skops"


def test_readme_figures_are_on_a_results_page_and_results_linked_once():
    readme = README.read_text()
    results = "".join(p.read_text() for p in DOCS.glob("results_*.rst"))
    for figure in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", readme):
        assert Path(figure).name in results, f"README figure {figure} is on no results page"
    links = re.findall(r"\]\((docs/results_[^)]*)\)", readme)
    assert len(links) == 1, f"link the results pages once, found {links}"


def test_install_page_lists_every_extra():
    text = (DOCS / "install.rst").read_text()
    extras = set(_extras((REPO / "pyproject.toml").read_text())) - {"all", "second-engine"}
    missing = sorted(e for e in extras if f"``{e}``" not in text)
    assert not missing, f"docs/install.rst's extras table omits {missing}"


def test_readme_good_calibration_is_what_gpcd_calibrate_checks():
    """The README's "good calibration" is the bar below which gpcd calibrate warns."""
    from sklearn_gpcd.workflow.calibration import GOOD_MARGIN

    text = " ".join(README.read_text().split())
    assert f"margin of at most {GOOD_MARGIN:g} and expects no false alarm" in text


def test_readme_training_duration_is_what_gpcd_train_checks():
    """The recipe's "10+ min" is the bar below which gpcd train warns."""
    from sklearn_gpcd.workflow.training import MIN_TRAINING_SECONDS

    recipe = README.read_text().split("**The recipe.**", 1)[1].split("```", 2)[1]
    train = next(line for line in recipe.splitlines() if line.startswith("gpcd train"))
    assert f"# {MIN_TRAINING_SECONDS / 60:g}+ min" in train
