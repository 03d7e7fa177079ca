#!/usr/bin/env bash
# Build the HTML documentation into docs/_build/html, warnings as errors.
#
#   docs/build.sh            incremental build (sphinx-gallery reruns only changed examples)
#   docs/build.sh clean      remove every generated file first, then build
#   docs/build.sh [clean] -- EXTRA SPHINX OPTIONS, e.g. -- -D plot_gallery=0
#
# Needs the docs extra: python -m pip install -e ".[docs]"
set -euo pipefail
cd "$(dirname "$0")"

if [ "${1:-}" = "clean" ]; then
  shift
  rm -rf _build generated auto_examples gen_modules sg_execution_times.rst
fi
if [ "${1:-}" = "--" ]; then
  shift
fi

# -E re-reads every page: the API pages are generated from the package's
# docstrings, whose changes Sphinx does not track. Executed gallery examples
# are cached by sphinx-gallery (an example reruns when its file changes;
# "clean" reruns them all, e.g. after changing the package).
export MPLBACKEND=Agg
start=$(date +%s)
python -m sphinx -b html -E -W --keep-going -q -d _build/doctrees . _build/html "$@"
echo "docs built in $(( $(date +%s) - start )) s: $(pwd)/_build/html/index.html"
