"""Pages generated at build time from the package itself.

* :func:`write_api_pages` -- one reference page per public submodule, listing
  exactly the names in the submodule's ``__all__`` (classes and functions get
  an autosummary stub page, constants their ``#:`` doc comment), plus the
  table of the top-level ``sklearn_gpcd`` names. New public names appear in
  the reference without editing ``docs/``.
* :func:`write_cli_help` -- ``gpcd --help`` and every subcommand's help.
* :func:`write_reproduce_results` -- the tables of ``docs/results_reproduce.rst``
  from the ``results.json`` files of ``gpcd reproduce`` runs, or a "Pending"
  section when a run has not been added yet.

Everything is written below ``docs/generated/`` (git-ignored), and a file is
rewritten only when its content changes so that Sphinx's incremental build
keeps working.
"""

import ast
import importlib
import inspect
import json
import math
import pkgutil
from pathlib import Path

#: Public submodules of ``sklearn_gpcd``, in reference order, with page titles.
PUBLIC_MODULES = {
    "layout": "Column layout of the inputs",
    "io": "Recordings and loaders",
    "robots": "Robot models",
    "dynamics": "Rigid-body features",
    "features": "Inputs, derivatives and quasi-static masks",
    "kernels": "Kernels",
    "gp": "Semi-parametric GP regression",
    "detection": "Collision detection",
    "contact": "After the alarm: isolation and force",
    "metrics": "Metrics",
    "plotting": "Plotting",
    "datasets": "Simulator and data sets",
    "diagnosis": "Sim-to-real diagnosis",
    "experiments": "The paper's experiments",
    "persistence": "Saving and loading models",
    "workflow": "Training and calibrating a detector (gpcd train, gpcd calibrate)",
    "monitoring": "Live monitoring (gpcd monitor)",
    "cli": "The gpcd command",
}

GENERATED = "generated"
MAX_VALUE_REPR = 100


def _write(path, text):
    """Write ``text`` to ``path`` unless it already holds exactly that."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


def _heading(text, char):
    return f"{text}\n{char * len(text)}\n"


def public_names(module):
    """Split a module's ``__all__`` into classes, functions and data.

    Parameters
    ----------
    module : module

    Returns
    -------
    groups : dict of str -> list of str
        ``{"classes": [...], "functions": [...], "data": [...]}``, each in
        ``__all__`` order.
    """
    groups = {"classes": [], "functions": [], "data": []}
    for name in module.__all__:
        obj = getattr(module, name)
        if inspect.isclass(obj):
            groups["classes"].append(name)
        elif callable(obj):
            groups["functions"].append(name)
        else:
            groups["data"].append(name)
    return groups


def defining_module(module, name):
    """Name of the module that binds ``module.<name>`` to the same object.

    ``module`` itself, or for a package the submodule where the object is
    assigned (re-exports are followed to their origin).

    Returns
    -------
    modname : str or None
    """
    obj = getattr(module, name)
    candidates = [module.__name__]
    if hasattr(module, "__path__"):
        candidates += sorted(m.name for m in pkgutil.walk_packages(module.__path__,
                                                                   module.__name__ + "."))
    for modname in candidates:
        sub = importlib.import_module(modname)
        if sub.__dict__.get(name, None) is obj and _assignment_line(sub, name) is not None:
            return modname
    return None


def _assignment_line(module, name):
    """0-based line index of the module-level assignment of ``name``, or None."""
    try:
        source = inspect.getsource(module)
    except (OSError, TypeError):
        return None
    for node in ast.parse(source).body:
        targets = (node.targets if isinstance(node, ast.Assign)
                   else [node.target] if isinstance(node, ast.AnnAssign) else [])
        if any(isinstance(t, ast.Name) and t.id == name for t in targets):
            return node.lineno - 1
    return None


def data_docstring(module, name):
    """Doc comment of a constant re-exported by ``module``.

    Sphinx's conventions: ``#:`` comment lines right above the module-level
    assignment (in the module that defines it), or a string literal right
    after it.

    Returns
    -------
    lines : list of str
        The documentation lines (empty when the constant is undocumented).
    """
    modname = defining_module(module, name)
    if modname is None:
        return []
    sub = importlib.import_module(modname)
    source = inspect.getsource(sub)
    lines = source.splitlines()
    index = _assignment_line(sub, name)
    doc = []
    k = index - 1
    while k >= 0 and lines[k].lstrip().startswith("#:"):
        doc.insert(0, lines[k].lstrip()[2:].strip())
        k -= 1
    if doc:
        return doc
    body = ast.parse(source).body
    for node, following in zip(body, body[1:]):
        if node.lineno - 1 == index and isinstance(following, ast.Expr) \
                and isinstance(following.value, ast.Constant) \
                and isinstance(following.value.value, str):
            return inspect.cleandoc(following.value.value).splitlines()
    return []


def _autosummary(names):
    # stubs use _templates/autosummary/{class,function}.rst, picked by object type
    lines = [".. autosummary::", "   :toctree: .", ""]
    return "\n".join(lines + [f"   {name}" for name in names]) + "\n"


def _data_entry(module, name):
    obj = getattr(module, name)
    lines = [f".. py:data:: {name}", f"   :type: {type(obj).__name__}"]
    value = repr(obj)
    if len(value) <= MAX_VALUE_REPR:
        lines.append(f"   :value: {value}")
    lines.append("")
    for line in data_docstring(module, name):
        lines.append(f"   {line}" if line else "")
    return "\n".join(lines).rstrip() + "\n"


def module_page(short, title):
    """reStructuredText of the reference page of ``sklearn_gpcd.<short>``."""
    modname = f"sklearn_gpcd.{short}"
    module = importlib.import_module(modname)
    groups = public_names(module)
    parts = [
        f".. _api-{short}:\n",
        _heading(f":mod:`{modname}`: {title}", "="),
        f".. automodule:: {modname}\n   :no-members:\n   :no-inherited-members:\n",
        f".. currentmodule:: {modname}\n",
    ]
    if groups["classes"]:
        parts += [_heading("Classes", "-"), _autosummary(groups["classes"])]
    if groups["functions"]:
        parts += [_heading("Functions", "-"), _autosummary(groups["functions"])]
    if groups["data"]:
        parts += [_heading("Constants", "-")]
        parts += [_data_entry(module, name) for name in groups["data"]]
    return "\n".join(parts), groups


def top_level_table():
    """List table of ``sklearn_gpcd.__all__`` with links to where each is documented."""
    import sklearn_gpcd

    rows = []
    for name in sklearn_gpcd.__all__:
        if name == "__version__":
            continue
        short = sklearn_gpcd._EXPORTS[name]
        obj = getattr(sklearn_gpcd, name)
        role = "class" if inspect.isclass(obj) else "func" if callable(obj) else "data"
        summary = (inspect.getdoc(obj) or "").strip().split("\n")[0] if role != "data" else ""
        rows.append(f"   * - :{role}:`~sklearn_gpcd.{short}.{name}`\n"
                    f"     - :mod:`sklearn_gpcd.{short}`\n"
                    f"     - {summary}")
    header = (".. list-table::\n   :header-rows: 1\n   :widths: 25 20 55\n\n"
              "   * - name\n     - defined in\n     - summary\n")
    return header + "\n".join(rows) + "\n"


def write_api_pages(srcdir):
    """Write the reference pages and remove stale generated stubs.

    Parameters
    ----------
    srcdir : path
        The Sphinx source directory (``docs/``).

    Returns
    -------
    names : dict of str -> dict
        ``public_names`` of every module, keyed by short module name.
    """
    out = Path(srcdir) / GENERATED
    out.mkdir(parents=True, exist_ok=True)
    expected = set()
    names = {}
    toc = [".. toctree::", "   :maxdepth: 1", ""]
    for short, title in PUBLIC_MODULES.items():
        text, groups = module_page(short, title)
        names[short] = groups
        page = f"sklearn_gpcd.{short}"
        _write(out / f"{page}.rst", text)
        expected.add(f"{page}.rst")
        expected.update(f"{page}.{n}.rst" for n in groups["classes"] + groups["functions"])
        toc.append(f"   {GENERATED}/{page}")
    _write(out / "api_toc.rst.inc", "\n".join(toc) + "\n")
    _write(out / "api_top_level.rst.inc", top_level_table())
    expected.update({"api_toc.rst.inc", "api_top_level.rst.inc"})
    # autosummary never deletes the stub of a name that left ``__all__``;
    # an orphan stub would fail the -W build, so remove it here.
    for path in out.glob("sklearn_gpcd.*.rst"):
        if path.name not in expected:
            path.unlink()
    return names


def write_cli_help(srcdir):
    """Write the help of ``gpcd`` and of each subcommand, and their sections.

    ``generated/cli_<command>.txt`` holds each help text and
    ``generated/cli_commands.rst.inc`` one section per subcommand (its
    one-line help and the full help), so a new subcommand is documented
    without editing ``docs/``.

    Returns
    -------
    commands : list of str
    """
    import argparse

    from sklearn_gpcd.cli import build_parser

    out = Path(srcdir) / GENERATED
    parser = build_parser()
    _write(out / "cli_gpcd.txt", _help(parser))
    subparsers = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    summaries = {a.dest: a.help or "" for a in subparsers._choices_actions}
    sections = []
    for command, sub in subparsers.choices.items():
        _write(out / f"cli_{command}.txt", _help(sub))
        summary = summaries.get(command, "")
        sections.append(
            f".. _cli-{command}:\n\n"
            + _heading(f"gpcd {command}", "=")
            + (f"\n{summary[0].upper() + summary[1:]}.\n" if summary else "")
            + f"\n.. literalinclude:: /{GENERATED}/cli_{command}.txt\n   :language: text\n"
        )
    _write(out / "cli_commands.rst.inc", "\n".join(sections))
    return list(subparsers.choices)


def _help(parser):
    import os

    columns = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "88"  # stable wrapping whatever the terminal
    try:
        return parser.format_help()
    finally:
        if columns is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = columns


# -- results of ``gpcd reproduce`` -------------------------------------------

ESTIMATORS = ("P_f", "SP_S", "SP_P")
REPRODUCE_DIR = Path("_static") / "reproduce"


def _fmt(value, digits=3):
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    return f"{value:.{digits}g}"


def _grid(rows):
    """A reStructuredText grid table (header = first row)."""
    widths = [max(len(str(r[i])) for r in rows) for i in range(len(rows[0]))]
    sep = "+" + "+".join("-" * (w + 2) for w in widths) + "+"
    head = sep.replace("-", "=")

    def line(row):
        return "| " + " | ".join(str(c).ljust(w) for c, w in zip(row, widths)) + " |"

    out = [sep, line(rows[0]), head]
    for row in rows[1:]:
        out += [line(row), sep]
    return "\n".join(out) + "\n"


def _nmse_rows(nmse, dataset, regime):
    n = len(nmse["SP_P"][dataset][regime])
    rows = [["estimator"] + [f"joint {j + 1}" for j in range(n)]]
    for name in ESTIMATORS:
        rows.append([name] + [_fmt(v) for v in nmse[name][dataset][regime]])
    rows.append(["samples"] + [str(c) for c in nmse["SP_P"][dataset][f"n_{regime}"]])
    return rows


def reproduce_section(results, mode, figure_dir):
    """reStructuredText of one ``gpcd reproduce`` run, from its ``results.json``.

    Parameters
    ----------
    results : dict
        The content of ``results.json``.
    mode : str
        ``"quick"`` or ``"full"``.
    figure_dir : str
        Folder of the run's figures, relative to the including page.

    Returns
    -------
    text : str
    """
    cfg = results["config"]
    checks = results["checks"]
    inter = results["interaction"]
    parts = [
        f"Robot ``{results['robot']}``, ``random_state={results['random_state']}``, "
        f"sizes ``{cfg}``; the run took {_fmt(results.get('elapsed_s'), 4)} s. "
        "Every number below is read from the run's ``results.json``.\n",
        _heading("Verdict", "~"),
        f"* SP_P has the lowest quasi-static nMSE on D2 for "
        f"{len(checks['sp_p_quasi_static_best_joints'])} of "
        f"{len(results['nmse']['SP_P']['D2']['quasi_static'])} joints "
        f"(majority: **{checks['sp_p_quasi_static_best_majority']}**).",
        f"* All pushes detected: **{checks['all_pushes_detected']}**.",
        f"* No false alarm in the collision-free rest phases: "
        f"**{checks['no_false_alarm_at_rest']}** "
        f"({inter['false_alarms_rest']} at rest, {inter['false_alarms_moving']} while moving).\n",
        _heading("Data and training", "~"),
        _grid([["set", "samples"]] + [[k, str(v)] for k, v in results["n_samples"].items()]),
        _grid([["estimator", "fit time [s]", "log marginal likelihood per joint"]]
              + [[name, _fmt(results["fit_seconds"][name], 3),
                  ", ".join(_fmt(v, 5) for v in results["log_marginal_likelihood"][name])]
                 for name in ESTIMATORS]),
    ]
    for regime, title in (("dynamic", "nMSE (Eq. 18), dynamic samples"),
                          ("quasi_static", "nMSE (Eq. 18), quasi-static samples")):
        parts.append(_heading(title, "~"))
        for dataset in ("D1_test", "D2"):
            parts += [f"**{dataset}**\n", _grid(_nmse_rows(results["nmse"], dataset, regime))]
        key = f"nmse_{regime}"
        if key in results.get("figures", {}):
            parts.append(f".. image:: {figure_dir}/{results['figures'][key]}\n"
                         f"   :alt: {title}\n")
    parts.append(_heading("Cyclic actuation of joint 1 (Sec. III-C)", "~"))
    rest = results["cyclic_rest_phases"]
    rows = [["rest", "q1 [rad]", "mean abs(s) SP_S [A]", "mean abs(s) SP_P [A]"]]
    for k, (a, b) in enumerate(zip(rest["SP_S"], rest["SP_P"])):
        rows.append([str(k + 1), f"{a['q1']:.2f}", _fmt(a["mean_abs_s"]), _fmt(b["mean_abs_s"])])
    parts.append(_grid(rows))
    if "cyclic" in results.get("figures", {}):
        parts.append(f".. image:: {figure_dir}/{results['figures']['cyclic']}\n"
                     "   :alt: monitoring signals of SP_S and SP_P on the cyclic test\n")
    parts.append(_heading("Human-interaction test (Sec. V-B)", "~"))
    parts.append("Thresholds per joint: "
                 + ", ".join(_fmt(v) for v in results["detector"]["thresholds"]) + ".\n")
    rows = [["push", "interval [s]", "robot", "detected", "delay [s]"]]
    for p in inter["pushes"]:
        rows.append([str(p["event"]), f"{p['start_s']:.1f}-{p['stop_s']:.1f}",
                     "moving" if p["while_moving"] else "at rest",
                     "yes" if p["detected"] else "NO", _fmt(p["delay_s"])])
    parts.append(_grid(rows))
    if "interaction" in results.get("figures", {}):
        parts.append(f".. image:: {figure_dir}/{results['figures']['interaction']}\n"
                     "   :alt: the interaction test with the detector's alarms\n")
    return "\n".join(parts)


def pending_section(mode, command):
    """The "Pending" placeholder of a run that has not been added yet."""
    return (
        _heading("Pending", "~")
        + f"\n.. admonition:: Pending: numbers of ``{command}``\n   :class: warning\n\n"
        f"   PLACEHOLDER -- no ``{mode}`` run has been added to the documentation yet, so "
        "no number is shown here. To fill this section, run\n\n"
        f"   .. code-block:: bash\n\n"
        f"      {command} -o docs/{REPRODUCE_DIR.as_posix()}/{mode}\n\n"
        "   and rebuild the documentation: the tables are generated from the run's "
        "``results.json`` and figures.\n"
    )


def write_reproduce_results(srcdir):
    """Write ``generated/reproduce_{quick,full}.rst.inc`` for the results page.

    Returns
    -------
    found : dict of str -> bool
        Whether a ``results.json`` was found for each mode.
    """
    srcdir = Path(srcdir)
    found = {}
    commands = {"quick": "gpcd reproduce --quick", "full": "gpcd reproduce"}
    for mode, command in commands.items():
        run_dir = srcdir / REPRODUCE_DIR / mode
        path = run_dir / "results.json"
        found[mode] = path.is_file()
        if found[mode]:
            results = json.loads(path.read_text())
            text = reproduce_section(results, mode, "/" + (REPRODUCE_DIR / mode).as_posix())
        else:
            text = pending_section(mode, command)
        _write(srcdir / GENERATED / f"reproduce_{mode}.rst.inc", text)
    return found


# -- gallery order -------------------------------------------------------------

#: Gallery examples in reading order; others follow alphabetically, and
#: examples that are not executed (no ``plot_`` prefix) come last.
EXAMPLE_ORDER = (
    "plot_quick_start.py",
    "plot_grid_search_sigma_v.py",
    "plot_threshold_cv.py",
    "plot_streaming_monitor.py",
    "plot_diagnosis_concealed_effect.py",
)


def example_sort_key(filename):
    """Sort key of a gallery example file name (see :data:`EXAMPLE_ORDER`)."""
    if filename in EXAMPLE_ORDER:
        return (0, EXAMPLE_ORDER.index(filename), filename)
    return (1 if filename.startswith("plot_") else 2, 0, filename)
