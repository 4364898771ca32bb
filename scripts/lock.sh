#!/usr/bin/env bash
# Regenerates python/requirements.lock: resolves python/requirements.txt in a
# throw-away venv and pins what it installed. Only `name==version` lines are
# kept, so an editable install, a local path or a URL (the project's own
# package, say) can never be written into the lock file.
set -euo pipefail
cd "$(dirname "$0")/.."
base=${PUPPER_BASE_PYTHON:-python3}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$base" -m venv "$tmp/venv"
"$tmp/venv/bin/python" -m pip install -q --disable-pip-version-check -r python/requirements.txt
{
  sed -n '1,/^# Regenerate/p' python/requirements.lock
  "$tmp/venv/bin/python" -m pip freeze --exclude-editable --all \
    | grep -E '^[A-Za-z0-9][A-Za-z0-9._-]*==[^ ;@]+$' \
    | grep -viE '^(pip|setuptools|wheel|pupper[-_]core)=='
} > "$tmp/lock"
mv "$tmp/lock" python/requirements.lock
echo "wrote python/requirements.lock ($(grep -c '==' python/requirements.lock) packages)"
