#!/usr/bin/env bash
# Regenerate requirements/lock.txt: resolve the newest releases that pyproject.toml's bounds allow
# into a fresh virtualenv, then freeze them. Run `bash .ci/run` after it, and commit the lock only
# if CI passes with it: the lock is the set of versions CI has passed with.
set -euo pipefail
cd "$(dirname "$0")/.."
venv=$(mktemp -d)/venv
python3 -m venv "$venv"
"$venv/bin/python" -m pip install -q --upgrade pip
"$venv/bin/python" -m pip install -q -e ".[dev]"
{
  echo "# The versions CI passed with (Python 3.11, Linux x86_64). Regenerate: bash requirements/lock.sh"
  "$venv/bin/python" -m pip freeze --exclude-editable | grep -v '^softevo'
} > requirements/lock.txt
rm -rf "$(dirname "$venv")"
echo "wrote requirements/lock.txt ($(grep -vc '^#' requirements/lock.txt) packages)"
