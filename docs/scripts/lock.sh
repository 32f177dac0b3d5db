#!/usr/bin/env bash
# Write requirements-lock.txt: the exact versions of everything `pip install .` installs, from a
# fresh virtual environment of this checkout, for reproducing the numbers of BENCHMARKS.md and
# docs/studies.md (`pip install -r requirements-lock.txt -e .`). Run from the repository root:
#   bash docs/scripts/lock.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
venv="$(mktemp -d)/venv"
python3 -m venv "$venv"
"$venv/bin/python" -m pip install --quiet -e .
{
    echo "# The exact versions of mjx_balance's dependencies (pip install . in a fresh venv,"
    echo "# $("$venv/bin/python" --version), $(uname -m) Linux), written by docs/scripts/lock.sh."
    echo "# Install: pip install -r requirements-lock.txt -e ."
    "$venv/bin/python" -m pip freeze --exclude-editable --all | grep -v -E '^(pip|setuptools|wheel)=='
} > requirements-lock.txt
rm -rf "$(dirname "$venv")"
echo "wrote requirements-lock.txt ($(grep -vc '^#' requirements-lock.txt) packages)"
